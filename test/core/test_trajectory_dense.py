"""Dense output of exact runs (``Trajectory.state_at``) and the figures read from it.

Expected values never come from ``state_at`` itself: they are samples of other runs taken at
exactly those times (``simulate(..., t_eval=[..., t])``), runs without the periodic skip (every
period integrated, not shifted), a ``Stepper`` advanced to t (its state at the end of the
integration), or sums over whole periods that the physics fixes (a steady crawl moves by the
same displacement every period).
"""
from __future__ import annotations

import gc
import math
import pickle
import weakref
from fractions import Fraction

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits
from test.support.quadrature import positive_work_of_cubic_pieces, positive_work_reference

# The README's first example at the frequency of issue 39: t_end - period is not a sample of the
# default grid, and 25 of its 27 periods are skipped (one stored block)
CRAWLER = cs.Crawler(masses=[0.5, 1.0], mu=0.3)
F = 1.37
T_END = 20.0


def _scallop(f: float = F) -> gaits.Scallop:
    return gaits.Scallop(mean=0.1, amplitude=0.02, frequency=f, asymmetry=0.2)


def _com(crawler: cs.Crawler, x: np.ndarray) -> np.ndarray:
    m = crawler.masses
    return x @ (m / m.sum())


FIELDS = ('x', 'v', 'friction', 'contact', 'linkage_force', 'lengths', 'rates')


@pytest.fixture(scope='module')
def run():
    # skip on: 27 periods of a 2-body crawler are too short for the default to skip
    tr = cs.simulate(CRAWLER, _scallop(), T_END, periodic_skip=True)
    assert tr.info['skipped_periods'] > 10        # the times below fall in a skipped block
    return tr


def test_state_at_equals_a_run_sampled_there(run):
    # inside the first integrated periods, inside the skipped block, in the last integrated
    # period, at an event (inside the block), at both ends
    ev = [e.time for e in run.events if 5.0 < e.time < 6.0][0]
    times = np.sort([0.0, 0.3, 1.1, 7.77, ev, 13.3, 19.5, T_END])
    ref = cs.simulate(CRAWLER, run.dense.gait, T_END, t_eval=times, periodic_skip=True)
    got = run.state_at(times)
    for k, t in enumerate(times):
        one = run.state_at(float(t))
        assert one.t == t
        for name in FIELDS:
            assert np.max(np.abs(getattr(one, name) - getattr(ref, name)[k]), initial=0) <= 1e-13
            np.testing.assert_array_equal(getattr(got, name)[k], getattr(one, name))
        assert one.indeterminate == bool(ref.indeterminate[k])


def test_state_at_inside_skipped_periods_equals_integrating_them(run):
    """The block's samples are the template period shifted by whole displacements; a run
    without the skip integrates every period: the same states to rounding."""
    times = np.array([2.0, 7.77, 13.3, 18.9])
    full = cs.simulate(CRAWLER, run.dense.gait, T_END, t_eval=times, periodic_skip=False)
    assert full.info['skipped_periods'] == 0
    got = run.state_at(times)
    assert np.abs(got.x - full.x).max() < 1e-12
    assert np.abs(got.v - full.v).max() < 1e-12
    np.testing.assert_array_equal(got.contact, full.contact)
    # and a Stepper integrated up to each time (its state at the end of the span)
    for t, x in zip(times, got.x):
        st = cs.Stepper(CRAWLER, run.dense.gait)
        st.advance(float(t))
        assert np.abs(st.state.x - x).max() < 1e-12


def test_state_at_vector_shapes_and_order(run):
    times = np.array([13.3, 0.5, 19.0, 0.5])          # unsorted, repeated
    s = run.state_at(times)
    p = CRAWLER.p
    assert s.x.shape == s.v.shape == s.friction.shape == s.contact.shape == (4, p)
    assert s.lengths.shape == s.rates.shape == s.linkage_force.shape == (4, p - 1)
    assert s.indeterminate.shape == (4,) and s.indeterminate.dtype == bool
    assert s.contact.dtype == np.int8
    np.testing.assert_array_equal(s.t, times)
    for k, t in enumerate(times):
        np.testing.assert_array_equal(s.x[k], run.state_at(float(t)).x)
    # the gait's own lengths at those times (a periodic gait: up to the shift's rounding)
    np.testing.assert_allclose(s.lengths, run.dense.gait(times)[0], rtol=0, atol=1e-15)
    assert run.state_at(np.empty(0)).x.shape == (0, p)


