"""The independent stiction reference (test/support/stiction_reference.py) against the hand
values of STICTION.md s.8 (T1-T5, kinetic twins too), against today's exact method with static =
kinetic, and the exact method with stiction against the reference on random 2- and 3-body scenes
(issue 40: agreement to 1e-9 m).

Notation (STICTION.md): F_i resists forward motion (friction on body i is -F_i); f^{k,+-} kinetic,
f^{s,+-} static bounds [N]; M = sum m_i; X the centre of mass, e_i the offsets (x_i = X + e_i);
for p = 2, e_0 = -m_1 l / M, e_1 = m_0 l / M. Every expected number is derived in the comment
above its test; none comes from crawler_sim.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits
from test.support.stiction_reference import (RULE_SEEDS, Load, StictionReference,
                                             exact_positions, piecewise_accel,
                                             random_scene, reference_positions,
                                             sample_times)

G = 9.81


def _rigid(length: float):
    """A linkage held at ``length``: l' = l'' = 0."""
    def kin(t):
        t = np.asarray(t, float)
        return np.full((t.size, 1), length), np.zeros((t.size, 1)), np.zeros((t.size, 1))
    return kin


def _no_links(t):
    t = np.asarray(t, float)
    return (np.zeros((t.size, 0)),) * 3


# ----------------------------------------------------------------------------------------------
# T1a: one body, m = 1, f^s = 2, f^k = 1, pushed by F(t) = k t, k = 1, at rest.
# Stuck while k t <= f^s: t_b = 2. Then m v' = k t - f^k: v = t(t - 2)/2, v(3) = 3/2,
# x(3) = int_2^3 s(s - 2)/2 ds = [s^3/6 - s^2/2]_2^3 = 0 - (4/3 - 2) = 2/3.
# Kinetic only (f^s = f^k = 1): t_b = 1, v = (t - 1)^2/2 -> v(3) = 2; x = (t - 1)^3/6 -> 4/3.
# ----------------------------------------------------------------------------------------------
RAMP = Load(lambda t: 1.0 * t, lambda t: 0.5 * t * t, lambda t: t ** 3 / 6.0)


@pytest.mark.parametrize('static, t_b, v3, x3', [(2.0, 2.0, 1.5, 2 / 3), (1.0, 1.0, 2.0, 4 / 3)],
                         ids=['stiction', 'kinetic'])
