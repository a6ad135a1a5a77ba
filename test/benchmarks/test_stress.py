"""Stress tests of numerical stability (issue 6), bounded for CI (the whole file in about a minute).

The checks live in ``benchmarks.solvers.stress`` (``python -m benchmarks.solvers stress`` runs them longer, with
the 1e5-period run); here they run at CI sizes. Every check returns a result whose message
names each problem, so a failure says what went wrong.
"""
from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings, strategies as st
import numpy as np
import pytest

from crawler_sim import Crawler, Stepper, gaits, simulate, verify
from benchmarks.solvers import stress
from benchmarks.solvers.stress import (check_close_events, check_friction_ratio,
                                      check_high_frequency, check_history_against_fine,
                                      check_implicit_large_steps, check_long_run,
                                      check_many_bodies, check_mass_ratio, check_penalty_huge_n,
                                      check_random_scene, check_tolerance_ladder,
                                      check_touching_force, check_touching_velocity)

TWO_PI = 2.0 * math.pi


# ------------------------------------------------------------------ random scenes (hypothesis)

@st.composite
def scene_specs(draw) -> dict:
    """Random scenes in the format of ``stress.random_spec``: p from 2 to 12, masses and friction
    forces over six orders of magnitude, frictionless bodies, direction-dependent friction,
    slopes, random smooth gaits (Sinusoid or Fourier, random phases), sometimes v0 != 0."""
    p = draw(st.integers(2, 12))
    decades = st.floats(-3.0, 3.0)
    masses = [10.0 ** draw(decades) for _ in range(p)]
    friction = [0.0 if draw(st.integers(0, 5)) == 0 else 10.0 ** draw(decades)
                for _ in range(p)]
    if draw(st.booleans()):
        backward = [f * 10.0 ** draw(st.floats(-1.0, 1.0)) for f in friction]
    else:
        backward = list(friction)
    slope = draw(st.one_of(st.just(0.0), st.floats(-0.5, 0.5)))
    n = p - 1
    frequency = 10.0 ** draw(st.floats(-0.5, 1.0))
    phases = [draw(st.floats(0.0, TWO_PI)) for _ in range(n)]
    # amplitudes up to 0.1 m about a mean of 0.2 m: a Fourier gait's harmonics add up to at
    # most 1.83 x 0.1 m, so every length stays > 0 (a gait whose bodies cross is refused)
    amplitudes = [10.0 ** draw(st.floats(-3.0, -1.0)) for _ in range(n)]
    if draw(st.booleans()):
        gait = {'type': 'sinusoid', 'mean': 0.2, 'amplitude': amplitudes, 'frequency': frequency,
                'phase': phases}
    else:
        K = draw(st.integers(1, 3))
        extra = [[draw(st.floats(0.0, TWO_PI)) for _ in range(K)] for _ in range(n)]
        amp = [[a / (k + 1) for k in range(K)] for a in amplitudes]
        gait = {'type': 'fourier', 'mean': 0.2, 'frequency': frequency,
                'cos': [[a * math.cos(ph) for a, ph in zip(ar, pr)] for ar, pr in zip(amp, extra)],
                'sin': [[a * math.sin(ph) for a, ph in zip(ar, pr)] for ar, pr in zip(amp, extra)]}
    v0 = draw(st.one_of(st.just(0.0), st.floats(-0.1, 0.1)))
    return {'masses': masses, 'friction': friction, 'friction_backward': backward,
            'slope': slope, 'gait': gait, 'periods': draw(st.floats(1.0, 2.0)), 'v0': v0}


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(scene_specs())
def test_every_method_passes_verify_and_implicit_converges_to_exact_on_random_scenes(spec):
    res = check_random_scene(spec)
    assert res.ok, res.message


def test_random_spec_draws_scenes_that_build_and_cover_the_ranges():
    rng = np.random.default_rng(0)
    specs = [stress.random_spec(rng) for _ in range(200)]
    ps = [len(s['masses']) for s in specs]
    masses = np.concatenate([s['masses'] for s in specs])
    friction = np.concatenate([s['friction'] for s in specs])
    assert min(ps) == 2 and max(ps) == 12
    assert masses.max() / masses.min() > 1e5
    assert np.any(friction == 0.0) and friction.max() / friction[friction > 0].min() > 1e5
    assert any(s['slope'] != 0.0 for s in specs)
    assert any(s['friction'] != s['friction_backward'] for s in specs)
    for s in specs[:20]:
        crawler, gait, t_end, _ = stress.build(s)
        assert crawler.p == gait.n_links + 1 and t_end >= gait.period


