"""Two ways the exact solver used to stall inside sim_node (issue 14), and their causes.

* Session seed 20 of benchmarks/node_sessions.py (p = 5): where the actuator settles, l' jumps to
  exactly 0 (by design, |jump| <= 1e-10 m/s). A sliding body whose velocity then pointed against
  its contact sign was sent to the acceleration-level inclusion, which chose the sign opposite to
  its velocity; the segment ended one float later on that body's velocity row, for ever. The
  contact sign now comes from the actual velocity; a rounding residue is not a velocity (seed
  2383: bodies 0 and 2 of p = 4, rigidly linked, at -9e-19 and -5e-18 m/s, traded the stuck role
  every float while each residue's sign was taken as a direction).
* Session seed 128 (p = 4): a rigid pair whose relative-velocity row started at +2.8e-16 (rounding,
  not motion) was scanned as an ordinary row: the bound-based step sqrt(4 g / B2) was ~1e-9 s, the
  compiled search ran out of iterations and reported "no event", the separation of the pair at
  t = 3.243 s was missed, and the state was inconsistent from then on. A row at zero to within
  its rounding noise is now *watched* (an event only below minus the noise), and a search that
  runs out of steps raises instead of answering "no event".
* Seeds 35 and 88 (the Taylor step of the compiled search, this round): the step to the first
  zero of g + g' h - B2 h^2 / 2 was computed as (g' + sqrt(g'^2 + 2 B2 g)) / B2, which cancels to
  0 for g' < 0 when B2 g << g'^2 (a jerk bound of 3e-17: the actuator's pieces), and 0 / 0 -> 0
  for a constant row (g' = 0, B2 = 0: constant acceleration); steps of 64 tol ran out of steps.
  Seed 141: a relative velocity settling onto zero with the command (5.6e-17 m/s, slope 1e-14)
  never crosses it; Taylor steps of ~sqrt(noise / B2) = 8e-10 s ran out of steps. A row come
  down to its rounding noise without the slope to cross zero in the shortest step is now an
  event (watching it instead, as a first fix did, missed a velocity touching zero between two
  search points: `python -m benchmarks.solvers stress --seed 11`, scene 224, body 1 of p = 12 sticks for 1.8 ms). Seed 337: bodies 0 and 2 stuck as a rigid pair
  whose link rates cancel to -5.3e-16 m/s, not 0 (mirrored commands): the rigid rows' noise,
  1e-13 of |l'| ~ 1e-15, was 1e-27, so the pair split one float later, for ever. A row declared
  zero by the mode counts its start value as noise too.
"""
import math

import numpy as np
import pytest

from crawler_sim.core import gaits




@pytest.mark.parametrize('seed', [20, 35, 88, 128, 141, 337, 2383])
def test_node_sessions_that_stalled_run_to_the_end_on_the_exact_method(seed):
    from benchmarks.node_sessions import session
    r = session(seed, 10.0, 'exact')
    assert r['failures'] == [] and r['method'] == 'exact', r
    assert r['finite'] and not r['crash'], r


def _core(p: int = 2):
    from crawler_sim import Crawler
    from crawler_sim.core.solvers.exact import ExactSolver
    return ExactSolver(Crawler([1.0] * p, [1.0] * p), gaits.Sinusoid([1.0] * (p - 1), 0.1,
                                                                     1.0))._core


def test_the_taylor_step_of_nearly_linear_and_constant_rows_is_not_zero():
    # g = 1, g' = -2, |g''| <= 1e-30: the first zero of 1 - 2 h - 5e-31 h^2 is 0.5 (by hand),
    # and the rigorous step (just inside it, 0.9999 of it) agrees with Newton's 0.5 to far
    # better than 20 %: the row is straight, so the step goes just past the root (1.001 x 0.5)
    # and the next point brackets the event instead of creeping up on it;
    # g = 1, g' = 0, g'' = 0: never zero, the step is unbounded (the cap, a cost setting, holds
    # only while some row is watched)
    core = _core()
    one, off = np.ones(1), np.zeros(1, dtype=bool)
    h = core.taylor_step(one, np.array([-2.0]), off, np.array([1e-30]), np.array([math.inf]),
                         1e-13, 10.0)
    assert h == 0.5 * 1.001
    assert core.taylor_step(one, np.zeros(1), off, np.zeros(1), np.array([math.inf]), 1e-13,
                            10.0) == math.inf
    two, watched = np.ones(2), np.array([False, True])
    assert core.taylor_step(two, np.zeros(2), watched, np.zeros(2), np.full(2, math.inf),
                            1e-13, 10.0) == 10.0
    # a curved row (|g''| <= 8: the rigorous step 0.31, well short of Newton's 0.5) keeps the
    # rigorous step, just inside the first zero of 1 - 2 h - 4 h^2 (by hand: (sqrt(5) - 1) / 4)
    hc = core.taylor_step(one, np.array([-2.0]), off, np.array([8.0]), np.array([math.inf]),
                          1e-13, 10.0)
    assert 0.9998 * (math.sqrt(5) - 1) / 4 <= hc < (math.sqrt(5) - 1) / 4
    # that step is proven by the Taylor bound from its left end alone
    assert core.proven_interval(hc, one, one - 2 * hc - 4 * hc ** 2, np.array([-2.0]),
                                np.array([-2.0 - 8 * hc]), off, np.array([8.0]),
                                np.array([math.inf]))


