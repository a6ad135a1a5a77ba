"""The exact method with stiction (issue 40): STICTION.md's hand-derived cases, zero drift at
rest, Rule S's options, the incumbent as state.

Notation (STICTION.md, MODEL.md s. 2): M = sum m_i, X the centre of mass, e_i = x_i - X,
l = x_1 - x_0 for p = 2 (e_0 = -m_1 l / M, e_1 = m_0 l / M). Ground force R_i on body i (the
code's ``friction``): -f^{k,+}_i sliding forward, +f^{k,-}_i sliding backward, anywhere in
[-f^{s,+}_i, f^{s,-}_i] stuck. M V' = F_ext + sum R_i, F_ext = -M g sin(slope). Every expected
number is derived by hand in the comment above its test (STICTION.md s. 8 gives the same).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_sim.core.gaits import Cubic, PiecewiseParabolic
from crawler_sim.core.model import Crawler
from crawler_sim.core.solvers.base import capabilities
from crawler_sim.core.stepper import Stepper, simulate

G = 9.81
TOL = 1e-12


def com(tr, crawler):
    return tr.x @ crawler.masses / crawler.total_mass


# ----------------------------------------------------------------------------------------------
# T1b: body 0 with f^s = 2, f^k = 1, body 1 frictionless, m = (1, 1), l = 5 - t^3/6 (l'' = -t).
# Body 0 stuck: R_0 = -M e_0'' - R_1 = m_1 l'' = -t (e_0'' = -m_1 l''/M, R_1 = 0): it holds
# while t <= f^{s,+} = 2 (t_b = 2). Then body 0 slides forward: M V' = -f^{k,+} = -1, so
# v_0' = V' + e_0'' = -1/2 + t/2 and, from v_0(2) = 0, v_0(t) = ((t-1)^2 - 1)/4 = t(t-2)/4:
# v_0(3) = 3/4, x_0(3) - x_0(0) = int_2^3 t(t-2)/4 dt
# = [t^3/12 - t^2/4]_2^3 = (27/12 - 9/4) - (8/12 - 1) = 1/3. Kinetic: t_b = 1, v_0 = (t-1)^2/4,
# x_0(3) - x_0(0) = int_1^3 (t-1)^2/4 = 8/12 = 2/3.
# ----------------------------------------------------------------------------------------------
T1B_GAIT = Cubic(0.0, 5.0, 0.0, 0.0, -1.0)


def test_t1b_breakaway_under_a_ramp_is_at_the_static_bound_and_slides_at_the_kinetic_one():
    c = Crawler([1.0, 1.0], [1.0, 0.0], static_friction=[2.0, 0.0])
    tr = simulate(c, T1B_GAIT, 3.0, t_eval=[0.0, 3.0])
    assert [(e.time, e.body, e.old, e.new) for e in tr.events] == [(2.0, 0, 0, 1)]
    assert abs(tr.x[-1, 0] - tr.x[0, 0] - 1 / 3) <= TOL
    assert abs(tr.v[-1, 0] - 0.75) <= TOL
    kin = simulate(Crawler([1.0, 1.0], [1.0, 0.0]), T1B_GAIT, 3.0, t_eval=[0.0, 3.0])
    assert abs(kin.x[-1, 0] - kin.x[0, 0] - 2 / 3) <= TOL


# ----------------------------------------------------------------------------------------------
# T2: rigid pair (l = 0.3) on tan(a) = 1/2 (sin a = 1/sqrt5, cos a = 2/sqrt5), m = (1, 2),
# mu^k = (0.5, 0.35), mu^s = (0.7, 0.55): sum mu^k m = 1.2, sum mu^s m = 1.8, M = 3.
# Weight along the slope M g sin a = 3g/sqrt5, within the static capacity 3.6 g/sqrt5 but above
# the kinetic 2.4 g/sqrt5.
# (a) launched uphill at V0 = 1: a_up = -(3 sin a + 1.2 cos a) g / 3 = -1.8 g/sqrt5, stops at
#     t_s = sqrt5/(1.8 g) at X_s = V0^2 / (2 |a_up|) = sqrt5/(3.6 g), then sticks (arrival within
#     the static interval): X(2) = X_s. Kinetic: slides back at a_dn = -(3 sin a - 1.2 cos a) g/3
#     = -0.2 g/sqrt5: X(2) = X_s + a_dn (2 - t_s)^2 / 2.
# (b) from rest: holds, X(2) = 0; kinetic X(2) = a_dn 2^2/2 = -0.4 g/sqrt5.
# ----------------------------------------------------------------------------------------------
T2_SLOPE = math.atan(0.5)
T2_GAIT = PiecewiseParabolic([0.0, 1.0], [0.0], 0.3, 0.0, periodic=False)


def t2_crawler(stiction: bool = True) -> Crawler:
    kw = {'mu_static': [0.7, 0.55]} if stiction else {}
    return Crawler([1.0, 2.0], slope=T2_SLOPE, mu=[0.5, 0.35], **kw)


@pytest.mark.parametrize('v0', [1.0, 0.0], ids=['launched_uphill', 'from_rest'])
def test_t2_a_pair_on_a_slope_holds_with_stiction_and_slides_with_kinetic_friction(v0):
    s5 = math.sqrt(5.0)
    t_s, x_s, a_dn = s5 / (1.8 * G), s5 / (3.6 * G), -0.2 * G / s5
    c = t2_crawler()
    tr = simulate(c, T2_GAIT, 2.0, t_eval=[0.0, 2.0], v0=v0)
    X = com(tr, c)
    assert abs(X[-1] - X[0] - (x_s if v0 else 0.0)) <= TOL
    if v0:
        assert abs(tr.events[0].time - t_s) <= TOL
    ck = t2_crawler(False)
    kin = simulate(ck, T2_GAIT, 2.0, t_eval=[0.0, 2.0], v0=v0)
    Xk = com(kin, ck)
    expect = x_s + a_dn * (2 - t_s) ** 2 / 2 if v0 else a_dn * 2.0
    assert abs(Xk[-1] - Xk[0] - expect) <= 1e-9 * (1 + abs(expect))


# ----------------------------------------------------------------------------------------------
# T3: bang-bang inchworm, m = (1, 1), f^{k,+} = 1, f^{k,-} = 4, f^{s,+} = 2, f^{s,-} = 5 on both
# bodies; l'' = +A, -A, 0, -A, +A, 0 on unit pieces, A = 2.5, period 6. With e_0'' = -l''/2:
# extension, body 0 stuck, body 1 sliding forward (R_1 = -1): R_0 = -M e_0'' - R_1 = l'' + 1
# = 3.5 (l'' = A) then -1.5 (l'' = -A), both inside [-f^{s,+}, f^{s,-}] = [-2, 5]; t = 2: the
# pair, rigid in the dwell, needs 0; t = 3 (l'' = -A): body 0 stuck would leave body 1 sliding
# backward (R_1 = +4) and need R_0 = l'' - 4 = -6.5 < -2; body 1 stuck leaves body 0 sliding
# forward (R_0 = -1) and needs R_1 = -M e_1'' + 1 = -l'' + 1 = 3.5, inside: body 1 holds; the
# mirror image follows. Each body advances by the stroke A tau^2 = 2.5 per period: X(6k) = 2.5 k.
# Kinetic (f^s = f^k): body 0 breaks at t = 1 (needs 1.5 > 1) and the pair glides: 2.8125 per
# period (STICTION.md s. 8: 0.625 + 0.75 + 0.03125 per half period).
# ----------------------------------------------------------------------------------------------
A3 = 2.5
T3_GAIT = PiecewiseParabolic([0, 1, 2, 3, 4, 5, 6], [A3, -A3, 0.0, -A3, A3, 0.0], 1.0, 0.0)


@pytest.mark.parametrize('skip', [False, True])
def test_t3_the_inchworm_advances_its_stroke_per_period_with_stiction(skip):
    c = Crawler([1.0, 1.0], 1.0, 4.0, static_friction=2.0, static_friction_backward=5.0)
    tr = simulate(c, T3_GAIT, 18.0, t_eval=[0.0, 6.0, 12.0, 18.0], periodic_skip=skip)
    X = com(tr, c)
    np.testing.assert_allclose(X - X[0], [0.0, 2.5, 5.0, 7.5], rtol=0, atol=TOL)
    kin = simulate(Crawler([1.0, 1.0], 1.0, 4.0), T3_GAIT, 18.0, t_eval=[0.0, 6.0, 12.0, 18.0])
    Xk = com(kin, c)
    np.testing.assert_allclose(Xk - Xk[0], [0.0, 2.8125, 5.625, 8.4375], rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------------------------
# T4: a rigid pair (m = (0.5, 0.5), M = 1) pushed down a slope by F_ext = 1.5 N, f^s = 1 + 1,
# f^k = 0.5 + 0.5: at rest, both "stays" (1.5 <= 2) and "slides at (1.5 - 1)/M" are consistent.
# Rule S holds: x(2) = 0; the kinetic crawler slides (1.5 - 1)/M 2^2 / 2 = 1 m forward (downhill
# is +x: slope < 0).
# ----------------------------------------------------------------------------------------------
def test_t4_a_start_from_rest_with_two_continuations_holds_and_is_flagged():
    slope = math.asin(-1.5 / G)
    c = Crawler([0.5, 0.5], 0.5, static_friction=1.0, slope=slope)
    tr = simulate(c, T2_GAIT, 2.0, t_eval=[0.0, 2.0])
    assert tr.x[-1, 0] == tr.x[0, 0]
    assert tr.info['choices'] == 1 and tr.info['choice_times'].tolist() == [0.0]
    kin = simulate(Crawler([0.5, 0.5], 0.5, slope=slope), T2_GAIT, 2.0, t_eval=[0.0, 2.0])
    assert abs(kin.x[-1, 0] - kin.x[0, 0] - 1.0) <= TOL


# ----------------------------------------------------------------------------------------------
# T5: m = (1, 1), f^k = 1 on both, f^s = (2, 2.5); l'' = +0.5 on [0, 2), -0.5 on [2, 4),
# periodic, l'(0) = -0.5: l' = 0 at t = 1, 3, 5, 7. Body 0 at rest at t = 0 (v0 = 0), body 1
# sliding backward. At t = 1 (e_0'' = -0.25, e_1'' = +0.25) three continuations are consistent:
# body 0 holds (R_0 = -M e_0'' + f^{k,+}_1 = 1.5, margin 0.5 in [-2, 2]), body 1 holds
# (R_1 = -M e_1'' - f^{k,-}_0 = -1.5, margin 1.0 in [-2.5, 2.5]), both slide (a = 0).
# Rule S ('incumbent'): body 0 was stuck on [0, 1): it holds, and again at t = 3, 5, 7 (the
# mirror needs -1.5 there): x_0(8) - x_0(0) = 0. 'margin': body 1 holds from t = 1 on:
# x_1(8) - x_1(0) = int_0^1 l' dt = -0.5 + 0.25 = -1/4, and X(8) - X(0) = -1/4.
# ----------------------------------------------------------------------------------------------
T5_GAIT = PiecewiseParabolic([0.0, 2.0, 4.0], [0.5, -0.5], 1.0, -0.5)
T5_CRAWLER = Crawler([1.0, 1.0], 1.0, static_friction=[2.0, 2.5])


@pytest.mark.parametrize('rule, anchored, shift', [('incumbent', 0, 0.0), ('margin', 1, -0.25)])
def test_t5_the_rule_at_a_stroke_reversal_decides_which_body_anchors(rule, anchored, shift):
    c = T5_CRAWLER
    tr = simulate(c, T5_GAIT, 8.0, t_eval=[0.0, 8.0], stiction_rule=rule, initial_stuck=0)
    X = com(tr, c)
    assert abs(X[-1] - X[0] - shift) <= TOL
    assert abs(tr.x[-1, anchored] - tr.x[0, anchored] - shift) <= TOL
    # flagged at every reversal with its three continuations
    assert tr.info['choice_times'].tolist() == [1.0, 3.0, 5.0, 7.0]
    st = Stepper(c, T5_GAIT, stiction_rule=rule, initial_stuck=0)
    st.advance(1.5)           # (the decision at t = 1 is taken by the call that goes past it)
    assert st.solver.choices == [(1.0, 3, False)]


def test_the_incumbent_is_state_the_stepper_reports_and_keeps_across_calls():
    st = Stepper(T5_CRAWLER, T5_GAIT, initial_stuck=0)
    assert st.state.incumbent.tolist() == [True, False]
    x0 = st.state.x[0]
    for t in np.linspace(0.25, 8.0, 32):
        st.advance(float(t))        # streamed: every call ends inside a segment
        assert st.state.incumbent.tolist() == [True, False]
    assert st.state.x[0] == x0
    st.reset(t0=0.0, x0=0.0, v0=0.0)                     # no incumbent after a plain reset
    assert st.state.incumbent.tolist() == [False, False]
    st.reset(t0=0.0, x0=0.0, v0=0.5, initial_stuck=1)    # body 1 at rest: v0 + l'(0) = 0
    assert st.state.incumbent.tolist() == [False, True]
    with pytest.raises(ValueError, match='initial_stuck: body 0 must be at rest'):
        st.reset(t0=0.0, x0=0.0, v0=0.5, initial_stuck=0)


def test_initial_stuck_is_refused_naming_it_for_a_moving_body_or_a_bad_index():
    with pytest.raises(ValueError, match=r'initial_stuck: body 1 must be at rest'):
        Stepper(T5_CRAWLER, T5_GAIT, initial_stuck=1)
    with pytest.raises(ValueError, match=r'initial_stuck must be None or a body index in \[0, 1\]'):
        simulate(T5_CRAWLER, T5_GAIT, 1.0, initial_stuck=2)
    with pytest.raises(ValueError, match='stiction_rule'):
        simulate(T5_CRAWLER, T5_GAIT, 1.0, stiction_rule='largest')


def test_a_method_without_the_stiction_capability_is_refused_naming_it():
    assert capabilities('exact').stiction and not capabilities('penalty').stiction
    with pytest.raises(ValueError, match="method 'penalty' cannot simulate static friction"):
        simulate(T5_CRAWLER, T5_GAIT, 1.0, method='penalty')


# ----------------------------------------------------------------------------------------------
# Zero drift at rest over 1e4 s under a steady push between the kinetic and the static capacity
# (kinetic = 0.5 static). Flat: body `stuck` has f^s = 1, the other is frictionless, m = (1, 1),
# and the gait accelerates the link at constant l'' = q: the stuck body needs R = -M e'' =
# +q (body 0, e_0'' = -l''/2) or -q (body 1): a push of q of its static capacity. Slope: a rigid
# pair whose weight along the slope is q of the static capacity, tan(a) = q mu^s, up or down.
# The kinetic crawler moves in every case (the push exceeds its capacity).
# ----------------------------------------------------------------------------------------------
PUSHES = [0.51, 0.75, 0.9, 0.999]
T_REST = 1e4


@pytest.mark.parametrize('q', PUSHES)
@pytest.mark.parametrize('stuck', [0, 1])
def test_zero_drift_on_flat_ground_under_a_steady_push_below_the_static_capacity(q, stuck):
    fk = [0.5, 0.0] if stuck == 0 else [0.0, 0.5]
    fs = [1.0, 0.0] if stuck == 0 else [0.0, 1.0]
    gait = PiecewiseParabolic([0.0, T_REST], [q], 1.0, 0.0, periodic=False)
    c = Crawler([1.0, 1.0], fk, static_friction=fs)
    tr = simulate(c, gait, T_REST, t_eval=np.linspace(0.0, T_REST, 11))
    assert np.all(tr.x[:, stuck] == tr.x[0, stuck]) and np.all(tr.v[:, stuck] == 0.0)
    kin = simulate(Crawler([1.0, 1.0], fk), gait, 1.0, t_eval=[0.0, 1.0])
    assert kin.x[-1, stuck] != kin.x[0, stuck]


@pytest.mark.parametrize('q', PUSHES)
@pytest.mark.parametrize('sign', [1, -1], ids=['uphill_push', 'downhill_push'])
def test_zero_drift_on_a_slope_steeper_than_kinetic_friction_allows(q, sign):
    mu_s = 0.6
    slope = sign * math.atan(q * mu_s)
    gait = PiecewiseParabolic([0.0, 1.0], [0.0], 0.3, 0.0, periodic=False)
    c = Crawler([1.0, 2.0], slope=slope, mu=0.5 * mu_s, mu_static=mu_s)
    tr = simulate(c, gait, T_REST, t_eval=np.linspace(0.0, T_REST, 11))
    assert np.all(tr.x == tr.x[0]) and np.all(tr.v == 0.0)
    kin = simulate(Crawler([1.0, 2.0], slope=slope, mu=0.5 * mu_s), gait, 1.0, t_eval=[0, 1.0])
    assert kin.x[-1, 0] != kin.x[0, 0]


# ----------------------------------------------------------------------------------------------
# Static == kinetic: the same bits as the crawler without static bounds (the Rule S path is off;
# the same identity against the commit before stiction: /tmp-free check script in the report).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('seed', range(6))
def test_static_bounds_equal_to_the_kinetic_ones_change_no_bit(seed):
    rng = np.random.default_rng(seed)
    p = int(rng.integers(2, 5))
    m, f, fb = (10.0 ** rng.uniform(-1, 1, p) for _ in range(3))
    times = np.cumsum(rng.uniform(0.2, 1.0, 5))
    acc = rng.normal(0.0, 2.0, (4, p - 1))
    gait = PiecewiseParabolic(times - times[0], acc, np.full(p - 1, 10.0), 0.0, periodic=False)
    plain = simulate(Crawler(m, f, fb), gait, 3.0)
    same = simulate(Crawler(m, f, fb, static_friction=f, static_friction_backward=fb), gait, 3.0)
    assert not Crawler(m, f, fb, static_friction=f, static_friction_backward=fb).has_stiction
    for name in ('t', 'x', 'v', 'friction', 'linkage_force'):
        assert np.array_equal(getattr(plain, name), getattr(same, name))
    assert 'choices' not in plain.info


def test_a_streamed_run_and_a_periodic_skip_give_the_whole_runs_answer_with_stiction():
    # T3 streamed in calls that end mid-segment and on events, against the whole run
    c = Crawler([1.0, 1.0], 1.0, 4.0, static_friction=2.0, static_friction_backward=5.0)
    st = Stepper(c, T3_GAIT)
    for t in np.arange(0.5, 60.0 + 1e-9, 0.5):
        st.advance(float(t))
    X = float(st.state.x @ c.masses / 2)
    x0 = Stepper(c, T3_GAIT).state.x @ c.masses / 2
    assert abs(X - x0 - 25.0) <= 1e-11          # 10 periods of 2.5 m


def test_a_failed_call_restores_the_incumbent_with_the_rest_of_the_state():
    # the core's save/restore (what ``advance`` does around a call that raises) carries the
    # incumbent: a change made after the save is undone
    st = Stepper(T5_CRAWLER, T5_GAIT, initial_stuck=0, stiction_rule='margin')
    st.advance(0.5)
    core = st.solver._core
    core.save()
    st.advance(1.5)                          # 'margin': body 1 takes over at t = 1
    assert st.state.incumbent.tolist() == [False, True]
    core.restore()
    assert st.t == 0.5 and st.state.incumbent.tolist() == [True, False]


@pytest.mark.parametrize('rule, x_end', [('incumbent', [0.0, 1.0]), ('margin', [-0.25, 0.75])])
def test_the_periodic_skip_repeats_rule_s_and_counts_the_choices_of_the_periods_it_skips(
        rule, x_end):
    # T5 over 100 periods (400 s): the anchored body where T5 leaves it (x_0 = 0, or x_1 = 1 -
    # 1/4), the other 1 m from it (l = 1 at t = 400, a multiple of the period), one flagged
    # reversal every 2 s (200), skip on or off alike
    runs = [simulate(T5_CRAWLER, T5_GAIT, 400.0, t_eval=[0.0, 400.0], periodic_skip=skip,
                     initial_stuck=0, stiction_rule=rule) for skip in (True, False)]
    assert runs[0].info['skipped_periods'] > 0 and runs[1].info['skipped_periods'] == 0
    for tr in runs:
        np.testing.assert_allclose(tr.x[-1], x_end, rtol=0, atol=1e-12)
        assert tr.info['choices'] == 200
