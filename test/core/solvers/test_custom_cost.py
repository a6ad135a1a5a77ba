"""Issue 39: Custom gaits fast from the first period. ``vectorized=True`` (the callables take
an array of times) samples every node of a round in one call of each function and builds the
same pieces as the scalar path; scalar callables are called once a node. Counts of the user's
calls are asserted, never timings (``benchmarks.custom_cost`` prints those)."""
from __future__ import annotations

import math

import numpy as np
from numpy.polynomial.chebyshev import chebval
import pytest

import crawler_sim as cs
from crawler_sim.core.gaits import Custom, Fourier
from crawler_sim.core.solvers import proxy
from test.core.test_gaits import _bang_bang_fmod

# the gait and crawler of benchmarks.custom_cost (issue 39's reproducer): 4 linkages, 3 sines
# each
from benchmarks.custom_cost import A, F, FM, FP, JB, K, M, PH, W

CRAWLER = cs.Crawler(M, FP, FM)


class Counted:
    """A callable counting its calls and the times it was asked for."""

    def __init__(self, fn):
        self.fn, self.calls, self.points = fn, 0, 0

    def __call__(self, t):
        self.calls += 1
        self.points += np.size(t)
        return self.fn(t)


def _scalar():
    return (lambda t: 1.0 + (A * np.sin(K * W * t + PH)).sum(1),
            lambda t: (A * K * W * np.cos(K * W * t + PH)).sum(1),
            lambda t: -(A * (K * W) ** 2 * np.sin(K * W * t + PH)).sum(1))


def _rows(fns):
    """The scalar functions as array functions, row by row: the same values to the bit (the
    pieces of both paths can then be compared exactly)."""
    return tuple((lambda f: lambda ts: np.array([f(t) for t in ts]).reshape(len(ts), -1))(f)
                 for f in fns)


def _vector():
    def arg(t):
        return K * W * np.asarray(t)[:, None, None] + PH
    return (lambda t: 1.0 + (A * np.sin(arg(t))).sum(2),
            lambda t: (A * K * W * np.cos(arg(t))).sum(2),
            lambda t: -(A * (K * W) ** 2 * np.sin(arg(t))).sum(2))


def _twin():
    return Fourier([1.0] * 4, (A * np.sin(PH), A * np.cos(PH)), F)


def _run(g, nper):
    T = nper / F
    return cs.simulate(CRAWLER, g, T, t_eval=np.linspace(0.0, T, 9), periodic_skip=False)


@pytest.mark.parametrize('period', [None, 1.0 / F])
def test_vectorized_builds_the_pieces_of_the_scalar_path(period):
    # the nodes' times are cheb_sample's to the float: with the same values, the same pieces
    tables = []
    for vec in (False, True):
        fns = _rows(_scalar()) if vec else _scalar()
        g = Custom(*fns, jerk_bound=JB, period=period, vectorized=vec)
        _run(g, 2)
        tables.append(g.compiled().table)
    s, v = tables
    np.testing.assert_array_equal(v.knots, s.knots)
    np.testing.assert_array_equal(v.coef, s.coef)
    np.testing.assert_array_equal(v.bj, s.bj)
    # (a start shared with the piece before is asked again in the array: no more calls)
    assert v.calls >= s.calls and 0 < v.batches <= 4 and s.batches == 0, (v.batches, v.calls)


def test_vectorized_stroke_with_breakpoints_reads_the_one_sided_limits():
    # a bang-bang stroke (l'' jumps at listed times, read BREAK_ULPS inside each piece): the
    # same pieces as the scalar callables, and the built-in twin to 1e-12 m
    fns, T, jumps, twin = _bang_bang_fmod()
    breaks = [k * T + x for k in range(2) for x in jumps][:-1]
    cr = cs.Crawler(masses=[1.0, 1.0], friction=[3.0, 1.0])
    grid = np.linspace(0.0, 2 * T, 41)
    gs = Custom(*fns, breakpoints=breaks)
    gv = Custom(*_rows(fns), breakpoints=breaks, vectorized=True)
    xs = cs.simulate(cr, gs, 2 * T, t_eval=grid).x
    xv = cs.simulate(cr, gv, 2 * T, t_eval=grid).x
    np.testing.assert_array_equal(gv.compiled().table.coef, gs.compiled().table.coef)
    np.testing.assert_array_equal(xv, xs)
    want = cs.simulate(cr, twin, 2 * T, t_eval=grid).x
    assert np.abs(xv - want).max() <= 1e-12


