"""Issue 14's comparison, in one run: exact vs scipy LSODA on the seed's penalised ODE, the
implicit method's speed and convergence, and the cold start.

Scenes: l = 1 + 0.3 (sin wt + 0.3 sin 2wt), T = 10 periods, from rest (body 0 at x = 0):
m = (1, 1), f = (0.5, 1) at 1 Hz; m = (1, 2), f = (1, 1) at 1 Hz; m = (1, 1), f = (5, 10) at
5 Hz. Each with the built-in ``Fourier`` gait and with the ``Custom`` gait of plain ``math.sin``
lambdas without a period (the issue's user gait), made anew for every timed run, so its
sampling into Chebyshev pieces (``core.solvers.proxy``), once per gait object, is timed too.

* exact: ``simulate(..., t_eval=grid)`` with the defaults (periodic skip allowed), whatever
  solver is on this branch;
* LSODA: ``solve_ivp(method='LSODA')`` with the analytic Jacobian on the seed's penalised ODE
  in its own state (x_0, y = x_0'), n = 1e8, rtol = atol = 1e-10
  (``baselines.seed_penalised_lsoda``, the gait's rates in scalar math), as the issue names it,
  and the same with max_step = T / 1000; both reach 1e-8 to 4e-8 m, as the issue's LSODA did.
  The same model in the centre of mass's coordinates (``baselines.run_baseline``) is reported
  too: there LSODA steps over whole strokes of scene 2 (3.6 ms, 0.8 m off);
* the reference: a deliberately simple event-driven solver for two bodies written apart from
  the exact solver (``reference.py``: modes from the model, events by a 1e-5 s scan and
  ``brentq``), good to about 1e-13 m. Cross-check: the implicit method Richardson-extrapolated
  from h = 1e-5 s, h/2 and h/4 (its first-order error constant is known in closed form,
  (h/2)(V(T) - V(0)), see ``implicit.py``; two levels remove the h and h^2 terms), which agrees
  to about 1e-10 m, the limit of its rounding. Errors are the position of body 0 at T and the
  largest |x - x_ref| of the centre of mass over the grid;
* implicit: steps/s of the kernel (two bodies, scene 1, dt = 1e-5 s, wall and CPU time), the
  log-log slope of |error of x_0(T)| over dt = 1e-3 ... 1e-5 s against the reference, and
  ``ImplicitBatch`` body-steps/s;
* cold start: a fresh interpreter's ``import crawler_sim``, first exact and first implicit
  ``simulate`` (the compiled core is built at install: nothing compiles on first use).

Timings are medians after one untimed warm-up run, each method alike, over many runs: the
first runs of a process load caches, branch predictors and allocator pools, and a median of
five 0.1 ms runs still carries that (the first scene's exact runs measured 0.12-0.13 ms so
against 0.08 ms steady). The exact and LSODA runs of a scene are timed side by side, in at
least ``repeats`` rounds in which each runs in turn for ``MIN_TIMED`` / 4 s (a 0.1 ms run a few
hundred times, a 40 ms one once or twice), so both sides of a ratio see the same load; other
figures over at least ``repeats`` runs and ``MIN_TIMED`` seconds of them (timeit's
autorange). The cold start is reported on its own. Wall time (``perf_counter``) and CPU time
(``process_time``: steadier on a shared machine).
"""
from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import time
from typing import Any, Callable

import numpy as np

from crawler_sim.core import gaits
from crawler_sim.core.model import Crawler
from crawler_sim.core.solvers.implicit import ImplicitSolver
from crawler_sim.core.stepper import simulate
from .baselines import run_baseline, seed_penalised_lsoda
from test.support.oracle import two_body_reference

__all__ = ['SCENES', 'scene', 'run_compare', 'compare_markdown', 'compare_lines']

SCENES = {'m11_f05_1': ([1.0, 1.0], [0.5, 1.0], 1.0),
          'm12_f1_1': ([1.0, 2.0], [1.0, 1.0], 1.0),
          'm11_f5_10_5hz': ([1.0, 1.0], [5.0, 10.0], 5.0)}
PERIODS = 10
MIN_TIMED = 0.2         # s of timed runs per figure at least (short runs repeated more)
COMMAND = 'python -m benchmarks.solvers compare'