# ------------------------------------------------------------------ extremes

def test_mass_ratio_of_a_million_passes_verify_and_implicit_converges():
    res = check_mass_ratio(1e6)
    assert res.ok, res.message


def test_friction_ratio_of_a_million_passes_verify_and_implicit_converges():
    res = check_friction_ratio(1e6)
    assert res.ok, res.message


def test_one_hundred_bodies_pass_verify_with_every_method():
    res = check_many_bodies(100, 1.0, (64,))
    assert res.ok, res.message
    assert res.figures['events'] > 100


def test_a_one_kilohertz_gait_passes_verify_and_implicit_converges():
    res = check_high_frequency(1000.0, 5.0)
    assert res.ok, res.message


def test_implicit_steps_longer_than_the_gait_period_stay_finite_and_bounded():
    res = check_implicit_large_steps((1.0, 3.7, 10.0, 100.0))
    assert res.ok, res.message


def test_penalty_at_n_1e12_is_stable_and_converges_with_the_step():
    res = check_penalty_huge_n(1e12)
    assert res.ok, res.message


def test_two_thousand_periods_keep_a_constant_displacement_per_period_without_drift():
    # Every period computed (periodic skip off) runs at about 500-700 periods/s here, so CI
    # takes 2,000 periods (~5 s); ``python -m benchmarks.solvers stress`` runs 100,000.
    res = check_long_run(2_000)
    assert res.ok, res.message
    assert res.figures['max_rel_deviation'] <= 1e-9
    assert res.figures['skip_vs_full_rel'] <= 1e-9


# ------------------------------------------------------------------ grazing

def test_a_velocity_touching_zero_without_crossing_is_not_a_stick_phase():
    res = check_touching_velocity(3)
    assert res.ok, res.message


def test_a_required_force_touching_its_bound_keeps_the_body_stuck():
    res = check_touching_force(3)
    assert res.ok, res.message


@pytest.mark.parametrize('theta', [1e-2, 1e-3, 1e-5, 1e-6])
def test_transitions_closer_than_the_grid_and_the_sampling_are_found_at_their_times(theta):
    # theta = 1e-6: the slide peaks 1e-12 relative above zero, at rounding level, where the
    # check accepts a missed slide but nothing else
    res = check_close_events(theta, 3)
    assert res.ok, res.message
    assert res.figures['separation'] < 1.0 / 64


def test_close_transitions_agree_with_an_independent_fine_implicit_run():
    res = check_close_events(1e-2, 1, fine_dt=1e-4)
    assert res.ok, res.message


@pytest.mark.parametrize('scene', ['scallop_2body', 'wave_3body', 'slope_climb'])
def test_exact_stick_slip_history_matches_a_fine_implicit_computation(scene):
    res = check_history_against_fine(scene, 1.0, (500, 5_000))
    assert res.ok, res.message


# ------------------------------------------------------------------ regressions
# Each failure mode the stress runs found, reduced to a few lines.

def test_time_steppers_do_not_report_a_moving_frictionless_body_as_stuck_at_the_start():
    # Found by the random scenes: "implicit" and "penalty" copied the initial contact state of a
    # frictionless body as 0 (stuck) while it moved with the gait (verify: stuck velocity).
    crawler = Crawler([1.0, 1.0], [1.0, 0.0])
    gait = gaits.Sinusoid(0.1, 0.01, 1.0)
    for method in ('implicit', 'penalty'):
        tr = simulate(crawler, gait, 1.0, method, dt=0.01, penalty=1e8, t_eval=[0.0, 0.5])
        assert tr.v[0, 1] > 0.0
        assert tr.contact[0, 1] == 1, f'{method}: state at t = 0 is {tr.contact[0].tolist()}'
        assert verify(tr).ok(1e-8)


def test_exact_leaves_rest_when_the_next_transition_falls_inside_the_first_grid_interval():
    # Found by the stiff bench scene: body 0 leaves rest at t = 0 and its velocity returns to
    # zero 3e-4 s later, inside the first bracketing interval (T / 64); the solver used to loop
    # on zero-length segments ("exact solver stalled at t = 0").
    crawler = Crawler([0.002, 0.005], [0.4 * 0.002 * 9.81, 0.4 * 0.005 * 9.81])
    gait = gaits.Sinusoid(0.1, 0.0005, 50.0)
    tr = simulate(crawler, gait, 0.04, t_eval=np.linspace(0.0, 0.04, 9))
    assert verify(tr).ok(1e-9)
    first = [e for e in tr.events if e.body == 0][:3]
    assert [e.new for e in first] == [-1, 0, 1]
    assert first[1].time == pytest.approx(3.0396296374e-4, rel=1e-9)


