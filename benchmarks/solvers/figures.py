"""Throughput figures: periods per second, batch body-steps per second, the cost of a rest and
the cost of outputs nobody asked for.

* ``exact_throughput``: gait periods simulated per wall second by method "exact" at full
  accuracy (default tolerance), with the periodic skip on and off, for the bare solve
  (``Stepper.advance``, no history) and for ``simulate`` with two output times.
* ``batch_throughput``: ``ImplicitBatch`` body-steps per second (crawlers x bodies x steps / s).
* ``rest_cost``: the time of method "exact" over a rest (constant command, every body stuck)
  against its length; it must not grow with the length.
* ``output_cost``: the same run with few and with many output times, and without history.
"""
from __future__ import annotations

import inspect
import math
import statistics
import time
from typing import Any, Callable

import numpy as np

from crawler_sim.core import gaits
from crawler_sim.core.model import Crawler
from crawler_sim.core.solvers.implicit import ImplicitBatch
from crawler_sim.core.stepper import Stepper, simulate

__all__ = ['exact_throughput', 'batch_throughput', 'rest_cost', 'output_cost']

_STEPPER_PARAMS = set(inspect.signature(Stepper).parameters)


def _timed(fn: Callable[[], Any], repeats: int = 3) -> tuple[float, Any]:
    """Median wall time of ``repeats`` calls, and the last result."""
    times, out = [], None
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def _stepper(crawler: Crawler, gait: gaits.Gait, **kw: Any) -> Stepper:
    if 'periodic_skip' in kw and 'periodic_skip' not in _STEPPER_PARAMS:
        kw.pop('periodic_skip')
    return Stepper(crawler, gait, 'exact', **kw)


def _advance(crawler: Crawler, gait: gaits.Gait, t_end: float, **kw: Any) -> Stepper:
    st = _stepper(crawler, gait, **kw)
    st.advance(t_end)
    return st


def exact_throughput(crawler: Crawler, gait: gaits.Gait, periods: int, *,
                     repeats: int = 3) -> dict:
    """Periods per second of method "exact" over ``periods`` periods of a periodic gait."""
    T = gait.period
    t_end = periods * T
    out: dict[str, Any] = {'periods': periods, 'p': crawler.p}
    for skip in (True, False):
        key = 'skip' if skip else 'noskip'
        n = periods
        t, st = _timed(lambda: _advance(crawler, gait, n * T, periodic_skip=skip), repeats)
        out[f'stepper_{key}_periods'] = n
        out[f'stepper_{key}_time'] = t
        out[f'stepper_{key}_periods_per_s'] = n / t
        ts, tr = _timed(lambda: simulate(crawler, gait, n * T, t_eval=[0.0, n * T],
                                         **({'periodic_skip': skip} if 'periodic_skip' in
                                            _STEPPER_PARAMS else {})), repeats)
        out[f'simulate_{key}_time'] = ts
        out[f'simulate_{key}_periods_per_s'] = n / ts
        out[f'displacement_per_period_{key}'] = tr.displacement / n
    out['t_end'] = t_end
    return out


def batch_throughput(n_crawlers: int = 10_000, p: int = 2, steps: int = 200, *,
                     repeats: int = 3, seed: int = 0) -> dict:
    """Body-steps per second of ``ImplicitBatch`` (B crawlers with random parameters, one
    shared sinusoidal gait, dt = 1 ms)."""
    rng = np.random.default_rng(seed)
    masses = rng.uniform(0.5, 2.0, (n_crawlers, p))
    friction = rng.uniform(0.5, 5.0, (n_crawlers, p)) * masses
    gait = gaits.Sinusoid(0.1, 0.02, 2.0, -np.linspace(0.0, 1.5, p - 1), n_links=p - 1)
    h = 1e-3
    rates = gait(h * np.arange(1, steps + 1))[1]

    def run() -> ImplicitBatch:
        b = ImplicitBatch(masses, friction)
        for k in range(steps):
            b.step(h, rates[k])
        return b

    def run_numpy() -> ImplicitBatch:
        # the numpy-only step (solve_inclusion_batch below): the baseline the
        # compiled step must not be slower than, run in the same process
        b = ImplicitBatch(masses, friction)
        for k in range(steps):
            ep = b._ep(rates[k])
            b.V, _ = solve_inclusion_batch(b.M / h, b.V, b.F_ext, -ep, b.f_plus, b.f_minus)
            b.X = b.X + h * b.V
        return b

    run()                                   # load the kernel outside the timing
    t, b = _timed(run, repeats)
    tn, bn = _timed(run_numpy, repeats)
    finite = bool(np.all(np.isfinite(b.X)) and np.all(np.isfinite(b.V)))
    return {'crawlers': n_crawlers, 'p': p, 'steps': steps, 'time': t,
            'body_steps_per_s': n_crawlers * p * steps / t,
            'crawler_steps_per_s': n_crawlers * steps / t, 'finite': finite,
            'numpy_time': tn, 'numpy_body_steps_per_s': n_crawlers * p * steps / tn,
            'speedup_vs_numpy': tn / t,
            'max_diff_vs_numpy': float(np.max(np.abs(b.X - bn.X)))}


def _constant_gait(kind: str, l0: float = 0.1) -> gaits.Gait:
    if kind == 'cubic':
        return gaits.Cubic(0.0, [l0], [0.0], [0.0], [0.0])
    if kind == 'custom':
        return gaits.Custom(lambda t: np.array([l0]), lambda t: np.zeros(1),
                            lambda t: np.zeros(1))
    if kind == 'stroke_then_rest':
        # one bang-bang stroke on [0, 1] s (extend by 2 cm and back), then hold still
        a = 0.08
        return gaits.PiecewiseParabolic([0.0, 0.25, 0.5, 0.75, 1.0], [a, -a, -a, a], l0, 0.0,
                                        periodic=False)
    raise ValueError(f'unknown rest gait {kind!r}')