def test_state_at_several_chunks_no_period():
    """A three-body Fourier run long enough for several calls of the compiled loop (their
    records joined in one table), no period skipped."""
    crawler = cs.Crawler(masses=[1.0, 0.4, 0.7], mu=[0.3, 0.5, 0.2])
    g = gaits.Fourier([0.1, 0.12], ([[0.02, 0.004], [0.015, 0.0]], [[0.0, 0.003], [0.01, 0.002]]),
                      2.3)
    tr = cs.simulate(crawler, g, 60.0, periodic_skip=False)
    assert len(tr.events) > 300
    rng = np.random.default_rng(7)
    times = np.sort(rng.uniform(0, 60.0, 25))
    ref = cs.simulate(crawler, g, 60.0, t_eval=times, periodic_skip=False)
    got = tr.state_at(times)
    for name in FIELDS:
        assert np.abs(getattr(got, name) - getattr(ref, name)).max() <= 1e-13


def test_state_at_bad_times(run):
    for bad in (math.nan, math.inf, -1e-3, T_END * (1 + 1e-12), [1.0, math.nan]):
        with pytest.raises(ValueError, match=r't must be finite and within the run \[0.0, 20.0\]'):
            run.state_at(bad)
    with pytest.raises(ValueError, match='1-d array'):
        run.state_at(np.ones((2, 2)))


@pytest.mark.parametrize('method', ['implicit', 'penalty'])
def test_state_at_refused_for_stepping_methods(method):
    tr = cs.simulate(CRAWLER, _scallop(), 2.0, method, dt=1e-3,
                     penalty=1e3 if method == 'penalty' else None)
    assert tr.dense is None
    with pytest.raises(RuntimeError, match=f"method '{method}' keeps no interpolant"):
        tr.state_at(1.0)


def test_mean_speed_is_the_exact_window(run):
    """Issue 39: the README's example at 1.37 Hz. The window's start t_end - T is not a
    sample: the figure must equal a run sampled there (it was interpolated: 6.6e-4 off)."""
    T = 1.0 / F
    assert not np.any(run.t == T_END - T)
    ref = cs.simulate(CRAWLER, run.dense.gait, T_END, t_eval=[T_END - T, T_END])
    exact = (ref.com[1] - ref.com[0]) / T
    assert run.mean_speed(T) == pytest.approx(exact, rel=1e-12, abs=0)
    interpolated = (run.com[-1] - np.interp(T_END - T, run.t, run.com)) / T
    assert abs(interpolated - exact) > 1e-4 * abs(exact)    # what the test would catch
    # the crawl is steady: the last period moves as much as any late whole period does
    late = cs.simulate(CRAWLER, run.dense.gait, T_END, t_eval=[10 * T, 11 * T])
    assert run.mean_speed(T) == pytest.approx((late.com[1] - late.com[0]) / T, rel=1e-9)


def test_mean_speed_derivative_in_frequency():
    """Central differences of the figure against those of runs integrated without the skip and
    sampled exactly at t_end - T: the same derivative (it had the wrong sign when interpolated,
    issue 39)."""
    def figure(f):
        return cs.simulate(CRAWLER, _scallop(f), T_END).mean_speed(1.0 / f)

    def window(f):
        T = 1.0 / f
        ref = cs.simulate(CRAWLER, _scallop(f), T_END, t_eval=[T_END - T, T_END],
                          periodic_skip=False)
        return (ref.com[1] - ref.com[0]) / T

    h = 1e-4
    d_fig = (figure(F + h) - figure(F - h)) / (2 * h)
    d_ref = (window(F + h) - window(F - h)) / (2 * h)
    assert d_ref > 0
    assert d_fig == pytest.approx(d_ref, rel=1e-6)


def test_mean_speed_implicit_interpolates():
    tr = cs.simulate(CRAWLER, _scallop(), 3.0, 'implicit', dt=1e-3, t_eval=np.linspace(0, 3, 31))
    T = 1.0 / F
    expected = (tr.com[-1] - np.interp(3.0 - T, tr.t, tr.com)) / T
    assert tr.mean_speed(T) == expected