def test_T1a_a_ramp_breaks_a_block_free_at_its_static_bound(static, t_b, v3, x3):
    ref = StictionReference([1.0], 1.0, 1.0, static, static, _no_links, f_ext=RAMP)
    sol = ref.solve(3.0)
    assert sol.events[0][0] == pytest.approx(t_b, abs=1e-12)
    x, v, _ = sol.state_at(3.0)
    assert v[0] == pytest.approx(v3, abs=1e-12)
    assert x[0] == pytest.approx(x3, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# T1b: the same law in the crawler. m = (1, 1); body 0 f^s = 2, f^k = 1; body 1 frictionless;
# l = 1 - t^3/6 (l' = -t^2/2, l'' = -t). Body 0 stuck needs F_0 = -F_1 + M e_0'' = -m_1 l'' = t:
# breaks at t_b = 2; after, M v_0' = -f^k + t, v_0 = t(t - 2)/4, v_0(3) = 3/4,
# x_0(3) - x_0(0) = int_2^3 t(t - 2)/4 dt = 1/3. Kinetic (f^s = 1): t_b = 1,
# v_0 = (t - 1)^2/4, dx_0 = int_1^3 (t - 1)^2/4 dt = 2/3. At t = 0 both bodies are at rest and
# l' = l'' = 0: only l''' tells body 1 goes backward (the degenerate look-ahead, s.10 q.2).
# ----------------------------------------------------------------------------------------------
def _cubic_kin(t):
    t = np.asarray(t, float)[:, None]
    return 1.0 - t ** 3 / 6.0, -0.5 * t * t, -t


@pytest.mark.parametrize('static, t_b, v3, dx3', [(2.0, 2.0, 0.75, 1 / 3),
                                                  (1.0, 1.0, 1.0, 2 / 3)],
                         ids=['stiction', 'kinetic'])
def test_T1b_the_crawler_breaks_body_0_free_when_the_link_force_reaches_its_static_bound(
        static, t_b, v3, dx3):
    ref = StictionReference([1.0, 1.0], [1.0, 0.0], [1.0, 0.0], [static, 0.0],
                            [static, 0.0], _cubic_kin)
    sol = ref.solve(3.0)
    assert sol.events[0][0] == pytest.approx(t_b, abs=1e-12)
    x, v, _ = sol.state_at(3.0)
    assert v[0] == pytest.approx(v3, abs=1e-12)
    assert x[0] - sol.state_at(0.0)[0][0] == pytest.approx(dx3, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# T2: a rigid pair (l = 0.3) on a slope tan(a) = 1/2 (sin = 1/sqrt5, cos = 2/sqrt5), m = (1, 2),
# mu^s = (0.7, 0.55), mu^k = (0.5, 0.35): sum mu^k m = 1.2, sum mu^s m = 1.8. Weight along the
# slope M g sin a = 3g/sqrt5 is within the static capacity 3.6g/sqrt5, above the kinetic 2.4g/sqrt5.
# (a) launched uphill V0 = 1: a_up = -(3 sin + 1.2 cos) g/3 = -1.8g/sqrt5, stops at
# t_s = sqrt5/(1.8g), X_s = sqrt5/(3.6g); Rule S (arrival) sticks: X(2) = X_s. Kinetic: slides
# back at a_dn = -(3 sin - 1.2 cos) g/3 = -0.2g/sqrt5: X(2) = X_s + a_dn (2 - t_s)^2/2.
# (b) from rest: stiction X(2) = 0; kinetic X(2) = a_dn 2^2/2 = -0.4g/sqrt5.
# ----------------------------------------------------------------------------------------------
S5 = math.sqrt(5.0)
T_S = S5 / (1.8 * G)
X_S = S5 / (3.6 * G)
A_DN = -0.2 * G / S5


@pytest.mark.parametrize('static, v0, X2', [
    (True, 1.0, X_S), (False, 1.0, X_S + A_DN * (2 - T_S) ** 2 / 2),
    (True, 0.0, 0.0), (False, 0.0, -0.4 * G / S5)],
    ids=['stiction-launched', 'kinetic-launched', 'stiction-rest', 'kinetic-rest'])
def test_T2_a_pair_on_a_slope_holds_with_stiction_and_slides_back_without(static, v0, X2):
    m = np.array([1.0, 2.0])
    cos, sin = 2 / S5, 1 / S5
    fk = np.array([0.5, 0.35]) * m * G * cos
    fs = np.array([0.7, 0.55]) * m * G * cos if static else fk
    ref = StictionReference(m, fk, fk, fs, fs, _rigid(0.3), f_ext=-3.0 * G * sin)
    sol = ref.solve(2.0, v0=v0, h=1e-3)
    X0 = sol.com(0.0)[0]
    assert sol.com(2.0)[0] - X0 == pytest.approx(X2, abs=1e-12)
    if v0:
        assert sol.events[0][0] == pytest.approx(T_S, abs=1e-13)


# ----------------------------------------------------------------------------------------------
# T3: bang-bang inchworm, m = (1, 1), both bodies f^{k,+} = 1, f^{k,-} = 4, f^{s,+} = 2,
# f^{s,-} = 5; period 6: l'' = +A, -A, 0, -A, +A, 0 on unit steps, A = 2.5 (l' = 0 at 0, 2, 3, 5).
# Stuck requirements (other body kinetic; e_0'' = -l''/2, e_1'' = +l''/2):
#   extension l'' = +A: F_0 = -f^{k,+} - A = -3.5 (in [-5, 2]); F_1 = f^{k,-} + A = 6.5 (> 2);
#   slide: a = (4 - 1)/2 = 1.5 < -e_0'' ... not consistent -> body 0 holds; at t = 1,
#   F_0 = -1 + 2.5 = 1.5 <= 2: holds; dwell: 0; contraction mirrors with body 1.
# So each body advances A tau^2 = 2.5 a period: X(6k) - X(0) = 2.5 k (stiction).
# Kinetic (f^s = f^k): body 0 breaks at t = 1 (1.5 > 1); both slide with a = -1 from
# V(1) = l'(1)/2 = 1.25: V = 2.25 - t, v_0 = V + e_0' = (t - 1)/4 -> v_0(1.5) = 1/8,
# V(2.1) = 0.15 (the rigid pair decelerates at 1 from 0.25 at t = 2). Per half period
# 0.625 + 0.75 + 0.03125 = 1.40625: X(6k) - X(0) = 2.8125 k.
# ----------------------------------------------------------------------------------------------
A3 = 2.5
T3_KIN, T3_BREAKS = piecewise_accel(1.0, 0.0, [0, 1, 2, 3, 4, 5, 6],
                                    [A3, -A3, 0, -A3, A3, 0], 6.0)


def _t3(static: bool) -> StictionReference:
    fs, fsb = (2.0, 5.0) if static else (1.0, 4.0)
    return StictionReference([1.0, 1.0], 1.0, 4.0, fs, fsb, T3_KIN,
                             breakpoints=T3_BREAKS(18.0))


@pytest.mark.parametrize('static, per_period', [(True, 2.5), (False, 2.8125)],
                         ids=['stiction', 'kinetic'])
def test_T3_the_inchworm_advances_2_5_a_period_with_stiction_and_2_8125_without(
        static, per_period):
    sol = _t3(static).solve(18.0, h=2e-3)
    X0 = sol.com(0.0)[0]
    for k in (1, 2, 3):
        assert sol.com(6.0 * k)[0] - X0 == pytest.approx(per_period * k, abs=1e-12)
    assert not any(d.tie for d in sol.flags)


def test_T3_kinetic_intermediate_velocities():
    sol = _t3(False).solve(3.0, h=2e-3)
    assert sol.state_at(1.5)[1][0] == pytest.approx(0.125, abs=1e-12)
    assert sol.com(2.1)[1] == pytest.approx(0.15, abs=1e-12)


def test_T3_with_stiction_a_body_is_always_stuck_and_its_force_stays_static():
    # the stuck body's total F_C^req is within its static bounds [-5, 2] at every sampled time,
    # and reaches +1.5 (> f^{k,+} = 1: held only by stiction) on [1, 2)
    sol = _t3(True).solve(6.0, h=2e-3)
    totals = [sol.friction(t)[1] for t in np.linspace(0.01, 5.99, 200)]
    assert all(-5.0 <= F <= 2.0 for F in totals)
    assert sol.friction(1.5)[1] == pytest.approx(1.5, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# T4: one body, m = 1, f^s = 2, f^k = 1, F_ext = 1.5, at rest. Rule S holds it: x(2) = 0;
# the kinetic model slides: x = (1.5 - 1) t^2 / 2 -> x(2) = 1. With stiction both continuations
# are consistent at t = 0 (1.5 in [-2, 2]; slide a = 0.5 > 0): the decision is flagged (2).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('static, x2, flagged', [(2.0, 0.0, 2), (1.0, 1.0, None)],
                         ids=['stiction', 'kinetic'])
def test_T4_a_push_between_kinetic_and_static_holds_only_with_stiction(static, x2, flagged):
    sol = StictionReference([1.0], 1.0, 1.0, static, static, _no_links,
                            f_ext=1.5).solve(2.0)
    assert sol.state_at(2.0)[0][0] == pytest.approx(x2, abs=1e-12)
    assert [d.n_consistent for d in sol.flags if d.t == 0.0] == ([flagged] if flagged else [])


# ----------------------------------------------------------------------------------------------
# T5: stroke reversal, m = (1, 1), F_ext = 0; body 0 f^k = 1, f^s = 2; body 1 f^k = 1,
# f^s = 2.5; l'' = +0.5 on [0, 2), -0.5 on [2, 4), periodic; l'(0) = -0.5; body 0 at rest.
# At t = 1 (l' = 0, link starts extending): body 0 stuck needs F_0 = -f_1^k - m_1 l'' = -1.5
# (margin 0.5), body 1 stuck needs F_1 = f_0^k + m_0 l'' = +1.5 (margin 1.0), the slide
# a = 0 in (-0.25, 0.25): three continuations (flagged at 1, 3, 5, 7).
# Rule S: body 0 incumbent holds forever: x_0(8) - x_0(0) = 0.
# Margin: body 1 sticks at t = 1 (margin 1.0 > 0.5) and again wins at t = 3, where l'' = -0.5
# (body 1 stuck, body 0 slides forward: F_1 = -f_0^{k,+} + M e_1'' = -1 - 0.5 = -1.5, margin
# min(-1.5 + 2.5, 2.5 + 1.5) = 1.0; body 0 stuck, body 1 slides backward: F_0 = f_1^{k,-} +
# M e_0'' = 1 + 0.5 = 1.5, margin min(1.5 + 2, 2 - 1.5) = 0.5): anchored from t = 1,
# x_1(8) - x_1(0) = int_0^1 l' = int_0^1 (-0.5 + 0.5 t) dt = -1/4, and X - X(0) the same
# (l(8) = l(0), x_1 = X + l/2).
# Kinetic: slide apart with V = 0 from t = 1: X(8) - X(0) = (l(1) - l(0))/2 = -1/8.
# ----------------------------------------------------------------------------------------------
T5_KIN, T5_BREAKS = piecewise_accel(1.0, -0.5, [0, 2, 4], [0.5, -0.5], 4.0)


@pytest.mark.parametrize('static, rule, body, dx', [
    ((2.0, 2.5), 'incumbent', 0, 0.0), ((2.0, 2.5), 'margin', 1, -0.25),
    ((2.0, 2.5), 'margin', None, -0.25), ((1.0, 1.0), 'incumbent', None, -0.125)],
    ids=['rule-S', 'margin-body1', 'margin-com', 'kinetic-com'])
def test_T5_the_rule_decides_the_stroke_reversal(static, rule, body, dx):
    ref = StictionReference([1.0, 1.0], 1.0, 1.0, static, static, T5_KIN,
                            breakpoints=T5_BREAKS(8.0))
    sol = ref.solve(8.0, rule=rule, h=2e-3)
    if body is None:
        got = sol.com(8.0)[0] - sol.com(0.0)[0]
    else:
        got = sol.state_at(8.0)[0][body] - sol.state_at(0.0)[0][body]
    assert got == pytest.approx(dx, abs=1e-12)
    if rule == 'incumbent' and static[0] > 1.0:
        assert [(d.t, d.n_consistent) for d in sol.flags] == [(1.0, 3), (3.0, 3), (5.0, 3),
                                                              (7.0, 3)]


# ----------------------------------------------------------------------------------------------
# Random 2- and 3-body scenes (stiction_reference.random_scene): masses, kinetic bounds each
# direction, static bounds up to twice the kinetic ones, a slope, and a Sinusoid, Fourier or
# bang-bang gait of the core whose l, l', l'' the support module writes from the formulas (the
# reference never evaluates a crawler_sim gait). Positions are compared at five times over three
# periods, to 1e-9 m (issue 40).
# ----------------------------------------------------------------------------------------------
SEEDS = range(32)      # 8 of each family, half of them 3-body


@pytest.mark.parametrize('seed', SEEDS)
def test_with_static_equal_to_kinetic_the_reference_agrees_with_todays_exact_method(seed):
    # the reference's kinetic answers against the exact method as it was before stiction (an
    # independent check of the reference's scan, decisions and closed forms)
    sc = random_scene(seed, stiction=False)
    crawler = cs.Crawler(sc['masses'], sc['friction'], sc['friction_backward'],
                         slope=sc['slope'], gravity=G)
    times = sample_times(sc)
    run = cs.simulate(crawler, sc['gait'], times[-1], method='exact', t_eval=times)
    assert np.max(np.abs(run.x - reference_positions(sc))) <= 1e-9


def _stiction_crawler(sc) -> cs.Crawler:
    """The scene's crawler with its static bounds [N] (issue 40's contract)."""
    return cs.Crawler(sc['masses'], sc['friction'], sc['friction_backward'],
                      slope=sc['slope'], gravity=G, static_friction=sc['static_friction'],
                      static_friction_backward=sc['static_friction_backward'])


@pytest.mark.parametrize('rule', ['incumbent', 'margin'])
@pytest.mark.parametrize('seed', SEEDS)
def test_the_exact_method_with_stiction_agrees_with_the_reference_on_random_scenes(seed, rule):
    sc = random_scene(seed)
    got = exact_positions(sc, rule)
    want = reference_positions(sc, rule)
    err = np.abs(got - want)
    assert err.max() <= 1e-9, (f'seed {seed}, rule {rule}: times {sample_times(sc).tolist()}, '
                               f'exact {got.tolist()}, reference {want.tolist()}')


# ----------------------------------------------------------------------------------------------
# initial_stuck: T5's crawler on its stroke shifted by 1 s, so t = 0 is the reversal with both
# bodies at rest (l'(0) = 0, v0 = 0): l'' = +0.5 on [0, 1), -0.5 on [1, 3), +0.5 on [3, 4).
# At t = 0 (link extending): body 0 stuck needs -1.5 (margin 0.5), body 1 stuck +1.5 (margin
# 1.0). No incumbent: Rule S takes the margin, body 1 holds, body 0 moves with the link:
# x_0(1) - x_0(0) = -(l(1) - l(0)) = -int_0^1 0.5 t dt = -0.25. initial_stuck=0: body 0 is the
# incumbent and can hold: x_0(1) - x_0(0) = 0. initial_stuck=1: body 1, -0.25.
# ----------------------------------------------------------------------------------------------
SHIFTED_KIN, SHIFTED_BREAKS = piecewise_accel(1.0, 0.0, [0, 1, 3, 4], [0.5, -0.5, 0.5], 4.0)


@pytest.mark.parametrize('stuck, dx0', [(None, -0.25), (0, 0.0), (1, -0.25)])
def test_initial_stuck_names_the_incumbent_at_a_start_from_coincident_rest(stuck, dx0):
    ref = StictionReference([1.0, 1.0], 1.0, 1.0, [2.0, 2.5], [2.0, 2.5], SHIFTED_KIN,
                            breakpoints=SHIFTED_BREAKS(1.0))
    sol = ref.solve(1.0, h=1e-3, initial_stuck=stuck)
    assert sol.state_at(1.0)[0][0] - sol.state_at(0.0)[0][0] == pytest.approx(dx0, abs=1e-12)
    crawler = cs.Crawler([1.0, 1.0], 1.0, static_friction=[2.0, 2.5])
    gait = gaits.PiecewiseParabolic([0, 1, 3, 4], [0.5, -0.5, 0.5], l0=1.0)
    run = cs.simulate(crawler, gait, 1.0, initial_stuck=stuck)
    assert run.state_at(1.0).x[0] - run.state_at(0.0).x[0] == pytest.approx(dx0, abs=1e-12)




@pytest.mark.parametrize('rule', ['incumbent', 'margin'])
@pytest.mark.parametrize('seed', RULE_SEEDS)
def test_the_exact_method_applies_the_chosen_rule_where_rule_s_and_margin_differ(seed, rule):
    sc = random_scene(seed, family='reversal')
    want = reference_positions(sc, rule)
    other = reference_positions(sc, 'margin' if rule == 'incumbent' else 'incumbent')
    assert np.abs(want - other).max() > 1e-3          # the scene does tell the rules apart
    got = exact_positions(sc, rule)
    assert np.abs(got - want).max() <= 1e-9, (
        f'reversal seed {seed}, rule {rule}: times {sample_times(sc).tolist()}, '
        f'exact {got.tolist()}, reference {want.tolist()}')


@pytest.mark.parametrize('seed', range(0, 32, 3))
def test_the_reference_does_not_depend_on_its_scan_step(seed):
    # events are roots refined to ~1e-15 s whatever the grid, so a 4x coarser scan gives the
    # same positions unless an event was missed or misplaced
    sc = random_scene(seed)
    T, times = sc['period'], sample_times(sc)
    fine = sc['ref'].solve(times[-1], h=T / 4000).positions(times)
    coarse = sc['ref'].solve(times[-1], h=T / 1000).positions(times)
    assert np.max(np.abs(fine - coarse)) <= 1e-12


@pytest.mark.parametrize('seed', range(0, 32, 2))
def test_the_exact_method_reports_the_instants_where_the_rule_chose(seed):
    # the instants with more than one consistent continuation (STICTION.md s.3, U1-U3): the
    # reference's flagged decisions against the run's info['choice_times'] (every period
    # integrated), to 1e-9 s
    sc = random_scene(seed)
    T = sc['period']
    crawler = _stiction_crawler(sc)
    info = cs.simulate(crawler, sc['gait'], 3 * T, periodic_skip=False).info
    want = [d.t for d in sc['ref'].solve(3 * T, h=T / 4000).flags]
    got = np.asarray(info['choice_times'], float)
    assert got.shape == (len(want),), (got.tolist(), want)
    assert np.max(np.abs(got - want), initial=0.0) <= 1e-9


@pytest.mark.parametrize('rule', ['incumbent', 'margin'])
@pytest.mark.parametrize('seed', [3, 12, 21, 27])
def test_the_exact_method_agrees_with_the_reference_over_20_periods(seed, rule):
    # long enough for the exact method's periodic skip (seeds 3, 12 and 21 skip 18 of the 20
    # periods, 27 none), so the incumbent carried across skipped periods is checked too
    sc = random_scene(seed)
    T = sc['period']
    times = np.array([12.3, 19.6, 20.0]) * T
    run = cs.simulate(_stiction_crawler(sc), sc['gait'], times[-1], t_eval=times,
                      stiction_rule=rule)
    want = sc['ref'].solve(times[-1], h=T / 2000, rule=rule).positions(times)
    assert np.max(np.abs(run.x - want)) <= 1e-9


@pytest.mark.parametrize('seed', [0, 3, 4, 6])
def test_the_implicit_method_with_stiction_converges_to_the_reference_at_first_order(seed):
    # halving dt halves the error against the independent reference (issue 40: slope 0.9-1.1);
    # measured 0.998-1.013 on these four scenes (one of each family)
    sc = random_scene(seed)
    times = sample_times(sc)
    crawler = _stiction_crawler(sc)
    want = reference_positions(sc)
    dts = np.array([2e-3, 1e-3, 5e-4])
    errs = np.array([np.max(np.abs(cs.simulate(crawler, sc['gait'], times[-1], method='implicit',
                                               dt=dt, t_eval=times).x - want)) for dt in dts])
    slopes = np.log(errs[:-1] / errs[1:]) / np.log(dts[:-1] / dts[1:])
    assert np.all((slopes >= 0.9) & (slopes <= 1.1)), (errs.tolist(), slopes.tolist())
