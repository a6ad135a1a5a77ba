"""Sweep figures: transient detection, hand-derived energies, and the model's symmetries."""
from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_sim.sweep import spec_from_dict
from crawler_sim.sweep.metrics import STEADY_RTOL, scene_figures, steady_window


def scene(masses=(1.0, 1.0), mu=0.3, asymmetry=0.5, **run):
    s = spec_from_dict({'base': {
        'crawler': {'masses': list(masses), 'mu': mu},
        'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                 'asymmetry': asymmetry},
        **({'run': run} if run else {})}})
    return s.scene({})


def test_the_steady_window_starts_where_the_period_displacements_stop_changing():
    # displacements per period 5, 3, 1, 1, 1, 1: periods 0 and 1 are the transient
    x = np.concatenate([[0.0], np.cumsum([5.0, 3.0, 1.0, 1.0, 1.0, 1.0])])
    assert steady_window(x, 1.0) == (2, True)
    # a change just above the tolerance in the second-to-last period leaves one steady period
    x = np.concatenate([[0.0], np.cumsum([1.0, 1.0, 1.0, 1.0 + 3 * STEADY_RTOL, 1.0])])
    assert steady_window(x, 1.0) == (2, False)     # fewer than two agree: last half, flagged


def test_a_stuck_heavy_body_makes_the_light_one_dissipate_its_friction_times_four_amplitudes():
    # body 1 has friction 0.6 * 9.81 = 5.886 N; body 0 sliding needs at most f_0 + m_0 A w^2 =
    # 2.943 + 0.02 (2 pi)^2 = 3.73 N from it, so body 1 never moves and body 0 follows the stroke:
    # it slides 2 A forward and 2 A back per period and dissipates f_0 * 4 A, moving nothing.
    f = scene_figures(scene(mu=[0.3, 0.6]), periods=8, samples_per_period=40)
    assert f['stick_fraction_1'] == 1.0 and f['stick_fraction_0'] == 0.0
    assert f['dissipated_energy'] == pytest.approx(0.3 * 9.81 * 4 * 0.02, rel=1e-12)
    assert f['mean_speed'] == 0.0 and f['steady'] and f['transient_periods'] == 0
    assert math.isinf(f['cost_of_transport'])
    assert f['verify_ok']


def test_an_initial_push_is_detected_as_a_transient_and_the_steady_speed_is_unchanged():
    # the steady state of this crawler does not depend on the initial velocity (it is reached
    # from rest and from a push); only the transient length does
    rest = scene_figures(scene(masses=(0.5, 1.0), asymmetry=0.2), 20, 50)
    push = scene_figures(scene(masses=(0.5, 1.0), asymmetry=0.2, v0=1.0), 20, 50)
    assert push['transient_periods'] > rest['transient_periods']
    assert push['steady'] and rest['steady']
    assert push['mean_speed'] == pytest.approx(rest['mean_speed'], rel=1e-9)
    assert rest['mean_speed'] > 1e-4           # it does move: unequal masses, r = 0.2


@pytest.mark.parametrize('asymmetry', [0.2, 0.5, 0.8])
def test_equal_bodies_have_zero_steady_speed_for_every_stroke(asymmetry):
    # MODEL.md 6: equal masses and frictions are symmetric under x -> -x with the bodies swapped
    f = scene_figures(scene(asymmetry=asymmetry), 20, 50)
    assert f['steady'] and abs(f['mean_speed']) < 1e-12


def test_scaling_masses_and_frictions_together_changes_no_figure_but_the_energies():
    a = scene_figures(scene(masses=(0.5, 1.0), mu=[0.3, 0.5], asymmetry=0.3), 12, 40)
    b = scene_figures(scene(masses=(1.5, 3.0), mu=[0.3, 0.5], asymmetry=0.3), 12, 40)
    for key in ('mean_speed', 'stick_fraction_0', 'stick_fraction_1', 'cost_of_transport'):
        assert b[key] == pytest.approx(a[key], rel=1e-9, abs=1e-15), key
    assert b['dissipated_energy'] == pytest.approx(3 * a['dissipated_energy'], rel=1e-9)