def _custom(hz: float) -> gaits.Custom:
    w = 2.0 * math.pi * hz
    return gaits.Custom(lambda t: 1.0 + 0.3 * (math.sin(w * t) + 0.3 * math.sin(2 * w * t)),
                        lambda t: 0.3 * w * (math.cos(w * t) + 0.6 * math.cos(2 * w * t)),
                        lambda t: -0.3 * w * w * (math.sin(w * t) + 1.2 * math.sin(2 * w * t)))


def scene(name: str) -> tuple[Crawler, gaits.Gait, gaits.Gait, float]:
    """(crawler, built-in Fourier gait, Custom lambda gait, T [s]) of one scene."""
    m, f, hz = SCENES[name]
    return (Crawler(m, f), gaits.Fourier(1.0, ([0.0, 0.0], [0.3, 0.09]), hz), _custom(hz),
            PERIODS / hz)


def _timed(fn: Callable[[], Any], repeats: int) -> tuple[dict, Any]:
    """({wall, cpu: medians [s], runs: how many, spread: wall quartiles [s]}, fn's result)
    over at least ``repeats`` runs and ``MIN_TIMED`` s of them (see the module doc)."""
    fn()                                  # warm-up, not timed
    wall, cpu, out = [], [], None
    start = time.perf_counter()
    while len(wall) < max(repeats, 1) or time.perf_counter() - start < MIN_TIMED:
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return _summary(wall, cpu), out


def _summary(wall: list, cpu: list) -> dict:
    """Medians of the wall and CPU times [s], how many runs, the wall times' quartiles."""
    q = statistics.quantiles(wall, n=4) if len(wall) > 1 else wall * 3
    return {'wall': statistics.median(wall), 'cpu': statistics.median(cpu), 'runs': len(wall),
            'spread': [q[0], q[2]]}


def _timed_together(fns: dict, repeats: int) -> dict:
    """{name: (timing as ``_timed``'s or {error}, the last result)} of ``fns`` timed side by
    side: after one untimed run of each, rounds in which each runs, in turn, for at least
    ``MIN_TIMED`` / 4 s (a 0.1 ms run a few hundred times, a 40 ms one once or twice), at
    least ``repeats`` rounds. Both sides of a ratio then see the same load, however it
    drifts during the run (timed apart, LSODA's median moved 38-67 ms between runs)."""
    out: dict = {}
    for k, fn in fns.items():
        try:
            out[k] = ({}, fn())
        except Exception as exc:  # noqa: BLE001 (reported as the result of that solver)
            out[k] = ({'error': f'{type(exc).__name__}: {exc}'}, None)
    live = [k for k in fns if 'error' not in out[k][0]]
    wall: dict = {k: [] for k in live}
    cpu: dict = {k: [] for k in live}
    for _ in range(max(repeats, 1)):
        for k in live:
            start = time.perf_counter()
            while True:
                w0, c0 = time.perf_counter(), time.process_time()
                res = fns[k]()
                cpu[k].append(time.process_time() - c0)
                wall[k].append(time.perf_counter() - w0)
                if time.perf_counter() - start >= MIN_TIMED / 4:
                    break
            out[k] = (out[k][0], res)
    for k in live:
        out[k] = (_summary(wall[k], cpu[k]), out[k][1])
    return out


def _implicit_x0(crawler: Crawler, gait: gaits.Gait, T: float, dt: float) -> float:
    s = ImplicitSolver(crawler, gait, dt=dt)
    s.advance(T)
    return float(s.current()['x'][0])


def _implicit_run(crawler: Crawler, gait: gaits.Gait, grid: np.ndarray,
                  dt: float) -> tuple[np.ndarray, float]:
    """(centre of mass on the grid, x_0 at its end) of the implicit method."""
    s = ImplicitSolver(crawler, gait, dt=dt)
    out = []
    for t in grid:
        s.advance(float(t))
        out.append(s.X)
    return np.array(out), float(s.current()['x'][0])


