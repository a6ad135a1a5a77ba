"""Tests of crawler_sim.core.gaits: the gait contract, each gait's defining property, bad input."""
from __future__ import annotations

import math

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal
import pytest

from crawler_sim.core import gaits
from crawler_sim.core.gaits import (Cubic, Custom, Fourier, Gait, PiecewiseCubic, PiecewiseParabolic,
                               Scallop, Sinusoid, Spline)

TWO_PI = 2.0 * math.pi


def _custom() -> Custom:
    def length(t):
        return np.array([0.1 + 0.01 * math.sin(2.0 * t), 0.2 - 0.02 * math.cos(3.0 * t)])

    def velocity(t):
        return np.array([0.02 * math.cos(2.0 * t), 0.06 * math.sin(3.0 * t)])

    def acceleration(t):
        return np.array([-0.04 * math.sin(2.0 * t), 0.18 * math.cos(3.0 * t)])

    return Custom(length, velocity, acceleration, period=TWO_PI)


_PERIODIC_SPLINE_T = np.linspace(0.0, 2.0, 9)

# name -> (factory, expected period or None, number of linkages)
CASES = {
    'sinusoid': (lambda: Sinusoid([0.1, 0.12], [0.02, 0.03], 1.5, [0.0, 1.0]), 1 / 1.5, 2),
    'fourier': (lambda: Fourier([0.1, 0.2], ([[0.01, 0.003], [0.02, 0.0]],
                                             [[0.0, 0.004], [0.01, 0.002]]), 0.8), 1 / 0.8, 2),
    'fourier_shared': (lambda: Fourier(0.1, ([0.01, 0.0, 0.002], [0.0, 0.003, 0.0]), 2.0,
                                       n_links=3), 0.5, 3),
    'scallop': (lambda: Scallop(0.1, 0.02, 2.0, 0.2, [0.0, 0.5, 1.0]), 0.5, 3),
    'parabolic_stroke': (lambda: PiecewiseParabolic.stroke([0.1, 0.15], [0.02, 0.01], 1.25, 0.3),
                         0.8, 2),
    'parabolic_open': (lambda: PiecewiseParabolic([0.0, 0.2, 0.5, 0.7], [1.0, -0.5, 0.25], 0.1,
                                                  0.05, periodic=False), None, 1),
    'spline_clamped': (lambda: Spline([0.0, 0.3, 0.7, 1.0],
                                      [[0.1, 0.2], [0.12, 0.18], [0.11, 0.21], [0.1, 0.2]]),
                       None, 2),
    'spline_periodic': (lambda: Spline(_PERIODIC_SPLINE_T,
                                       0.1 + 0.02 * np.sin(math.pi * _PERIODIC_SPLINE_T) ** 3,
                                       periodic=True), 2.0, 1),
    'cubic': (lambda: Cubic(0.5, [0.1, 0.2], [0.01, -0.02], [0.3, 0.1], [-1.0, 2.0]), None, 2),
    'custom': (_custom, TWO_PI, 2),
}
PERIODIC = [name for name, (_, period, _) in CASES.items() if period is not None]


def _make(name: str) -> Gait:
    return CASES[name][0]()


def _kinks(gait: Gait, lo: float, hi: float) -> np.ndarray:
    """Times near which finite differences are not smooth: l'' jumps, and spline knots (l''')."""
    kinks = [gait.breakpoints(lo, hi)]
    if isinstance(gait, Spline):
        knots = gait.times
        if gait.period is not None:
            m = np.arange(math.floor(lo / gait.period) - 1, math.ceil(hi / gait.period) + 2)
            knots = (knots[None, :] + gait.period * m[:, None]).ravel()
        kinks.append(knots)
    return np.concatenate(kinks)


@pytest.mark.parametrize('name', CASES)
def test_derivatives_match_central_differences_away_from_breakpoints(name):
    gait = _make(name)
    h = 1e-5
    t = np.linspace(-1.3, 3.1, 701)
    kinks = _kinks(gait, -2.0, 4.0)
    if kinks.size:
        t = t[np.min(np.abs(t[:, None] - kinks[None, :]), axis=1) > 10 * h]
    assert t.size > 500
    l_plus, ld_plus, _ = gait(t + h)
    l_minus, ld_minus, _ = gait(t - h)
    _, ld, ldd = gait(t)
    fd_ld = (l_plus - l_minus) / (2 * h)
    fd_ldd = (ld_plus - ld_minus) / (2 * h)
    assert np.max(np.abs(ld)) > 0 and np.max(np.abs(ldd)) > 0
    assert np.max(np.abs(fd_ld - ld)) < 1e-6 * np.max(np.abs(ld))
    assert np.max(np.abs(fd_ldd - ldd)) < 1e-6 * np.max(np.abs(ldd))


@pytest.mark.parametrize('name', CASES)
def test_array_evaluation_equals_scalar_evaluation(name):
    gait = _make(name)
    t = np.array([-0.7, 0.0, 0.13, 0.5, 1.01, 2.345, 7.9])
    arrays = gait(t)
    for k, tk in enumerate(t):
        for from_array, from_scalar in zip(arrays, gait(float(tk))):
            assert_allclose(from_array[k], from_scalar, rtol=1e-13, atol=1e-14)


ONE_LINK = {
    'scallop1': lambda: Scallop(0.1, 0.02, 2.0, 0.2, 0.3),
    'sinusoid1': lambda: Sinusoid(0.1, 0.02, 1.5, 0.4),
    'spline_periodic': CASES['spline_periodic'][0],
    'parabolic_open': CASES['parabolic_open'][0],
}


@pytest.mark.parametrize('name', ONE_LINK)
def test_the_float_fast_paths_at_and_at1_equal_array_evaluation_of_a_one_linkage_gait(name):
    # at() and at1() are scalar-math rewrites the exact solver relies on (at1 in its root
    # finders); the array path (_eval, numpy ufuncs) is the independent reference.
    gait = ONE_LINK[name]()
    assert gait.n_links == 1
    t = np.array([-0.7, 0.0, 0.13, 0.5, 1.01, 2.345, 7.9])
    arrays = gait(t)
    for k, tk in enumerate(t):
        l, ld, ldd = gait.at1(float(tk))
        assert all(isinstance(v, float) for v in (l, ld, ldd))
        for from_array, one, arr in zip(arrays, (l, ld, ldd), gait.at(float(tk))):
            assert_allclose(one, from_array[k, 0], rtol=1e-13, atol=1e-14)
            assert one == float(arr[0])       # at() and at1() are the same arithmetic


@pytest.mark.parametrize('name', CASES)
def test_scalar_call_gives_n_links_and_array_call_gives_n_by_n_links(name):
    gait = _make(name)
    n = CASES[name][2]
    assert gait.n_links == n
    for t in (0.3, np.float64(0.3), np.array(0.3)):
        assert [np.shape(a) for a in gait(t)] == [(n,)] * 3
    assert [np.shape(a) for a in gait(np.linspace(0.0, 1.0, 5))] == [(5, n)] * 3
    assert [np.shape(a) for a in gait([0.1, 0.2])] == [(2, n)] * 3