@pytest.mark.parametrize('eps0', [0.0, 3e-16, 1e-15])
def test_a_row_at_zero_to_rounding_that_goes_negative_is_an_event(eps0):
    # one row g(t) = l'(t) - l'(0) + eps0 with l = 1 + 0.3 sin(2 pi t): g(0) = eps0 and
    # g(t) = eps0 - 0.3 w (1 - cos w t) ~ eps0 - 0.15 w^3 t^2 < 0 just after 0 (by hand)
    w = 2 * math.pi
    gait = gaits.Fourier(1.0, ([0.0], [0.3]), 1.0)
    t, hit, _ = _core().search_rows(gait.compiled(), 0.0, 1.0, [eps0 - 0.3 * w], [0.0],
                                    [[1.0]], [[0.0]], 1e-13, 0.125)
    # the row is below -noise (1e-13 of its scale 0.6 w) once 0.15 w^3 t^2 > 4e-13: t ~ 1e-6 s;
    # any answer past 1e-4 s (or "no event", inf) misses the event
    assert 0.0 < t < 1e-4 and hit.tolist() == [True]
    assert eps0 - 0.3 * w * (1 - math.cos(w * t)) < 0.0


def test_a_link_whose_velocity_is_a_few_ulps_splits_its_stuck_pair_instead_of_stalling():
    """A user's tanh step, l = 1 + 0.05 tanh((t - 0.5) / 0.02), on two equal bodies: both are
    stuck while l' is exactly 0 in floats; at t = 0.1188 s, l' becomes 5.6e-16 (one rounding
    quantum of 1 - tanh^2). The two ends' accelerations differ by 5.6e-14, within the tie
    tolerance that merges a rigid pair into one kink, so the pair was kept stuck, found not rigid
    one float later, and so on: "stalled at t = 0.11876905069203364". A link found not rigid is
    now never merged. Equal bodies and frictions started at V = 0: the centre of mass stays at
    0.475 m (the symmetry of test_invariants), so at l(1) = 1.05 m, x = 0.475 -+ 0.525 =
    (-0.05, 1.0); the oracle gives the same. Advanced in 0.1 s syncs, as a node would (one
    advance over the whole second is correct but slow: the global jerk estimate makes the
    search step tiny on the near-zero tail, a known cost of gaits without local bounds)."""
    from test.support.oracle import Oracle
    from crawler_sim import Crawler
    from crawler_sim.core.solvers.exact import ExactSolver
    w, A = 0.02, 0.05

    def th(t):
        return math.tanh((t - 0.5) / w)
    gait = gaits.Custom(lambda t: 1 + A * th(t), lambda t: A / w * (1 - th(t) ** 2),
                        lambda t: -2 * A / w ** 2 * th(t) * (1 - th(t) ** 2))
    crawler = Crawler([1, 1], [1, 1])
    solver = ExactSolver(crawler, gait)
    for k in range(1, 11):
        solver.advance(0.1 * k)
    x = solver.current()['x']

    def kin(t):
        h = np.tanh((np.asarray(t) - 0.5) / w)
        return ((1 + A * h)[:, None], (A / w * (1 - h * h))[:, None],
                (-2 * A / w ** 2 * h * (1 - h * h))[:, None])
    ref, _ = Oracle.for_crawler(crawler, kin).solve(1.0, [0.0, 1.0], h=1e-5)
    np.testing.assert_allclose(x, ref[1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(x, [-A, 1.0], rtol=0, atol=1e-6)   # symmetry, by hand


def test_a_velocity_that_touches_zero_is_a_stick():
    # stress seed 11, random scene 224 (p = 12, a Sinusoid): body 1 slides backward, its
    # velocity touches zero at t = 0.13224 s and it sticks until 0.13404 s (the independent
    # oracle of test/support/oracle.py agrees on the positions)
    from test.support.oracle import Oracle
    from benchmarks.solvers import stress
    import crawler_sim as cs
    rng = np.random.default_rng(11)
    for _ in range(225):
        spec = stress.random_spec(rng)
    crawler, gait, _, _ = stress.build(spec)
    t = np.linspace(0.0, 0.2, 21)
    run = cs.simulate(crawler, gait, 0.2, periodic_skip=False, t_eval=t)
    ev = [(e.body, e.old, e.new) for e in run.events if 0.13 < e.time < 0.135]
    assert ev == [(1, -1, 0), (1, 0, -1)]
    ref, _ = Oracle.for_crawler(crawler, lambda s: gait(np.asarray(s, float))).solve(
        0.2, t, h=2e-5)
    np.testing.assert_allclose(run.x, ref, rtol=0, atol=1e-10)


@pytest.mark.parametrize('c0,c1', [(0.5, -0.5), (3.0, -2.0), (0.75, -0.25)])
def test_a_row_that_lands_exactly_on_zero_ends_the_narrowing_at_once(c0, c1):
    # g(t) = c0 + c1 t, its root -c0 / c1 a float where g rounds to exactly 0.0 (by hand: 1,
    # 1.5, 3). Newton's point lands on it, so the bracket's bad end b has g(b) = 0: the root
    # is b. The float below b then closes the bracket (it was halved from a towards b instead:
    # 55 evaluations of the gait for one event).
    gait = gaits.Fourier(1.0, ([0.0], [0.3]), 1.0)
    t, hit, n = _core().search_rows(gait.compiled(), 0.0, 8.0, [c0], [c1], [[0.0]], [[0.0]],
                                    1e-13, 1.0)
    assert t == -c0 / c1 and hit.tolist() == [True]
    assert n <= 4, n
