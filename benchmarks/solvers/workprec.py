"""Work-precision measurements: every method and baseline over a ladder of settings, per scene.

For one scene (`BenchScene`) this runs

* method "exact" over a ladder of event tolerances (``tol``) and of ``max_step``, with the
  periodic skip on (the default) and off;
* method "implicit" over a ladder of steps dt = T / d;
* method "penalty" over a ladder of n (at a fine step) and of steps (at a large n);
* the scipy baselines (``baselines.py``): Radau and LSODA with the analytic Jacobian on the
  seed's penalised ODE (n ladder, rtol = atol tightened with n) and on a tanh-smoothed law
  (eps ladder, tolerances tightened with eps);

and measures each run against the reference, method "exact" at its tightest tolerance with the
periodic skip off (``metrics.py``). A timing is the median wall time of ``repeats`` (>= 3) calls
of what a user would write: ``simulate(..., t_eval=grid)`` or ``solve_ivp(..., t_eval=grid)``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
import inspect
import math
import statistics
import time
from typing import Any, Callable

import numpy as np

from crawler_sim.core.stepper import simulate
from crawler_sim.core.verify import verify
from . import metrics
from .baselines import baseline_history, run_baseline
from .scenes import BenchScene

__all__ = ['Ladders', 'RunRecord', 'THRESHOLDS', 'bench_scene', 'summarise', 'SERIES']

THRESHOLDS = (1e-3, 1e-6, 1e-9)

#: series label -> (kind, description) in the order of the tables
SERIES = {
    'exact': 'method "exact", tol ladder (periodic skip on, the default)',
    'exact-noskip': 'method "exact", tol and max_step ladders, periodic skip off',
    'implicit': 'method "implicit", dt ladder',
    'penalty': 'method "penalty" (backward Euler on the penalised ODE), n and dt ladders',
    'scipy-LSODA-penalised': 'solve_ivp LSODA + Jacobian, seed penalised ODE, rtol = atol ~ 1e-2/n',
    'scipy-Radau-penalised': 'solve_ivp Radau + Jacobian, seed penalised ODE, rtol = atol ~ 1e-2/n',
    'scipy-LSODA-tanh': 'solve_ivp LSODA + Jacobian, tanh(v/eps) friction, rtol = atol ~ eps/100',
    'scipy-Radau-tanh': 'solve_ivp Radau + Jacobian, tanh(v/eps) friction, rtol = atol ~ eps/100',
}
SCIPY_SERIES = tuple(k for k in SERIES if k.startswith('scipy'))


@dataclass
class Ladders:
    """The settings each series runs over (step divisors d give dt = T / d)."""

    exact_tol: tuple = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
    exact_max_step_div: tuple = (8, 32, 128)      # max_step = T / d (at the tightest tol)
    implicit_div: tuple = (16, 64, 256, 1024, 4096)
    penalty_n: tuple = (1e4, 1e6, 1e8, 1e10, 1e12)
    penalty_n_div: int = 256                      # the step of the n ladder, T / d
    penalty_div: tuple = (64, 1024)               # the step ladder at penalty_dt_n
    penalty_dt_n: float = 1e8
    scipy_n: tuple = (1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10)       # LSODA
    radau_n: tuple = (1e4, 1e6, 1e8, 1e10)
    tanh_eps: tuple = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)  # LSODA
    radau_eps: tuple = (1e-3, 1e-6, 1e-9)
    reference_tol: float = 1e-14
    reference_max_step_div: int = 512
    repeats: int = 3
    budget: float = 4.0            # wall seconds allowed for one scipy run (else 'timeout')
    max_steps: int = 25_000        # skip implicit / penalty runs with more steps than this

    @classmethod
    def quick(cls) -> Ladders:
        """Two or three rungs per series, for tests (each scene in about a second)."""
        return cls(exact_tol=(1e-8, 1e-12), exact_max_step_div=(16,), implicit_div=(16, 128),
                   penalty_n=(1e5, 1e8), penalty_n_div=128, penalty_div=(32,),
                   penalty_dt_n=1e8, scipy_n=(1e4, 1e6), radau_n=(1e4, 1e6),
                   tanh_eps=(1e-3, 1e-5), radau_eps=(1e-3, 1e-5),
                   reference_tol=1e-14, reference_max_step_div=256, repeats=3, budget=1.5,
                   max_steps=5_000)


@dataclass
class RunRecord:
    """One run of one series: settings, timing and errors against the reference."""

    series: str
    params: dict
    status: str = 'ok'             # ok | timeout | failed | skipped | error
    message: str = ''
    time: float = math.nan         # median wall time [s]
    times: list = field(default_factory=list)
    err_displacement: float = math.inf
    err_position: float = math.inf
    err_events: float = math.inf
    events_missing: int = 0
    history_mismatch: float = math.inf
    n_events: int = 0
    verify_worst: float | None = None
    info: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {k: _json_float(v) for k, v in asdict(self).items()}


def _json_float(v: Any) -> Any:
    """inf / nan as strings so the JSON is standard; everything else unchanged."""
    if isinstance(v, float) and not math.isfinite(v):
        return 'inf' if v > 0 else ('-inf' if v < 0 else 'nan')
    if isinstance(v, dict):
        return {k: _json_float(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json_float(x) for x in v]
    return v


_SIM_PARAMS = set(inspect.signature(simulate).parameters)


def _simulate(scene: BenchScene, method: str, grid: np.ndarray, **kw: Any):
    if 'periodic_skip' in kw and 'periodic_skip' not in _SIM_PARAMS:
        kw.pop('periodic_skip')
    return simulate(scene.crawler, scene.gait, scene.t_end, method, t_eval=grid, **kw)


def _median_time(fn: Callable[[], Any], repeats: int) -> tuple[float, list[float], Any]:
    times, out = [], None
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


@dataclass
class Reference:
    """The reference run: centre of mass on the grid, contact history."""

    grid: np.ndarray
    X: np.ndarray
    initial: list
    events: list
    time: float
    params: dict
    verify_worst: float
    displacement: float


def reference_run(scene: BenchScene, lad: Ladders) -> Reference:
    """Method "exact" at the tightest tolerance and a fine max_step, periodic skip off."""
    grid = scene.grid()
    T = scene.period or scene.t_end
    params = {'tol': lad.reference_tol, 'max_step': T / lad.reference_max_step_div,
              'periodic_skip': False}
    t0 = time.perf_counter()
    tr = _simulate(scene, 'exact', grid, **params)
    elapsed = time.perf_counter() - t0
    X = tr.com
    return Reference(grid, X, tr.contact[0].tolist(),
                     metrics.canonical_events(tr.events, scene.t_end), elapsed, params,
                     verify(tr).worst, float(X[-1] - X[0]))


def _score(rec: RunRecord, ref: Reference, X: np.ndarray, initial, events, t_end: float) -> None:
    rec.err_displacement = metrics.displacement_error(X, ref.X)
    rec.err_position = metrics.position_error(X, ref.X)
    ev = metrics.canonical_events(events, t_end)
    rec.n_events = len(ev)
    rec.err_events, rec.events_missing = metrics.event_error(ev, ref.events)
    rec.history_mismatch = metrics.history_mismatch(initial, ev, ref.initial, ref.events, t_end)


def _core_run(scene: BenchScene, ref: Reference, lad: Ladders, series: str, method: str,
              params: dict) -> RunRecord:
    rec = RunRecord(series, dict(params))
    grid = ref.grid
    try:
        rec.time, rec.times, tr = _median_time(
            lambda: _simulate(scene, method, grid, **params), lad.repeats)
    except Exception as exc:  # noqa: BLE001 (a solver failure is a result of the bench)
        rec.status, rec.message = 'error', f'{type(exc).__name__}: {exc}'
        return rec
    X = tr.com
    if not np.all(np.isfinite(tr.x)):
        rec.status, rec.message = 'failed', 'non-finite positions'
        return rec
    _score(rec, ref, X, tr.contact[0].tolist(), tr.events, scene.t_end)
    rec.verify_worst = float(verify(tr).worst)
    rec.info = {k: v for k, v in tr.info.items() if isinstance(v, (int, float, str))}
    return rec


def _scipy_run(scene: BenchScene, ref: Reference, lad: Ladders, series: str, solver: str,
               model: str, reg: float, tol: float) -> RunRecord:
    key = 'n' if model == 'penalised' else 'eps'
    rec = RunRecord(series, {key: reg, 'rtol': tol, 'atol': tol})
    grid = ref.grid

    def once(budget: float):
        return run_baseline(scene.crawler, scene.gait, scene.t_end, grid, solver=solver,
                            model=model, reg=reg, rtol=tol, atol=tol, budget=budget)

    t0 = time.perf_counter()
    res = once(lad.budget)
    t_first = time.perf_counter() - t0
    if res.status != 'ok':
        rec.status, rec.message, rec.time = res.status, res.message, t_first
        rec.times = [t_first]
        return rec
    # the repeats are the same computation: give them room for timing noise
    _, times, res = _median_time(lambda: once(4 * lad.budget), lad.repeats - 1)
    rec.times = [t_first] + times
    rec.time = statistics.median(rec.times)
    rec.info = {'nfev': res.nfev, 'njev': res.njev}
    # the stick/slip history from a dense run (not timed)
    dense = run_baseline(scene.crawler, scene.gait, scene.t_end, grid, solver=solver,
                         model=model, reg=reg, rtol=tol, atol=tol, budget=4 * lad.budget,
                         dense=True)
    if dense.status == 'ok':
        initial, events = baseline_history(scene.crawler, scene.gait, scene.t_end, dense.sol,
                                           model=model, reg=reg)
    else:
        initial, events = ref.initial, []
    _score(rec, ref, res.X, list(initial), events, scene.t_end)
    return rec


def scipy_tolerance(model: str, reg: float) -> float:
    """rtol = atol tightened with the regularisation: 1e-2 / n, or eps / 100 (in [1e-13, 1e-3])."""
    tol = 1e-2 / reg if model == 'penalised' else reg / 100.0
    return float(min(max(tol, 1e-13), 1e-3))


def plan(scene: BenchScene, lad: Ladders, series: tuple[str, ...] | None = None) -> list[tuple]:
    """The runs of a scene as (series, kind, arguments), in execution order."""
    T = scene.period or scene.t_end
    steps = lambda d: scene.t_end / (T / d)  # noqa: E731
    runs: list[tuple] = []
    for tol in lad.exact_tol:
        runs.append(('exact', 'core', ('exact', {'tol': tol})))
    for tol in lad.exact_tol:
        runs.append(('exact-noskip', 'core', ('exact', {'tol': tol, 'periodic_skip': False})))
    for d in lad.exact_max_step_div:
        runs.append(('exact-noskip', 'core', ('exact', {'tol': min(lad.exact_tol),
                                                        'max_step': T / d,
                                                        'periodic_skip': False})))
    for d in lad.implicit_div:
        runs.append(('implicit', 'core', ('implicit', {'dt': T / d}), steps(d)))
    for n in lad.penalty_n:
        runs.append(('penalty', 'core', ('penalty', {'penalty': n, 'dt': T / lad.penalty_n_div}),
                     steps(lad.penalty_n_div)))
    for d in lad.penalty_div:
        runs.append(('penalty', 'core', ('penalty', {'penalty': lad.penalty_dt_n, 'dt': T / d}),
                     steps(d)))
    for solver, ns, epss in (('LSODA', lad.scipy_n, lad.tanh_eps),
                             ('Radau', lad.radau_n, lad.radau_eps)):
        for n in ns:
            runs.append((f'scipy-{solver}-penalised', 'scipy',
                         (solver, 'penalised', n, scipy_tolerance('penalised', n))))
        for eps in epss:
            runs.append((f'scipy-{solver}-tanh', 'scipy',
                         (solver, 'tanh', eps, scipy_tolerance('tanh', eps))))
    if series is not None:
        runs = [r for r in runs if r[0] in series]
    return runs


def bench_scene(scene: BenchScene, lad: Ladders, *, progress: Callable | None = None,
                series: tuple[str, ...] | None = None,
                extra_runs: list[tuple] = ()) -> dict:
    """Run every series of `plan` (plus ``extra_runs``) on one scene; returns plain data."""
    say = progress or (lambda *a: None)
    ref = reference_run(scene, lad)
    say(f'{scene.name}: reference exact (tol {lad.reference_tol:g}) in {ref.time * 1e3:.1f} ms, '
        f'displacement {ref.displacement:.6g} m, {len(ref.events)} events')
    runs = plan(scene, lad, series) + list(extra_runs)
    records: list[RunRecord] = []
    for k, run in enumerate(runs):
        name, kind, args = run[0], run[1], run[2]
        if kind == 'core' and len(run) > 3 and run[3] > lad.max_steps:
            rec = RunRecord(name, dict(args[1]), status='skipped',
                            message=f'{run[3]:.0f} steps > max_steps {lad.max_steps}')
        elif kind == 'core':
            rec = _core_run(scene, ref, lad, name, *args)
        else:
            rec = _scipy_run(scene, ref, lad, name, *args)
        records.append(rec)
        say(k + 1, len(runs), f'{scene.name} {name} {_fmt_params(rec.params)}: '
            f'{_fmt_time(rec.time)} err {rec.err_displacement:.2e} '
            f'{"" if rec.status == "ok" else rec.status}'.rstrip())
    return {
        'name': scene.name, 'description': scene.description, 'p': scene.crawler.p,
        't_end': scene.t_end, 'periods': scene.periods, 'period': scene.period,
        'n_grid': int(ref.grid.size),
        'reference': {'params': ref.params, 'time': ref.time, 'displacement': ref.displacement,
                      'n_events': len(ref.events), 'verify_worst': ref.verify_worst},
        'runs': [r.to_dict() for r in records],
        'summary': summarise(records),
    }


def _fmt_params(params: dict) -> str:
    return ' '.join(f'{k}={v:.3g}' if isinstance(v, float) else f'{k}={v}'
                    for k, v in params.items())


def _fmt_time(t: float) -> str:
    if not math.isfinite(t):
        return '   -   '
    return f'{t * 1e3:7.1f} ms' if t < 10 else f'{t:7.1f} s '


def _num(v: Any) -> float:
    if isinstance(v, str):
        return float(v)
    return math.nan if v is None else float(v)


def summarise(records: list[RunRecord] | list[dict]) -> dict:
    """Per series: cheapest time reaching each threshold (displacement and position error),
    best errors, the run count."""
    rows = [r.to_dict() if isinstance(r, RunRecord) else r for r in records]
    out: dict[str, dict] = {}
    for series in dict.fromkeys(r['series'] for r in rows):
        ok = [r for r in rows if r['series'] == series and r['status'] == 'ok']
        s: dict[str, Any] = {'runs': sum(r['series'] == series for r in rows), 'ok': len(ok)}
        for measure in ('displacement', 'position'):
            errs = [(_num(r[f'err_{measure}']), _num(r['time']), r['params']) for r in ok]
            for thr in THRESHOLDS:
                hits = [(t, e, p) for e, t, p in errs if e <= thr]
                best = min(hits, key=lambda h: h[0]) if hits else None
                s[f'time_{measure}_{thr:g}'] = best[0] if best else None
                s[f'params_{measure}_{thr:g}'] = best[2] if best else None
            s[f'best_{measure}'] = min((e for e, _, _ in errs), default=math.inf)
        s['best_events'] = min((_num(r['err_events']) for r in ok), default=math.inf)
        s['best_mismatch'] = min((_num(r['history_mismatch']) for r in ok), default=math.inf)
        out[series] = _json_float(s)
    return out
