"""A ``Custom`` gait on the compiled loop (the CALLBACK kind of ``core.solvers._gait``): the
user's lambdas called from the segment loop, bounds estimated from a scan of l'' and grown when
a value contradicts them (``core.solvers.estimate``), or the user's ``jerk_bound``.

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
from crawler_sim.core.solvers.estimate import BoundEstimate
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


def test_bounds_that_prove_too_small_are_grown_and_the_search_redone(monkeypatch):
    # the first scan's estimate made 50 times too small: the search's values contradict it,
    # the scan cell where that happened takes the value seen, the search runs again, and the
    # answer is the oracle's
    scan = BoundEstimate._scan
    first = [True]

    def small(self, a, b):
        scan(self, a, b)
        if first.pop() if first else False:
            self.d1 /= 50.0
            self.d2 /= 50.0
    monkeypatch.setattr(BoundEstimate, '_scan', small)
    c = cs.Crawler([1, 1], [0.5, 1])
    g = _sine()
    _, x = _run(c, g, 3.0)
    ref, _ = Oracle.for_crawler(c, _sine_kin(1.0, 0.3, W)).solve(3.0, [0.0, 3.0], h=1e-4)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    assert g.compiled().exceeded > 0


def test_a_sharp_feature_sets_the_bounds_of_its_own_block_only():
    # a Scallop of asymmetry 0.006 as user lambdas: |l'''| in its sharp phase is ~1e5 times the
    # slow phase's. One bound for the whole run made the slow phase take ~1e6 evaluations
    # (12.8 s); with blocks the run needs ~1e3. Reference: the oracle.
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


def test_a_periodic_gait_is_scanned_one_period_and_then_repeated():
    # 1024 cells a period (estimate.PER_PERIOD): a sine's scan needs no refinement, so one
    # period is 1025 evaluations of l'' (by count); the window of 4096 cells used to scan four
    # periods of a periodic gait, three of them for nothing. Later stretches, near or far,
    # are the first period's cells shifted: no evaluation.
    calls = []

    def accel(t):
        calls.append(t)
        return -math.sin(2 * math.pi * t)

    est = BoundEstimate(accel, 1, period=1.0)
    est.ensure(0.0, 0.01, 0.0, 100.0)
    assert 1025 <= len(calls) <= 1100 and max(calls) <= 1.0
    assert est.lo == 0.0 and est.hi == 1.0
    n = len(calls)
    est.ensure(2.5, 2.6, 0.0, 100.0)
    est.ensure(40.2, 40.3, 0.0, 100.0)
    assert len(calls) == n and est.hi >= 40.3
