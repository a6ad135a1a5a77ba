"""A ``Custom`` gait on the compiled loop: its functions sampled into Chebyshev pieces (the
PROXY kind of ``core.solvers._gait``, ``core.solvers.proxy``), with or without ``jerk_bound``
(which the pieces are checked against).

Reference: the independent event-driven oracle (test/support/oracle.py, written apart from the
solvers, accurate to ~1e-12 m here); the tolerance is 1e-10 m. A search with bounds that fit
the gait takes ~17 evaluations per segment (a global bound took ~200), which the evaluation
count checks.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim import gaits
from crawler_sim.core.solvers.exact import ExactSolver

from test.support.oracle import Oracle

W = 2 * math.pi


def _sine(amp=0.3, w=W, calls=None):
    """The issue's Custom gait l = 1 + amp sin(w t), recording every time it is called at."""
    def rec(t):
        if calls is not None:
            calls.append(t)
        return t
    return gaits.Custom(lambda t: 1 + amp * math.sin(w * rec(t)),
                        lambda t: amp * w * math.cos(w * rec(t)),
                        lambda t: -amp * w * w * math.sin(w * rec(t)))


def _sine_kin(mean, amp, w):
    mean, amp = np.atleast_1d(mean), np.atleast_1d(amp)

    def kin(t):
        t = np.asarray(t, float)[:, None]
        return mean + amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)
    return kin


def _run(crawler, gait, T):
    s = ExactSolver(crawler, gait)
    s.advance(T)
    return s, s.current()['x']


def test_the_issue_gait_runs_compiled_and_matches_the_oracle():
    c = cs.Crawler([1, 1], [1, 1])
    g = _sine()
    s, x = _run(c, g, 4.25)          # the issue's stall at 4.25 s
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(4.25, [0.0, 4.25], h=1e-4)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    assert s.n_evals < 40 * s.n_segments, (s.n_evals, s.n_segments)


def test_three_bodies_with_array_valued_functions_match_the_oracle():
    # the general callback (functions returning one value per linkage)
    mean, amp, w = np.array([1.0, 0.8]), np.array([0.2, 0.15]), 1.7 * W
    g = gaits.Custom(lambda t: mean + amp * np.sin(w * t), lambda t: amp * w * np.cos(w * t),
                     lambda t: -amp * w * w * np.sin(w * t))
    c = cs.Crawler([1.0, 2.0, 0.5], [1.0, 3.0, 0.4])
    s, x = _run(c, g, 2.0)
    ref, _ = Oracle.for_crawler(c, _sine_kin(mean, amp, w)).solve(2.0, [0.0, 2.0], h=1e-4)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    assert s.n_evals < 40 * s.n_segments, (s.n_evals, s.n_segments)


def test_the_users_functions_are_called_only_inside_the_run():
    # a gait defined on [0, T] only (an interpolated recording, say) must not be asked for
    # l'' at T + d by the differences of the callback
    calls: list[float] = []
    cs.simulate(cs.Crawler([1, 1], [0.5, 1]), _sine(calls=calls), 3.0, t_eval=[0.0, 3.0])
    assert calls and min(calls) >= 0.0 and max(calls) <= 3.0


def test_a_users_exception_inside_the_loop_reaches_the_caller_unchanged():
    def accel(t):
        if t > 0.7:
            raise ZeroDivisionError('the user gait broke at t > 0.7')
        return -0.3 * W * W * math.sin(W * t)
    g = gaits.Custom(lambda t: 1 + 0.3 * math.sin(W * t), lambda t: 0.3 * W * math.cos(W * t),
                     accel)
    with pytest.raises(ZeroDivisionError, match='broke at t > 0.7'):
        cs.simulate(cs.Crawler([1, 1], [1, 1]), g, 2.0)
    # and the next run with a sound gait is unaffected
    _, x = _run(cs.Crawler([1, 1], [1, 1]), _sine(), 1.0)
    assert np.all(np.isfinite(x))


def test_a_non_finite_acceleration_is_an_error_naming_it():
    g = gaits.Custom(lambda t: 1.0, lambda t: 0.0, lambda t: math.nan if t > 0.5 else 0.0)
    with pytest.raises(ValueError, match='acceleration must be finite'):
        cs.simulate(cs.Crawler([1, 1], [1, 1]), g, 1.0)