@pytest.mark.parametrize('nper', [2, 20])
@pytest.mark.parametrize('period', [None, 1.0 / F])
def test_vectorized_numpy_functions_run_as_the_builtin_twin(nper, period):
    got = _run(Custom(*_vector(), jerk_bound=JB, period=period, vectorized=True), nper)
    want = _run(_twin(), nper)
    assert len(got.events) == len(want.events)
    assert np.abs(got.x - want.x).max() <= 1e-12


@pytest.mark.parametrize('period', [None, 1.0 / F])
def test_vectorized_calls_each_function_once_a_round(period):
    # a 2-period run: l'' asked once for the first instant and once for all the nodes of
    # the one window (every piece resolved at once); (l, l') once at the window's start and
    # once at its pieces' ends; the gait's own probe of n_links is one call of l
    fns = tuple(Counted(f) for f in _vector())
    g = Custom(*fns, jerk_bound=JB, period=period, vectorized=True)
    _run(g, 2)
    fl, fv, fa = fns
    assert fa.calls <= 2 and fl.calls <= 4 and fv.calls <= 3, (fl.calls, fv.calls, fa.calls)


@pytest.mark.parametrize('vectorized', [True, False])
def test_a_window_far_from_resolved_is_halved_twice_and_sampled_once_a_node(vectorized):
    # 20 periods, no period given: the first window's 8 pieces (2.5 periods each, 7.5 periods
    # of the third harmonic) leave a tail of ~6e-3 of their values; each is halved twice
    # (32 pieces of 0.62 periods, each resolved: degree ~24 of 32), a node shared with the
    # piece before not asked again: at most 8 + 16 + 32 pieces of 33 nodes and the first
    # instant (cutting in four at once, ``proxy.WIDE``, is off: it moves Custom runs' rounding)
    fns = tuple(Counted(f) for f in (_vector() if vectorized else _scalar()))
    got = _run(Custom(*fns, jerk_bound=JB, vectorized=vectorized), 20)
    assert fns[2].points <= (8 + 16 + 32) * 33 + 1, fns[2].points
    want = _run(_twin(), 20)
    assert len(got.events) == len(want.events)
    assert np.abs(got.x - want.x).max() <= 1e-12


@pytest.mark.parametrize('period, most', [(None, 8 * 33 + 2), (1.0 / F, 32 * 32 + 1 + 2)])
def test_scalar_l2_is_called_once_a_node(period, most):
    # a 2-period run: one window of 8 pieces (1/256 of the run a cell) or one period of 32
    # pieces (1/1024 of it a cell); a start shared with the piece before is not asked again
    fns = tuple(Counted(f) for f in _scalar())
    g = Custom(*fns, jerk_bound=JB, period=period)
    _run(g, 2)
    assert fns[2].calls <= most, fns[2].calls
    # (l, l') at the pieces' ends only: a few after the period's pieces are joined
    assert fns[0].calls <= (40 if period else 12), fns[0].calls


@pytest.mark.parametrize('which, bad, match', [
    ('acceleration', lambda t: np.zeros(len(t)),
     r"acceleration\(t\) for t of shape \(\d+,\) must return shape \(\d+, 4\), got shape"),
    ('velocity', lambda t: np.zeros((len(t), 3)),
     r"velocity\(t\) for t of shape \(\d+,\) must return shape \(\d+, 4\), got shape \(\d+, 3\)"),
    ('acceleration', lambda t: np.where(t[:, None] > 0.1, np.nan, np.zeros((len(t), 4))),
     r"acceleration\(t\) must be finite, got \[nan, nan, nan, nan\] at t = "),
])
def test_vectorized_values_are_checked(which, bad, match):
    fns = dict(zip(('length', 'velocity', 'acceleration'), _vector()))
    fns[which] = bad
    g = Custom(*fns.values(), vectorized=True)
    with pytest.raises(ValueError, match=match) as err:
        _run(g, 2)
    assert '\n' not in str(err.value)


def test_vectorized_length_probe_names_the_shape():
    with pytest.raises(ValueError, match=r'length\(t\) for t of shape \(1,\) must return an '
                                         r'array of shape \(1, n_links\), got shape \(\)'):
        Custom(lambda t: 1.0, lambda t: 0.0, lambda t: 0.0, vectorized=True)


