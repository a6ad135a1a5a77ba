"""Gait optimisation: the stroke families, the actuator-limit check and the objective."""
from __future__ import annotations

from dataclasses import replace
import math

import numpy as np
import pytest

from crawler_sim.core.actuator import ActuatorLimits
from crawler_sim.core.scene import scene_from_dict, scene_to_dict
from crawler_sim.sweep.metrics import scene_figures
from crawler_sim.core.plant import Engine
from crawler_sim.core.plant.streams import trajectory_points
from crawler_sim.core.plant.inputs import PreparedTrajectory
from crawler_sim.sweep.optimize import (PENALTY, STREAM, Objective, _violation, family,
                                        optimize, plant_for)

BASE = scene_from_dict({'crawler': {'masses': [0.5, 1.0], 'mu': 0.3},
                        'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                 'frequency': 1.0, 'asymmetry': 0.3}})


def test_the_bang_bang_strokes_speed_excess_is_its_analytic_peak_rate():
    # PiecewiseParabolic.stroke: a_e = 8 A / (r T)^2 = 8 * 0.02 / 0.5^2 = 0.64 m/s^2 and the
    # peak rate a_e r T / 2 = 0.16 m/s (at a breakpoint, which the check samples exactly)
    limits = ActuatorLimits(bandwidth=5.0, max_speed=0.1, max_acceleration=5.0)
    fam = family('stroke', BASE, limits)
    z = np.array([0.02, 1.0, 0.5])
    assert _violation(fam.gait(z), fam, z, limits) == pytest.approx(0.16 / 0.1 - 1, rel=1e-12)
    relaxed = ActuatorLimits(bandwidth=5.0, max_speed=0.16 * 1.001, max_acceleration=0.64 * 1.001)
    assert _violation(fam.gait(z), fam, z, relaxed) == 0.0
    assert _violation(fam.gait(z), fam, z,
                      ActuatorLimits(0.5, 1.0, 1.0)) == pytest.approx(1.0 / 0.5 - 1)  # 1 Hz > 0.5


def test_the_ideal_objective_is_minus_the_steady_speed_and_a_penalty_beyond_the_limits():
    limits = ActuatorLimits()
    fam = family('scallop', BASE, limits)
    obj = Objective(scene_to_dict(BASE), fam, limits, 'speed', periods=10, score='ideal')
    z = np.array([0.035, 1.5, 0.42])           # near the optimum of docs/sweeps.md: it moves
    direct = scene_figures(replace(BASE, gait=fam.gait(z)), 10, 40)   # the same gait by hand
    assert obj(z) == -direct['mean_speed'] and direct['mean_speed'] > 0
    fast = np.array([0.08, 4.9, 0.1])            # 4 pi^2 f^2 A is already ~76 m/s^2 > 5
    assert obj(fast) >= PENALTY
    cot = Objective(scene_to_dict(BASE), fam, limits, 'cot', periods=10, score='ideal')
    assert cot(z) == pytest.approx(direct['cost_of_transport'])
    assert cot(np.array([0.015, 1.0, 0.3])) >= PENALTY / 2    # too gentle to move: no cost


@pytest.mark.parametrize('name, n_params', [('scallop', 3), ('stroke', 3), ('fourier', 6)])
def test_each_family_builds_a_periodic_gait_of_the_right_size_inside_its_bounds(name, n_params):
    fam = family(name, BASE, ActuatorLimits(), harmonics=3)
    assert len(fam.names) == len(fam.bounds) == n_params
    z = np.array([(lo + hi) / 2 for lo, hi in fam.bounds])
    g = fam.gait(z)
    assert g.n_links == 1 and g.period > 0
    assert np.allclose(g(0.0)[0], g(g.period)[0])      # closes after one period


def test_a_three_body_scallop_also_optimises_the_phase_lag():
    three = scene_from_dict({'crawler': {'masses': [1.0, 1.0, 1.0], 'mu': 0.3},
                             'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                      'frequency': 1.0, 'asymmetry': 0.5}})
    fam = family('scallop', three, ActuatorLimits())
    assert fam.names[-1] == 'phase_lag' and fam.bounds[-1] == (-math.pi, math.pi)


def test_the_optimum_beats_every_global_candidate_and_is_reproducible_with_its_seed():
    kw = dict(maxiter=2, popsize=4, local_maxiter=20, periods=8, seed=3)
    a, b = optimize(BASE, **kw), optimize(BASE, **kw)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.best['feasible'] and a.best['score'] == min(h['score'] for h in a.history)
    lo, hi = np.array(a.family.bounds).T
    assert np.all(a.x >= lo) and np.all(a.x <= hi)


def _engine_speed(plant, gait, periods: int) -> float:
    """The steady speed as sim_node's engine computes it, tick by tick with its own sync
    points (an independent path: Engine integrates its pieces in its Stepper; the objective
    hands the actuator's output to ``simulate`` in one call): the preload of gait_node applied
    at tick 0, the centre of mass over the second half of ``periods`` periods."""
    eng = Engine(plant.engine_config())
    T = gait.period
    tfs, pos, vel, acc = trajectory_points(gait, 0.0, periods * T + 0.02, STREAM.rate)
    eng.trajectory(PreparedTrajectory(0, tfs, pos, vel, acc))
    m = plant.crawler.masses
    t, com = [0.0], [float(m @ eng.state.x / m.sum())]
    while eng.t < periods * T + 0.05:
        if eng.tick():
            t.append(eng.t)
            com.append(float(m @ eng.state.x / m.sum()))
    a, b = np.interp([periods / 2 * T, periods * T], t, com)
    return (b - a) / (periods / 2 * T)


@pytest.mark.parametrize('name,z', [('scallop', [0.035, 1.5, 0.42]),
                                    ('stroke', [0.03, 2.0, 0.3])])
def test_the_node_objective_is_the_speed_the_nodes_engine_computes(name, z):
    """Score "node" (the default): gait_node's preloaded trajectory through sim_node's actuator
    on its tick grid. Compared with the node's own engine run tick by tick; the windows differ
    (steady detection vs the second half), which a steady crawl does not notice."""
    limits = ActuatorLimits()
    fam = family(name, BASE, limits)
    plant = plant_for(BASE, fam, limits)
    obj = Objective(scene_to_dict(BASE), fam, limits, 'speed', periods=12, plant=plant.values)
    z = np.array(z)
    got = -obj(z)
    want = _engine_speed(plant, fam.gait(z), 12)
    assert got == pytest.approx(want, rel=1e-3)
    ideal = Objective(scene_to_dict(BASE), fam, limits, 'speed', periods=12, score='ideal')
    assert abs(got + ideal(z)) > 1e-3 * abs(got)       # the servo changes the crawl


def test_the_node_objective_refuses_a_stroke_outside_the_plants_lengths():
    limits = ActuatorLimits()
    fam = family('scallop', BASE, limits)
    plant = plant_for(BASE, fam, limits)
    obj = Objective(scene_to_dict(BASE), fam, limits, 'speed', plant=plant.values)
    assert obj(np.array([0.12, 1.0, 0.3])) >= PENALTY          # l goes below 0
    assert plant.values['min_length'] <= 0.1 - 0.09 and plant.values['max_length'] >= 0.19
    assert obj(np.array([0.09, 1.0, 0.3])) < 0                 # the family's widest stroke