def test_a_sharp_feature_is_resolved_where_it_is():
    # a Scallop of asymmetry 0.006 as user lambdas: |l'''| in its sharp phase is ~1e5 times the
    # slow phase's. One bound for the whole run made the slow phase take ~1e6 evaluations
    # (12.8 s); the pieces halve only where the gait is sharp. Reference: the oracle.
    sc = gaits.Scallop(1.0, 0.2, 1.0, 0.006)
    g = gaits.Custom(lambda t: sc.at(t)[0], lambda t: sc.at(t)[1], lambda t: sc.at(t)[2])
    c = cs.Crawler([1.0, 1.0], [1.0, 2.0])
    s, x = _run(c, g, 1.5)
    kin = lambda t: sc(np.asarray(t, float))       # noqa: E731
    ref, _ = Oracle.for_crawler(c, kin).solve(1.5, [0.0, 1.5], h=1e-5)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    assert s.n_evals < 20_000, s.n_evals


@pytest.mark.parametrize('kw', [{'jerk_bound': 0.3 * W ** 3},
                                {'jerk_bound': lambda t0, t1: 0.3 * W ** 3},
                                {'breakpoints': [0.5]}, {'period': 1.0}])
def test_every_form_of_custom_gait_runs_compiled_and_matches_the_oracle(kw):
    # a bound (float or callable), breakpoints, a period: the same loop, the same answer
    g = gaits.Custom(*_sine()._fns, **kw)
    c = cs.Crawler([1, 1], [1, 1])
    s, x = _run(c, g, 2.5)
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(2.5, [0.0, 2.5], h=1e-4)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    assert s.n_evals < 60 * s.n_segments, (s.n_evals, s.n_segments)


def test_a_custom_gait_that_ran_compiled_still_pickles():
    # sweeps send gaits to their workers (cloudpickle handles the lambdas); the compiled form
    # and its estimate must not travel with the gait
    cloudpickle = pytest.importorskip('cloudpickle')
    g = _sine()
    x = cs.simulate(cs.Crawler([1, 1], [1, 1]), g, 2.0, t_eval=[0.0, 2.0]).x[-1]
    assert '_compiled' in g.__dict__
    g2 = cloudpickle.loads(cloudpickle.dumps(g))
    assert '_compiled' not in g2.__dict__
    x2 = cs.simulate(cs.Crawler([1, 1], [1, 1]), g2, 2.0, t_eval=[0.0, 2.0]).x[-1]
    np.testing.assert_array_equal(x, x2)


def test_one_custom_gait_shared_by_solvers_in_threads_gives_each_the_sequential_answer():
    # the callback's state lives on the gait; solvers in other threads take turns with it
    from concurrent.futures import ThreadPoolExecutor
    g = _sine()
    crawlers = [cs.Crawler([1, 1 + 0.25 * k], [0.5 + 0.1 * k, 1]) for k in range(8)]
    alone = [cs.simulate(c, _sine(), 3.0, t_eval=[0.0, 3.0]).x[-1] for c in crawlers]
    with ThreadPoolExecutor(4) as pool:
        shared = list(pool.map(lambda c: cs.simulate(c, g, 3.0, t_eval=[0.0, 3.0]).x[-1],
                               crawlers * 4))
    for k, x in enumerate(shared):
        np.testing.assert_allclose(x, alone[k % 8], rtol=0, atol=1e-12)


@pytest.mark.parametrize('p', [2, 8])
def test_an_advance_of_one_float_then_to_the_event_time_is_fine(p):
    # Stepper.advance(nextafter(te, 0)) then advance(te) with a Custom gait given its period:
    # the span of one float made the difference step of l''' zero (ZeroDivisionError), and at
    # p = 8 the estimate's stop value was read as a non-finite gait value
    n = p - 1
    ph = np.arange(n) * 0.3
    if n == 1:
        g = gaits.Custom(lambda t: 1 + 0.2 * math.sin(W * t), lambda t: 0.2 * W * math.cos(W * t),
                         lambda t: -0.2 * W * W * math.sin(W * t), period=1.0)
    else:
        g = gaits.Custom(lambda t: 1 + 0.2 * np.sin(W * t + ph),
                         lambda t: 0.2 * W * np.cos(W * t + ph),
                         lambda t: -0.2 * W * W * np.sin(W * t + ph), period=1.0)
    c = cs.Crawler(np.ones(p), np.ones(p))
    st = cs.Stepper(c, g)
    st.advance(float(np.nextafter(0.37, 0.0)))
    st.advance(0.37)
    one = cs.Stepper(c, gaits.Custom(*g._fns, period=1.0))
    one.advance(0.37)
    np.testing.assert_allclose(st.state.x, one.state.x, rtol=0, atol=1e-12)


