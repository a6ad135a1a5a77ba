"""The search's third-order Taylor bound, for rows of l' alone (a sliding body's velocity, the
relative velocity of a rigid pair).

Such a row g = c0 + c1 t + A1 . l' has a known curvature at each point, g'' = A1 . l''', and
|g'''| <= B3 = |A1| . (snap bound) on an interval, so g(a + x) >= L(x) = g + g' x + g'' x^2 / 2 -
B3 x^3 / 6 there. Where a slip starts smoothly (the required force reaches its bound with zero
slope: a Scallop's stick-to-slip) the velocity row leaves zero as c x^2: the second-order bound,
which must assume the worst curvature -B2, let each step grow about twofold (13 evaluations in
the first microsecond, 31 to the next event); the third-order one, which knows the curvature is
+2c, proves the row over ~3 c / B3 at once.

References: the cubic's roots by numpy (companion matrix), independent of the solver's root
finder; rows built from a sine whose zeros are known by hand.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_sim.core import gaits

from test.core.solvers.test_exact_stall import _core

INF = math.inf


def _first_root(g, d, c, b3):
    """The first positive real root of g + d x + c x^2 / 2 - b3 x^3 / 6 (numpy), inf if none."""
    r = np.roots([-b3 / 6.0, c / 2.0, d, g] if b3 > 0 else [c / 2.0, d, g])
    r = [z.real for z in r if abs(z.imag) <= 1e-9 * abs(z) and z.real > 0]
    return min(r) if r else INF


def _cubic(g, d, c, b3, x):
    return g + d * x + c * x * x / 2.0 - b3 * x ** 3 / 6.0


@pytest.mark.parametrize('seed', range(4))
def test_the_third_order_step_lands_just_inside_the_first_zero_of_the_bound(seed):
    # random rows: value g > 0, slope d and curvature c of either sign, B3 from 0 to large;
    # the shapes that matter all occur: falling onto zero (convexly, before a local minimum,
    # or concavely), a local minimum above zero then a fall, rising then falling, and no zero
    # at all (B3 = 0 with c >= 0). No B2 or B1 bound (inf): the step is the cubic's alone.
    rng = np.random.default_rng(seed)
    core = _core()
    one, off = np.ones(1), np.zeros(1, dtype=bool)
    kinds = set()
    for _ in range(400):
        g = 10.0 ** rng.uniform(-12, 1)
        d = rng.choice([-1, 1]) * 10.0 ** rng.uniform(-6, 2)
        c = rng.choice([-1, 1]) * 10.0 ** rng.uniform(-3, 3)
        b3 = 0.0 if rng.random() < 0.1 else 10.0 ** rng.uniform(-2, 5)
        root = _first_root(g, d, c, b3)
        h = core.taylor_step(g * one, np.array([d]), off, np.array([INF]), np.array([INF]),
                             1e-300, INF, ca=np.array([c]), B3=np.array([b3]))
        if d < 0 and h == pytest.approx(g / -d * 1.001, rel=1e-12):
            # the straight-fall rule: a step just past Newton's root g / -d, where the bound
            # (found to 1e-2, less 1e-4) is within 20 % of it and short of it (or where the
            # bound falls convexly onto zero: beyond Newton's root)
            assert 0.8 * (g / -d) <= root
            kinds.add('newton')
            continue
        if root == INF:
            assert h == INF
            kinds.add('none')
            continue
        kinds.add('other')
        # just inside the first zero of the bound (found to 1e-2, less 1e-4)
        assert 0.9899 * root <= h < root, (g, d, c, b3, h, root)
        # L > 0 on the whole step (dense samples)
        x = np.linspace(0.0, h, 2001)
        assert np.all(_cubic(g, d, c, b3, x) > 0.0)
    assert kinds >= {'none', 'newton', 'other'}, kinds


@pytest.mark.parametrize('seed', range(3))
def test_the_third_order_proof_accepts_up_to_the_first_zero_and_not_beyond(seed):
    # the row *is* its lower bound (g''' = -B3 throughout: the worst case the bound allows):
    # an interval ending at 0.999 of the first zero is proven from its left end, one ending at
    # 1.001 of it is not (its right end is negative); also where the row dips below zero and
    # comes back inside the interval (local minimum < 0 < both ends): not proven
    rng = np.random.default_rng(100 + seed)
    core = _core()
    off = np.zeros(1, dtype=bool)
    n_dip = 0
    for _ in range(300):
        g = 10.0 ** rng.uniform(-10, 0)
        d = rng.choice([-1, 1]) * 10.0 ** rng.uniform(-5, 1)
        c = rng.choice([-1, 1]) * 10.0 ** rng.uniform(-2, 2)
        b3 = 10.0 ** rng.uniform(-1, 3)
        root = _first_root(g, d, c, b3)
        if root == INF:
            continue

        def proven(h):
            gb, db = _cubic(g, d, c, b3, h), d + c * h - b3 * h * h / 2
            return core.proven_interval(h, [g], [gb], [d], [db], off, [INF], [INF],
                                        ca=[c], cb=[c - b3 * h], B3=[b3])

        assert proven(0.999 * root)
        assert not proven(1.001 * root)
        # a longer interval whose right end is back above zero: the dip inside is seen
        roots = sorted(z.real for z in np.roots([-b3 / 6, c / 2, d, g])
                       if abs(z.imag) <= 1e-9 * abs(z) and z.real > root * 1.01)
        if roots:
            back = roots[0] * 1.001
            if _cubic(g, d, c, b3, back) > 0:       # back above zero after the dip
                n_dip += 1
                assert not proven(back)
    assert n_dip >= 10


def test_a_velocity_leaving_zero_smoothly_is_proven_in_a_few_steps():
    # one watched row g(t) = l'(t) - l'(0.5) with l = 1 + 0.3 sin(2 pi t): l' has its minimum
    # at t = 0.5, so g = 0.3 w (1 + cos w t) >= 0 starts at zero with zero slope and curvature
    # 0.3 w^3 > 0, and is zero again at 1.5 only (by hand): no event in (0.5, 1.2]. The search
    # used to creep away from the double zero in twofold steps from ~1e-9 s (21 evaluations);
    # the row's third-order bound proves it over ~3 g'' / B3 = 0.48 s at once (3).
    w = 2 * math.pi
    gait = gaits.Fourier(1.0, ([0.0], [0.3]), 1.0)
    t, hit, n = _core().search_rows(gait.compiled(), 0.5, 1.2, [0.3 * w], [0.0], [[1.0]],
                                    [[0.0]], 1e-13, 0.125)
    assert t == INF and not hit.any()
    assert n <= 6, n
    # the same row with a small downward slope, c1 = -1e-3: it dips below zero first,
    # g ~ c1 x + 0.15 w^3 x^2 < 0 for x < -c1 / (0.15 w^3) = 2.7e-5 s (minimum -6.7e-9, far
    # below its rounding noise), then rises: the dip is an event, found inside it
    t, hit, n = _core().search_rows(gait.compiled(), 0.5, 1.2, [0.3 * w], [-1e-3],
                                    [[1.0]], [[0.0]], 1e-13, 0.125)
    assert 0.5 < t < 0.5 + 2.7e-5 and hit.tolist() == [True], t