def rest_cost(lengths: tuple = (1.0, 1e2, 1e4, 1e6), *, repeats: int = 3) -> dict:
    """Wall time of method "exact" over rests of increasing length [s].

    Three gaits: ``cubic`` (a ``Cubic`` with zero rates: the gait says it is constant),
    ``custom`` (user callables returning constants: the solver cannot know), and
    ``stroke_then_rest`` (one stroke, then a rest of the given length).
    """
    crawler = Crawler([0.5, 1.0], [1.5, 2.9])
    out: dict[str, Any] = {'lengths': list(lengths)}
    for kind in ('cubic', 'custom', 'stroke_then_rest'):
        gait = _constant_gait(kind)
        rows = []
        for L in lengths:
            t_end = L + (1.0 if kind == 'stroke_then_rest' else 0.0)
            try:
                t, st = _timed(lambda: _advance(crawler, gait, t_end), repeats)
                segs = getattr(st.solver, 'n_segments', None)
                rows.append({'length': L, 'time': t, 'segments': segs,
                             'contact': st.state.contact.tolist()})
            except Exception as exc:  # noqa: BLE001 (reported, not raised)
                rows.append({'length': L, 'time': math.nan, 'error': f'{type(exc).__name__}: '
                                                                       f'{exc}'})
        times = [r['time'] for r in rows]
        ok = all(math.isfinite(x) for x in times)
        growth = times[-1] / times[0] if ok and times[0] > 0 else math.inf
        out[kind] = {'rows': rows, 'growth': growth, 'flat': bool(ok and growth < 3.0)}
    return out


def output_cost(crawler: Crawler, gait: gaits.Gait, periods: int, *,
                counts: tuple = (2, 1_000, 100_000), repeats: int = 3) -> dict:
    """Method "exact" (and "implicit") with few and many output times.

    Rows: the bare solve without history (``Stepper``), then ``simulate`` with ``counts``
    output times, then the default output (1001 samples plus every event time).
    """
    T = gait.period
    t_end = periods * T
    rows = []
    for skip in (True, False):
        kw = {'periodic_skip': skip} if 'periodic_skip' in _STEPPER_PARAMS else {}
        t, _ = _timed(lambda: _advance(crawler, gait, t_end, **kw), repeats)
        rows.append({'method': 'exact', 'periodic_skip': skip, 'outputs': 'none (Stepper)',
                     'n': 0, 'time': t})
        for n in counts:
            grid = np.linspace(0.0, t_end, n)
            t, _ = _timed(lambda: simulate(crawler, gait, t_end, t_eval=grid, **kw), repeats)
            rows.append({'method': 'exact', 'periodic_skip': skip, 'outputs': f't_eval {n}',
                         'n': n, 'time': t})
        t, tr = _timed(lambda: simulate(crawler, gait, t_end, **kw), repeats)
        rows.append({'method': 'exact', 'periodic_skip': skip,
                     'outputs': 'default (1001 + events)', 'n': int(tr.t.size), 'time': t})
    # implicit: 10 periods at dt = T / 256, outputs at 2 times and at every step
    t_imp = min(periods, 10) * T
    dt = T / 256
    for n in (2, int(round(t_imp / dt)) + 1):
        grid = np.linspace(0.0, t_imp, n)
        t, _ = _timed(lambda: simulate(crawler, gait, t_imp, 'implicit', dt=dt, t_eval=grid),
                      repeats)
        rows.append({'method': 'implicit', 'periodic_skip': None, 'outputs': f't_eval {n}',
                     'n': n, 'time': t, 'periods': min(periods, 10)})
    return {'periods': periods, 'rows': rows}


def solve_inclusion_batch(c, u_ref, force, kinks, f_plus, f_minus):
    """The numpy baseline of ``ImplicitBatch``'s compiled step: the inclusion of
    ``solvers._inclusion`` vectorised over B crawlers with the same p.

    ``c``, ``u_ref``, ``force``: shape (B,); ``kinks``, ``f_plus``, ``f_minus``: shape (B, p).
    Returns ``(u, at_kink)`` with shapes (B,) and (B, p) bool.
    """
    B, p = kinks.shape
    order = np.argsort(kinks, axis=1)
    rows = np.arange(B)[:, None]
    k = kinks[rows, order]
    a = f_plus[rows, order]
    b = f_minus[rows, order]
    ca = np.cumsum(a, axis=1)
    cb = np.cumsum(b, axis=1)
    below_a = ca - a
    above_b = cb[:, -1:] - (cb - b)
    g_low = (c * (-u_ref) - force)[:, None] + c[:, None] * k + below_a - above_b
    g_high = g_low + a + b
    ok = g_high >= 0.0
    i = np.argmax(ok, axis=1)
    any_ok = ok[np.arange(B), i]
    i_safe = i
    gl = g_low[np.arange(B), i_safe]
    ki = k[np.arange(B), i_safe]
    free = u_ref + (force - below_a[np.arange(B), i_safe] + above_b[np.arange(B), i_safe]) / c
    right = u_ref + (force - ca[:, -1]) / c
    u = np.where(any_ok, np.where(gl <= 0.0, ki, free), right)
    at_kink = kinks == u[:, None]
    return u, at_kink