def test_pickle_keeps_dense_output(run):
    back = pickle.loads(pickle.dumps(run))
    np.testing.assert_array_equal(back.state_at(13.3).x, run.state_at(13.3).x)
    assert back.mean_speed(1.0 / F) == run.mean_speed(1.0 / F)


def test_pickle_of_an_unpicklable_gait_drops_dense_output():
    w = 2 * math.pi
    g = gaits.Custom(lambda t: np.array([0.1 + 0.02 * math.sin(w * t)]),
                     lambda t: np.array([0.02 * w * math.cos(w * t)]),
                     lambda t: np.array([-0.02 * w * w * math.sin(w * t)]), period=1.0)
    tr = cs.simulate(CRAWLER, g, 3.0)
    back = pickle.loads(pickle.dumps(tr))            # it pickled before dense output too
    np.testing.assert_array_equal(back.x, tr.x)
    with pytest.raises(RuntimeError, match='its gait \\(Custom\\) could not be pickled'):
        back.state_at(1.0)


def test_custom_gait_functions_not_called_again():
    """state_at reads the pieces the gait was sampled into during the run: functions that
    later fail (or change) do not change it."""
    w = 2 * math.pi
    broken = []

    def check():
        if broken:
            raise RuntimeError('gone')

    def length(t):
        check()
        return np.array([0.1 + 0.02 * math.sin(w * t)])

    def ld(t):
        check()
        return np.array([0.02 * w * math.cos(w * t)])

    def ldd(t):
        check()
        return np.array([-0.02 * w * w * math.sin(w * t)])

    g = gaits.Custom(length, ld, ldd, period=1.0)
    tr = cs.simulate(CRAWLER, g, 7.3)
    times = np.array([0.3, 5.55, 7.3])
    ref = cs.simulate(CRAWLER, g, 7.3, t_eval=times)
    broken.append(True)
    got = tr.state_at(times)
    assert np.abs(got.x - ref.x).max() <= 1e-13


def test_dense_output_freed_by_reference_counting():
    """No reference cycle: the gait goes with the last Trajectory that holds it, with the
    cyclic collector off (the project frees gaits by reference counting, ``Gait._weak``)."""
    was = gc.isenabled()
    gc.disable()
    try:
        g = _scallop()
        ref = weakref.ref(g)
        tr = cs.simulate(CRAWLER, g, T_END)
        tr.state_at([1.0, 13.3])
        del g
        assert ref() is not None          # the Trajectory keeps what state_at needs
        del tr
        assert ref() is None
    finally:
        if was:
            gc.enable()


def test_run_figures_exact_at_period_boundaries():
    """The sweep's speed of an exact run equals the window sampled exactly at k0 T and N T,
    also when its sample grid misses the boundaries by up to 1e-9 T (the node's tick grid)."""
    from crawler_sim.sweep.metrics import run_figures

    g = _scallop()
    T, periods = g.period, 12
    t_end = periods * T
    grid = np.linspace(0.0, t_end, periods * 8 + 1)
    grid[1:-1] += 0.5e-9 * T * np.sin(np.arange(grid.size - 2))   # off the boundaries
    tr = cs.simulate(CRAWLER, g, t_end, t_eval=np.sort(grid))
    fig = run_figures(tr, T, periods)
    k0 = fig['transient_periods']
    ref = cs.simulate(CRAWLER, g, t_end, t_eval=[k0 * T, t_end])
    exact = (ref.com[1] - ref.com[0]) / (t_end - k0 * T)
    assert fig['mean_speed'] == pytest.approx(exact, rel=1e-12, abs=0)
    assert fig['displacement_per_period'] == pytest.approx(exact * T, rel=1e-12, abs=0)