@pytest.mark.parametrize('name', PERIODIC)
def test_periodic_gaits_repeat_after_their_period(name):
    gait = _make(name)
    assert gait.period == pytest.approx(CASES[name][1], rel=1e-15)
    t = np.linspace(-0.4, 1.7, 211)
    one = gait(t)
    assert np.ptp(one[0]) > 1e-3          # not trivially constant
    kinks = _kinks(gait, -5.0, 5.0)       # l'' is one-sided there: compare it elsewhere
    smooth = np.all(np.abs(t[:, None] - kinks[None, :]) > 1e-9, axis=1)
    for shift in (gait.period, 3 * gait.period, -2 * gait.period):
        l, ld, ldd = gait(t + shift)
        assert_allclose(l, one[0], rtol=0, atol=1e-9 * np.max(np.abs(one[0])))
        assert_allclose(ld, one[1], rtol=0, atol=1e-9 * np.max(np.abs(one[1])))
        assert_allclose(ldd[smooth], one[2][smooth], rtol=0, atol=1e-9 * np.max(np.abs(one[2])))


def test_every_gait_class_is_exported():
    expected = {'Gait', 'Custom', 'Sinusoid', 'Fourier', 'Scallop', 'PiecewiseParabolic',
                'Spline', 'Cubic'}
    assert expected <= set(gaits.__all__)
    assert all(hasattr(gaits, name) for name in gaits.__all__)


# ---------------------------------------------------------------- Fourier

def test_fourier_matches_its_series_written_out():
    f = 1.3
    gait = Fourier([0.1, 0.2], ([[0.01, 0.003], [0.0, 0.02]], [[0.004, 0.0], [0.005, 0.001]]), f)
    t = np.linspace(0.0, 2.0, 17)
    w = TWO_PI * f * t
    l0 = 0.1 + 0.01 * np.cos(w) + 0.003 * np.cos(2 * w) + 0.004 * np.sin(w)
    l1 = 0.2 + 0.02 * np.cos(2 * w) + 0.005 * np.sin(w) + 0.001 * np.sin(2 * w)
    assert_allclose(gait.length(t), np.column_stack([l0, l1]), rtol=1e-13)
    assert gait.period == pytest.approx(1 / f)


# ---------------------------------------------------------------- Scallop

@pytest.mark.parametrize('asymmetry', [0.05, 0.2, 0.5, 0.7, 0.95])
def test_scallop_extends_for_the_asymmetry_fraction_of_the_period(asymmetry):
    gait = Scallop(0.1, 0.02, 2.0, asymmetry, [0.0, 1.3])
    t = np.linspace(0.0, gait.period, 200_001)[:-1]
    _, ld, _ = gait(t)
    assert_allclose(np.mean(ld > 0, axis=0), [asymmetry, asymmetry], atol=1e-3)


@pytest.mark.parametrize('asymmetry', [0.05, 0.2, 0.5, 0.95])
def test_scallop_runs_from_its_minimum_at_phase_zero_to_its_maximum_at_r_t(asymmetry):
    mean, amp, f = 0.1, 0.02, 2.0
    gait = Scallop(mean, amp, f, asymmetry)
    l, ld, _ = gait(np.array([0.0, asymmetry / f, 1.0 / f]))
    assert_allclose(l[:, 0], [mean - amp, mean + amp, mean - amp], rtol=1e-14)
    assert_allclose(ld[:, 0], 0.0, atol=1e-14)
    l_fine = gait.length(np.linspace(0.0, 1.0 / f, 10_001))
    assert np.min(l_fine) >= mean - amp - 1e-15 and np.max(l_fine) <= mean + amp + 1e-15


def test_scallop_with_half_asymmetry_is_a_cosine():
    mean, amp, f, phase = 0.1, 0.02, 1.5, np.array([0.0, 0.7])
    gait = Scallop(mean, amp, f, 0.5, phase)
    t = np.linspace(-1.0, 2.0, 31)
    arg = TWO_PI * f * t[:, None] + phase
    assert_allclose(gait.length(t), mean - amp * np.cos(arg), rtol=1e-13)
    assert_allclose(gait.velocity(t), amp * TWO_PI * f * np.sin(arg), atol=1e-13)


def test_scallop_phase_leads_the_stroke_like_a_time_shift():
    f, phase = 2.0, 0.9
    lead = Scallop(0.1, 0.02, f, 0.3, [0.0, phase])
    t = np.linspace(0.0, 1.0, 41)
    l = lead.length(t)
    assert_allclose(l[:, 1], lead.length(t + phase / (TWO_PI * f))[:, 0], rtol=1e-12)


def test_scallop_is_c2_while_the_bang_bang_stroke_is_not():
    def max_acceleration_jump(gait: Gait) -> float:
        ldd = gait.acceleration(np.linspace(0.0, gait.period, 1_000_001))
        return np.max(np.abs(np.diff(ldd, axis=0))) / np.max(np.abs(ldd))

    assert max_acceleration_jump(Scallop(0.1, 0.02, 2.0, 0.2)) < 1e-4
    assert max_acceleration_jump(PiecewiseParabolic.stroke(0.1, 0.02, 2.0, 0.2)) > 0.1


@pytest.mark.parametrize('asymmetry', [0.01, 0.05, 0.2, 0.5, 0.9])
def test_scallop_bounds_hold_on_every_bin_and_stay_close_to_the_true_maxima(asymmetry):
    """The event search's jerk and snap bounds, bin by bin over a period: never below the
    jerk and snap of central differences of l'' (independent of the closed-form derivatives
    the bounds use), and within a small factor of them where the stroke is not razor-sharp
    (Cauchy's estimate alone was 46x above at r = 0.2: 5x the search steps of a Fourier
    gait)."""
    gait = Scallop(0.1, 0.02, 2.0, asymmetry, [0.0, 1.3])
    T = gait.period
    cg = gait.compiled()
    nb = 256
    edges = np.linspace(0.0, T, nb + 1)
    h = 1e-6 * T
    worst = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        jb, sb = cg.bounds(a, b)
        t = np.linspace(a + 2 * h, b - 2 * h, 9)
        acc = [gait.acceleration(t + k * h) for k in (-2, -1, 0, 1, 2)]
        jerk = (acc[3] - acc[1]) / (2 * h)
        snap = (acc[3] - 2 * acc[2] + acc[1]) / h ** 2
        # the differences carry truncation and rounding error: a relative 1e-3 slack
        assert np.all(np.abs(jerk) <= jb * (1 + 1e-3)), (a, b, np.abs(jerk).max(0), jb)
        assert np.all(np.abs(snap) <= sb * (1 + 1e-3) + 1e-3 * np.abs(snap).max()), (a, b)
        worst = max(worst, float(np.max(jb / np.maximum(np.abs(jerk).max(0), 1e-300))))
    # the largest jerk of the period, against the largest bound
    t = np.linspace(0.0, T, 200_001)
    acc = gait.acceleration(t)
    true_max = np.abs(np.diff(acc, axis=0) / np.diff(t)[:, None]).max(0)
    bound_max = np.max([cg.bounds(a, b)[0] for a, b in zip(edges[:-1], edges[1:])], axis=0)
    assert np.all(bound_max >= true_max * (1 - 1e-3))
    assert np.all(bound_max <= (4.0 if asymmetry >= 0.05 else 30.0) * true_max), (
        bound_max / true_max)