def test_a_periodic_custom_copy_of_a_sharp_scallop_keeps_its_short_reversal():
    # asymmetry 0.0053 (a 5 ms extension per period), p = 3, period= given: the estimate scans
    # one period finely (1/1024 of it, refined where the gait is sharp) and repeats it; a 3 ms
    # reversal was missed, 1.8 mm off. Reference: the oracle fed the built-in Scallop.
    sc = gaits.Scallop([1.0, 1.0], 0.2, 1.0, 0.0053, [0.0, -1.0])
    c = cs.Crawler([1.0, 1.5, 0.8], [1.0, 2.0, 1.0])
    g = gaits.Custom(lambda t: sc.at(t)[0], lambda t: sc.at(t)[1], lambda t: sc.at(t)[2],
                     period=1.0)
    t = np.linspace(0.0, 3.0, 7)
    x = cs.simulate(c, g, 3.0, t_eval=t).x
    ref, _ = Oracle.for_crawler(c, lambda s: sc(np.asarray(s, float))).solve(3.0, t, h=2e-5)
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10)
    # the period's pieces, joined where one series holds two, still follow the sharp phase:
    # l'' of the pieces (numpy's chebval) against the Scallop's closed form, densely where
    # it is sharp (its 83,000 m/s^2 peak; the formula's own rounding there is ~1e-11 of it)
    from numpy.polynomial import chebyshev as C
    tb = g.compiled().table
    assert 8 < tb.knots.size - 1 < 32
    ts = np.concatenate([np.linspace(0.0, 1.0, 4001), np.linspace(0.99, 1.0, 4001),
                         np.linspace(0.0, 0.01, 4001)])
    k = np.clip(np.searchsorted(tb.knots, ts, side='right') - 1, 0, tb.knots.size - 2)
    u = (2 * ts - tb.knots[k] - tb.knots[k + 1]) / (tb.knots[k + 1] - tb.knots[k])
    got = np.array([[C.chebval(u[i], tb.coef[k[i], j, 2]) for j in range(2)]
                    for i in range(ts.size)])
    want = sc(ts)[2]
    assert np.abs(got - want).max() < 1e-10 * np.abs(want).max()


def test_a_jump_of_l_acceleration_without_breakpoints_is_refused_naming_them():
    # l'' = 0.2 before t = 0.5 and 0 after, no breakpoints=: a contract breach. The search used
    # to run out of steps after minutes; the scan now finds the jump and names it.
    g = gaits.Custom(lambda t: 1 + 0.1 * t * t if t < 0.5 else 1.025 + 0.1 * (t - 0.5),
                     lambda t: 0.2 * t if t < 0.5 else 0.1,
                     lambda t: 0.2 if t < 0.5 else 0.0)
    with pytest.raises(ValueError, match=r"jumps by .* at t = 0\.5.* breakpoints="):
        cs.simulate(cs.Crawler([1, 1], [1, 1]), g, 1.0)
    # with the breakpoint given it runs, and the same gait from the oracle agrees
    gb = gaits.Custom(*g._fns, breakpoints=[0.5])
    x = cs.simulate(cs.Crawler([1, 1], [1, 1]), gb, 1.0, t_eval=[0.0, 1.0]).x
    pp = gaits.PiecewiseParabolic([0.0, 0.5, 1.0], [0.2, 0.0], 1.0, 0.0, periodic=False)
    ref, _ = Oracle.for_crawler(cs.Crawler([1, 1], [1, 1]), lambda s: pp(np.asarray(s, float)),
                                [0.5]).solve(1.0, [0.0, 1.0], h=1e-4)
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10)