def _gauss_integrals(crawler, g, t_end, events):
    """(dissipated, actuator work) [J] by 8-point Gauss-Legendre quadrature of the sampled
    powers on every interval between events (cut to <= 0.01 s): the powers are smooth there
    and no node lies on an event, where they jump. An independent run sampled at the nodes."""
    edges = np.union1d([0.0, t_end], [e.time for e in events])
    cuts = [np.linspace(a, b, int(np.ceil((b - a) / 0.01)) + 1) for a, b in zip(edges, edges[1:])
            if b > a]
    lo = np.concatenate([c[:-1] for c in cuts])
    hi = np.concatenate([c[1:] for c in cuts])
    u, w = np.polynomial.legendre.leggauss(8)
    nodes = (0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * u).ravel()
    weights = (0.5 * (hi - lo)[:, None] * w).ravel()
    order = np.argsort(nodes)
    s = cs.simulate(crawler, g, t_end, t_eval=nodes[order])
    diss = -np.sum(s.friction * s.v, axis=1) @ weights[order]
    work = np.sum(s.linkage_force * s.rates, axis=1) @ weights[order]
    return float(diss), float(work)


def test_energy_figures_exact_on_a_slope():
    """dissipated_energy (sliding distances at every event) and actuator_work (the energy
    balance) against Gauss quadrature between events; the trapezoid over the default samples
    was 0.6 % and 1.9 % off."""
    crawler = cs.Crawler(masses=[0.5, 1.0], mu=0.3, slope=0.1)
    g = _scallop()
    tr = cs.simulate(crawler, g, T_END)
    diss, work = _gauss_integrals(crawler, g, T_END, tr.events)
    assert tr.dissipated_energy == pytest.approx(diss, rel=1e-10)
    assert tr.actuator_work == pytest.approx(work, rel=1e-10)
    # the same figures from a run sampled on a coarse grid without its events
    coarse = cs.simulate(crawler, g, T_END, t_eval=np.linspace(0.0, T_END, 77))
    assert coarse.dissipated_energy == pytest.approx(diss, rel=1e-10)
    assert coarse.actuator_work == pytest.approx(work, rel=1e-10)


def test_sliding_distance_of_a_light_body_dragged_by_a_stuck_heavy_one():
    """Body 1 (friction 5.9 N) never moves; body 0 follows the stroke, 2 A forward and 2 A back
    per period (the hand case of test_sweep_metrics), on any window of whole periods, here read
    between samples that are not period boundaries."""
    crawler = cs.Crawler(masses=[1.0, 1.0], mu=[0.3, 0.6])
    g = gaits.Scallop(mean=0.1, amplitude=0.02, frequency=1.0, asymmetry=0.5)
    tr = cs.simulate(crawler, g, 8.0, t_eval=np.linspace(0.0, 8.0, 23))
    fwd, back = tr.sliding_distance(1.25, 6.25)       # five whole periods
    np.testing.assert_allclose(fwd, [5 * 0.04, 0.0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back, [5 * 0.04, 0.0], rtol=1e-12, atol=1e-15)
    assert tr.dissipated_energy == pytest.approx(0.3 * 9.81 * 4 * 0.02 * 8, rel=1e-12)
    with pytest.raises(ValueError, match='inside the run'):
        tr.sliding_distance(-1.0, 2.0)




def test_positive_work_exact_across_skipped_periods():
    """On a slope (the power changes sign ~70 times in the window, 25 periods skipped)."""
    crawler = cs.Crawler(masses=[0.5, 1.0], mu=0.3, slope=0.1)
    g = _scallop()
    tr = cs.simulate(crawler, g, T_END)
    assert tr.info['skipped_periods'] > 10
    expected = positive_work_reference(crawler, g, T_END, 1.3, 17.77)
    assert tr.positive_work(1.3, 17.77) == pytest.approx(expected, rel=1e-12)
    trapezoid = _trapezoid_positive(tr, 1.3, 17.77)
    assert abs(trapezoid - expected) > 1e-4 * expected          # what the samples gave
    assert tr.positive_actuator_work == tr.positive_work(0.0, T_END)
    # the positive part can only exceed the net work, which the energy balance gives
    assert tr.positive_actuator_work >= tr.actuator_work


def _trapezoid_positive(tr, a, b):
    sel = (tr.t >= a) & (tr.t <= b)
    power = np.maximum(np.sum(tr.linkage_force[sel] * tr.rates[sel], axis=1), 0.0)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(tr.t[sel])))


def test_positive_work_of_stepping_methods_is_the_trapezoid():
    tr = cs.simulate(CRAWLER, _scallop(), 3.0, 'implicit', dt=1e-3)
    assert tr.positive_work(0.5, 2.5) == pytest.approx(_trapezoid_positive(tr, 0.5, 2.5),
                                                       rel=1e-14)
    with pytest.raises(ValueError, match='inside the run'):
        tr.positive_work(0.5, 3.5)