@pytest.mark.parametrize('asymmetry', [0.2, 0.004])
def test_scallop_bounds_over_any_interval_are_the_largest_of_the_bins_it_touches(asymmetry):
    """The search looks up bounds over intervals of any length (range maxima of the bins);
    each must be the largest of the bins' own bounds (``Scallop._bounds`` per bin, read here
    bin by bin) over the bins the interval touches, or one more to its right (the lookup
    rounds the interval's length up to whole bins). Intervals wrap around the period and
    run from a fraction of a bin to almost a period."""
    gait = Scallop(0.1, 0.02, 2.0, asymmetry, [0.0, 1.3])
    T = gait.period
    cg = gait.compiled()
    nb = gait._bins
    k = np.arange(nb)
    bins = np.stack(gait._bounds(k * T / nb, (k + 1) * T / nb), axis=1)   # (nb, 2, n_links)
    rng = np.random.default_rng(3)
    for n_bins in [rng.uniform(0, 4, 150), rng.uniform(4, 200, 150),
                   rng.uniform(200, nb - 3, 100)]:
        for width in n_bins:
            a = rng.uniform(-2 * T, 2 * T)
            b = a + width * T / nb
            k0, k1 = int(np.floor(a / T * nb)), int(np.floor(b / T * nb))
            got = np.array(cg.bounds(a, b))
            low = bins[np.arange(k0, k1 + 1) % nb].max(axis=0)
            high = bins[np.arange(k0, k1 + 2) % nb].max(axis=0)
            assert np.all(low <= got) and np.all(got <= high), (a, b)


def test_scallop_with_zero_amplitude_is_a_rest():
    gait = Scallop(0.1, 0.0, 2.0, 0.3)
    assert gait.is_constant(0.0, 10.0)
    assert not Scallop(0.1, 0.01, 2.0, 0.3).is_constant(0.0, 0.01)


# ---------------------------------------------------------------- PiecewiseParabolic

# Pieces of 0.2, 0.3, 0.2, 0.3 s with l'' = 3, -2, -3, 2 (second linkage twice that).
# By hand: l' at the knots 0, 0.6, 0, -0.6, 0; l - l0 at the knots 0, 0.06, 0.15, 0.09, 0.
TIMES = [0.0, 0.2, 0.5, 0.7, 1.0]
ACC = np.array([[3.0, 6.0], [-2.0, -4.0], [-3.0, -6.0], [2.0, 4.0]])


def _closed() -> PiecewiseParabolic:
    return PiecewiseParabolic(TIMES, ACC, [0.1, 0.3])


def test_parabolic_acceleration_is_exactly_the_given_constant_inside_each_piece():
    gait = _closed()
    for period in range(-1, 3):
        for k in range(4):
            t = period + np.linspace(TIMES[k], TIMES[k + 1], 9)[1:-1]
            assert_array_equal(gait.acceleration(t), np.tile(ACC[k], (7, 1)))


def test_parabolic_length_and_rate_at_the_knots_match_the_hand_integration():
    l, ld, _ = _closed()(np.array(TIMES) + 2.0)
    assert_allclose(l, np.array([0.1, 0.3]) + np.outer([0, 0.06, 0.15, 0.09, 0], [1, 2]),
                    rtol=1e-12, atol=1e-14)
    assert_allclose(ld, np.outer([0, 0.6, 0, -0.6, 0], [1, 2]), atol=1e-12)


def test_parabolic_length_and_rate_are_continuous_across_breakpoints():
    gait = _closed()
    eps = 1e-9
    b = gait.breakpoints(-1.1, 2.9)
    assert b.size == 16                    # -1.0, -0.8, -0.5, -0.3, 0.0, ..., 2.7
    before, after = gait(b - eps), gait(b + eps)
    assert np.max(np.abs(after[0] - before[0])) < 1e-8
    assert np.max(np.abs(after[1] - before[1])) < 1e-7
    # ... while l'' really jumps there, by a_k - a_{k-1}.
    jumps = np.tile(ACC - np.roll(ACC, 1, axis=0), (4, 1))
    assert_allclose(after[2] - before[2], jumps, rtol=1e-12)


def test_parabolic_breakpoints_are_exactly_the_jump_times_over_several_periods():
    gait = _closed()
    expected = [-0.3, 0.0, 0.2, 0.5, 0.7, 1.0, 1.2, 1.5, 1.7, 2.0, 2.2, 2.5]
    assert_allclose(gait.breakpoints(-0.35, 2.6), expected, rtol=0, atol=1e-12)
    assert_allclose(gait.breakpoints(0.2, 0.7), [0.5])             # open interval
    assert gait.breakpoints(0.21, 0.49).size == 0


@pytest.mark.parametrize('name', ['parabolic_stroke', 'parabolic_open', 'spline_clamped'])
def test_at_a_reported_breakpoint_the_gait_already_takes_the_next_piece(name):
    # The exact solver starts a new segment at each reported breakpoint; the gait must hand it
    # the acceleration of that segment (right limit), even many periods away from t = 0.
    gait = _make(name)
    b = gait.breakpoints(-3.0, 40.0)
    assert b.size >= 2
    at, right, left = (gait.acceleration(b + dt) for dt in (0.0, 1e-7, -1e-7))
    assert_allclose(at, right, rtol=1e-5, atol=1e-12)
    assert np.all(np.abs(at - left) > 1e-3 * np.max(np.abs(at)))


def test_symmetric_bang_bang_stroke_jumps_only_at_quarter_periods():
    # r = 0.5: l'' = +a, -a, -a, +a on quarters, so it changes only at T/4 and 3T/4.
    gait = PiecewiseParabolic.stroke(0.1, 0.02, 2.0, 0.5)
    assert_allclose(gait.breakpoints(0.0, 1.0), [0.125, 0.375, 0.625, 0.875], atol=1e-15)


@pytest.mark.parametrize('asymmetry', [0.1, 0.3, 0.5, 0.8])
def test_bang_bang_stroke_spans_the_amplitude_and_extends_for_the_asymmetry_fraction(asymmetry):
    mean, amp, f = 0.1, 0.02, 2.0
    gait = PiecewiseParabolic.stroke(mean, amp, f, asymmetry)
    l, ld, _ = gait(np.array([0.0, asymmetry / f, 1.0 / f]))
    assert_allclose(l[:, 0], [mean - amp, mean + amp, mean - amp], rtol=1e-13)
    assert_allclose(ld[:, 0], 0.0, atol=1e-14)
    t = np.linspace(0.0, 1.0 / f, 100_001)[:-1]
    assert np.mean(gait.velocity(t) > 0) == pytest.approx(asymmetry, abs=1e-3)
    # Rest to rest over a time D with l'' = +a then -a for D / 2 each covers 2 A: a = 8 A / D^2.
    t_ext, t_con = asymmetry / f, (1 - asymmetry) / f
    ldd = gait.acceleration(np.array([0.1, 0.9]) * t_ext)
    assert_allclose(ldd[:, 0], np.array([1, -1]) * 8 * amp / t_ext ** 2, rtol=1e-12)
    ldd = gait.acceleration(t_ext + np.array([0.1, 0.9]) * t_con)
    assert_allclose(ldd[:, 0], np.array([-1, 1]) * 8 * amp / t_con ** 2, rtol=1e-12)