def test_a_custom_gait_reused_for_a_longer_run_costs_what_a_fresh_one_does():
    """The scan grid of a Custom gait without period or max_step is 1/256 of the span; a gait
    object that served a 1 s run first kept that grid, so a 1e4 s rest then evaluated l''
    about 2.5 million times (1.3 s; a 1e6 s rest took 3 minutes). Counted in calls of the
    user's l'', not in seconds: the reused gait needs about as many as a fresh one."""
    calls = [0]

    def acc(t):
        calls[0] += 1
        return np.zeros(1)

    def count(runs):
        gait = gaits.Custom(lambda t: np.array([0.1]), lambda t: np.zeros(1), acc)
        crawler = cs.Crawler([0.5, 1.0], [1.5, 2.9])
        for t_end in runs:
            calls[0] = 0
            tr = cs.simulate(crawler, gait, t_end, t_eval=[0.0, t_end])
            assert (tr.contact[-1] == 0).all()          # a rest: every body stays stuck
        return calls[0]

    fresh = count([1e4])
    reused = count([1.0, 1e4])
    assert reused <= 2 * fresh + 100, (fresh, reused)


# ---------------------------------------------------------------- the Chebyshev pieces
def _table(gait, t0, t1):
    """The pieces a solve over [t0, t1] builds (``proxy.ChebTable``)."""
    cg = gait.compiled()
    cg.table.ensure(t0, t0, t1)
    cg.table.ensure(t1, t0, t1)
    return cg.table


def test_the_pieces_match_the_functions_and_numpys_chebyshev_calculus():
    # l = 1 + 0.3 (sin w t + 0.3 sin 2 w t) over 10 periods: each piece's four series
    # (numpy.polynomial.chebyshev evaluates them, an implementation apart from ours) against
    # the closed forms, to the rounding of the functions themselves (|t| eps l''' ~ 3e-13 at
    # t = 10 for l''); l''' is numpy's derivative of our l'' series.
    from numpy.polynomial import chebyshev as C
    l3 = lambda t: -0.3 * W ** 3 * (math.cos(W * t) + 2.4 * math.cos(2 * W * t))  # noqa: E731
    g = gaits.Custom(lambda t: 1 + 0.3 * (math.sin(W * t) + 0.3 * math.sin(2 * W * t)),
                     lambda t: 0.3 * W * (math.cos(W * t) + 0.6 * math.cos(2 * W * t)),
                     lambda t: -0.3 * W * W * (math.sin(W * t) + 1.2 * math.sin(2 * W * t)))
    tb = _table(g, 0.0, 10.0)
    ts = np.linspace(0.0, 10.0, 2001)
    k = np.clip(np.searchsorted(tb.knots, ts, side='right') - 1, 0, tb.knots.size - 2)
    a, b = tb.knots[k], tb.knots[k + 1]
    u = (2 * ts - a - b) / (b - a)
    fns = g._fns + (l3,)
    scale = (1.3, 0.3 * W * 1.6, 0.3 * W * W * 2.2, 0.3 * W ** 3 * 3.4)
    for d, fn in enumerate(fns):
        got = np.array([C.chebval(u[i], tb.coef[k[i], 0, d]) for i in range(ts.size)])
        want = np.array([fn(t) for t in ts])
        assert np.max(np.abs(got - want)) < (1e-13, 1e-12, 1e-11, 2e-8)[d] * scale[d], d
    for q in range(tb.knots.size - 1):
        half = 0.5 * (tb.knots[q + 1] - tb.knots[q])
        der = C.chebder(tb.coef[q, 0, 2]) / half
        np.testing.assert_allclose(der, tb.coef[q, 0, 3][:der.size], rtol=0, atol=1e-9)
        # the bound of |l'''| on each piece holds
        inside = (ts >= tb.knots[q]) & (ts <= tb.knots[q + 1])
        assert np.max(np.abs([l3(t) for t in ts[inside]])) <= tb.bj[q, 0] * (1 + 1e-12)