def _jerk_pieces(n_links, n, dt, seed):
    """A PiecewiseCubic of n pieces of dt [s] per linkage with random jerks about a rest
    length: the form of the node's actuator output (constant jerk per tick)."""
    rng = np.random.default_rng(seed)
    starts = np.arange(n) * dt
    coef = np.zeros((n, n_links, 4))
    l, v, acc = np.full(n_links, 0.1), np.zeros(n_links), np.zeros(n_links)
    for k in range(n):
        jerk = rng.uniform(-40, 40, n_links) - 8 * acc / dt / 20 - 2 * v / dt / 20
        coef[k] = np.stack([l, v, acc, jerk], axis=-1)
        l, v, acc = (l + dt * (v + dt * (acc / 2 + dt * jerk / 6)),
                     v + dt * (acc + dt * jerk / 2), acc + dt * jerk)
    return gaits.PiecewiseCubic.from_arrays(starts, starts.copy(), coef)


@pytest.mark.parametrize('masses, slope, n, dt', [
    ([0.5, 1.0], 0.0, 400, 0.01),                   # p = 2, level
    ([1.0, 0.4, 0.7], 0.1, 300, 0.01),              # p = 3, slope
    ([0.3, 0.5, 0.2, 0.6, 0.4, 0.3, 0.5, 0.7], -0.05, 80, 0.025),   # p = 8
])
def test_positive_work_of_constant_jerk_pieces_exact(masses, slope, n, dt):
    """Constant-jerk pieces (the power a cubic on each piece, integrated in closed form)
    against the independent quadrature with the pieces' joins as edges; a sub-window too."""
    crawler = cs.Crawler(masses=masses, mu=0.3, slope=slope)
    g = _jerk_pieces(len(masses) - 1, n, dt, seed=len(masses))
    t_end = n * dt
    tr = cs.simulate(crawler, g, t_end)
    assert len(tr.events) > 5
    for a, b in ((0.0, t_end), (0.1234, 0.77 * t_end)):
        expected = positive_work_reference(crawler, g, t_end, a, b, g.starts)
        assert expected > 0
        assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-12)


def test_positive_work_of_a_node_run_exact():
    """A stroke played as the node plays it (the actuator's ~1 ms constant-jerk pieces: the
    optimiser's "node" score) on a slope; the reference samples the played gait."""
    from dataclasses import replace

    from crawler_sim.core.actuator import ActuatorLimits
    from crawler_sim.core.plant.streams import simulate_as_node
    from crawler_sim.core.scene import scene_from_dict
    from crawler_sim.sweep.optimize import STREAM, family, plant_for

    base = scene_from_dict({'crawler': {'masses': [0.5, 1.0], 'mu': 0.3, 'slope_deg': 2.0},
                            'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                     'frequency': 1.0, 'asymmetry': 0.3}})
    limits = ActuatorLimits()
    fam = family('scallop', base, limits)
    plant = plant_for(base, fam, limits)
    g = fam.gait(np.array([0.02, 1.37, 0.2]))
    t_end = 2 * g.period
    stream = replace(STREAM, duration=t_end + 2.0 / STREAM.rate)
    tr = simulate_as_node(plant, g, stream, t_end)
    played = tr.dense.gait                      # the actuator's output, as run
    assert isinstance(played, gaits.PiecewiseCubic) and played.starts.size > 1000
    a, b = 0.05, t_end - 0.03
    expected = positive_work_reference(tr.crawler, played, t_end, a, b, played.starts)
    assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-12)


def _families():
    """(crawler, gait, t_end) of gait families the fitted forces meet: a bang-bang stroke (l''
    constant on its pieces, so the power is affine there) of 2 and 3 bodies, a Custom gait
    (read through its sampled pieces)."""
    w = 2 * math.pi
    custom = gaits.Custom(lambda t: np.array([0.1 + 0.02 * math.sin(w * t)]),
                          lambda t: np.array([0.02 * w * math.cos(w * t)]),
                          lambda t: np.array([-0.02 * w * w * math.sin(w * t)]), period=1.0)
    return {
        'stroke, p = 2, slope': (cs.Crawler(masses=[0.5, 1.0], mu=[0.3, 0.4], slope=-0.04),
                                 gaits.PiecewiseParabolic.stroke(0.1, 0.02, 1.37, 0.3), 12.0),
        'stroke, p = 3': (cs.Crawler(masses=[1.0, 0.4, 0.7], mu=[0.3, 0.5, 0.2]),
                          gaits.PiecewiseParabolic.stroke([0.1, 0.12], [0.02, 0.015], 1.1, 0.35),
                          10.0),
        'Custom, p = 2': (CRAWLER, custom, 8.0),
    }


@pytest.mark.parametrize('name', list(_families()))
def test_positive_work_of_gait_families_exact(name):
    """Against the independent quadrature (the gait's breakpoints among its edges: the power
    jumps where l'' does): the whole run, and a window that starts and ends inside periods
    (inside the block of skipped periods)."""
    crawler, g, t_end = _families()[name]
    tr = cs.simulate(crawler, g, t_end, periodic_skip=True)     # (the block is the point)
    assert tr.info['skipped_periods'] > 3
    joins = g.breakpoints(0.0, t_end)
    for a, b in ((0.0, t_end), (0.37 * g.period + 1.1, t_end - 0.61 * g.period - 0.9)):
        expected = positive_work_reference(crawler, g, t_end, a, b, joins)
        assert expected > 0
        assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-12), (a, b)