def test_parabolic_rest_pieces_are_constant_and_moving_pieces_are_not():
    # +a, -a (extend), rest, -a, +a (contract), rest.
    a = 2.0
    gait = PiecewiseParabolic([0.0, 0.1, 0.2, 0.5, 0.6, 0.7, 1.0], [a, -a, 0, -a, a, 0], 0.1)
    assert gait.is_constant(0.2, 0.5) and gait.is_constant(0.25, 0.45)
    assert gait.is_constant(0.7, 1.0) and gait.is_constant(2.8, 2.9)
    assert not gait.is_constant(0.15, 0.3)
    assert not gait.is_constant(0.75, 1.05)
    assert not gait.is_constant(0.2, 1.4)
    _, ld, ldd = gait(np.linspace(1.21, 1.49, 15))
    assert np.all(ld == 0) and np.all(ldd == 0)


@pytest.mark.parametrize('accelerations, v0', [
    ([1.0, -1.0, 1.0], 0.0),     # l' does not come back
    ([1.0, -1.0, 0.0], 0.0),     # l' comes back but l has grown
    ([0.0, 0.0, 0.0], 0.1),      # constant drift
])
def test_periodic_stroke_that_does_not_close_is_rejected(accelerations, v0):
    with pytest.raises(ValueError, match='accelerations'):
        PiecewiseParabolic([0.0, 1.0, 2.0, 3.0], accelerations, 0.1, v0)


def test_open_parabolic_profile_holds_still_after_it_ends():
    gait = PiecewiseParabolic([0.0, 1.0, 2.0], [1.0, -1.0], 0.1, periodic=False)
    assert gait.period is None
    l, ld, ldd = gait(np.array([-1.0, 2.0, 5.0]))
    assert_allclose(l[:, 0], [0.1, 1.1, 1.1], rtol=1e-14)    # 0.1 + 2 * (1/2 * 1 * 1^2)
    assert_array_equal(ld[:, 0], 0.0)
    assert_array_equal(ldd[:, 0], 0.0)
    assert gait.is_constant(2.5, 10.0) and gait.is_constant(-3.0, 0.0)
    assert not gait.is_constant(1.5, 2.5)
    assert_array_equal(gait.breakpoints(-1.0, 3.0), [0.0, 1.0, 2.0])


# ---------------------------------------------------------------- Spline

def test_spline_passes_through_its_samples():
    times = np.array([0.0, 0.3, 0.7, 1.0, 1.6])
    lengths = np.array([[0.1, 0.2], [0.12, 0.18], [0.11, 0.21], [0.1, 0.2], [0.13, 0.19]])
    gait = Spline(times, lengths)
    assert_allclose(gait.length(times), lengths, rtol=1e-14)


def test_periodic_spline_passes_through_its_samples_and_is_c2_across_the_wrap():
    t = _PERIODIC_SPLINE_T
    y = 0.1 + 0.02 * np.sin(math.pi * t) ** 3
    gait = Spline(t, y, periodic=True)
    assert_allclose(gait.length(t)[:, 0], y, rtol=1e-14)
    eps = 1e-9
    before, after = gait(t[-1] - eps), gait(t[-1] + eps)
    for a, b in zip(before, after):
        assert_allclose(a, b, rtol=0, atol=1e-6)
    assert gait.breakpoints(-5.0, 5.0).size == 0


def test_clamped_spline_starts_and_ends_at_rest_and_holds_outside_its_range():
    gait = Spline([0.0, 0.3, 0.7, 1.0], [0.1, 0.14, 0.11, 0.12])
    assert_allclose(gait.velocity(np.array([0.0, 1.0])), 0.0, atol=1e-14)
    l, ld, ldd = gait(np.array([-2.0, -1e-9, 1.0 + 1e-9, 3.0]))
    assert_allclose(l[:, 0], [0.1, 0.1, 0.12, 0.12], rtol=1e-12)
    assert_array_equal(ld, 0.0)
    assert_array_equal(ldd, 0.0)
    assert gait.is_constant(-3.0, 0.0) and gait.is_constant(1.0, 4.0)
    assert not gait.is_constant(-1.0, 0.5)
    assert_array_equal(gait.breakpoints(-1.0, 2.0), [0.0, 1.0])     # l'' jumps to 0 there


# ---------------------------------------------------------------- bad input

