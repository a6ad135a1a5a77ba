"""The three methods agree: implicit -> exact at order 1, penalty -> exact within the seed's bound,
verify() passes on every method, the batch stepper equals the single one.

The implicit step is also checked against an independent brute-force minimisation of its convex
step function, written here, so that "implicit converges to exact" ties the exact method to a
scheme whose every step is verified from first principles.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq

import crawler_sim as cs
from crawler_sim.core import gaits
from test.support.core import random_crawler as _crawler, wave as _wave






# ----------------------------------------------------------------------------------------------
# An independent Moreau-Jean step: minimise J(V) = M/(2h) (V - V_k)^2 - F_ext V +
# sum_i phi_i(V + e_i') by brute force: J is convex and piecewise quadratic with kinks at -e_i',
# so its minimiser is a kink or the stationary point of one quadratic piece (clipped to it).
# ----------------------------------------------------------------------------------------------
def _offsets(masses, rates):
    s = np.concatenate([[0.0], np.cumsum(rates)])
    return s - s @ masses / masses.sum()


def _reference_step(M, h, Vk, F, ep, fp, fm):
    def J(V):
        w = V + ep
        return (M / (2 * h) * (V - Vk) ** 2 - F * V
                + np.sum(fp * np.maximum(w, 0.0) + fm * np.maximum(-w, 0.0)))

    kinks = np.sort(-ep)
    cands = list(kinks)
    edges = np.concatenate([[-np.inf], kinks, [np.inf]])
    for lo, hi in zip(edges[:-1], edges[1:]):
        probe = (lo + hi) / 2 if np.isfinite(lo) and np.isfinite(hi) else (
            hi - 1.0 if np.isfinite(hi) else lo + 1.0)
        slope_phi = np.sum(np.where(probe + ep > 0, fp, -fm))
        V = Vk + h / M * (F - slope_phi)
        cands.append(min(max(V, lo), hi))
    vals = [J(V) for V in cands]
    return cands[int(np.argmin(vals))]


def _reference_run(crawler, gait, h, n_steps, v0=0.0):
    m, fp, fm = crawler.masses, crawler.friction, crawler.friction_backward
    M, F = m.sum(), crawler.external_force
    l, ld, _ = gait(0.0)
    V = v0 - _offsets(m, ld)[0]
    X = -(_offsets(m, l)[0])  # x0 = 0
    Vs, Xs = [V], [X]
    for k in range(1, n_steps + 1):
        ep = _offsets(m, gait(k * h)[1])
        V = _reference_step(M, h, V, F, ep, fp, fm)
        X = X + h * V
        Vs.append(V)
        Xs.append(X)
    return np.array(Vs), np.array(Xs)


class _PlainMJ:
    """The plain Moreau-Jean stepper (method implicit places transitions inside steps)."""

    def __init__(self, crawler, gait, _method, **kw):
        from crawler_sim.core.solvers.implicit import ImplicitSolver
        self.solver = ImplicitSolver(crawler, gait, locate_transitions=False, **kw)

    def advance(self, t):
        self.solver.advance(t)


@pytest.mark.parametrize('p,slope', [(2, 0.0), (3, 0.05), (10, -0.02)])
def test_each_implicit_step_is_the_minimiser_of_the_moreau_jean_step_function(p, slope):
    crawler = _crawler(p, slope, seed=60 + p)
    gait = _wave(p)
    h, n = 2e-3, 500
    Vref, Xref = _reference_run(crawler, gait, h, n, v0=0.05)
    st = _PlainMJ(crawler, gait, 'implicit', dt=h, v0=0.05)
    V, X = [], []
    for k in range(1, n + 1):
        st.advance(k * h)
        V.append(st.solver.V)
        X.append(st.solver.X)
    np.testing.assert_allclose(V, Vref[1:], rtol=0, atol=1e-12)
    np.testing.assert_allclose(X, Xref[1:], rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------------------------
# Implicit -> exact at order 1 in h. Stick/slip makes the error constant C(h) in e(h) = C(h) h
# fluctuate with where events fall inside steps, so with p = 2 the order is read from three step
# sizes (successive ratios) and with p = 3, 10 from a least-squares fit over six step sizes.
# ----------------------------------------------------------------------------------------------
def _implicit_errors(crawler, gait, T, ns, v0=0.05):
    t = np.linspace(0.0, T, 101)
    ex = cs.simulate(crawler, gait, T, t_eval=t, v0=v0)
    errs = []
    for n in ns:
        im = cs.simulate(crawler, gait, T, 'implicit', dt=T / n, t_eval=t, v0=v0)
        errs.append(np.max(np.abs(im.x - ex.x)))
    return np.array(errs)


def test_implicit_converges_to_exact_at_order_one_for_two_bodies():
    crawler, gait, T = _crawler(2, 0.03, seed=45), _wave(2), 2.0
    ns = np.array([400, 800, 1600])
    errs = _implicit_errors(crawler, gait, T, ns)
    orders = np.log2(errs[:-1] / errs[1:])
    assert np.all((orders >= 0.8) & (orders <= 1.3)), orders


@pytest.mark.parametrize('p,seed', [(3, 51), (10, 51)])
def test_implicit_converges_to_exact_at_order_one_for_more_bodies(p, seed):
    crawler, gait, T = _crawler(p, 0.03, seed=seed), _wave(p), 2.0
    ns = np.array([100, 200, 400, 800, 1600, 3200])
    errs = _implicit_errors(crawler, gait, T, ns)
    order = np.polyfit(np.log(T / ns), np.log(errs), 1)[0]
    assert 0.8 <= order <= 1.3, (order, errs)
    assert errs[-1] < errs[0] / 8


def test_the_independent_reference_scheme_converges_to_the_exact_solution():
    # Ties the exact solver to code written here: the brute-force Moreau-Jean scheme.
    crawler, gait, T = _crawler(2, 0.03, seed=45), _wave(2), 1.0
    t_ref = np.linspace(0.0, T, 11)
    ex = cs.simulate(crawler, gait, T, t_eval=t_ref, v0=0.05)
    errs = []
    for n in (250, 500, 1000):
        _, X = _reference_run(crawler, gait, T / n, n, v0=0.05)
        errs.append(np.max(np.abs(X[:: n // 10] - ex.com)))
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    assert np.all((orders >= 0.8) & (orders <= 1.3)), (orders, errs)


# ----------------------------------------------------------------------------------------------
# Penalty: the seed's estimate (with the mass restored, MODEL.md s.4):
#   sup_[0,t] |V^n - V| <= sqrt(2 t / M * sum_i f_i^2 / n_i),
# derived from d/dt (V^n - V)^2 <= (2/M) sum f_i^2 / n_i (seed's Lemma 1 with r -> infinity).
# With h = 1e-4 the time discretisation is negligible (the implicit run at that step is within
# 1e-14 of exact here). Body velocities differ from V by the same e_i', so the bound holds for them.
# ----------------------------------------------------------------------------------------------
def test_penalty_converges_as_n_grows_and_stays_within_the_seeds_a_priori_bound():
    crawler, gait, T = _crawler(2, 0.03, seed=45), _wave(2), 0.5
    t = np.linspace(0.0, T, 101)
    ex = cs.simulate(crawler, gait, T, t_eval=t, v0=0.05)
    im = cs.simulate(crawler, gait, T, 'implicit', dt=1e-4, t_eval=t, v0=0.05)
    assert np.max(np.abs(im.com_velocity - ex.com_velocity)) < 1e-10
    ns = [100.0, 1000.0, 10000.0]
    errs = []
    for n in ns:
        pe = cs.simulate(crawler, gait, T, 'penalty', dt=1e-4, penalty=n, t_eval=t, v0=0.05)
        err = np.maximum.accumulate(np.max(np.abs(pe.v - ex.v), axis=1))
        bound = cs.penalty_bound(crawler, n, t)
        assert np.all(err <= bound), np.max(err - bound)
        np.testing.assert_allclose(pe.info['error_bound'], bound, rtol=1e-15)
        errs.append(err[-1])
    rate = np.log10(errs[0] / errs[-1]) / 2
    assert rate >= 0.5, errs       # at least the a priori rate 1/2 in 1/n
    assert errs[-1] < 1e-3


def test_penalty_bound_matches_the_seeds_formula():
    # f_i = max(f_plus_i, f_minus_i) = (2, 3), n = (10, 40), M = 3, t = 2:
    # sqrt(2 * 2 / 3 * (4/10 + 9/40)) = sqrt(4/3 * 0.625) = sqrt(5/6)
    crawler = cs.Crawler([1.0, 2.0], [2.0, 1.0], [1.0, 3.0])
    assert cs.penalty_bound(crawler, [10.0, 40.0], 2.0) == pytest.approx(math.sqrt(5 / 6), rel=1e-15)
    assert cs.penalty_bound(crawler, 10.0, 0.0) == 0.0


# ----------------------------------------------------------------------------------------------
# verify() on every method. Exact and implicit satisfy the momentum balance and the friction law
# to rounding. The penalty method regularises the law: a body in the linear zone |n v| < f is
# reported stuck with |v| < f/n (creep) and dissipation gap f|v| - n v^2 <= f^2 / (4 n), so its
# relative violations are below f_max / (n v_max).
# ----------------------------------------------------------------------------------------------
SCENES = {
    'p2': (lambda: _crawler(2, 0.0, seed=45), lambda: _wave(2)),
    'p3_slope': (lambda: _crawler(3, 0.05, seed=51), lambda: _wave(3)),
    'p10': (lambda: _crawler(10, 0.0, seed=51), lambda: _wave(10)),
}


@pytest.mark.parametrize('scene', SCENES)
@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_verify_passes_on_exact_and_implicit_runs(scene, method):
    crawler, gait = SCENES[scene][0](), SCENES[scene][1]()
    tr = cs.simulate(crawler, gait, 3.0, method, dt=2e-3, v0=0.05)
    rep = cs.verify(tr)
    assert rep.ok(1e-9), rep


@pytest.mark.parametrize('scene', SCENES)
@pytest.mark.parametrize('n', [300.0, 3000.0])
def test_verify_passes_on_penalty_runs_at_a_tolerance_set_by_n(scene, n):
    crawler, gait = SCENES[scene][0](), SCENES[scene][1]()
    tr = cs.simulate(crawler, gait, 2.0, 'penalty', dt=2e-3, penalty=n, v0=0.05)
    f_max = max(crawler.friction.max(), crawler.friction_backward.max())
    tol = f_max / (n * np.abs(tr.v).max())
    rep = cs.verify(tr)
    assert rep.ok(tol * (1 + 1e-9)), (rep, tol)
    assert rep.momentum_rel < 1e-12
    assert rep.stuck_velocity > 0.0        # the regularised law creeps, and verify sees it
    assert not rep.ok(1e-9)


def test_verify_detects_a_friction_force_beyond_its_bound_and_a_broken_momentum_balance():
    crawler, gait = SCENES['p2'][0](), SCENES['p2'][1]()
    tr = cs.simulate(crawler, gait, 1.0)
    assert cs.verify(tr).ok(1e-9)
    bad_f = replace(tr, friction=tr.friction * 1.5)
    rep = cs.verify(bad_f)
    assert rep.friction_bound > 0.4 * min(crawler.friction.min(), crawler.friction_backward.min())
    assert not rep.ok(1e-3)
    bad_k = replace(tr, impulse=tr.impulse * 1.01)
    assert not cs.verify(bad_k).ok(1e-6)
    moving = np.abs(tr.v) > 1e-3
    creep = tr.contact.copy()
    creep[moving] = 0
    assert cs.verify(replace(tr, contact=creep)).stuck_velocity >= 1e-3


# ----------------------------------------------------------------------------------------------
# ImplicitBatch: B crawlers with different parameters stepped together give, for each, exactly
# the single-crawler Moreau-Jean run (same step function, only vectorised).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3, 10])
@pytest.mark.parametrize('shared_rates', [True, False])
def test_the_batch_stepper_equals_the_single_crawler_implicit_solver(p, shared_rates):
    rng = np.random.default_rng(70 + p)
    B, h, n = 5, 2e-3, 400
    m = rng.uniform(0.3, 2.0, (B, p))
    f = rng.uniform(0.0, 1.5, (B, p))
    fb = f * rng.uniform(0.5, 3.0, (B, p))
    slope = rng.uniform(-0.1, 0.1, B)
    base = _wave(p)
    amps = rng.uniform(0.5, 1.5, B)
    gaits_b = [base if shared_rates else
               gaits.Sinusoid(base.mean, base.amplitude * amps[b], base.frequency, base.phase)
               for b in range(B)]
    batch = cs.ImplicitBatch(m, f, fb, slope)
    singles = []
    for b in range(B):
        c = cs.Crawler(m[b], f[b], fb[b], slope=slope[b])
        l, ld, _ = gaits_b[b](0.0)
        # start at X = 0, V = 0 like the batch: body 0 at e_0(0) moving at e_0'(0)
        singles.append(_PlainMJ(c, gaits_b[b], 'implicit', dt=h, x0=_offsets(m[b], l)[0],
                                  v0=_offsets(m[b], ld)[0]))
    for k in range(1, n + 1):
        rates = (base(k * h)[1] if shared_rates
                 else np.array([g(k * h)[1] for g in gaits_b]))
        batch.step(h, rates)
        for st in singles:
            st.advance(k * h)
    V = np.array([st.solver.V for st in singles])
    X = np.array([st.solver.X for st in singles])
    np.testing.assert_allclose(batch.V, V, rtol=0, atol=1e-12)
    np.testing.assert_allclose(batch.X, X, rtol=0, atol=1e-12)
    assert batch.t == pytest.approx(n * h)
    assert np.ptp(batch.V) > 1e-3          # the crawlers really differ


# ----------------------------------------------------------------------------------------------
# Exact method on scenes that expose stalls (found while writing these tests). Expected values
# are derived by hand / by independent root finding, and cross-checked against fine implicit.
# ----------------------------------------------------------------------------------------------
# p = 2, m = (1, 2), M = 3, f_plus = (2, 1.5), f_minus = (1, 0.5), l = 0.1 + 0.02 sin(2 pi t),
# v0 = 0.05. Both slide forward: V' = -(2 + 1.5)/3, so v_0(t) = 0.05 - (7/6) t - (2/3)(l'(t) -
# l'(0)) until it vanishes at t1. There body 1 slides forward (R_1 = -1.5) and body 0 could only
# stick with R_0 = M (2/3) l'' + 1.5 = 2 l'' + 1.5 <= f0_minus = 1, i.e. l'' <= -0.25; at t1
# l'' = -0.224, so body 0 slides backward with V' = (1 - 1.5)/3 = -1/6 and
# v_0(t) = -(t - t1)/6 - (2/3)(l'(t) - l'(t1)), back to zero at t2 (where l'' < -0.25: it sticks).
def _short_slip_times():
    A, w = 0.02, 2 * math.pi
    ld = lambda t: A * w * math.cos(w * t)          # noqa: E731
    t1 = brentq(lambda t: 0.05 - 7 / 6 * t - 2 / 3 * (ld(t) - ld(0.0)), 1e-3, 0.2, xtol=1e-15)
    t2 = brentq(lambda t: -(t - t1) / 6 - 2 / 3 * (ld(t) - ld(t1)), t1 + 1e-4, 0.2, xtol=1e-15)
    return t1, t2


def test_the_hand_derived_short_slip_matches_a_fine_implicit_run():
    # Sanity of the derivation without the exact method.
    t1, t2 = _short_slip_times()
    assert 0.04 < t1 < t2 < t1 + 0.02
    crawler = cs.Crawler([1.0, 2.0], [2.0, 1.5], [1.0, 0.5])
    tr = cs.simulate(crawler, gaits.Sinusoid(0.1, 0.02, 1.0), 0.1, 'implicit', dt=1e-5, v0=0.05)
    ev0 = [e for e in tr.events if e.body == 0]
    assert ev0[0].time == pytest.approx(t1, abs=2e-5)
    assert ev0[-1].time == pytest.approx(t2, abs=2e-5) and ev0[-1].new == 0


def test_a_short_backward_slip_is_resolved_by_the_exact_method_at_the_hand_times():
    t1, t2 = _short_slip_times()
    crawler = cs.Crawler([1.0, 2.0], [2.0, 1.5], [1.0, 0.5])
    tr = cs.simulate(crawler, gaits.Sinusoid(0.1, 0.02, 1.0), 0.1, v0=0.05)
    ev0 = [e for e in tr.events if e.body == 0]
    assert abs(ev0[0].time - t1) <= 1e-12 and ev0[-1].new == 0
    assert abs(ev0[-1].time - t2) <= 1e-12


def test_the_exact_method_runs_a_three_body_travelling_wave_through_a_double_zero():
    crawler = cs.Crawler([1.405604276690312, 0.5772267932117432, 0.7725697559186377],
                         [1.121850482246133, 1.4340284082893642, 0.5849467869387766],
                         [2.180703058117212, 3.102316283955396, 1.0336976455969602], slope=0.03)
    gait = gaits.Sinusoid([0.1, 0.11], [0.02, 0.022], 1.0, [0.0, -0.7])
    t = np.linspace(0.0, 1.0, 51)
    tr = cs.simulate(crawler, gait, 1.0, v0=0.05, t_eval=t)
    assert cs.verify(tr).ok(1e-9)
    im = cs.simulate(crawler, gait, 1.0, 'implicit', dt=1e-4, v0=0.05, t_eval=t)
    assert np.max(np.abs(tr.x - im.x)) < 1e-4


# Periodic bang-bang stroke (PiecewiseParabolic.stroke), m = (1, 1), M = 2, f = (1, 2) both ways,
# amplitude A = 0.02, T = 0.5, extension time te = r T, contraction tc = (1 - r) T,
# l'' = +a_e, -a_e (each te/2), then -a_c, +a_c (each tc/2), a_e = 8A/te^2, a_c = 8A/tc^2,
# l' = 0 at t = 0, te, T. e_0' = -l'/2, e_1' = +l'/2. Hand solution of one period:
# * t = 0: both at rest; body 0 alone cannot hold (needs m1 a_e + f1 > f0), nor body 1
#   (m0 a_e + f0 > f1): they slide apart, R = (+1, -2), V' = -1/2, V = -t/2.
# * body 1 (v_1 = V + l'/2, l' = a_e (te - t) on [te/2, te)) stops at t1 = a_e te / (1 + a_e);
#   holding would need R_1 = M a_e/2 - 1 = a_e - 1 > 2, so it reverses: R = (+1, +2), V' = 3/2.
# * body 0 (v_0 = V - l'/2, l' = -a_c (t - te) after te) stops at
#   t2 = (2 t1 + a_c te / 2) / (3/2 + a_c / 2); holding needs R_0 = -a_c - 2 < -1: it reverses,
#   R = (-1, +2), V' = 1/2, V = V2 + (t - t2)/2 with V2 = -t1/2 + 3/2 (t2 - t1).
# * body 1 (l' = -a_c (T - t) on [te + tc/2, T)) stops at
#   t3 = (t2/2 - V2 + a_c T/2) / (1/2 + a_c/2) and holds: R_1 = -a_c + 1 in [-2, 2]; V = -l'/2.
# * t = T: l' = 0, both at rest again, l'' jumps to +a_e: body 1 slips exactly at the jump and the
#   period repeats. Displacement per period D = int_0^T V dt, piece by piece (V linear, then
#   quadratic on [t3, T]).
def _stroke_hand(r, A=0.02, T=0.5):
    te, tc = r * T, (1 - r) * T
    a_e, a_c = 8 * A / te ** 2, 8 * A / tc ** 2
    assert a_e + 2 > 1 and a_e + 1 > 2 and a_e - 1 > 2 and -a_c - 2 < -1 and -a_c + 1 >= -2
    t1 = a_e * te / (1 + a_e)
    t2 = (2 * t1 + a_c * te / 2) / (1.5 + a_c / 2)
    V1 = -t1 / 2
    V2 = V1 + 1.5 * (t2 - t1)
    t3 = (t2 / 2 - V2 + a_c * T / 2) / (0.5 + a_c / 2)
    assert te / 2 <= t1 < te < t2 < te + tc / 2 <= t3 < T
    assert V1 + 1.5 * (te - t1) < 0                         # body 0 still moving back at te
    D = (-0.25 * t1 ** 2 + V1 * (t2 - t1) + 0.75 * (t2 - t1) ** 2 + V2 * (t3 - t2)
         + 0.25 * (t3 - t2) ** 2 + a_c * (T - t3) ** 2 / 4)
    return t1, t2, t3, D


@pytest.mark.parametrize('r', [0.2, 0.3])
def test_a_bang_bang_stroke_has_the_hand_computed_events_and_displacement_every_period(r):
    t1, t2, t3, D = _stroke_hand(r)
    T, n = 0.5, 4
    crawler = cs.Crawler([1.0, 1.0], [1.0, 2.0])
    gait = gaits.PiecewiseParabolic.stroke(0.1, 0.02, 1 / T, r)
    tk = np.arange(n + 1) * T
    tr = cs.simulate(crawler, gait, n * T, t_eval=tk)
    np.testing.assert_allclose(np.diff(tr.com), D, rtol=1e-12, atol=1e-15)
    expected = []
    for k in range(n):
        o = k * T
        expected += [(o, 0, 0 if k == 0 else 1, -1), (o, 1, 0, 1), (o + t1, 1, 1, -1),
                     (o + t2, 0, -1, 1), (o + t3, 1, -1, 0)]
    got = sorted((e.time, e.body, e.old, e.new) for e in tr.events)
    expected.sort()
    assert [g[1:] for g in got] == [e[1:] for e in expected], got
    np.testing.assert_allclose([g[0] for g in got], [e[0] for e in expected], rtol=0, atol=1e-12)
    assert cs.verify(cs.simulate(crawler, gait, n * T)).ok(1e-9)


def test_a_penalty_given_per_body_equal_to_a_scalar_gives_the_same_run():
    crawler, gait = _crawler(3, 0.0, seed=51), _wave(3)
    a = cs.simulate(crawler, gait, 0.5, 'penalty', dt=1e-3, penalty=200.0)
    b = cs.simulate(crawler, gait, 0.5, 'penalty', dt=1e-3, penalty=[200.0, 200.0, 200.0])
    assert np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)
    # a stiffer body creeps less: the body that sticks most, given n_k = 2e5, has stuck speeds
    # below max(f_plus_k, f_minus_k) / 2e5 (linear zone |n_k v_k| < f) instead of f / 200
    k = int(np.argmax(cs.simulate(crawler, gait, 0.5).stick_fraction))
    n = np.full(3, 200.0)
    n[k] = 2e5
    c = cs.simulate(crawler, gait, 0.5, 'penalty', dt=1e-3, penalty=n)
    stuck = c.contact[:, k] == 0
    assert stuck.sum() > 10
    f_k = max(crawler.friction[k], crawler.friction_backward[k])
    assert np.all(np.abs(c.v[stuck, k]) <= f_k / 2e5 * (1 + 1e-12))
    assert np.max(np.abs(a.v[a.contact[:, k] == 0, k])) > 10 * f_k / 2e5