def test_positive_work_of_cubic_pieces_built_from_objects():
    """A PiecewiseCubic of Cubic objects (coefficients read from each piece) gives the
    positive work of the same pieces built from arrays, and the independent quadrature's."""
    arrays = _jerk_pieces(1, 200, 0.01, seed=5)
    objects = gaits.PiecewiseCubic(arrays.starts, [arrays._piece(k) for k in range(200)])
    a, b = 0.2, 1.9
    got = cs.simulate(CRAWLER, objects, 2.0).positive_work(a, b)
    assert got == pytest.approx(cs.simulate(CRAWLER, arrays, 2.0).positive_work(a, b),
                                rel=1e-14)
    expected = positive_work_reference(CRAWLER, objects, 2.0, a, b, arrays.starts)
    assert got == pytest.approx(expected, rel=1e-12)


def test_piecewise_cubic_gives_its_arrays():
    """``PiecewiseCubic.as_arrays`` (what the dense output's closed form reads): a gait built
    from arrays returns them as they are; one of Cubic objects the same values as arrays, from
    which ``from_arrays`` builds the same gait (equal values to the bit)."""
    rng = np.random.default_rng(3)
    starts = np.arange(50) * 0.01
    anchors = starts + rng.uniform(-1e-3, 1e-3, 50)
    coef = rng.uniform(-1.0, 1.0, (50, 2, 4))
    built = gaits.PiecewiseCubic.from_arrays(starts, anchors, coef)
    assert all(x is y for x, y in zip(built.as_arrays(), (starts, anchors, coef)))
    objects = gaits.PiecewiseCubic(starts, [gaits.Cubic(anchors[k], *coef[k].T)
                                            for k in range(50)])
    for got, want in zip(objects.as_arrays(), (starts, anchors, coef)):
        assert got.dtype == np.float64
        np.testing.assert_array_equal(got, want)
    t = np.linspace(-0.1, 0.6, 301)
    again = gaits.PiecewiseCubic.from_arrays(*objects.as_arrays())
    for got, want in zip(again(t), objects(t)):
        np.testing.assert_array_equal(got, want)


def test_positive_work_of_eight_bodies_finds_close_roots():
    """A Fourier stroke of 8 bodies on a slope: its power has pairs of roots a few ms apart
    between events (9 probes a piece missed one pair: 4.0e-8 low). Its l'' spans only the
    stroke's harmonics, so the forces' fit is refused and the run is sampled."""
    rng = np.random.default_rng(8)
    fourier = gaits.Fourier(np.full(7, 0.1), (rng.uniform(-0.01, 0.01, (7, 2)),
                                              rng.uniform(-0.01, 0.01, (7, 2))), 1.3)
    crawler = cs.Crawler(masses=rng.uniform(0.2, 1.0, 8), mu=0.3, slope=0.05)
    tr = cs.simulate(crawler, fourier, 2.0)
    for a, b in ((0.0, 2.0), (0.123, 1.7)):
        expected = positive_work_reference(crawler, fourier, 2.0, a, b)
        assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-12)