def _reference(crawler: Crawler, gait: gaits.Gait, T: float, grid: np.ndarray,
               h: float) -> dict:
    """Two-level Richardson extrapolation of the implicit method from steps h, h/2, h/4: its
    error is C h + D h^2 + ... (C = (V(T) - V(0)) / 2, see ``implicit.py``), so
    R1(h) = 2 x(h/2) - x(h) removes C h and (4 R1(h/2) - R1(h)) / 3 removes D h^2."""
    runs = [_implicit_run(crawler, gait, grid, h / k) for k in (1, 2, 4)]
    (c1, x1), (c2, x2), (c4, x4) = runs
    r_h, r_h2 = 2 * x2 - x1, 2 * x4 - x2
    rc_h, rc_h2 = 2 * c2 - c1, 2 * c4 - c2
    return {'x0': (4 * r_h2 - r_h) / 3, 'com': (4 * rc_h2 - rc_h) / 3, 'h': h,
            'richardson_correction': x2 - x1, 'second_correction': (r_h2 - r_h) / 3}


def _scene_row(name: str, repeats: int, h_ref: float, say: Callable) -> dict:
    crawler, builtin, _, T = scene(name)
    grid = np.linspace(0.0, T, 16 * PERIODS + 1)
    ref = two_body_reference(crawler, builtin, T, grid)
    rich = _reference(crawler, builtin, T, grid, h_ref)
    row: dict[str, Any] = {'scene': name, 'T': T, 'reference_x0': ref['x0'],
                           'richardson_x0': rich['x0'],
                           'richardson_vs_reference': abs(rich['x0'] - ref['x0']),
                           'reference_richardson_correction': rich['richardson_correction'],
                           'reference_second_correction': rich['second_correction']}
    hz = SCENES[name][2]
    w1 = float(crawler.masses[1] / crawler.total_mass)

    def lsoda(max_step: float) -> Callable[[], Any]:
        return lambda: seed_penalised_lsoda(crawler, builtin, T, grid, n=1e8, rtol=1e-10,
                                            atol=1e-10, max_step=max_step)
    # the Custom gait made anew for every run: its sampling into Chebyshev pieces
    # (``solvers.proxy``), once per gait object, is timed too. The ratios' two sides are
    # timed in the same rounds (``_timed_together``).
    timed = _timed_together({
        'exact_builtin': lambda: simulate(crawler, builtin, T, t_eval=grid),
        'exact_custom': lambda: simulate(crawler, _custom(hz), T, t_eval=grid),
        'lsoda': lsoda(math.inf), 'lsoda_max_step': lsoda(T / 1000)}, repeats)
    for label in ('exact_builtin', 'exact_custom'):
        tm, tr = timed[label]
        if 'error' in tm:   # a failing solver is a result of the bench
            row[label] = tm
        else:
            row[label] = {**tm, 'err_x0': abs(float(tr.x[-1, 0]) - ref['x0']),
                          'err_com': float(np.max(np.abs(tr.com - ref['com'])))}
        say(f'{name} {label}: {_fmt(row[label])}')
    for label in ('lsoda', 'lsoda_max_step'):
        tm, x0 = timed[label]
        if 'error' in tm:
            raise RuntimeError(f'{name} {label}: {tm["error"]}')
        com = x0 + w1 * builtin(grid)[0][:, 0]
        row[label] = {**tm, 'status': 'ok', 'err_x0': abs(float(x0[-1]) - ref['x0']),
                      'err_com': float(np.max(np.abs(com - ref['com'])))}
        say(f'{name} {label}: {_fmt(row[label])}')
    # the same model in the centre of mass's (X, V) (``run_baseline``): LSODA's steps depend
    # on the coordinates; reported, not compared with
    tm, res = _timed(lambda: run_baseline(crawler, builtin, T, grid, solver='LSODA',
                                          model='penalised', reg=1e8, rtol=1e-10, atol=1e-10,
                                          budget=60.0), repeats)
    x0 = res.X[-1] - w1 * float(builtin(T)[0][0])
    row['lsoda_com_coordinates'] = {**tm, 'status': res.status, 'nfev': res.nfev,
                                    'err_x0': abs(float(x0) - ref['x0']),
                                    'err_com': float(np.max(np.abs(res.X - ref['com'])))}
    say(f'{name} lsoda in (X, V): {_fmt(row["lsoda_com_coordinates"])}')
    for ex in ('exact_builtin', 'exact_custom'):
        for lab in ('lsoda', 'lsoda_max_step'):
            if 'wall' in row[ex]:
                row[f'ratio_{ex}_vs_{lab}'] = row[lab]['wall'] / row[ex]['wall']
                row[f'ratio_cpu_{ex}_vs_{lab}'] = row[lab]['cpu'] / row[ex]['cpu']
    # implicit convergence: |x_0(T) - reference| over dt, slope of the log-log fit
    dts = [1e-3, 3e-4, 1e-4, 3e-5, 1e-5]
    errs = [abs(_implicit_x0(crawler, builtin, T, d) - ref['x0']) for d in dts]
    slope = float(np.polyfit(np.log(dts), np.log(errs), 1)[0])
    ex_v = simulate(crawler, builtin, T, t_eval=[0.0, T]).v @ (crawler.masses /
                                                               crawler.total_mass)
    row['implicit'] = {'dts': dts, 'errors': errs, 'slope': slope,
                       'constant': [e / d for e, d in zip(errs, dts)],
                       'predicted_constant': abs(0.5 * float(ex_v[-1] - ex_v[0]))}
    say(f'{name} implicit: slope {slope:.3f}, errors {", ".join(f"{e:.2e}" for e in errs)}')
    return row