@pytest.mark.parametrize('seed', range(4))
def test_each_pieces_jerk_and_snap_bounds_hold_and_are_tight(seed):
    # Random two-linkage gaits of a few harmonics (2 to 9 per period, random phases), over 10
    # periods: on every piece, |l'''| and |l''''| of its series (numpy's chebval of our l'''
    # series and numpy's chebder of it: an implementation apart from ours), read at 4,001
    # points, stay within the piece's bounds, and the bounds are within 1.5 times that
    # largest value: the search's steps grow as the bound shrinks (measured 1.02 to 1.46
    # times; the sums of the coefficients' magnitudes, the bounds before, reach 2.2 to 3.0
    # times it on each of these gaits and fail the second check).
    from numpy.polynomial import chebyshev as C
    rng = np.random.default_rng(seed)
    ks = rng.choice(np.arange(1, 10), size=(2, 3), replace=True)
    amp = rng.uniform(0.02, 0.2, size=(2, 3))
    ph = rng.uniform(0.0, 2 * math.pi, size=(2, 3))

    def deriv(d):
        def f(t):
            return np.array([sum(a * (W * k) ** d * math.sin(W * k * t + p + d * math.pi / 2)
                                 for a, k, p in zip(amp[j], ks[j], ph[j])) for j in range(2)])
        return f
    g = gaits.Custom(lambda t: 1.0 + deriv(0)(t), deriv(1), deriv(2))
    tb = _table(g, 0.0, 10.0)
    u = np.linspace(-1.0, 1.0, 4001)
    for q in range(tb.knots.size - 1):
        half = 0.5 * (tb.knots[q + 1] - tb.knots[q])
        for j in range(2):
            jerk = np.max(np.abs(C.chebval(u, tb.coef[q, j, 3])))
            snap = np.max(np.abs(C.chebval(u, C.chebder(tb.coef[q, j, 3]) / half)))
            for got, top in ((tb.bj[q, j], jerk), (tb.bs[q, j], snap)):
                assert top <= got * (1 + 1e-12), (q, j, top, got)
                assert got <= 1.5 * top, (q, j, top, got)


class _Subclass(gaits.Gait):
    """A user's Gait subclass (its own ``_eval``, breakpoints and jerk bound)."""

    n_links = 1
    period = None

    def _eval(self, t):
        return ((1 + 0.3 * np.sin(W * t))[:, None], (0.3 * W * np.cos(W * t))[:, None],
                (-0.3 * W * W * np.sin(W * t))[:, None])

    def breakpoints(self, t0, t1):
        return np.array([x for x in (0.5,) if t0 < x < t1])

    def jerk_bound(self, t0, t1):
        return np.array([0.3 * W ** 3])


@pytest.mark.parametrize('make', [
    lambda: _sine(), lambda: gaits.Custom(*_sine()._fns, breakpoints=[0.5],
                                          jerk_bound=lambda t0, t1: 0.3 * W ** 3),
    lambda: gaits.Custom(*_sine()._fns, period=1.0), _Subclass], ids=[
        'custom', 'custom_hints', 'custom_period', 'subclass'])
def test_a_gait_and_its_compiled_form_are_freed_without_the_cyclic_collector(make):
    # The compiled form of a Python gait (its pieces, the callables that read the user's
    # functions) is owned by the gait; were it to refer back to the gait, each gait would be
    # a cycle that only the cyclic collector frees, which a new gait per run then triggers
    # often (a fresh Custom gait's run 280 -> 440 us in a process of 50,000 objects). With
    # the collector off, a gait used by simulate and a Stepper is gone with its last name.
    import gc
    import weakref
    c = cs.Crawler([1, 1], [0.5, 1])
    gc.collect()
    gc.disable()
    try:
        g = make()
        cs.simulate(c, g, 2.0, t_eval=[0.0, 2.0])
        st = cs.Stepper(c, g)
        st.advance(1.0)
        st.advance(1.5, g)
        assert float(g.compiled().values(np.array([0.25]))[0][0, 0]) == pytest.approx(1.3)
        ref = weakref.ref(g)
        del g, st
        assert ref() is None
    finally:
        gc.enable()


@pytest.mark.parametrize('jerk', [None, 0.3 * W ** 3, lambda t0, t1: 0.3 * W ** 3])
def test_a_run_calls_the_functions_once_per_cell_not_per_evaluation(jerk):
    # 10 periods, no period given: 256 cells (1/256 of the span), 33 nodes per 32 cells, two
    # values (l, l') per join; the search and the 161 output samples read the pieces. The
    # answer is the oracle's. A jerk_bound (|l'''| = 0.3 w^3 exactly) changes nothing of it:
    # it is checked against the pieces, not called at every evaluation (~4,000 calls before)
    calls = []
    g = gaits.Custom(*_sine(calls=calls)._fns, jerk_bound=jerk)
    c = cs.Crawler([1, 1], [0.5, 1])
    grid = np.linspace(0.0, 10.0, 161)
    tr = cs.simulate(c, g, 10.0, t_eval=grid)
    assert len(calls) <= 8 * 33 + 2 * 9 + 3 * 3, len(calls)
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(10.0, grid, h=1e-4)
    np.testing.assert_allclose(tr.x, ref, rtol=0, atol=1e-10)