def _dips(n_links, n, h, jerk, s, shift):
    """n constant-jerk pieces of h [s] where l' = jerk / 2 ((d - r)^2 - s^2) on each (d the
    time into the piece): l' dips below zero between r - s and r + s, r = h / 2 + shift on
    even pieces and h / 2 - shift on odd ones (the mirror image: l and l' continuous)."""
    coef = np.zeros((n, n_links, 4))
    length = 0.1
    for k in range(n):
        r = h / 2 + (shift if k % 2 == 0 else -shift)
        v0, a0 = 0.5 * jerk * (r * r - s * s), -jerk * r
        coef[k] = [length, v0, a0, jerk]
        length += h * (v0 + h * (a0 / 2 + h * jerk / 6))
    starts = np.arange(n) * h
    return gaits.PiecewiseCubic.from_arrays(starts, starts.copy(), coef)


def _zero_rate_joins(n_links, n, h, jerk):
    """n constant-jerk pieces of h [s] with l' = jerk_k / 2 d (d - h), jerk_k = +-jerk in
    turn: l' = 0 at every join (the power's roots at the pieces' ends), l'' continuous."""
    coef = np.zeros((n, n_links, 4))
    length = 0.1
    for k in range(n):
        j = jerk if k % 2 == 0 else -jerk
        coef[k] = [length, 0.0, -j * h / 2, j]
        length += h * h * h * (-j / 4 + j / 6)
    starts = np.arange(n) * h
    return gaits.PiecewiseCubic.from_arrays(starts, starts.copy(), coef)


# every body sliding down (mu 0.1 on a slope of 0.3 rad): the rate l' changes sign with no
# event, so its roots are the power's inside the segments; and the force's root at l'' = 0,
# between them: three roots within 2 s of each other (s of _dips) in a piece of 0.25 s
SLIDING = {2: cs.Crawler(masses=[0.5, 1.0], mu=0.1, slope=0.3),
           3: cs.Crawler(masses=[0.5, 1.0, 0.7], mu=0.1, slope=0.3)}


@pytest.mark.parametrize('p', [2, 3])
@pytest.mark.parametrize('s, shift', [(1e-3, 0.02), (1e-3, 0.06), (3e-4, 0.0), (3e-4, 0.07)])
def test_positive_work_of_cubic_pieces_with_close_roots(p, s, shift):
    """Three roots of the power within 2 s (s = 1e-3, 3e-4 s: the rate's pair, the force's
    between them) in pieces without events. p = 3 runs both linkages in lockstep (the same
    gait for both), so the forces' fit is refused and the cubic comes from the run's own
    power: it went to the 25 probes, which missed pairs (2.9e-9 low at s = 1e-3, shift 0.02;
    5.9e-11 at 3e-4). Reference: each piece's cubic from 9 samples, its roots from the
    companion matrix, refined in long double (the brentq reference's 40,001-point grid
    cannot separate them: 4e-10 off at its own refinements)."""
    crawler = SLIDING[p]
    g = _dips(p - 1, 8, 0.25, 4.0, s, shift)
    tr = cs.simulate(crawler, g, 2.0)
    for a, b in ((0.0, 2.0), (0.1234, 1.77)):
        expected, resid = positive_work_of_cubic_pieces(crawler, g, 2.0, a, b, g.starts)
        assert resid < 1e-12                      # the power is a cubic on each piece
        assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-13, abs=0)


@pytest.mark.parametrize('p', [2, 3])
def test_positive_work_of_cubic_pieces_with_roots_at_their_ends(p):
    """The rate is zero at every join (the power's roots there, one float from the pieces'
    ends), and changes sign across it: against both references."""
    crawler = SLIDING[p]
    g = _zero_rate_joins(p - 1, 8, 0.25, 4.0)
    tr = cs.simulate(crawler, g, 2.0)
    for a, b in ((0.0, 2.0), (0.1234, 1.77)):
        expected, resid = positive_work_of_cubic_pieces(crawler, g, 2.0, a, b, g.starts)
        assert resid < 1e-12
        assert tr.positive_work(a, b) == pytest.approx(expected, rel=1e-13, abs=0)
        assert tr.positive_work(a, b) == pytest.approx(
            positive_work_reference(crawler, g, 2.0, a, b, g.starts), rel=1e-12, abs=0)