BAD = {
    'sinusoid frequency 0': (lambda: Sinusoid(0.1, 0.01, 0.0), 'frequency'),
    'fourier frequency < 0': (lambda: Fourier(0.1, ([0.01], [0.0]), -1.0), 'frequency'),
    'fourier frequency inf': (lambda: Fourier(0.1, ([0.01], [0.0]), math.inf), 'frequency'),
    'fourier coefficient nan': (lambda: Fourier(0.1, ([math.nan], [0.0]), 1.0), 'coefficients'),
    'fourier cos/sin shapes': (lambda: Fourier(0.1, ([0.1, 0.2], [0.0]), 1.0), 'coefficients'),
    'fourier not a pair': (lambda: Fourier(0.1, [0.1, 0.2, 0.3], 1.0), 'coefficients'),
    'fourier rows vs n_links': (lambda: Fourier(0.1, ([[0.1], [0.2]], [[0.0], [0.0]]), 1.0,
                                                n_links=3), 'coefficients'),
    'fourier mean inf': (lambda: Fourier([0.1, math.inf], ([0.1], [0.0]), 1.0), 'mean'),
    'scallop asymmetry 0': (lambda: Scallop(0.1, 0.02, 1.0, 0.0), 'asymmetry'),
    'scallop asymmetry 1': (lambda: Scallop(0.1, 0.02, 1.0, 1.0), 'asymmetry'),
    'scallop asymmetry > 1': (lambda: Scallop(0.1, 0.02, 1.0, 1.5), 'asymmetry'),
    'scallop asymmetry nan': (lambda: Scallop(0.1, 0.02, 1.0, math.nan), 'asymmetry'),
    'scallop frequency nan': (lambda: Scallop(0.1, 0.02, math.nan, 0.3), 'frequency'),
    'scallop frequency < 0': (lambda: Scallop(0.1, 0.02, -2.0, 0.3), 'frequency'),
    'scallop amplitude < 0': (lambda: Scallop(0.1, -0.02, 1.0, 0.3), 'amplitude'),
    'scallop phase size': (lambda: Scallop(0.1, 0.02, 1.0, 0.3, [0, 1], n_links=3), 'phase'),
    'scallop n_links 0': (lambda: Scallop(0.1, 0.02, 1.0, 0.3, n_links=0), 'n_links'),
    'parabolic unsorted times': (lambda: PiecewiseParabolic([0.0, 0.5, 0.4, 1.0],
                                                            [1, -1, 0], 0.1), 'times'),
    'parabolic repeated time': (lambda: PiecewiseParabolic([0.0, 0.5, 0.5, 1.0],
                                                           [1, -1, 0], 0.1), 'times'),
    'parabolic nan time': (lambda: PiecewiseParabolic([0.0, math.nan, 1.0], [1, -1], 0.1),
                           'times'),
    'parabolic acc rows': (lambda: PiecewiseParabolic([0.0, 0.5, 1.0], [1, -1, 0], 0.1),
                           'accelerations'),
    'parabolic acc inf': (lambda: PiecewiseParabolic([0.0, 0.5, 1.0], [math.inf, 0], 0.1),
                          'accelerations'),
    'parabolic l0 size': (lambda: PiecewiseParabolic([0.0, 0.5, 1.0], [[1, 1], [-1, -1]],
                                                     [0.1, 0.2, 0.3]), 'l0'),
    'parabolic v0 nan': (lambda: PiecewiseParabolic([0.0, 0.5, 1.0], [1, -1], 0.1, math.nan),
                         'v0'),
    'stroke asymmetry 1': (lambda: PiecewiseParabolic.stroke(0.1, 0.02, 1.0, 1.0), 'asymmetry'),
    'stroke frequency 0': (lambda: PiecewiseParabolic.stroke(0.1, 0.02, 0.0, 0.3), 'frequency'),
    'stroke amplitude < 0': (lambda: PiecewiseParabolic.stroke(0.1, -0.02, 1.0, 0.3),
                             'amplitude'),
    'spline unsorted times': (lambda: Spline([0.0, 1.0, 0.5], [0.1, 0.2, 0.1]), 'times'),
    'spline one sample': (lambda: Spline([0.0], [0.1]), 'times'),
    'spline lengths rows': (lambda: Spline([0.0, 0.5, 1.0], [0.1, 0.2]), 'lengths'),
    'spline lengths nan': (lambda: Spline([0.0, 0.5, 1.0], [0.1, math.nan, 0.1]), 'lengths'),
    'spline periodic open': (lambda: Spline([0.0, 0.5, 1.0], [0.1, 0.2, 0.15], periodic=True),
                             'lengths'),
    'cubic l0 nan': (lambda: Cubic(0.0, [0.1, math.nan], 0.0, 0.0, 0.0), 'l0'),
    'call with 2-D times': (lambda: Sinusoid(0.1, 0.01, 1.0)(np.zeros((2, 2))), 't must'),
    'breakpoints t1 < t0': (lambda: _closed().breakpoints(1.0, 0.0), 't1'),
    'custom breakpoints nan': (lambda: Custom(*_custom()._fns, breakpoints=[0.5, math.nan]),
                               'breakpoints'),
    'custom breakpoints text': (lambda: Custom(*_custom()._fns, breakpoints=['soon']),
                                'breakpoints'),
    'custom breakpoints 2-D': (lambda: Custom(*_custom()._fns, breakpoints=[[0.5, 1.0]]),
                               'breakpoints'),
}


@pytest.mark.parametrize('make, parameter', BAD.values(), ids=list(BAD))
def test_bad_input_raises_value_error_naming_the_parameter(make, parameter):
    with pytest.raises(ValueError, match=rf'\b{parameter}\b'):
        make()


def test_value_errors_state_the_allowed_range():
    with pytest.raises(ValueError, match=r'asymmetry must be in the open interval \(0, 1\)'):
        Scallop(0.1, 0.02, 1.0, 1.2)
    with pytest.raises(ValueError, match='frequency must be finite and > 0 Hz'):
        Fourier(0.1, ([0.01], [0.0]), 0.0)


@pytest.mark.parametrize('name', ['sinusoid', 'fourier', 'fourier_shared', 'parabolic_stroke',
                                  'parabolic_open', 'cubic'])
def test_jerk_bound_holds_for_the_finite_difference_jerk_between_breakpoints(name):
    # The exact solver skips a dip search when the jerk bound proves a velocity stays positive;
    # a bound below the true jerk would make it miss events. Central differences of l'' are
    # the independent estimate of the jerk.
    gait = _make(name)
    h = 1e-5
    t = np.linspace(-1.3, 3.1, 2001)
    kinks = _kinks(gait, -2.0, 4.0)
    if kinks.size:
        t = t[np.min(np.abs(t[:, None] - kinks[None, :]), axis=1) > 10 * h]
    jerk = (gait(t + h)[2] - gait(t - h)[2]) / (2 * h)
    bound = gait.jerk_bound(-1.3, 3.1)
    assert bound.shape == (gait.n_links,)
    assert np.all(np.abs(jerk) <= bound * (1 + 1e-6) + 1e-9), (np.abs(jerk).max(axis=0), bound)


def test_jerk_bound_of_piecewise_cubic_is_the_largest_jerk_of_the_pieces_it_spans():
    pieces = [Cubic(0.0, [0.1, 0.2], 0.0, 0.0, [1.0, -2.0]),
              Cubic(1.0, [0.1, 0.2], 0.0, 0.0, [-3.0, 0.5]),
              Cubic(2.0, [0.1, 0.2], 0.0, 0.0, [0.25, 4.0])]
    pc = PiecewiseCubic([0.0, 1.0, 2.0], pieces)
    assert pc.jerk_bound(0.1, 0.9).tolist() == [1.0, 2.0]
    assert pc.jerk_bound(0.5, 1.5).tolist() == [3.0, 2.0]
    assert pc.jerk_bound(0.5, 2.5).tolist() == [3.0, 4.0]


def test_piecewise_cubic_small_and_large_evaluations_agree_bit_for_bit():
    # few points are evaluated in Python floats, many with numpy: the same IEEE expressions
    rng = np.random.default_rng(7)
    starts = np.cumsum(rng.uniform(1e-3, 2e-3, 12))
    pieces = [Cubic(t0, rng.uniform(0.05, 0.15, 2), rng.normal(0, 0.1, 2), rng.normal(0, 1, 2),
                    rng.normal(0, 10, 2)) for t0 in starts]
    pc = PiecewiseCubic(starts, pieces)
    t = np.sort(rng.uniform(starts[0] - 1e-3, starts[-1] + 3e-3, 200))
    big = pc(t)                      # 200 points: the numpy path
    for k in range(0, 200, 8):
        small = pc(t[k:k + 8])       # 8 points: the float path
        for a, b in zip(big, small):
            assert np.array_equal(a[k:k + 8], b)
        one = pc.at(float(t[k]))
        for a, b in zip(big, one):
            assert np.array_equal(a[k], b)


