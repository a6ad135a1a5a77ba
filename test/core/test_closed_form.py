"""Closed-form pieces of the p-body dry-friction crawler, checked against hand derivations.

Notation (MODEL.md s.2): M = sum m_i, X the centre of mass, V = X', e_i the offset of body i
from X (e_0 = -m_1 l / M, e_1 = m_0 l / M for p = 2), v_i = V + e_i'. Ground force R_i on body
i: -f_plus_i sliding forward, +f_minus_i sliding backward, in [-f_plus_i, f_minus_i] stuck.
F_ext = -M g sin(slope). Every expected number below is derived in the comment above it.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits

G = 9.81


def _events_of(tr, body):
    return [ev for ev in tr.events if ev.body == body]


# ----------------------------------------------------------------------------------------------
# 1. A slide phase: constant COM acceleration, exactly quadratic X, hand-computed stop time.
# ----------------------------------------------------------------------------------------------
# p = 2, m = (1, 2), M = 3, f_plus = (3, 1), f_minus = (2.5, 1.5); gait l' = c + a t (Cubic with
# zero jerk). With a large |v0| (velocity of body 0) both bodies slide in the direction s = sign(v0)
# and the COM acceleration is A = -s (f0^s + f1^s) / M, V = V0 + A t, X = X0 + V0 t + A t^2 / 2,
# with V0 = v0 - e_0'(0) = v0 + m1 c / M and X0 = x0 - e_0(0) = x0 + m1 l0 / M.
# Body 0: v_0 = V + e_0' = v0 + (A - m1 a / M) t, so it stops at t* = -v0 / (A - m1 a / M).
#   forward  (v0 = +1, c = +0.2, a = +0.5): A = -4/3, A - m1 a/M = -5/3  -> t* = 0.6
#   backward (v0 = -1, c = -0.2, a = -0.5): A = +4/3, A - m1 a/M = +5/3  -> t* = 0.6
# Body 1 still slides then: v_1 = v_0 + l' = (v0 + c) + (A + m0 a / M) t* = +-0.5.
# After t* body 0 sticks: its required ground force is R_0 = M A_stick - F_ext - R_1 with
# A_stick = -e_0'' = m1 a / M, i.e. R_0 = m1 a + s f1^s = +2 (forward) / -2.5 (backward), inside
# [-f0^+, f0^-] = [-3, 2.5]; it stays inside forever (a constant), so body 0 never moves again
# and x_0 stays at x_0(t*) = x0 + v0 t* + (A - m1 a / M) t*^2 / 2 = x0 +- 0.3.
SLIDE_CASES = {
    'forward': dict(v0=1.0, c=0.2, a=0.5, t_star=0.6, x0_final=0.3 + 0.25, R0_stuck=2.0),
    'backward': dict(v0=-1.0, c=-0.2, a=-0.5, t_star=0.6, x0_final=-0.3 + 0.25, R0_stuck=-2.5),
}


@pytest.mark.parametrize('case', SLIDE_CASES, ids=list(SLIDE_CASES))
def test_a_slide_phase_has_exactly_quadratic_com_and_stops_at_the_hand_computed_time(case):
    k = SLIDE_CASES[case]
    m, fp, fm = np.array([1.0, 2.0]), np.array([3.0, 1.0]), np.array([2.5, 1.5])
    M = m.sum()
    l0, x0 = 0.1, 0.25
    crawler = cs.Crawler(m, fp, fm)
    gait = gaits.Cubic(0.0, l0, k['c'], k['a'], 0.0)
    s = math.copysign(1.0, k['v0'])
    f_s = fp if s > 0 else fm
    A = -s * f_s.sum() / M
    V0 = k['v0'] + m[1] * k['c'] / M
    X0 = x0 + m[1] * l0 / M
    t_star = -k['v0'] / (A - m[1] * k['a'] / M)
    assert t_star == pytest.approx(k['t_star'], rel=1e-15)

    t = np.linspace(0.0, 1.5, 301)
    tr = cs.simulate(crawler, gait, 1.5, t_eval=t, x0=x0, v0=k['v0'])
    before, after = t < t_star - 1e-9, t > t_star + 1e-9
    X_hand = X0 + V0 * t + 0.5 * A * t ** 2
    np.testing.assert_allclose(tr.com[before], X_hand[before], rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.com_velocity[before], (V0 + A * t)[before], rtol=0, atol=1e-14)
    # both slide in direction s with the full friction force
    assert np.all(tr.contact[before] == s)
    np.testing.assert_array_equal(tr.friction[before], np.broadcast_to(-s * f_s, (before.sum(), 2)))

    ev0 = _events_of(tr, 0)
    assert len(ev0) == 1, tr.events
    assert ev0[0].old == s and ev0[0].new == 0
    assert abs(ev0[0].time - k['t_star']) <= 1e-12
    assert not _events_of(tr, 1)

    assert np.all(tr.v[after, 0] == 0.0)
    assert np.all(tr.contact[after, 0] == 0)
    np.testing.assert_allclose(tr.x[after, 0], k['x0_final'], rtol=0, atol=1e-14)
    # body 1 moves at exactly l' (body 0 anchored) and keeps sliding
    np.testing.assert_allclose(tr.v[after, 1], k['c'] + k['a'] * t[after], rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.friction[after, 0], k['R0_stuck'], rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------------------------
# 2. A body pushed below its friction bound stays exactly still.
# ----------------------------------------------------------------------------------------------
# Body 0 has friction F0 = 5 N. While it sticks the COM acceleration is A = -e_0'' and its required
# ground force is R_0 = M A - F_ext - sum_{i>0} R_i. On flat ground |R_0| <= sum_{i>0} f_i +
# |M e_0''| = sum_{i>0} f_i + |sum_{i>0} m_i s_i''| <= sum f_i + sum_i m_i sum_{j<i} A_j w^2.
#   p = 2: 0.3 + 0.5 * 0.03 * (3 pi)^2 = 1.63 < 5;  p = 3: 0.4 + (0.4*0.02 + 0.3*0.04) (2 pi)^2 =
#   1.19 < 5;  p = 10: 9 * 0.1 + 0.1 * 0.01 * (1+2+...+9) * (2 pi)^2 = 2.68 < 5.
# So body 0 never leaves x0: every sample of x_0 must be the same float, v_0 == 0.0 exactly.
ANCHOR_CASES = {
    'p2': (cs.Crawler([1.0, 0.5], [5.0, 0.3]), gaits.Sinusoid(0.1, 0.03, 1.5)),
    'p3': (cs.Crawler([1.0, 0.3, 0.4], [5.0, 0.2, 0.2]),
           gaits.Sinusoid([0.1, 0.1], [0.02, 0.02], 1.0, [0.0, 1.3])),
    'p10': (cs.Crawler([1.0] + [0.1] * 9, [5.0] + [0.1] * 9),
            gaits.Sinusoid(0.1, 0.01, 1.0, -0.6 * np.arange(9))),
}


@pytest.mark.parametrize('case', ANCHOR_CASES, ids=list(ANCHOR_CASES))
@pytest.mark.parametrize('x0', [0.0, 0.3])
def test_a_body_below_its_friction_bound_stays_exactly_still(case, x0):
    crawler, gait = ANCHOR_CASES[case]
    tr = cs.simulate(crawler, gait, 4.0, x0=x0)
    assert np.all(tr.x[:, 0] == tr.x[0, 0]), np.ptp(tr.x[:, 0])
    assert tr.x[0, 0] == pytest.approx(x0, abs=1e-15)
    assert np.all(tr.v[:, 0] == 0.0)
    assert np.all(tr.contact[:, 0] == 0)
    assert not _events_of(tr, 0)
    f0 = crawler.friction[0]
    assert np.all(np.abs(tr.friction[:, 0]) < f0)


@pytest.mark.parametrize('case', ANCHOR_CASES, ids=list(ANCHOR_CASES))
def test_implicit_method_gives_an_anchored_body_exactly_zero_velocity(case):
    # The Moreau-Jean step puts a stuck body exactly at its kink (MODEL.md s.3): v_0 == 0.0.
    crawler, gait = ANCHOR_CASES[case]
    tr = cs.simulate(crawler, gait, 2.0, 'implicit', dt=1e-3)
    assert np.all(tr.v[:, 0] == 0.0)
    assert np.all(tr.contact[:, 0] == 0)


# ----------------------------------------------------------------------------------------------
# 3. A rigid crawler (l constant) behaves as one body: decelerates at sum f / M, stops, stays put.
# ----------------------------------------------------------------------------------------------
# m = (1, 2), M = 3, f_plus = (3, 1), f_minus = (2, 2). l' = l'' = 0, so both bodies have velocity
# V. v0 = +1: A = -(3 + 1)/3, stop at t* = v0 M / sum f_plus = 0.75 after d = M v0^2 / (2 sum f)
# = 0.375. v0 = -1: A = +(2 + 2)/3, t* = 0.75, d = -0.375. Once stopped, F_ext = 0 and no force
# pushes: both stay stuck (V = 0 is the solution of M V' in -sum dphi_i(V) with V = 0), the total
# friction is 0 and the split is indeterminate.
def _rigid_gaits():
    return {
        'cubic': gaits.Cubic(0.0, 0.1, 0.0, 0.0, 0.0),
        'sinusoid_amp0': gaits.Sinusoid(0.1, 0.0, 1.0),
        'custom_const': gaits.Custom(lambda t: 0.1, lambda t: 0.0, lambda t: 0.0),
    }


@pytest.mark.parametrize('gait_name', ['cubic', 'sinusoid_amp0', 'custom_const'])
@pytest.mark.parametrize('v0', [1.0, -1.0])
def test_a_rigid_crawler_decelerates_at_total_friction_over_mass_and_stops_at_hand_time(gait_name,
                                                                                        v0):
    gait = _rigid_gaits()[gait_name]
    crawler = cs.Crawler([1.0, 2.0], [3.0, 1.0], [2.0, 2.0])
    M, s = 3.0, math.copysign(1.0, v0)
    f_tot = 4.0
    t_star = abs(v0) * M / f_tot
    d = s * M * v0 ** 2 / (2.0 * f_tot)
    t = np.linspace(0.0, 2.0, 201)
    tr = cs.simulate(crawler, gait, 2.0, t_eval=t, v0=v0)
    X0 = tr.com[0]
    before, after = t < t_star - 1e-9, t > t_star + 1e-9
    np.testing.assert_allclose(tr.com[before] - X0, v0 * t[before] - s * f_tot / M * t[before] ** 2
                               / 2, rtol=0, atol=1e-14)
    assert len(tr.events) == 2
    for body in (0, 1):
        (ev,) = _events_of(tr, body)
        assert (ev.old, ev.new) == (s, 0)
        assert abs(ev.time - t_star) <= 1e-12
    assert np.all(tr.v[after] == 0.0)
    np.testing.assert_allclose(tr.com[after] - X0, d, rtol=0, atol=1e-14)
    assert np.all(tr.x[after] == tr.x[-1])
    assert np.all(tr.indeterminate[after])
    assert not np.any(tr.indeterminate[before])
    np.testing.assert_allclose(tr.friction[after].sum(axis=1), 0.0, atol=1e-14)


# ----------------------------------------------------------------------------------------------
# 4. The statically indeterminate case: at rest on a slope with l' = 0.
# ----------------------------------------------------------------------------------------------
# mu = (0.5, 0.3) > tan(0.2) = 0.203: the crawler can hold. Total ground force must balance gravity:
# R_0 + R_1 = -F_ext = M g sin(0.2) exactly, each R_i in [-f_plus_i, f_minus_i]; only the total
# is determined, so `indeterminate` is True everywhere.
@pytest.mark.parametrize('gait_name', ['cubic', 'custom_const'])
@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_a_crawler_at_rest_on_a_slope_is_flagged_indeterminate_and_its_friction_balances_gravity(
        gait_name, method):
    gait = _rigid_gaits()[gait_name]
    slope = 0.2
    crawler = cs.Crawler.from_coefficients([1.0, 2.0], [0.5, 0.3], slope=slope)
    tr = cs.simulate(crawler, gait, 1.0, method, dt=1e-2 if method == 'implicit' else None)
    M = 3.0
    assert np.all(tr.indeterminate)
    assert np.all(tr.contact == 0)
    assert np.all(tr.v == 0.0)
    assert np.all(tr.x == tr.x[0])
    # A time-stepping method only knows the force over a step, so its first sample (t = 0, before
    # any step) is checked separately below; every later sample must hold the crawler.
    rows = slice(None) if method == 'exact' else slice(1, None)
    np.testing.assert_allclose(tr.friction[rows].sum(axis=1), M * G * math.sin(slope), rtol=1e-13)
    assert np.all(tr.friction <= crawler.friction_backward)
    assert np.all(tr.friction >= -crawler.friction)
    assert not tr.events
    assert cs.verify(tr).ok(1e-12)


@pytest.mark.parametrize('method', ['implicit', 'penalty'])
def test_the_first_sample_of_a_time_stepping_run_reports_the_friction_that_holds_the_crawler(method):
    # At t = 0 the crawler is at rest on the slope and stays so: the ground must already supply
    # M g sin(slope) in total (exactly as the exact method reports at t = 0).
    crawler = cs.Crawler.from_coefficients([1.0, 2.0], [0.5, 0.3], slope=0.2)
    tr = cs.simulate(crawler, _rigid_gaits()['cubic'], 0.1, method, dt=1e-2, penalty=1e6)
    assert tr.friction[0].sum() == pytest.approx(3.0 * G * math.sin(0.2), rel=1e-6)


def test_the_stepper_reports_the_indeterminate_rest_state():
    crawler = cs.Crawler.from_coefficients([1.0, 2.0], [0.5, 0.3], slope=0.2)
    st = cs.Stepper(crawler, gaits.Cubic(0.0, 0.1, 0.0, 0.0, 0.0))
    st.advance(0.5)
    s = st.state
    assert s.indeterminate
    assert np.all(s.contact == 0)
    assert s.friction.sum() == pytest.approx(3.0 * G * math.sin(0.2), rel=1e-13)


def test_the_documented_friction_split_puts_each_stuck_body_at_the_same_fraction_of_its_interval():
    # Documented choice (contact.split_friction): every stuck body of the group sits at the same
    # fraction theta of its own interval [-f_plus_i, f_minus_i], i.e.
    # (R_i + f_plus_i) / (f_plus_i + f_minus_i) is equal for all i; the total fixes theta.
    crawler = cs.Crawler.from_coefficients([1.0, 2.0], [0.5, 0.3], slope=0.2)
    tr = cs.simulate(crawler, _rigid_gaits()['cubic'], 1.0)
    fp, fm = crawler.friction, crawler.friction_backward
    theta = (tr.friction + fp) / (fp + fm)
    np.testing.assert_allclose(theta[:, 0], theta[:, 1], rtol=1e-13)


# ----------------------------------------------------------------------------------------------
# 5. Slopes: slide down when friction cannot hold, climb with direction-dependent friction.
# ----------------------------------------------------------------------------------------------
# mu = (0.2, 0.3) < tan(0.4) = 0.423, rigid crawler from rest: it slides down with
# A = -g sin(a) + g cos(a) (mu_0 m_0 + mu_1 m_1) / M (friction pushes uphill while sliding down).
@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_a_rigid_crawler_on_a_too_steep_slope_slides_down_at_the_computed_rate(method):
    slope, m, mu = 0.4, np.array([1.0, 2.0]), np.array([0.2, 0.3])
    crawler = cs.Crawler.from_coefficients(m, mu, slope=slope)
    A = -G * math.sin(slope) + G * math.cos(slope) * (mu @ m) / m.sum()
    assert A < 0
    t = np.linspace(0.0, 1.0, 101)
    tr = cs.simulate(crawler, _rigid_gaits()['cubic'], 1.0, method, t_eval=t, dt=1e-3)
    if method == 'exact':
        np.testing.assert_allclose(tr.com - tr.com[0], 0.5 * A * t ** 2, rtol=0, atol=1e-13)
        np.testing.assert_allclose(tr.com_velocity, A * t, rtol=0, atol=1e-13)
        assert all(ev.time == 0.0 and (ev.old, ev.new) == (0, -1) for ev in tr.events)
    else:
        # backward Euler on a constant acceleration: V is exact, X(t_k) = A t_k (t_k + h) / 2
        np.testing.assert_allclose(tr.com_velocity, A * t, rtol=0, atol=1e-12)
        np.testing.assert_allclose(tr.com - tr.com[0], 0.5 * A * t * (t + 1e-3), atol=1e-12)
    assert np.all(tr.contact[1:] == -1)


# Direction-dependent friction, quasi-static, exact: m = (0.1, 0.1), f_plus = 0.2, f_minus = 0.5,
# l = L + A sin(w t), A = 0.01, w = 2 pi. While l' > 0 (extension) body 0 sticks and body 1 slides
# forward: body 0 needs R_0 = m1 l'' + M g sin(a) + f1_plus, |m1 l''| <= 0.1 * 0.01 * w^2 = 0.0395,
# so at slope a = 0.1, R_0 <= 0.0395 + 0.1958 + 0.2 = 0.435 <= f0_minus = 0.5 and >= -0.2; the
# other mode (body 1 stuck, body 0 sliding back) would need R_1 = -m0 l'' + M g sin a - f0_minus
# <= -0.26 < -f1_plus: impossible. Symmetrically during contraction body 1 sticks and body 0
# slides forward. So body 1 advances by the full extension and body 0 by the full contraction:
# each body, hence the COM, advances exactly 2 A per period, on flat ground and up this slope.
# At slope 0.6 rad, M g sin = 1.108 > f0_minus + f1_minus = 1.0: the total ground force can never
# hold it, M V' <= -M g sin + sum f_minus < 0: it slides down, and once every body slides
# backward V' = (sum f_minus)/M - g sin(0.6) exactly.
def _bristle(slope):
    return cs.Crawler([0.1, 0.1], [0.2, 0.2], [0.5, 0.5], slope=slope)


@pytest.mark.parametrize('slope', [0.0, 0.1])
def test_direction_dependent_friction_crawls_forward_exactly_two_amplitudes_per_period(slope):
    A, T = 0.01, 1.0
    n_periods = 3
    t = np.arange(n_periods + 1) * T
    tr = cs.simulate(_bristle(slope), gaits.Sinusoid(0.1, A, 1.0), n_periods * T, t_eval=t)
    np.testing.assert_allclose(np.diff(tr.com), 2 * A, rtol=1e-12)
    np.testing.assert_allclose(np.diff(tr.x, axis=0), 2 * A, rtol=1e-12)
    assert cs.verify(tr).ok(1e-10)


def test_direction_dependent_friction_reversed_crawls_backward_by_the_same_amount():
    # Swapping f_plus and f_minus is the mirror image of the case above: during extension body 1
    # now sticks and body 0 slides back, during contraction body 0 sticks. Starting body 0 at
    # v0 = -l'(0) (body 1 at rest, consistent with that mode) the COM moves exactly -2 A per period.
    A, w = 0.01, 2 * math.pi
    crawler = cs.Crawler([0.1, 0.1], [0.5, 0.5], [0.2, 0.2])
    tr = cs.simulate(crawler, gaits.Sinusoid(0.1, A, 1.0), 3.0, t_eval=[0.0, 1.0, 2.0, 3.0],
                     v0=-A * w)
    np.testing.assert_allclose(np.diff(tr.com), -2 * A, rtol=1e-12)


def test_too_steep_a_slope_makes_the_same_crawler_slide_down_at_the_computed_rate():
    slope = 0.6
    crawler = _bristle(slope)
    A_down = 1.0 / 0.2 - G * math.sin(slope)
    assert A_down < 0
    t = np.linspace(0.0, 3.0, 301)
    tr = cs.simulate(crawler, gaits.Sinusoid(0.1, 0.01, 1.0), 3.0, t_eval=t)
    assert np.all(np.diff(tr.com_velocity) <= 1e-15)        # M V' <= -M g sin a + sum f_minus < 0
    late = t >= 1.0    # by then V << -max|e_i'| = -0.01 pi: every body slides backward
    assert np.all(tr.contact[late] == -1)
    np.testing.assert_allclose(np.diff(tr.com_velocity[late]), A_down * np.diff(t[late]),
                               rtol=1e-11)


# ----------------------------------------------------------------------------------------------
# 6. Event times for strokes solvable by hand.
# ----------------------------------------------------------------------------------------------
# Body 1 anchored (f1 = 100 N >> f0 + m0 A w^2), v0 = -l'(0) so body 1 starts at rest. Then body 1
# never moves, v_0 = -l' = -A w cos(w t) exactly, and body 0 reverses exactly where l' = 0:
# t = T/4 + k T/2, -1 -> +1 at T/4 + k T, +1 -> -1 at 3T/4 + k T.
def test_a_body_sliding_against_an_anchored_one_reverses_exactly_where_the_rate_vanishes():
    A, w = 0.02, 2 * math.pi
    crawler = cs.Crawler([0.5, 1.0], [1.0, 100.0])
    gait = gaits.Sinusoid(0.1, A, 1.0)
    t = np.linspace(0.0, 2.0, 401)
    tr = cs.simulate(crawler, gait, 2.0, v0=-A * w, t_eval=t)
    assert np.all(tr.x[:, 1] == tr.x[0, 1])
    np.testing.assert_allclose(tr.v[:, 0], -A * w * np.cos(w * t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(tr.x[:, 0], tr.x[0, 1] - 0.1 - A * np.sin(w * t), rtol=0, atol=1e-15)
    ev0 = _events_of(tr, 0)
    # a direct reversal may be recorded as one event (-1 -> +1) or as two at the same time (via 0)
    times = sorted({ev.time for ev in ev0})
    np.testing.assert_allclose(times, [0.25, 0.75, 1.25, 1.75], rtol=0, atol=1e-12)
    for tt, new in zip([0.25, 0.75, 1.25, 1.75], [1, -1, 1, -1]):
        last = [ev for ev in ev0 if abs(ev.time - tt) <= 1e-12][-1]
        assert last.new == new


def test_a_body_whose_initial_velocity_is_exactly_zero_starts_stuck_without_a_spurious_event():
    # Same scene: v0 = -A w and l'(0) = A w, so v_1(0) = v0 + l'(0) = 0.0 exactly in floating
    # point. Body 1 starts stuck and, anchored, never changes state: no event for body 1 at all.
    A, w = 0.02, 2 * math.pi
    v0 = -A * w
    assert v0 + gaits.Sinusoid(0.1, A, 1.0)(0.0)[1][0] == 0.0
    tr = cs.simulate(cs.Crawler([0.5, 1.0], [1.0, 100.0]), gaits.Sinusoid(0.1, A, 1.0), 1.0, v0=v0)
    assert tr.contact[0, 1] == 0
    assert tr.v[0, 1] == 0.0
    assert not _events_of(tr, 1), _events_of(tr, 1)


# Grazing: body 1 anchored, l' = A (1 - cos w t) >= 0 touches zero (with l'' = 0) at t = k T.
# Body 0 slides backward with v_0 = -l' on every (kT, (k+1)T): x_0 = x0 - (l(t) - l(0)) in closed
# form; at t = 0 it starts from rest and l' > 0 for every t > 0, so its slip starts at t = 0.
def _grazing_gait(A=0.02, w=2 * math.pi, L=0.1):
    return gaits.Custom(lambda t: L + A * (t - math.sin(w * t) / w),
                        lambda t: A * (1.0 - math.cos(w * t)),
                        lambda t: A * w * math.sin(w * t))


def test_a_grazing_zero_velocity_neither_stalls_nor_moves_the_anchored_body():
    crawler = cs.Crawler([0.5, 1.0], [1.0, 100.0])
    t = np.linspace(0.0, 3.0, 301)
    tr = cs.simulate(crawler, _grazing_gait(), 3.0, t_eval=t)
    assert np.all(tr.x[:, 1] == tr.x[0, 1])
    l = tr.lengths[:, 0]
    np.testing.assert_allclose(tr.x[:, 0], tr.x[0, 0] - (l - l[0]), rtol=0, atol=1e-15)
    interior = (t % 1.0 > 1e-6) & (t % 1.0 < 1 - 1e-6)
    assert np.all(tr.contact[interior, 0] == -1)
    assert cs.verify(tr).ok(1e-12)


def test_a_slip_that_starts_from_rest_with_a_cubic_onset_is_placed_at_t0():
    crawler = cs.Crawler([0.5, 1.0], [1.0, 100.0])
    tr = cs.simulate(crawler, _grazing_gait(), 0.5)
    ev0 = _events_of(tr, 0)
    assert ev0 and (ev0[0].old, ev0[0].new) == (0, -1)
    assert abs(ev0[0].time) <= 1e-12, ev0[0].time


# Stick -> slip exactly at an acceleration jump (bang-bang, PiecewiseParabolic, not periodic).
# m = (1, 1), M = 2, f = (3, 1) (equal forward/backward), l(0) = 0.1, l'(0) = 0,
# l'' = 1 on [0, 0.1), 4 on [0.1, 0.2), -2 on [0.2, 0.45), 0 after (l'(0.45) = 0.1 + 0.4 - 0.5 = 0).
# * [0, 0.1): body 1 slides forward (v_1 = l' > 0), body 0 stuck needs R_0 = m1 l'' + f1 = 2 <= 3.
#   (the other mode, body 1 stuck and body 0 sliding back, needs |R_1| = m0 l'' + f0 = 4 > 1.)
# * at 0.1 l'' jumps to 4: R_0 would be 4 + 1 = 5 > 3, so body 0 starts sliding backward exactly
#   at t = 0.1 with v_0' = (f0 - f1 - m1 l'') / M = (3 - 1 - 4) / 2 = -1: v_0(0.2) = -0.1.
# * at 0.2 l'' = -2: v_0' = (3 - 1 + 2) / 2 = 2, so v_0 = 0 at t = 0.2 + 0.1 / 2 = 0.25, where
#   l' = 0.5 - 2 * 0.05 = 0.4 > 0 (body 1 still forward). Body 0 sticks: R_0 = m1 l'' + f1 = -1,
#   inside [-3, 3].
# * body 1 stops at 0.45 (l' = 0), then rest: both stuck, indeterminate.
# Body 0 moved by the area of the triangle v_0 on [0.1, 0.25]: -0.1 * 0.15 / 2 = -0.0075.
# l(0.45) = 0.1 + 0.005 + (0.1*0.1 + 4*0.01/2) + (0.5*0.25 - 2*0.0625/2) = 0.1975.
BANG_BANG = gaits.PiecewiseParabolic([0.0, 0.1, 0.2, 0.45], [1.0, 4.0, -2.0], 0.1, 0.0,
                                     periodic=False)


def test_bang_bang_stroke_switches_stick_to_slip_exactly_at_the_acceleration_jump():
    crawler = cs.Crawler([1.0, 1.0], [3.0, 1.0])
    tr = cs.simulate(crawler, BANG_BANG, 1.0)
    ev0 = _events_of(tr, 0)
    assert [(e.old, e.new) for e in ev0] == [(0, -1), (-1, 0)]
    assert abs(ev0[0].time - 0.1) <= 1e-12
    assert abs(ev0[1].time - 0.25) <= 1e-12
    ev1 = _events_of(tr, 1)
    assert [(e.old, e.new) for e in ev1] == [(0, 1), (1, 0)]
    assert abs(ev1[0].time) <= 1e-12 and abs(ev1[1].time - 0.45) <= 1e-12
    np.testing.assert_allclose(tr.x[-1], [-0.0075, -0.0075 + 0.1975], rtol=0, atol=1e-14)
    assert tr.indeterminate[-1]
