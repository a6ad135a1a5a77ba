"""``run_bench``: the whole benchmark (work-precision per scene, figures, floors, outputs)."""
from __future__ import annotations

import datetime as _dt
import math
import os
from pathlib import Path
import platform
import sys
import time
from typing import Any, Callable

import numpy as np
import scipy

from . import figures as figs
from .report import fmt_time, markdown, plot_work_precision, write_json
from .scenes import BenchScene, load_bench_scenes
from .workprec import SCIPY_SERIES, Ladders, _json_float, bench_scene, plan

__all__ = ['run_bench', 'NAMED_BASELINE']

#: The baseline the issue names: LSODA + analytic Jacobian on the penalised ODE, n = 1e8,
#: rtol = atol = 1e-10, on ten periods of the two-body asymmetric stroke.
NAMED_BASELINE = {'scene': 'scallop_2body', 'series': 'scipy-LSODA-penalised',
                  'params': {'n': 1e8, 'rtol': 1e-10, 'atol': 1e-10}}
HEADLINE_SCENE = 'scallop_2body'

Progress = Callable[..., None] | None


def _machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as fh:
            for line in fh:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return f'{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}'


def _load() -> float:
    """The 1-minute load average (nan where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return math.nan


def _find_run(scene: dict, series: str, params: dict) -> dict | None:
    for r in scene['runs']:
        if r['series'] == series and all(
                math.isclose(float(r['params'].get(k, math.nan)), v) for k, v in params.items()):
            return r
    return None


def _cheapest(scene: dict, series: tuple[str, ...], measure: str, err: float) -> dict | None:
    ok = [r for r in scene['runs'] if r['series'] in series and r['status'] == 'ok'
          and float(r[f'err_{measure}']) <= err]
    return min(ok, key=lambda r: float(r['time'])) if ok else None


def _ratio_text(num: float | None, den: float | None) -> str:
    if num is None or den is None or not (den > 0):
        return '-'
    return f'{num / den:.1f}x'


def _headline(scene: dict) -> tuple[dict, dict]:
    """The named baseline against exact, and the ratio at equal error 1e-6."""
    named: dict[str, Any] = {'label': 'LSODA + Jacobian, penalised ODE, n = 1e8, '
                                      'rtol = atol = 1e-10', 'scene': scene['name'],
                             'periods': scene['periods']}
    r = _find_run(scene, NAMED_BASELINE['series'], NAMED_BASELINE['params'])
    if r is not None:
        named.update(status=r['status'], time=r['time'], err_displacement=r['err_displacement'],
                     err_position=r['err_position'], nfev=r['info'].get('nfev'))
        if r['status'] == 'ok':
            ex = _cheapest(scene, ('exact',), 'displacement', float(r['err_displacement']))
            if ex is not None:
                named.update(exact_time=ex['time'], exact_params=ex['params'],
                             ratio=float(r['time']) / float(ex['time']),
                             ratio_text=_ratio_text(float(r['time']), float(ex['time'])))
    ratio: dict[str, Any] = {'scene': scene['name'], 'error': 1e-6}
    for measure, suffix in (('displacement', ''), ('position', '_position')):
        ex = _cheapest(scene, ('exact',), measure, 1e-6)
        sp = _cheapest(scene, SCIPY_SERIES, measure, 1e-6)
        ratio[f'exact_time{suffix}'] = ex['time'] if ex else None
        ratio[f'scipy_time{suffix}'] = sp['time'] if sp else None
        ratio[f'scipy_series{suffix}'] = f'{sp["series"]} {sp["params"]}' if sp else None
        value = float(sp['time']) / float(ex['time']) if ex and sp else None
        ratio[f'ratio{suffix}'] = value
        ratio[f'ratio_text{suffix}'] = (_ratio_text(float(sp['time']), float(ex['time']))
                                        if ex and sp else
                                        ('scipy did not reach 1e-6' if ex else '-'))
    noskip = _cheapest(scene, ('exact-noskip',), 'displacement', 1e-6)
    sp = _cheapest(scene, SCIPY_SERIES, 'displacement', 1e-6)
    ratio['exact_noskip_time'] = noskip['time'] if noskip else None
    ratio['ratio_noskip'] = (float(sp['time']) / float(noskip['time'])
                             if noskip and sp else None)
    return named, ratio


def _floors(result: dict) -> dict:
    floors: dict[str, dict] = {}
    bests = {}
    for name, sc in result['scenes'].items():
        if sc.get('error'):
            bests[name] = math.inf
            continue
        best = min(float(sc['summary'].get(s, {}).get('best_displacement', math.inf))
                   for s in ('exact', 'exact-noskip'))
        bests[name] = best
    if bests:
        floors['exact displacement error <= 1e-10 on every scene'] = {
            'value': ', '.join(f'{k} {v:.1e}' for k, v in bests.items()),
            'pass': all(v <= 1e-10 for v in bests.values())}
    ratio = result.get('ratio_1e-6') or {}
    if ratio:
        floors['exact vs fastest scipy at error 1e-6 >= 20x'] = {
            'value': ratio.get('ratio_text', '-'),
            'pass': bool(ratio.get('ratio') and ratio['ratio'] >= 20)}
    thr = result['figures'].get('exact_throughput')
    if thr:
        floors['exact periods/s >= 5000 (two-body asymmetric gait)'] = {
            'value': f'{thr["stepper_skip_periods_per_s"]:,.0f}/s with periodic skip, '
                     f'{thr["stepper_noskip_periods_per_s"]:,.0f}/s without',
            'pass': thr['stepper_skip_periods_per_s'] >= 5000}
    for b in result['figures'].get('batch', []):
        if b['crawlers'] >= 10_000:
            floors[f'ImplicitBatch body-steps/s >= 1e7 (p = {b["p"]})'] = {
                'value': f'{b["body_steps_per_s"]:.3g}/s', 'pass': b['body_steps_per_s'] >= 1e7}
    rest = result['figures'].get('rest_cost')
    if rest:
        floors['exact rest cost does not grow with its length'] = {
            'value': ', '.join(f'{k} x{rest[k]["growth"]:.2f}'
                               for k in ('cubic', 'custom', 'stroke_then_rest')),
            'pass': all(rest[k]['flat'] for k in ('cubic', 'custom', 'stroke_then_rest'))}
    return floors


def _run_figures(scenes: list[BenchScene], quick: bool, say: Callable) -> dict:
    out: dict[str, Any] = {}
    head = next((s for s in scenes if s.name == HEADLINE_SCENE), None)
    if head is None:
        head = next((s for s in scenes if s.period and s.crawler.p == 2), None)
    if head is not None:
        periods = 20 if quick else 2000
        say(f'figures: exact throughput over {periods} periods of {head.name}')
        try:
            out['exact_throughput'] = figs.exact_throughput(head.crawler, head.gait, periods)
        except Exception as exc:  # noqa: BLE001
            out['exact_throughput_error'] = f'{type(exc).__name__}: {exc}'
        say('figures: output cost')
        try:
            out['output_cost'] = figs.output_cost(
                head.crawler, head.gait, 5 if quick else 100,
                counts=(2, 1_000) if quick else (2, 1_000, 100_000))
        except Exception as exc:  # noqa: BLE001
            out['output_cost_error'] = f'{type(exc).__name__}: {exc}'
    say('figures: ImplicitBatch throughput')
    if quick:
        out['batch'] = [figs.batch_throughput(1_000, 2, 20)]
    else:
        out['batch'] = [figs.batch_throughput(10_000, 2, 200),
                        figs.batch_throughput(10_000, 10, 50)]
    say('figures: rest cost')
    out['rest_cost'] = figs.rest_cost((1.0, 1e4) if quick else (1.0, 1e2, 1e4, 1e6))
    return out


def run_bench(out_dir: str | Path, scenes: list[str] | None = None, quick: bool = False,
              progress: Progress = None) -> dict:
    """Run the benchmark and write ``bench.json``, ``bench.md`` and ``bench.png`` to ``out_dir``.

    Parameters
    ----------
    out_dir : directory for the outputs (created).
    scenes : bench scene names (``benchmarks/scenes/<name>.yaml``) or YAML paths; default all.
    quick : two or three rungs per ladder, two periods per scene, small figures (seconds).
    progress : called with a message, or with ``(done, total, label)``.

    Returns
    -------
    dict : ``ok`` (every scene ran and every method returned a finite result), the output
    paths, the headline figures, the floors and each scene's summary (the runs are in the JSON).
    """
    say = progress or (lambda *a, **k: None)
    t_start = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lad = Ladders.quick() if quick else Ladders()
    loaded = load_bench_scenes(scenes)
    if quick:
        loaded = [s.with_periods(min(s.periods, 2)) if s.periods else s for s in loaded]
    result: dict[str, Any] = {
        'meta': {'date': _dt.datetime.now().isoformat(timespec='seconds'),
                 'machine': _machine(), 'python': platform.python_version(),
                 'numpy': np.__version__, 'scipy': scipy.__version__, 'quick': quick,
                 'command': ' '.join(['python -m benchmarks.solvers'] + (['--quick'] if quick else []) +
                                     (['--scenes'] + list(scenes) if scenes else [])),
                 'reference_tol': lad.reference_tol, 'repeats': lad.repeats,
                 'scipy_budget_s': lad.budget, 'max_steps': lad.max_steps,
                 'load_average': [_load()]},
        'scenes': {},
    }
    for scene in loaded:
        extra = []
        if scene.name == NAMED_BASELINE['scene']:
            p = NAMED_BASELINE['params']
            have = any(r[0] == NAMED_BASELINE['series'] and r[1] == 'scipy' and
                       r[2][2] == p['n'] and r[2][3] == p['rtol'] for r in plan(scene, lad))
            if not have:
                extra.append((NAMED_BASELINE['series'], 'scipy',
                              ('LSODA', 'penalised', p['n'], p['rtol'])))
        say(f'scene {scene.name}: {scene.description}')
        try:
            result['scenes'][scene.name] = bench_scene(scene, lad, progress=say,
                                                       extra_runs=extra)
        except Exception as exc:  # noqa: BLE001 (a failing scene is reported, not fatal)
            say(f'scene {scene.name} FAILED: {type(exc).__name__}: {exc}')
            result['scenes'][scene.name] = {'name': scene.name, 'description': scene.description,
                                            'error': f'{type(exc).__name__}: {exc}', 'runs': [],
                                            'summary': {}}
    head = result['scenes'].get(HEADLINE_SCENE)
    if head and not head.get('error'):
        result['named_baseline'], result['ratio_1e-6'] = _headline(head)
    result['figures'] = _json_float(_run_figures(loaded, quick, say))
    say('issue 14 comparison (exact vs LSODA, implicit, cold start)')
    from .compare import compare_floors, run_compare
    try:
        result['compare'] = _json_float(run_compare(quick=quick, progress=say))
    except Exception as exc:  # noqa: BLE001 (reported, not fatal)
        result['compare'] = {'error': f'{type(exc).__name__}: {exc}'}
    result['floors'] = _floors(result)
    if 'error' not in result['compare']:
        result['floors'].update(compare_floors(result['compare']))
    failures = []
    for name, sc in result['scenes'].items():
        if sc.get('error'):
            failures.append(f'{name}: {sc["error"]}')
        for r in sc['runs']:
            if r['series'] in ('exact', 'exact-noskip', 'implicit', 'penalty') and \
                    r['status'] not in ('ok', 'skipped'):
                failures.append(f'{name} {r["series"]} {r["params"]}: {r["status"]} '
                                f'{r["message"]}')
    if not quick:     # --quick runs too little to judge a floor: they are shown, not judged
        failures += [f'floor {name}: {f["value"]}' for name, f in result['floors'].items()
                     if not f['pass']]
    result['failures'] = failures
    result['ok'] = not failures
    result['meta']['wall_time'] = time.perf_counter() - t_start
    result['meta']['load_average'].append(_load())
    paths = {'json': out / 'bench.json', 'markdown': out / 'bench.md', 'png': out / 'bench.png'}
    write_json(result, paths['json'])
    md = markdown(result)
    if 'compare' in result and 'error' not in result['compare']:
        from .compare import compare_markdown
        md += '\n' + '\n'.join(compare_markdown(result['compare']))
    paths['markdown'].write_text(md, encoding='utf-8')
    plot_work_precision(result, paths['png'])
    for line in _headline_lines(result):
        say(line)
    summary = {k: v for k, v in result.items() if k != 'scenes'}
    summary['scenes'] = {k: v.get('error') or v['summary'] for k, v in result['scenes'].items()}
    summary.update({k: str(v) for k, v in paths.items()})
    return summary


def _headline_lines(result: dict) -> list[str]:
    lines = []
    ratio = result.get('ratio_1e-6')
    if ratio:
        lines.append(f'exact vs fastest scipy at error 1e-6: {ratio["ratio_text"]} '
                     f'(exact {fmt_time(ratio["exact_time"])}, {ratio["scipy_series"]} '
                     f'{fmt_time(ratio["scipy_time"])})')
    named = result.get('named_baseline')
    if named and 'time' in named:
        lines.append(f'named baseline {named["label"]}: {fmt_time(named["time"])}, '
                     f'error {float(named["err_displacement"]):.2e}; exact at that error '
                     f'{fmt_time(named.get("exact_time"))} ({named.get("ratio_text", "-")})')
    if 'compare' in result and 'error' not in result['compare']:
        from .compare import compare_lines
        lines += compare_lines(result['compare'])
    quick = result['meta'].get('quick')
    for name, f in result['floors'].items():
        verdict = 'not judged (--quick)' if quick else 'PASS' if f['pass'] else 'FAIL'
        lines.append(f'floor {verdict}: {name}: {f["value"]}')
    lines.append(f'bench wall time {result["meta"]["wall_time"]:.1f} s')
    return lines


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.solvers [--quick] [--out DIR] [--scenes NAME ...]``
    and ``python -m benchmarks.solvers stress [--seconds S] [--seed N]``."""
    import argparse
    import json

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == 'compare':
        from .compare import compare_floors, compare_lines, compare_markdown, run_compare
        ap = argparse.ArgumentParser(prog='python -m benchmarks.solvers compare',
                                     description='issue 14: exact vs LSODA, implicit, cold start')
        ap.add_argument('--quick', action='store_true')
        ap.add_argument('--repeats', type=int, default=5)
        ap.add_argument('--json', metavar='FILE')
        a = ap.parse_args(argv[1:])
        res = run_compare(repeats=a.repeats, quick=a.quick, progress=_print_progress)
        res['floors'] = compare_floors(res)
        if a.json:
            Path(a.json).write_text(json.dumps(res, indent=1, default=str) + '\n',
                                    encoding='utf-8')
        print('\n'.join(compare_markdown(res)))
        print('\n'.join(compare_lines(res)))
        for name, f in res['floors'].items():
            verdict = 'not judged (--quick)' if a.quick else 'PASS' if f['pass'] else 'FAIL'
            print(f'floor {verdict}: {name}: {f["value"]}')
        return 0 if a.quick or all(f['pass'] for f in res['floors'].values()) else 1
    if argv and argv[0] == 'stress':
        from .stress import run_stress
        ap = argparse.ArgumentParser(
            prog='python -m benchmarks.solvers stress',
            description='the fixed checks (about two minutes on two cores: extremes, a '
            '1e5-period run, the differential fuzz of every gait family), then random scenes '
            'until SECONDS of wall time have passed; one line per check')
        ap.add_argument('--seconds', type=float, default=60.0,
                        help='wall time budget of the whole run [s] (the fixed checks run '
                        'in full; random scenes fill what is left, at least 20 of them)')
        ap.add_argument('--seed', type=int, default=0)
        ap.add_argument('--json', metavar='FILE', help='write every figure to FILE')
        a = ap.parse_args(argv[1:])
        print('stress: fixed checks first (about two minutes), then random scenes up to '
              f'{a.seconds:g} s in all', flush=True)
        res = run_stress(seconds=a.seconds, seed=a.seed, progress=_print_progress)
        if a.json:
            Path(a.json).write_text(json.dumps(res, indent=1, default=str) + '\n',
                                    encoding='utf-8')
        for spec in res.get('failed_specs', []):
            print(f'failed random scene (check_random_scene(spec)): {spec}')
        return 0 if res.get('ok') else 1
    ap = argparse.ArgumentParser(prog='python -m benchmarks.solvers',
                                 description='work-precision benchmark of crawler_sim')
    ap.add_argument('--out', default='bench_out')
    ap.add_argument('--quick', action='store_true')
    ap.add_argument('--scenes', nargs='+')
    a = ap.parse_args(argv)
    res = run_bench(a.out, scenes=a.scenes, quick=a.quick, progress=_print_progress)
    print(Path(res['markdown']).read_text(encoding='utf-8'))
    return 0 if res['ok'] else 1


def _print_progress(*args: Any, **kwargs: Any) -> None:
    if len(args) >= 2 and all(isinstance(a, (int, float)) for a in args[:2]):
        print(f'[{args[0]}/{args[1]}] ' + ' '.join(str(a) for a in args[2:]), flush=True)
    else:
        print(' '.join(str(a) for a in args), flush=True)