def test_a_spline_gives_a_snap_bound_only_between_its_knots():
    """Cubic between knots: where snap_bound says 0, l'' must be exactly affine (checked on
    samples); an interval holding a knot (l''' jumps) gets None. Periodic knots wrap."""
    sp = gaits.Spline([0.0, 0.3, 0.7, 1.0], [1.0, 1.2, 0.9, 1.0], periodic=True)
    for t0, t1, inside in ((0.1, 0.2, True), (0.2, 0.4, False), (1.35, 1.39, True),
                           (1.25, 1.35, False), (-0.05, 0.05, False), (0.0, 2.0, False)):
        sb = sp.snap_bound(t0, t1)
        assert (sb is not None) == inside, (t0, t1, sb)
        if inside:
            t = np.linspace(t0, t1, 7)
            acc = sp.acceleration(t)[:, 0]
            line = acc[0] + (acc[-1] - acc[0]) * (t - t0) / (t1 - t0)
            assert np.max(np.abs(acc - line)) < 1e-9 * (1 + np.max(np.abs(acc)))


def test_a_phased_stroke_is_the_stroke_shifted_in_time_per_linkage():
    """stroke(..., phase) against the one-linkage stroke evaluated at t + phase / (2 pi f): l,
    l' and l'' on a grid of two periods, and every knot of each linkage is a breakpoint."""
    f, phase = 1.7, [0.0, -2.0, 2.5]
    g = gaits.PiecewiseParabolic.stroke([0.1, 0.12, 0.09], [0.02, 0.03, 0.01], f, 0.35, phase)
    t = np.linspace(0.0, 2.0 / f, 4001)
    for j, ph in enumerate(phase):
        one = gaits.PiecewiseParabolic.stroke([0.1, 0.12, 0.09][j], [0.02, 0.03, 0.01][j], f,
                                              0.35)
        want = one(t + ph / (2 * np.pi * f))
        got = g(t)
        for k in range(2):
            np.testing.assert_allclose(got[k][:, j], want[k][:, 0], atol=1e-13)
        # l'' away from the knots (where it jumps)
        knots = (one.breakpoints(-2.0, 4.0) - ph / (2 * np.pi * f))
        away = np.min(np.abs(t[:, None] - knots[None, :]), axis=1) > 1e-9
        np.testing.assert_array_equal(got[2][away, j], want[2][away, 0])
    assert g.period == pytest.approx(1.0 / f, rel=1e-15)
    zero = gaits.PiecewiseParabolic.stroke(0.1, 0.02, f, 0.35, 0.0)
    assert zero.times.tolist() == gaits.PiecewiseParabolic.stroke(0.1, 0.02, f, 0.35).times.tolist()


def test_a_piecewise_cubic_from_arrays_is_the_one_made_of_its_pieces():
    # the actuator's runs of ticks: (starts, anchors, coef) arrays, no Cubic per piece
    rng = np.random.default_rng(3)
    starts = np.cumsum(rng.uniform(1e-3, 2e-3, 40))
    anchors = starts.copy()
    anchors[20:] = anchors[20]                  # a rest piece handed out again keeps its t0
    coef = rng.normal(0, 1, (40, 2, 4))
    coef[20:] = [[0.1, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.0]]
    pieces = [Cubic.trusted(float(t0), *c.T.tolist()) for t0, c in zip(anchors, coef)]
    want = PiecewiseCubic(starts, pieces)
    got = PiecewiseCubic.from_arrays(starts, anchors, coef)
    t = np.sort(rng.uniform(starts[0] - 1e-3, starts[-1] + 3e-3, 300))
    for a, b in zip(got(t), want(t)):
        assert a.tobytes() == b.tobytes()
    lo, hi = float(starts[0]), float(starts[-1])
    assert got.breakpoints(lo, hi).tobytes() == want.breakpoints(lo, hi).tobytes()
    assert got.jerk_bound(lo, hi).tolist() == want.jerk_bound(lo, hi).tolist()
    assert got.is_constant(starts[25], starts[30]) and not got.is_constant(lo, hi)
    assert got.starts.tolist() == starts.tolist() and got.n_links == 2
    for k in (0, 7, 39):
        assert got._index(float(starts[k])) == want._index(float(starts[k])) == k
        assert got._piece(k)._rows == want.pieces[k]._rows and got._piece(k).t0 == anchors[k]
    assert [pc._rows for pc in got.pieces] == [pc._rows for pc in pieces]


@pytest.mark.parametrize('t_start', [0.0, 1000.0])
def test_piecewise_cubic_joins_within_rounding_are_not_breakpoints_and_real_jumps_are(t_start):
    """Pieces continued by ``cubic_values`` (C2 by construction) differ at a join by the
    rounding of evaluating the previous piece there (k dt - (k - 1) dt is not dt in floats):
    no breakpoint, so no segment ends there. A jump of l'' of 1e-9 of its size is one."""
    from crawler_sim.core.gaits.cubic import cubic_values
    rng = np.random.default_rng(3)
    dt, n = 0.005, 200
    starts = t_start + np.arange(n) * dt
    l, v, a = np.full(2, 1.0), np.zeros(2), np.array([3.0, -2.0])
    pieces, mismatched = [], 0
    for t0 in starts:
        jerk = rng.uniform(-80, 80, 2)
        pieces.append(Cubic(t0, l, v, a, jerk))
        l, v, a = cubic_values(l, v, a, jerk, dt)
    g = PiecewiseCubic(starts, pieces)
    # the rounding is really there: the joins' l'' from the previous piece differ from a0
    left = np.array([pieces[k - 1].at(float(starts[k]))[2] for k in range(1, n)])
    mismatched = int(np.sum(np.any(left != np.array([pc.a0 for pc in pieces[1:]]), axis=1)))
    assert mismatched > 10
    assert g.breakpoints(starts[0] - 1.0, starts[-1] + 1.0).size == 0
    # a real jump at piece 50 (and so at 51: piece 50 no longer ends at 51's a0)
    k = 50
    pc = pieces[k]
    jumped = pieces[:k] + [Cubic(pc.t0, pc.l0, pc.v0, pc.a0 * (1 + 1e-9), pc.jerk)] + pieces[k + 1:]
    assert PiecewiseCubic(starts, jumped).breakpoints(starts[0], starts[-1] + 1.0).tolist() == [
        starts[k], starts[k + 1]]