@pytest.mark.parametrize('form', ['float', 'callable', 'subclass'])
def test_a_jerk_bound_the_gait_exceeds_is_refused_naming_it(form):
    # l''' of 1 + 0.3 sin(w t) reaches 0.3 w^3 = 74.4 m/s^3; a bound of 0.9 of it is wrong
    # and must be named (a bound 1e-6 above it passes: the check allows only the rounding)
    bad, good = 0.9 * 0.3 * W ** 3, (1 + 1e-6) * 0.3 * W ** 3
    c = cs.Crawler([1, 1], [1, 1])

    def make(bound):
        if form == 'float':
            return gaits.Custom(*_sine()._fns, jerk_bound=bound)
        if form == 'callable':
            return gaits.Custom(*_sine()._fns, jerk_bound=lambda t0, t1: bound)

        class Sine(gaits.Gait):
            n_links = 1

            def _eval(self, t):
                s, co = np.sin(W * t)[:, None], np.cos(W * t)[:, None]
                return 1 + 0.3 * s, 0.3 * W * co, -0.3 * W * W * s

            def jerk_bound(self, t0, t1):
                return np.array([bound])
        return Sine()
    with pytest.raises(ValueError, match=r"jerk_bound of linkage 0 .* must bound \|l'''\|"):
        cs.simulate(c, make(bad), 2.0)
    x = cs.simulate(c, make(good), 2.0, t_eval=[0.0, 2.0]).x[-1]
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(2.0, [0.0, 2.0], h=1e-4)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)


def test_a_periodic_gait_is_sampled_one_period_then_repeated():
    # period= given: 1024 cells a period, 32 pieces of 33 nodes over [0, 1], none after it;
    # the 20th period reads the first one's pieces (the oracle agrees). A sine's period is one
    # series of degree < 30: the 32 pieces are joined into one (each join would end a
    # segment: 20 x 32 segments instead of about 5 a period)
    calls = []
    g = gaits.Custom(*_sine(calls=calls)._fns, period=1.0)
    c = cs.Crawler([1, 1], [0.5, 1])
    tr = cs.simulate(c, g, 20.0, t_eval=[0.0, 19.5, 20.0], periodic_skip=False)
    assert len(calls) <= 32 * 33 + 2 * 33 + 3 * 3 and max(calls) <= 1.0, (len(calls), max(calls))
    assert g.compiled().table.knots.tolist() == [0.0, 1.0]
    assert len(tr.events) <= 5 * 20 + 2
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(20.0, [0.0, 19.5, 20.0],
                                                               h=1e-4)
    np.testing.assert_allclose(tr.x, ref, rtol=0, atol=1e-10)


def test_a_kink_of_l_acceleration_is_found_in_one_split():
    # l'' = 1 + slope (t - 0.3137), the slope -20 before and 80 after (l''' jumps, l'' is
    # continuous: legal without breakpoints). The slopes' lines meet at the kink, where its
    # piece is split: a few hundred evaluations, not the ~900 of halving; the run agrees with
    # the same gait given the kink as a breakpoint (then each side is one polynomial).
    tk, s0, s1 = 0.3137, -20.0, 80.0

    def fns(d):
        s = s1 if d > 0 else s0
        return 1 + d + 0.5 * d * d + s * d ** 3 / 6, 1 + d + s * d * d / 2, 1 + s * d
    calls = [0]

    def acc(t):
        calls[0] += 1
        return fns(t - tk)[2]
    g = gaits.Custom(lambda t: fns(t - tk)[0], lambda t: fns(t - tk)[1], acc)
    c = cs.Crawler([1.0, 2.0], [0.3, 0.4])
    x = cs.simulate(c, g, 1.0, t_eval=[0.0, 0.5, 1.0]).x
    assert calls[0] < 400, calls[0]
    gb = gaits.Custom(*g._fns, breakpoints=[tk])
    xb = cs.simulate(c, gb, 1.0, t_eval=[0.0, 0.5, 1.0]).x
    np.testing.assert_allclose(x, xb, rtol=0, atol=1e-12)
    assert tk in g.compiled().table.knots


def test_a_velocity_that_is_not_the_integral_of_the_acceleration_is_refused():
    # l' off by a factor 2: the pieces' integral of l'' misses the user's l' at the first join
    g = gaits.Custom(lambda t: 1 + 0.3 * math.sin(W * t), lambda t: 0.6 * W * math.cos(W * t),
                     lambda t: -0.3 * W * W * math.sin(W * t))
    with pytest.raises(ValueError, match=r"gait velocity of linkage 0 at t = .* derivatives"):
        cs.simulate(cs.Crawler([1, 1], [1, 1]), g, 2.0)