def _fmt(r: dict) -> str:
    if 'error' in r:
        return f'FAILED {r["error"]}'
    return (f'{r["wall"] * 1e3:.2f} ms wall, {r["cpu"] * 1e3:.2f} ms CPU, error x0 '
            f'{r["err_x0"]:.1e}, com {r["err_com"]:.1e}')


def implicit_speed(repeats: int = 5, dt: float = 1e-5) -> dict:
    """Steps/s of the kernel: one two-body crawler, scene 1, 10 s at dt."""
    crawler, builtin, custom, T = scene('m11_f05_1')
    _implicit_x0(crawler, builtin, 0.01, dt)              # load the kernel first

    def run():
        s = ImplicitSolver(crawler, builtin, dt=dt)
        s.advance(T)
        return s.n_steps
    tm, n = _timed(run, repeats)
    tc, nc = _timed(lambda: _run_custom(crawler, custom, dt=1e-3, T=1.0), max(repeats // 2, 1))
    return {'steps': n, 'wall': tm['wall'], 'cpu': tm['cpu'], 'steps_per_s': n / tm['wall'],
            'steps_per_s_cpu': n / tm['cpu'], 'custom_steps_per_s': nc / tc['wall'],
            'custom_steps_per_s_cpu': nc / tc['cpu']}


def _run_custom(crawler: Crawler, gait: gaits.Gait, dt: float, T: float) -> int:
    s = ImplicitSolver(crawler, gait, dt=dt)
    s.advance(T)
    return s.n_steps


_COLD = r'''
import json, time
t0 = time.perf_counter()
import crawler_sim as cs
t1 = time.perf_counter()
c = cs.Crawler([1, 1], [0.5, 1]); g = cs.gaits.Fourier(1.0, ([0.0, 0.0], [0.3, 0.09]), 1.0)
cs.simulate(c, g, 10.0, t_eval=[0, 10])
t2 = time.perf_counter()
cs.simulate(c, g, 10.0, 'implicit', dt=1e-4, t_eval=[0, 10])
t3 = time.perf_counter()
cs.simulate(c, g, 10.0, 'implicit', dt=1e-4, t_eval=[0, 10])
t4 = time.perf_counter()
print(json.dumps({'import': t1 - t0, 'first_exact': t2 - t1, 'first_implicit': t3 - t2,
                  'second_implicit': t4 - t3}))
'''


def cold_start(repeats: int = 3) -> dict:
    """Fresh-interpreter timings [s] (medians): import, first exact and implicit simulate."""
    runs: list[dict] = []
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in sys.path if p)
    for _ in range(repeats):
        out = subprocess.run([sys.executable, '-c', _COLD], capture_output=True, text=True,
                             env=env, timeout=300, check=True).stdout
        runs.append(json.loads(out.strip().splitlines()[-1]))
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]} | {'repeats': repeats}