@pytest.mark.parametrize('scene', ['scallop_2body', 'wave_3body', 'stiff_hf', 'slope_climb'])
def test_exact_runs_and_agrees_over_every_tolerance_and_bracketing_grid(scene):
    res = check_tolerance_ladder(scene)
    assert res.ok, res.message


@pytest.mark.parametrize('scene, kwargs', [
    ('scallop_2body', {'tol': 1e-5}),
    ('scallop_2body', {'tol': 1e-10}),
    ('scallop_2body', {'tol': 1e-10, 'periodic_skip': False}),
    ('stiff_hf', {'tol': 1e-8}),
    ('stiff_hf', {'max_step': 0.02 / 8, 'periodic_skip': False}),
])
def test_exact_does_not_stall_at_a_stick_to_slip_transition_for_any_tolerance(scene, kwargs):
    # Found by the work-precision ladders: at some tolerances the root of a stuck body's force
    # event is returned on the stick side of the bound; the mode choice keeps the body stuck and
    # the solver loops on zero-length segments ("exact solver stalled at t = 0.4993...").
    from benchmarks.solvers.scenes import load_bench_scenes
    sc = load_bench_scenes([scene])[0]
    tr = simulate(sc.crawler, sc.gait, sc.t_end, t_eval=[0.0, sc.t_end], **kwargs)
    ref = simulate(sc.crawler, sc.gait, sc.t_end, t_eval=[0.0, sc.t_end], tol=1e-14,
                   periodic_skip=False)
    assert tr.displacement == pytest.approx(ref.displacement, rel=1e-6, abs=1e-12)


def test_stepper_state_at_each_period_matches_one_long_advance():
    # The long-run check samples with simulate(t_eval = k T); the streaming path must agree.
    crawler, gait = stress.long_run_scene()
    T = gait.period
    st = Stepper(crawler, gait, periodic_skip=False)
    xs = []
    for k in range(1, 21):
        st.advance(k * T)
        xs.append(st.state.x[0])
    tr = simulate(crawler, gait, 20 * T, t_eval=np.arange(1, 21) * T, periodic_skip=False)
    np.testing.assert_allclose(xs, tr.x[:, 0], rtol=0, atol=1e-13)


# A random scene (seed 2, draw 97 of ``stress.random_spec``) on which the exact solver's dip
# search called brentq on a derivative whose grid values changed sign but whose scalar values at
# the same two times did not: "ValueError: f(a) and f(b) must have different signs".
_DIP_SPEC = {
    'masses': [7.261829996220068, 0.010320244371016595, 0.24016283653609324, 11.310046967356566,
               17.619585144435735, 1.8451430188176667, 0.13002734728728513, 0.007232556297732444],
    'friction': [0.0, 0.016852146227376786, 0.26932771303177355, 100.12683731625789,
                 54.14289755126039, 0.0, 411.1419861908179, 52.76958067583772],
    'slope': 0.0, 'periods': 1.5362721040207188, 'v0': 0.0,
    'gait': {'type': 'fourier', 'mean': 0.1, 'frequency': 2.8891929363301743,
             'cos': [[-0.0005468867010172962, -0.0002237771818925955, 0.0003073683060601363],
                     [-0.0009536989290388041, -0.002299218381297738, -0.01503487318396044],
                     [-0.008345145073885268, 0.0036783328795839043, -0.0030957726981529843],
                     [-0.014004476338779928, -0.0010507899020761094, -0.0037379279950440205],
                     [-0.000785825773517925, 0.009023124645156986, 0.0059892091911257295],
                     [-0.0005003236939003805, -0.00040432200538629155, 5.3590531707273324e-05],
                     [-0.07420964117507133, 0.009462475442407496, -0.031653674629575745]],
             'sin': [[-0.000984473542907233, -0.0005167127615732783, 0.00021550863357322912],
                     [-0.045202402212974016, -0.022489003350588586, -0.0010402992385085779],
                     [0.0070709956814982555, -0.004047218030321768, -0.0019260249463105166],
                     [0.010385825511685558, 0.008654104393428083, -0.004450240665370072],
                     [0.018069878242820272, 0.0006064050643993958, 0.0006914060746920999],
                     [0.0014433118050097688, -0.000647990669107262, 0.0005063623273858644],
                     [-0.05925616659975888, 0.04653012561083024, -0.00029213114174518135]]},
}
_DIP_SPEC['friction_backward'] = list(_DIP_SPEC['friction'])


