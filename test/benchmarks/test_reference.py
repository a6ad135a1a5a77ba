"""The bench's independent two-body reference (``test/support/oracle.py``): closed forms
derived by hand, and agreement with the exact method on random two-body scenes."""
import math

import numpy as np
import pytest

import crawler_sim as cs
from test.support.oracle import two_body_reference


def _fourier(hz: float, a1: float = 0.3, a2: float = 0.09):
    return cs.gaits.Fourier(1.0, ([0.0, 0.0], [a1, a2]), hz)


def test_without_friction_the_centre_of_mass_never_moves():
    # No force at all: M V' = 0, so X(t) = X0 + V0 t; body 0 starts at rest at x = 0, so
    # V0 = (m1 / M) l'(0) and X0 = (m1 / M) l(0); x_0 = X - (m1 / M) l(t).
    crawler = cs.Crawler([1.0, 3.0], [0.0, 0.0])
    gait = _fourier(1.0)
    T = 2.0
    grid = np.linspace(0.0, T, 9)
    ref = two_body_reference(crawler, gait, T, grid)
    l, ld, _ = gait(grid)
    w = 3.0 / 4.0
    X = w * l[0, 0] + w * ld[0, 0] * grid
    np.testing.assert_allclose(ref['com'], X, rtol=0, atol=1e-14)
    assert ref['x0'] == pytest.approx(X[-1] - w * l[-1, 0], abs=1e-14)


def test_a_body_too_heavy_to_move_stays_put():
    # Body 0's friction 100 N exceeds anything the linkage can push with (m1 |l''| <= 1 * 0.3
    # (2 pi)^2 * 2.2 < 27 N plus body 1's 1 N): x_0 = 0 throughout, X = (m1 / M) l(t).
    crawler = cs.Crawler([1.0, 1.0], [100.0, 1.0])
    gait = _fourier(1.0)
    T = 3.0
    grid = np.linspace(0.0, T, 13)
    ref = two_body_reference(crawler, gait, T, grid)
    assert ref['x0'] == pytest.approx(0.0, abs=1e-14)
    np.testing.assert_allclose(ref['com'], 0.5 * gait(grid)[0][:, 0], rtol=0, atol=1e-14)


def test_it_needs_two_bodies():
    with pytest.raises(ValueError, match='p = 2'):
        two_body_reference(cs.Crawler([1.0, 1.0, 1.0], [1.0, 1.0, 1.0]),
                           cs.gaits.Fourier([1.0, 1.0], ([[0.0], [0.0]], [[0.3], [0.3]]), 1.0),
                           1.0, [0.0, 1.0])


@pytest.mark.parametrize('seed', range(8))
def test_it_agrees_with_the_exact_method_on_random_two_body_scenes(seed):
    # Two solvers written apart (events by Taylor bounds in a compiled loop vs a 1e-5 s scan
    # and brentq) on masses and frictions over two decades, direction-dependent friction.
    rng = np.random.default_rng(seed)
    m = 10 ** rng.uniform(-1, 1, 2)
    fp = 10 ** rng.uniform(-1, 1, 2)
    fm = fp * 10 ** rng.uniform(-0.5, 0.5, 2)
    hz = float(rng.uniform(0.5, 3.0))
    crawler = cs.Crawler(m, fp, friction_backward=fm)
    gait = _fourier(hz, float(rng.uniform(0.1, 0.4)), float(rng.uniform(-0.1, 0.1)))
    T = 4.0 / hz
    grid = np.linspace(0.0, T, 33)
    ref = two_body_reference(crawler, gait, T, grid)
    ex = cs.simulate(crawler, gait, T, t_eval=grid)
    assert abs(ex.x[-1, 0] - ref['x0']) <= 1e-10
    assert np.max(np.abs(ex.com - ref['com'])) <= 1e-10
    assert math.isfinite(ref['x0'])


def test_the_seed_lsoda_baseline_evaluates_the_gait_as_the_gait_does():
    # the bench's LSODA baseline writes the Fourier series out in scalar math
    from benchmarks.solvers.baselines import _two_rates
    gait = cs.gaits.Fourier(1.0, ([0.1, -0.2], [0.3, 0.09]), 1.7)
    rates = _two_rates(gait)
    for t in np.random.default_rng(3).uniform(0.0, 20.0, 50):
        _, ld, ldd = gait.at(float(t))
        assert rates(float(t)) == pytest.approx((ld[0], ldd[0]), rel=0, abs=1e-12)