def test_vectorized_gait_reads_the_user_values_in_python():
    g = Custom(*_vector(), vectorized=True)
    t = np.array([0.0, 0.3, 1.7])
    for got, want in zip(g(t), _vector()):
        np.testing.assert_array_equal(got, want(t))
    for got, want in zip(g(0.3), _scalar()):
        np.testing.assert_allclose(got, want(0.3), rtol=0, atol=1e-12)
    assert g.n_links == 4


def test_vectorized_jerk_bound_is_checked():
    # the bound 1/10 of |l'''|: refused, naming jerk_bound (a constant bound and a callable)
    for jb in ([x / 10 for x in JB], lambda t0, t1: [x / 10 for x in JB]):
        g = Custom(*_vector(), jerk_bound=jb, vectorized=True)
        with pytest.raises(ValueError, match=r"jerk_bound of linkage \d .* must bound"):
            _run(g, 2)
    g = Custom(*_vector(), jerk_bound=lambda t0, t1: JB, vectorized=True)
    assert np.abs(_run(g, 2).x - _run(_twin(), 2).x).max() <= 1e-12


def test_series_evaluation_agrees_with_numpy_chebval():
    # proxy._series_at (recurrence and one product) against numpy's Clenshaw, and the fixed
    # matrix of the nodes against both
    rng = np.random.default_rng(3)
    c = rng.standard_normal((6, proxy.N + 1, 3)) * 0.7 ** np.arange(proxy.N + 1)[None, :, None]
    a = np.sort(rng.random(6))
    b = a + 0.1 + rng.random(6)
    t = a[:, None] + (b - a)[:, None] * rng.random((6, 17))
    u = (2.0 * t - (a + b)[:, None]) / (b - a)[:, None]
    want = chebval(u[:, :, None], np.moveaxis(c, 1, 0)[:, :, None, :], tensor=False)
    np.testing.assert_allclose(proxy._series_at(c, a, b, t), want, rtol=0, atol=1e-14)
    at_nodes = proxy._series_at(c, a, b, proxy._nodes(a, b))
    np.testing.assert_allclose(proxy._at_own_nodes(c), at_nodes, rtol=0, atol=1e-13)


def _pl(t):
    return 1.0 + 0.1 * np.sin(3.0 * t)[:, None] * np.ones(2)


def _pv(t):
    return 0.3 * np.cos(3.0 * t)[:, None] * np.ones(2)


def _pa(t):
    return -0.9 * np.sin(3.0 * t)[:, None] * np.ones(2)


def test_vectorized_gait_of_module_functions_is_picklable():
    # a sweep sends gaits to its workers: the checked wrappers must pickle (closures did not)
    import pickle
    g = Custom(_pl, _pv, _pa, vectorized=True, max_step=0.05)
    h = pickle.loads(pickle.dumps(g))
    cr = cs.Crawler([1.0, 1.0, 1.0], [1.0, 2.0, 1.5])
    x = cs.simulate(cr, g, 2.0, t_eval=np.linspace(0.0, 2.0, 5)).x
    np.testing.assert_array_equal(cs.simulate(cr, h, 2.0, t_eval=np.linspace(0.0, 2.0, 5)).x, x)
    scalar = Custom(*((lambda f: lambda t: f(np.array([t]))[0])(f) for f in (_pl, _pv, _pa)),
                    max_step=0.05)
    want = cs.simulate(cr, scalar, 2.0, t_eval=np.linspace(0.0, 2.0, 5)).x
    assert np.abs(x - want).max() <= 1e-12


def test_vectorized_one_linkage_against_float_functions():
    # one linkage: (n, 1) arrays, read from Python as (1,) (the float path's _scalar is off)
    fns = (lambda t: 1.0 + 0.2 * math.sin(5.0 * t), lambda t: math.cos(5.0 * t),
           lambda t: -5.0 * math.sin(5.0 * t))
    g = Custom(*_rows(fns), vectorized=True)
    cr = cs.Crawler([1.0, 2.0], [1.0, 3.0])
    grid = np.linspace(0.0, 3.0, 7)
    got = cs.simulate(cr, g, 3.0, t_eval=grid)
    want = cs.simulate(cr, Custom(*fns), 3.0, t_eval=grid)
    np.testing.assert_array_equal(got.x, want.x)
    assert g.n_links == 1 and g(0.5)[0].shape == (1,)