def test_exact_dip_search_does_not_raise_when_grid_and_scalar_rounding_disagree():
    crawler, gait, t_end, v0 = stress.build(_DIP_SPEC)
    tr = simulate(crawler, gait, t_end, v0=v0, t_eval=np.linspace(0.0, t_end, 33))
    assert verify(tr).ok(1e-9)


@pytest.mark.parametrize('max_step', [None, 1.0 / 64, 1e-3])
def test_exact_finds_every_short_slide_whatever_the_bracketing_grid(max_step):
    # Found by the close-events check: body 0 slides forward for 3.2e-4 s around t = k + 1/2
    # (l' = A (cos(theta) + cos(2 pi t)), body 1 held). With max_step = 1/64 the solver found the
    # slides at t = 0.5 and 2.5 but not at 1.5; with max_step = 1e-3 only the first one.
    A, theta, w = 0.02, 1e-3, TWO_PI
    c = math.cos(theta)
    gait = gaits.Custom(lambda t: 0.1 + A * (c * t + math.sin(w * t) / w),
                        lambda t: A * (c + math.cos(w * t)), lambda t: -A * w * math.sin(w * t))
    hold = 100.0 * (0.3 * A * w + 0.05)
    crawler = Crawler([0.3, 0.7], [0.05, hold])
    tr = simulate(crawler, gait, 3.0, v0=-A * (c + 1.0), t_eval=[0.0, 3.0], max_step=max_step)
    starts = [e.time for e in tr.events if e.body == 0 and e.new == 1]
    np.testing.assert_allclose(starts, [k + (math.pi - theta) / w for k in range(3)], atol=1e-9)


# ------------------------------------------------------------------ the long fuzz profile

def test_the_stress_fuzz_check_runs_the_differential_fuzz_and_reports_its_figures():
    # one case per family through the same path `python -m benchmarks.solvers stress` takes: every one must pass
    res = stress.check_fuzz(2, seed=3, families=('custom', 'bang_bang', 'switch_cubic'))
    fig = res.figures
    assert fig['cases'] == 6
    assert set(fig['by_family']) == {'custom', 'bang_bang', 'switch_cubic'}
    for fam, text in fig['by_family'].items():
        assert text.startswith('0/'), (fam, res.problems)


def test_the_custom_period_check_runs_past_512_s_without_failing():
    # issue 37 item 1 at a small size: one Custom copy of a sharp Scallop with period= for
    # 1,000 periods (past 512 s), skip off and on, against its built-in twin
    res = stress.check_custom_period_long(1, 1_000, seed=0)
    assert res.ok, res.problems
    assert res.figures['cases'] == 1 and res.figures['worst_rel'] <= 1e-9


def test_the_penalty_audit_allows_its_force_rounding_and_no_more():
    # stress seed 13, random scene 2741: masses ~1e-3 kg, frictions ~1e-2 N, n = 1e8. The
    # penalty method computes a force as n v; v's rounding (~eps v_max) times n accumulates to
    # a momentum residual of 2.6e-8 of verify's scale (1.2e-9 N s), above the creep-only
    # tolerance of 1.05e-8; the derived bound 4 p n eps v_max / sum f is ~2e-7.
    rng = np.random.default_rng(13)
    for _ in range(2742):
        spec = stress.random_spec(rng)
    crawler, gait, t_end, v0 = stress.build(spec)
    grid = np.linspace(0.0, t_end, int(math.ceil(32 * t_end / gait.period)) + 1)
    pe = simulate(crawler, gait, t_end, 'penalty', dt=gait.period / 100, penalty=1e8,
                  t_eval=grid, v0=v0)
    rep = verify(pe)
    f_max = float(max(crawler.friction.max(), crawler.friction_backward.max()))
    v_max = float(np.abs(pe.v).max())
    creep_only = 2.0 * f_max / (1e8 * v_max) + stress.IMPLICIT_TOL
    assert creep_only < rep.momentum_rel <= stress.tolerances(crawler, 'penalty', pe, 1e8)
    assert stress.check_random_scene(spec).ok
    # the same run at n = 1e4: the rounding term is 1e4 times smaller, the creep term larger
    pe4 = simulate(crawler, gait, t_end, 'penalty', dt=gait.period / 100, penalty=1e4,
                   t_eval=grid, v0=v0)
    assert verify(pe4).momentum_rel <= stress.tolerances(crawler, 'penalty', pe4, 1e4)