def run_compare(repeats: int = 5, quick: bool = False, progress: Callable | None = None,
                batch: bool = True) -> dict:
    """The whole comparison; ``quick`` uses 2 repeats and a coarser reference (tests)."""
    say = progress or (lambda *a, **k: None)
    reps = 2 if quick else repeats
    h_ref = 1e-4 if quick else 1e-5
    out: dict[str, Any] = {'command': COMMAND + (' --quick' if quick else ''), 'repeats': reps,
                           'reference_h': h_ref, 'load_average': [_load()], 'scenes': {}}
    for name in SCENES:
        out['scenes'][name] = _scene_row(name, reps, h_ref, say)
    out['implicit_speed'] = implicit_speed(reps, dt=1e-4 if quick else 1e-5)
    say(f'implicit: {out["implicit_speed"]["steps_per_s"]:.3g} steps/s wall, '
        f'{out["implicit_speed"]["steps_per_s_cpu"]:.3g} CPU')
    if batch:
        from .figures import batch_throughput
        out['batch'] = batch_throughput(1_000 if quick else 10_000, 2, 20 if quick else 200,
                                        repeats=reps)
    out['cold_start'] = cold_start(1 if quick else 3)
    say(f'cold start: {out["cold_start"]}')
    out['load_average'].append(_load())
    return out


def _load() -> float:
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return math.nan


def _ms(v: float) -> str:
    return f'{v * 1e3:.3g} ms'


def compare_markdown(res: dict) -> list[str]:
    """The comparison as Markdown lines (tables and figures)."""
    lines = ['## Issue 14 comparison: exact vs LSODA on the penalised ODE, implicit method', '',
             f'Command: `{res["command"]}` (also part of `python -m benchmarks.solvers`). Medians of '
             f'runs after one warm-up run, exact and LSODA side by side in {res["repeats"]} '
             f'rounds of {MIN_TIMED / 4:g} s of runs each, wall (CPU) time; load average '
             f'{res["load_average"][0]:.2f} / {res["load_average"][-1]:.2f}. Errors against an '
             'independent event-driven two-body solver (`test/support/oracle.py`, '
             'events by scan and brentq): '
             '|x_0(T) - ref| and max |X - X_ref| over 16 samples per period; cross-check, the '
             f'implicit method Richardson-extrapolated (two levels) from h = '
             f'{res["reference_h"]:g} s, h/2, h/4 differs from it by ' +
             ', '.join(f'{r.get("richardson_vs_reference", math.nan):.0e}'
                       for r in res['scenes'].values()) + ' m. LSODA: the seed\'s penalised '
             'ODE in (x_0, y = x_0\'), n = 1e8, rtol = atol = 1e-10, analytic Jacobian; '
             '"+max_step" adds max_step = T / 1000. The same model '
             'in the centre of mass\'s (X, V), LSODA as named: ' +
             ', '.join(f'{_ms(r["lsoda_com_coordinates"]["wall"])} (error '
                       f'{r["lsoda_com_coordinates"]["err_x0"]:.1e} m)'
                       for r in res['scenes'].values()) + '.', '',
             '| scene | exact Fourier | exact Custom | LSODA | LSODA +max_step | ratio Fourier '
             '(vs LSODA / +max_step) | ratio Custom | implicit slope |',
             '|---|---|---|---|---|---|---|---|']

    def cell(r: dict) -> str:
        if 'error' in r:
            return 'failed: ' + r['error'][:60]
        return f'{_ms(r["wall"])} ({_ms(r["cpu"])}), err {r["err_x0"]:.1e} / {r["err_com"]:.1e}'

    def ratio(row: dict, ex: str) -> str:
        a, b = row.get(f'ratio_{ex}_vs_lsoda'), row.get(f'ratio_{ex}_vs_lsoda_max_step')
        return '-' if a is None else f'{a:.1f}x / {b:.1f}x'
    for name, row in res['scenes'].items():
        lines.append(f'| {name} | {cell(row["exact_builtin"])} | {cell(row["exact_custom"])} | '
                     f'{cell(row["lsoda"])} | {cell(row["lsoda_max_step"])} | '
                     f'{ratio(row, "exact_builtin")} | {ratio(row, "exact_custom")} | '
                     f'{row["implicit"]["slope"]:.3f} |')
    lines.append('')
    first = next(iter(res['scenes'].values()), None)
    if first is not None:
        lines.append('Implicit errors |x_0(T) - ref| for dt = ' +
                     ', '.join(f'{d:g}' for d in first['implicit']['dts']) + ' s:')
        lines.append('')
    for name, row in res['scenes'].items():
        im = row['implicit']
        lines.append(f'- {name}: ' + ', '.join(f'{e:.2e}' for e in im['errors']) +
                     f' (error / dt {im["constant"][-1]:.4f} m/s, predicted (V(T) - V(0)) / 2 = '
                     f'{im["predicted_constant"]:.4f})')
    sp = res['implicit_speed']
    lines += ['', f'- Implicit kernel, one two-body crawler, Fourier gait: '
                  f'{sp["steps_per_s"]:.3g} steps/s wall, {sp["steps_per_s_cpu"]:.3g} steps/s '
                  f'CPU ({sp["steps"]:,} steps); Custom gait (its lambdas called from Python, '
                  f'the steps in the kernel): '
                  f'{sp["custom_steps_per_s"]:,.0f} steps/s wall '
                  f'({sp["custom_steps_per_s_cpu"]:,.0f} CPU).']
    if 'batch' in res:
        b = res['batch']
        lines.append(f'- ImplicitBatch, {b["crawlers"]:,} crawlers, p = 2: '
                     f'{b["body_steps_per_s"]:.3g} body-steps/s (compiled step); the previous '
                     f'numpy step {b["numpy_body_steps_per_s"]:.3g}/s in the same run '
                     f'({b["speedup_vs_numpy"]:.1f}x; largest |X| difference '
                     f'{b["max_diff_vs_numpy"]:.1e} m).')
    cs_ = res['cold_start']
    lines.append(f'- Cold start (fresh interpreter, median of {cs_["repeats"]}): import '
                 f'crawler_sim {cs_["import"]:.2f} s; first exact simulate '
                 f'{cs_["first_exact"]:.2f} s; first implicit simulate {cs_["first_implicit"]:.2f}'
                 f' s (second {cs_["second_implicit"] * 1e3:.1f} ms).')
    lines.append('')
    return lines