def _exact_positive(k, roots):
    """Integral over [0, 1] of max(0, k (u - r1)(u - r2)(u - r3)), exactly (fractions), and
    the cubic's coefficients b0..b3 (fractions)."""
    r1, r2, r3 = roots
    b = [-k * r1 * r2 * r3, k * (r1 * r2 + r1 * r3 + r2 * r3), -k * (r1 + r2 + r3), k]

    def integral(u):
        return sum(c * u ** (i + 1) / (i + 1) for i, c in enumerate(b))
    cuts = sorted({Fraction(0), Fraction(1), *(r for r in roots if 0 < r < 1)})
    total = Fraction(0)
    for u0, u1 in zip(cuts, cuts[1:]):
        m = (u0 + u1) / 2
        if k * (m - r1) * (m - r2) * (m - r3) > 0:
            total += integral(u1) - integral(u0)
    whole = sum(abs(integral(u1) - integral(u0)) for u0, u1 in zip(cuts, cuts[1:]))
    return total, whole, b


CUBICS = [   # (k, roots): near-triple (the middle root on the derivative's vertex),
    # near-double inside and across the middle, double, roots at the ends, one root
    (Fraction(-60), (Fraction(416, 1000), Fraction(42, 100), Fraction(424, 1000))),
    (Fraction(3), (Fraction(1, 2), Fraction(1, 2) + Fraction(1, 10 ** 6), Fraction(9, 10))),
    (Fraction(-7), (Fraction(1, 10), Fraction(3, 10), Fraction(3, 10) + Fraction(1, 10 ** 7))),
    (Fraction(2), (Fraction(1, 4), Fraction(1, 4), Fraction(3, 4))),
    (Fraction(5), (Fraction(0), Fraction(3, 10), Fraction(1))),
    (Fraction(-1), (Fraction(0), Fraction(1), Fraction(1))),
    (Fraction(4), (Fraction(-1), Fraction(1, 3), Fraction(2))),
]


@pytest.mark.parametrize('batch', [1, 40])
def test_positive_part_of_a_cubic_against_fractions(batch):
    """``dense._positive_cubic`` (one cubic in floats, or more than 16 at once in arrays) on
    cubics of rational roots: close, double, at the interval's ends. The exact integral in
    fractions; the floats' own rounding moves it by a few eps of the integral of |P|."""
    from crawler_sim.core.dense import _positive_cubic

    for k, roots in CUBICS:
        exact, whole, b = _exact_positive(k, roots)
        got = _positive_cubic(np.tile(np.array([float(c) for c in b]), (batch, 1)))
        assert np.all(np.abs(got - float(exact)) <= 1e-14 * float(whole)), (roots, got[0])


def test_positive_work_of_a_crawler_sliding_for_seconds():
    """Friction 0.3 N against a 0.1 rad slope: the crawler slides down, one segment from
    0.1 s to 20 s. That segment was one piece of the quadrature: its 25 probes missed most
    roots, a half of it whose nodes all fell where the power is negative was taken as 0 (the
    run's positive work half its value), and windows from 5 s on split without end on the
    rounding of the Scallop's values (~1e-12 at 8 s). Now pieces are at most one period
    (and a disagreement at that rounding which halving no longer lowers ends a piece):
    each 5 s window and the whole run against the independent quadrature."""
    crawler = cs.Crawler([0.5, 1.0], 0.3, slope=0.1)
    g = gaits.Scallop(mean=0.1, amplitude=0.02, frequency=1.37, asymmetry=0.2)
    tr = cs.simulate(crawler, g, 20.0)
    assert len(tr.events) <= 3 and tr.x[-1, 0] < -100.0        # one long slide
    parts = []
    for a in (0.0, 5.0, 10.0, 15.0):
        parts.append(positive_work_reference(crawler, g, 20.0, a, a + 5.0))
        assert tr.positive_work(a, a + 5.0) == pytest.approx(parts[-1], rel=1e-12, abs=0)
    assert tr.positive_work(0.0, 20.0) == pytest.approx(sum(parts), rel=1e-12, abs=0)