@pytest.mark.parametrize('seed', range(4))
def test_cubic_tables_find_the_breakpoints_of_tables_own_classification(seed):
    """``Cubic`` and ``PiecewiseCubic`` hand ``table`` the joins where l'' jumps
    (``table_jumps``, issues 41/42: its own search was half of a table's build): the same
    breakpoints, and so the same compiled gait, as ``table`` deciding itself, at joins within
    a few ulps of the threshold, real jumps, anchors off the starts, large times, zeros, NaN."""
    from crawler_sim.core.gaits.cubic import cubic_values, table_jumps
    from crawler_sim.core.solvers._gait import table
    rng = np.random.default_rng(seed)
    found = 0
    for _ in range(150):
        n, nl = int(rng.integers(1, 30)), int(rng.integers(1, 4))
        dt = 10.0 ** rng.uniform(-4, -1)
        starts = rng.uniform(-1e4, 1e4) * rng.integers(0, 2) + dt * np.arange(n)
        anchors = starts + rng.choice([0.0, 1e-9, -dt / 3], n) * rng.integers(0, 2)
        coef = np.empty((n, nl, 4))
        coef[0] = rng.normal(size=(nl, 4))
        for k in range(1, n):
            coef[k, :, :3] = np.array(cubic_values(*coef[k - 1].T, starts[k] - anchors[k - 1])).T
            coef[k, :, 3] = rng.normal(size=nl)
            r = rng.random()
            if r < 0.2:                 # a real jump
                coef[k, :, 2] += rng.normal(size=nl)
            elif r < 0.5:               # a few ulps either way: around the threshold
                coef[k, :, 2] *= 1.0 + rng.integers(-12, 13, size=nl) * 2.0 ** -52
        if rng.random() < 0.3:
            coef[:, :, 1:][rng.random((n, nl, 3)) < 0.3] = 0.0
        if rng.random() < 0.05:
            coef[rng.integers(n), 0, rng.integers(4)] = np.nan
        own = table(coef, starts=starts, anchors=anchors)
        given = PiecewiseCubic.from_arrays(starts, anchors, coef)._kind()
        lo, hi = starts[0] - 1.0, starts[-1] + 1.0
        assert given.breakpoints(lo, hi).tolist() == own.breakpoints(lo, hi).tolist()
        found += int(np.sum(table_jumps(starts, anchors, coef)))
        one = Cubic.trusted(float(anchors[0]), *coef[0].T.tolist())
        single = table(coef[:1], starts=np.array([-math.inf]), anchors=anchors[:1])
        assert one._kind().breakpoints(-1e9, 1e9).tolist() == single.breakpoints(
            -1e9, 1e9).tolist() == []
    assert found > 100


def _random_cubics(n, seed):
    """n constant-jerk pieces of uneven widths from t = 0, C2 at the joins (by construction:
    each starts from the previous one's end state), and their (starts, jerks)."""
    rng = np.random.default_rng(seed)
    starts = np.concatenate([[0.0], np.cumsum(rng.uniform(2e-3, 8e-3, n - 1))])
    l, v, a = np.array([1.0, 0.9]), np.zeros(2), np.zeros(2)
    pieces, jerks = [], rng.normal(0.0, 40.0, (n, 2))
    jerks[rng.uniform(size=n) < 0.1] = jerks[0]        # some joins keep the jerk (no snap jump)
    for k, t0 in enumerate(starts):
        pieces.append(Cubic(t0, l, v, a, jerks[k]))
        w = starts[k + 1] - t0 if k + 1 < n else 0.0
        l, v, a = gaits.cubic_values(l, v, a, jerks[k], w)
    return PiecewiseCubic(starts, pieces), starts, jerks


@pytest.mark.parametrize('kind', ['pieces', 'periodic spline'])
def test_table_bounds_and_row_minima_over_any_interval_match_the_pieces_it_touches(kind):
    """The search reads a piecewise gait's |l'''| bound, whether a join inside changes the jerk
    (no snap bound), and a lower bound of each event row over intervals of any length (the
    pieces walked: runs of them from their tables of range extremes, single pieces from
    their quadratics). Each is checked against the pieces read one by one: the largest |jerk|
    of the pieces [a, b] touches (a piece starting at b is not); random rows c0 + c1 (t - t0)
    + A1 l' + A2 l'' at every join inside, both ends and 400 points per piece (a row is a
    quadratic on a piece, whose vertex may fall between: within 1e-5 of its range of the
    samples' minimum): a row's lower bound never above its minimum, and positive exactly when
    the minimum is (rows lifted or lowered to 1e-3 of their range from zero)."""
    if kind == 'pieces':
        gait, starts, jerks = _random_cubics(300, seed=5)
        period, lo_t, hi_t = None, 0.0, starts[-1] + 0.01
    else:
        tk = np.linspace(0.0, 1.0, 151)
        y = 1.0 + 0.2 * np.sin(2 * np.pi * tk)[:, None] * [1.0, -0.5] + 0.01 * np.cos(
            50 * tk)[:, None]
        y[-1] = y[0]
        gait = gaits.Spline(tk, y, periodic=True)
        starts, period, lo_t, hi_t = tk[:-1], 1.0, -1.3, 2.2
        mid = starts + 0.5 * np.diff(tk)
        jerks = (gait(mid + 1e-4)[2] - gait(mid - 1e-4)[2]) / 2e-4     # per piece (cubic)
    from crawler_sim import Crawler
    from crawler_sim.core.solvers.exact import ExactSolver
    cg = gait.compiled()
    core = ExactSolver(Crawler([1.0] * 3, [1.0] * 3), gait)._core      # rows of 2 links
    rng = np.random.default_rng(11)
    for trial in range(300):
        a = rng.uniform(lo_t, hi_t)
        b = a + rng.choice([1e-4, 5e-3, 0.05, 0.3, 1.5]) * rng.uniform()
        if trial % 5 == 0:        # b on a join
            k = np.searchsorted(starts, b % (period or np.inf)) % len(starts)
            b = starts[k] + (np.floor(b / period) * period if period else 0.0)
            if b <= a:
                continue
        # the pieces touched, one by one
        if period:
            m0, m1 = np.floor(a / period), np.floor(b / period)
            ts = np.concatenate([starts + q * period for q in np.arange(m0, m1 + 1)])
        else:
            ts = starts
        first = max(np.searchsorted(ts, a, side='right') - 1, 0)
        last = np.searchsorted(ts, b, side='left') - 1
        idx = np.arange(first, max(last, first) + 1) % len(starts)
        jb, sb = cg.bounds(a, b)
        assert_allclose(jb, np.abs(jerks[idx]).max(axis=0), rtol=1e-6, atol=1e-9)
        inner = np.array([jerks[(i + 1) % len(starts)] for i in idx[:-1]]).reshape(-1, 2)
        changes = bool(np.any(inner != jerks[idx[:-1]])) if idx.size > 1 else False
        if kind == 'pieces':
            assert (sb is None) == changes, (a, b)
        c0, c1 = rng.normal(size=4), rng.normal(size=4)
        A1, A2 = rng.normal(size=(4, 2)), rng.normal(size=(4, 2)) * 0.1
        A1[0] = 0.0                     # a row of l'' alone
        A2[1] = 0.0                     # a row of l' alone
        t0 = a - rng.uniform(0.0, 0.1)
        low = core.row_minima(cg, a, b, t0, c0, c1, A1, A2)
        pts = np.concatenate([[a, b], ts[(ts > a) & (ts < b)]])
        pts = np.concatenate([pts, np.linspace(a, b, 400 * idx.size + 2)])
        _, v, acc = gait(pts)
        rows = c0 + c1 * (pts - t0)[:, None] + v @ A1.T + acc @ A2.T      # (M, 4)
        span = rows.max(axis=0) - rows.min(axis=0)
        assert np.all(low <= rows.min(axis=0) + 1e-12), (a, b)
        # tight where it decides: rows lifted so that their minimum is 1e-3 of their range
        # above zero are proven (> 0), rows lowered as much are not
        for lift, proven in ((1e-3, True), (-1e-3, False)):
            c0s = c0 - rows.min(axis=0) + lift * span
            low = core.row_minima(cg, a, b, t0, c0s, c1, A1, A2)
            assert np.all((low > 0) == proven), (a, b, lift, low)