def test_the_rounding_of_a_late_time_is_not_taken_for_a_feature():
    # sin(w t) near t = 1e6 s is known to |t| eps w ~ 1e-9 of its size: the pieces accept that
    # noise (a tail halving no longer lowers) instead of halving down to nothing
    t0 = 1e6
    g = gaits.Custom(lambda t: 1 + 0.3 * math.sin(W * t), lambda t: 0.3 * W * math.cos(W * t),
                     lambda t: -0.3 * W * W * math.sin(W * t))
    st = cs.Stepper(cs.Crawler([1, 1], [1, 2]), g, t0=t0)
    st.advance(t0 + 2.0)
    tb = g.compiled().table
    assert tb.knots.size < 200 and tb.calls < 10_000, (tb.knots.size, tb.calls)
    assert np.all(np.isfinite(st.state.x))


@pytest.mark.parametrize('r', [0.004, 0.002])
def test_a_very_sharp_copy_is_resolved_to_its_own_rounding(r):
    # a Scallop of asymmetry 0.002 computes its sharp phase's l'' with a rounding of ~3e-11 of
    # its size (1 / (1 - cos(pi r)) ~ 1e5 amplifies eps): pieces there stop splitting at that
    # floor (measured over each piece's own values: over the largest value seen, the slow
    # phase's pieces were accepted 1e-7 off, 5e-9 m; with a floor below the rounding the
    # build never ended). Reference: the built-in Scallop's rigorous run of the same formula.
    sc = gaits.Scallop(1.0, 0.2, 1.0, r)
    g = gaits.Custom(lambda t: sc.at1(t)[0], lambda t: sc.at1(t)[1], lambda t: sc.at1(t)[2])
    c = cs.Crawler([1.0, 1.5], [1.0, 2.0])
    t = np.linspace(0.0, 2.0, 9)
    x = cs.simulate(c, g, 2.0, t_eval=t).x
    ref = cs.simulate(c, sc, 2.0, t_eval=t).x
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-10)
    assert g.compiled().table.calls < 10_000


def test_streaming_in_short_steps_keeps_only_the_pieces_ahead():
    # 2,000 steps of 1 ms: each step's span is sampled (1/256 of it a cell) and the pieces
    # behind the span are dropped; the table used to keep growing (up to 15,000 pieces, each
    # step copying it whole: 1.7 ms a step). The state agrees with the built-in Sinusoid.
    g = _sine(amp=0.2)
    c = cs.Crawler([1, 1.5], [0.5, 1.0])
    st = cs.Stepper(c, g)
    for k in range(1, 2001):
        st.advance(k * 1e-3)
    assert g.compiled().table.knots.size <= 40, g.compiled().table.knots.size
    ref = cs.simulate(c, gaits.Sinusoid(1.0, 0.2, 1.0), 2.0, t_eval=[0.0, 2.0]).x[-1]
    np.testing.assert_allclose(st.state.x, ref, rtol=0, atol=1e-10)


def test_streaming_in_short_steps_samples_as_one_run_does_not_each_step_finely():
    # 500 steps of 10 ms: a cell was 1/256 of each step (39 us), eight pieces of 33 samples a
    # step (273 calls of the user's functions a step; 91 us a step at p = 2, 613 us at p = 3
    # with numpy functions); it is 1/256 of the run so far, as for the same run in one call,
    # so one piece covers a step (33 samples and the end state: 35 calls). The state agrees
    # with the built-in Sinusoid as closely as before.
    calls = []
    g = _sine(amp=0.2, calls=calls)
    c = cs.Crawler([1, 1.5], [0.5, 1.0])
    st = cs.Stepper(c, g)
    for k in range(1, 401):
        st.advance(k * 1e-2)
    n0 = len(calls)
    for k in range(401, 501):
        st.advance(k * 1e-2)
    assert (len(calls) - n0) / 100 <= 60, len(calls) - n0
    ref = cs.simulate(c, gaits.Sinusoid(1.0, 0.2, 1.0), 5.0, t_eval=[0.0, 5.0]).x[-1]
    np.testing.assert_allclose(st.state.x, ref, rtol=0, atol=1e-10)