def compare_floors(res: dict) -> dict:
    """The floors on this comparison (issue 14's for the implicit method, issue 23's for the
    exact one): {name: {'value', 'pass'}}."""
    rows = res['scenes'].values()
    floors = {}
    slopes = [r['implicit']['slope'] for r in rows]
    floors['implicit error slope >= 0.9 (dt 1e-3 .. 1e-5, three scenes)'] = {
        'value': ', '.join(f'{s:.3f}' for s in slopes), 'pass': all(s >= 0.9 for s in slopes)}
    sp = res['implicit_speed']
    floors['implicit >= 1e7 steps/s, one two-body crawler'] = {
        'value': f'{sp["steps_per_s"]:.3g} wall, {sp["steps_per_s_cpu"]:.3g} CPU',
        'pass': sp['steps_per_s_cpu'] >= 1e7}
    for ex, need in (('exact_builtin', 300.0), ('exact_custom', 100.0)):
        vals = [r.get(f'ratio_{ex}_vs_lsoda') for r in rows]
        errs = [r[ex].get('err_x0', math.inf) for r in rows]
        floors[f'{ex.replace("_", " ")} >= {need:g}x LSODA-on-penalty at error <= 1e-10'] = {
            'value': ', '.join('-' if v is None else f'{v:.1f}x' for v in vals) + '; errors ' +
                     ', '.join(f'{e:.1e}' for e in errs),
            'pass': all(v is not None and v >= need for v in vals) and all(e <= 1e-10
                                                                          for e in errs)}
    return floors


def compare_lines(res: dict) -> list[str]:
    """Short headline lines for the console."""
    out = []
    for name, row in res['scenes'].items():
        out.append(f'{name}: exact/LSODA {row.get("ratio_exact_builtin_vs_lsoda", math.nan):.1f}x '
                   f'(Custom {row.get("ratio_exact_custom_vs_lsoda", math.nan):.1f}x), implicit '
                   f'slope {row["implicit"]["slope"]:.3f}')
    sp = res['implicit_speed']
    out.append(f'implicit kernel {sp["steps_per_s"]:.3g} steps/s wall, '
               f'{sp["steps_per_s_cpu"]:.3g} CPU; command: {res["command"]}')
    return out