# ------------------------------------------------------------------ Custom breakpoints (issue 37)

def _bang_bang_fmod():
    """Issue 37's bang-bang stroke written the way a user writes it: l'' = +a, -a, -b, +b over
    one period T, the phase taken with math.fmod. Returns (the Custom gait's callables, T, the
    jump times within one period (0 excluded, T included), and the same stroke as the built-in
    PiecewiseParabolic, the independent twin: its closed form is not sampled)."""
    te, tc, d = math.sqrt(4 / 3), 4.0, 1.0
    a, b = 4 * d / te ** 2, 4 * d / tc ** 2
    widths, acc = [te / 2, te / 2, tc / 2, tc / 2], [a, -a, -b, b]
    T = te + tc
    tb = np.concatenate([[0.0], np.cumsum(widths)])
    v0 = np.concatenate([[0.0], np.cumsum(np.array(acc) * np.diff(tb))])[:-1]
    l0 = np.concatenate([[1.0], 1.0 + np.cumsum(v0 * np.diff(tb)
                                                + 0.5 * np.array(acc) * np.diff(tb) ** 2)])[:-1]

    def piece(t):
        tt = math.fmod(t, T)
        k = min(int(np.searchsorted(tb, tt, side='right')) - 1, 3)
        return k, tt - tb[k]

    def length(t):
        k, s = piece(t)
        return l0[k] + v0[k] * s + 0.5 * acc[k] * s * s

    def velocity(t):
        k, s = piece(t)
        return v0[k] + acc[k] * s

    def acceleration(t):
        return acc[piece(t)[0]]

    twin = PiecewiseParabolic(tb, acc, 1.0, 0.0)
    return (length, velocity, acceleration), T, tb[1:], twin


def _twin_gap(fns, breaks, T, periods=2):
    """Largest |x(t) - x_twin(t)| [m] over a run of whole periods (the Custom gait against the
    built-in twin, same crawler, same samples), and whether verify() passes the Custom run
    (it reads l'' beside a breakpoint as the sampler does)."""
    from crawler_sim import Crawler, simulate, verify
    cr = Crawler(masses=[1.0, 1.0], friction=[3.0, 1.0])
    grid = np.linspace(0.0, periods * T, 41)
    g = Custom(*fns, breakpoints=breaks)
    got = simulate(cr, g, periods * T, t_eval=grid)
    _, _, _, twin = _bang_bang_fmod()
    want = simulate(cr, twin, periods * T, t_eval=grid)
    return float(np.abs(got.x - want.x).max()), got, verify(simulate(cr, g, periods * T), g).ok()


def test_a_custom_stroke_run_for_whole_periods_needs_no_breakpoint_at_its_end():
    # every interior jump listed (exact floats), the run ends at 2 T where l'' jumps back to
    # +a: a jump at the run's end is not an event (it was refused, naming t_end)
    fns, T, jumps, _ = _bang_bang_fmod()
    breaks = [k * T + x for k in range(2) for x in jumps][:-1]
    gap, tr, verified = _twin_gap(fns, breaks, T)
    assert tr.t[-1] == 2 * T and verified
    # the twin's jump times are its own arithmetic (k T + t_k): a few ulps from the user's,
    # which move x by (jump of l'') x (a few 1e-15 s) x t at most
    assert gap <= 1e-12, gap


@pytest.mark.parametrize('digits', [15, 16])
def test_custom_breakpoints_rounded_to_15_significant_digits_match_the_jumps(digits):
    # the jumps computed as k T + t_k and printed to 15 (or 16) significant digits: a few ulps
    # from where the user's fmod switches (it was refused one ulp off)
    fns, T, jumps, _ = _bang_bang_fmod()
    breaks = [float(f'{k * T + x:.{digits - 1}e}') for k in range(2) for x in jumps][:-1]
    exact = [k * T + x for k in range(2) for x in jumps][:-1]
    assert breaks != exact                       # the premise: some are off
    gap, _, verified = _twin_gap(fns, breaks, T)
    assert gap <= 1e-12, gap
    assert verified


def test_a_run_that_starts_on_a_jump_of_a_custom_gait_needs_no_breakpoint_there():
    from crawler_sim import Crawler, Stepper
    fns, T, jumps, twin = _bang_bang_fmod()
    cr = Crawler(masses=[1.0, 1.0], friction=[3.0, 1.0])
    t0 = float(jumps[0])                         # l'' jumps from +a to -a here
    rest = [x for x in jumps[1:]] + [T + x for x in jumps]
    got = Stepper(cr, Custom(*fns, breakpoints=rest[:-1]), t0=t0)
    want = Stepper(cr, twin, t0=t0)
    for t in (t0 + 0.3, T, 2 * T):
        got.advance(t)
        want.advance(t)
        assert np.abs(got.state.x - want.state.x).max() <= 1e-12, t


def test_a_jump_off_every_listed_breakpoint_is_refused_naming_the_nearest():
    # a listed time 1e-9 s from the jump (far beyond the rounding of a time): refused, and
    # the message names the listed value nearest to the jump and how far off it is
    from crawler_sim import Crawler, simulate
    fns, T, jumps, _ = _bang_bang_fmod()
    listed = [float(jumps[0]) + 1e-9] + [float(x) for x in jumps[1:3]]
    g = Custom(*fns, breakpoints=listed)
    with pytest.raises(ValueError) as err:
        simulate(Crawler(masses=[1.0, 1.0], friction=[3.0, 1.0]), g, 0.99 * T)
    msg = str(err.value)
    assert 'jumps by' in msg and 'breakpoints=' in msg
    assert f'{listed[0]!r}' in msg, msg              # the nearest listed value
    assert f'{float(jumps[0])!r}' in msg, msg        # the jump, to the ulp


class _StrokeSubclass(Gait):
    """A user's Gait subclass: the issue's stroke (its twin's values), its breakpoints each
    three float spacings late (a user's own arithmetic)."""

    def __init__(self):
        _, self.T, self.jumps, self.twin = _bang_bang_fmod()
        self.n_links = 1

    def _eval(self, t):
        return self.twin(t)

    def breakpoints(self, t0, t1):
        k = np.arange(math.floor(t0 / self.T), math.ceil(t1 / self.T) + 1)
        b = (k[:, None] * self.T + self.jumps[None, :]).ravel()
        b = np.nextafter(np.nextafter(np.nextafter(b, np.inf), np.inf), np.inf)
        return b[(b > t0) & (b < t1)]


def test_a_gait_subclass_whose_breakpoints_are_a_few_ulps_off_runs_as_its_twin():
    # the same rule for every gait sampled into pieces (Custom or a subclass): it was refused
    from crawler_sim import Crawler, simulate
    g = _StrokeSubclass()
    cr = Crawler(masses=[1.0, 1.0], friction=[3.0, 1.0])
    grid = np.linspace(0.0, 2 * g.T, 41)
    got = simulate(cr, g, 2 * g.T, t_eval=grid)
    want = simulate(cr, g.twin, 2 * g.T, t_eval=grid)
    assert np.abs(got.x - want.x).max() <= 1e-12
