"""Writing the benchmark: JSON, a Markdown table and a log-log work-precision plot (PNG)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .workprec import SERIES, THRESHOLDS

__all__ = ['write_json', 'markdown', 'plot_work_precision', 'fmt_time', 'fmt_err']


def _f(v: Any) -> float:
    if v is None:
        return math.nan
    return float(v)


def fmt_time(v: Any) -> str:
    """Seconds as '12.3 ms' / '4.56 s'; '-' for not reached."""
    t = _f(v)
    if not math.isfinite(t):
        return '-'
    if t < 1e-3:
        return f'{t * 1e6:.0f} us'
    if t < 1.0:
        return f'{t * 1e3:.3g} ms'
    return f'{t:.3g} s'


def fmt_err(v: Any) -> str:
    e = _f(v)
    if math.isnan(e):
        return '-'
    if math.isinf(e):
        return 'inf'
    return '0' if e == 0 else f'{e:.1e}'


def write_json(result: dict, path: Path) -> None:
    path.write_text(json.dumps(result, indent=1, default=str) + '\n', encoding='utf-8')


def _scene_table(scene: dict, measure: str) -> list[str]:
    head = ('| series | runs ok | ' + ' | '.join(f'time to {thr:g}' for thr in THRESHOLDS) +
            ' | best displacement err | best position err | best event-time err | '
            'best history mismatch |')
    lines = [head, '|' + '---|' * (6 + len(THRESHOLDS))]
    for series, s in scene['summary'].items():
        times = ' | '.join(fmt_time(s.get(f'time_{measure}_{thr:g}')) for thr in THRESHOLDS)
        lines.append(f'| {series} | {s["ok"]}/{s["runs"]} | {times} | '
                     f'{fmt_err(s["best_displacement"])} | {fmt_err(s["best_position"])} | '
                     f'{fmt_err(s["best_events"])} s | {fmt_err(s["best_mismatch"])} s |')
    return lines


def markdown(result: dict) -> str:
    """The report: per scene, time to reach each error and the best errors; then the figures."""
    meta = result['meta']
    load = meta.get('load_average')
    load_txt = (f' Load average at start / end: {load[0]:.2f} / {load[1]:.2f} (timings on a '
                f'shared machine are noisy; ratios are steadier).' if load else '')
    out = [f'# crawler_sim work-precision benchmark{" (quick)" if meta["quick"] else ""}', '',
           f'{meta["machine"]}; Python {meta["python"]}, numpy {meta["numpy"]}, '
           f'scipy {meta["scipy"]}; {meta["date"]}. Command: `{meta["command"]}`.{load_txt}',
           '',
           'Error = net displacement error [m] of the centre of mass at the end, against '
           'method "exact" at its tightest tolerance (tol ' +
           f'{meta["reference_tol"]:g} s, periodic skip off). "time to E" = median wall time '
           '(of >= 3 runs) of the cheapest run of the series with error <= E; "-" = no run '
           'of the ladder reached it. Position error = largest |x_i - x_ref| over the common '
           'output grid; event-time error = largest shift of a reference stick/slip transition '
           '(inf: one has no counterpart); history mismatch = total time, summed over the '
           'bodies, during which the contact state differs from the reference.', '']
    for scene in result['scenes'].values():
        out.append(f'## {scene["name"]}')
        out.append('')
        if scene.get('error'):
            out += [f'**failed**: {scene["error"]}', '']
            continue
        ref = scene['reference']
        periods = f'{scene["periods"]:g} periods, ' if scene.get('periods') else ''
        out.append(f'{scene["description"]} Run: p = {scene["p"]}, {periods}'
                   f't_end = {scene["t_end"]:g} s, '
                   f'reference displacement {ref["displacement"]:.9g} m, '
                   f'{ref["n_events"]} transitions, reference run {fmt_time(ref["time"])}.')
        out.append('')
        out += _scene_table(scene, 'displacement')
        out.append('')
        out.append('<details><summary>time to reach a largest position error</summary>')
        out.append('')
        out += _scene_table(scene, 'position')
        out.append('')
        out.append('</details>')
        out.append('')
    out += _figures_md(result)
    out.append('Series:')
    out.append('')
    for k, v in SERIES.items():
        out.append(f'- `{k}`: {v}')
    out.append('')
    return '\n'.join(out)


def _figures_md(result: dict) -> list[str]:
    fig = result.get('figures', {})
    out = ['## Figures and floors', '']
    named = result.get('named_baseline')
    if named:
        out.append(f'- Named baseline (issue 6): {named["label"]}: {fmt_time(named.get("time"))}, '
                   f'displacement error {fmt_err(named.get("err_displacement"))} m, '
                   f'position error {fmt_err(named.get("err_position"))} m. Method "exact" '
                   f'reaching that error: {fmt_time(named.get("exact_time"))} '
                   f'(ratio {named.get("ratio_text", "-")}).')
    ratio = result.get('ratio_1e-6')
    if ratio:
        out.append(f'- Speed ratio at equal error 1e-6 ({ratio["scene"]}, displacement): '
                   f'exact {fmt_time(ratio.get("exact_time"))} vs fastest scipy baseline '
                   f'{ratio.get("scipy_series") or "-"} {fmt_time(ratio.get("scipy_time"))}: '
                   f'**{ratio.get("ratio_text", "-")}** (floor 20x, aim 100x). On the largest '
                   f'position error: {ratio.get("ratio_text_position", "-")}.')
    thr = fig.get('exact_throughput')
    if thr:
        out.append(f'- Method "exact", two-body asymmetric gait, {thr["periods"]} periods at '
                   f'full accuracy: {thr["stepper_skip_periods_per_s"]:,.0f} periods/s with the '
                   f'periodic skip (simulate: {thr["simulate_skip_periods_per_s"]:,.0f}/s), '
                   f'{thr["stepper_noskip_periods_per_s"]:,.0f} periods/s without it '
                   f'(simulate: {thr["simulate_noskip_periods_per_s"]:,.0f}/s) (floor 5,000/s).')
    for b in fig.get('batch', []):
        extra = (f'; the previous numpy step {b["numpy_body_steps_per_s"]:.3g}/s in the same run '
                 f'({b["speedup_vs_numpy"]:.1f}x)' if 'numpy_body_steps_per_s' in b else '')
        out.append(f'- ImplicitBatch, {b["crawlers"]:,} crawlers, p = {b["p"]}, {b["steps"]} '
                   f'steps: {b["body_steps_per_s"]:.3g} body-steps/s (floor 1e7/s){extra}.')
    rest = fig.get('rest_cost')
    if rest:
        for kind in ('cubic', 'custom', 'stroke_then_rest'):
            r = rest[kind]
            cells = ', '.join(f'{row["length"]:g} s: {fmt_time(row["time"])}'
                              for row in r['rows'])
            out.append(f'- Rest cost, method "exact", {kind} gait: {cells} '
                       f'({"flat" if r["flat"] else "GROWS"}, x{r["growth"]:.2f}).')
    oc = fig.get('output_cost')
    if oc:
        cells = '; '.join(f'{r["method"]}{"" if r["periodic_skip"] in (None, True) else " noskip"}'
                          f' {r["outputs"]}: {fmt_time(r["time"])}' for r in oc['rows'])
        out.append(f'- Output cost ({oc["periods"]} periods of the scallop scene): {cells}.')
    floors = result.get('floors', {})
    if floors:
        out.append('')
        out.append('| floor | value | pass |')
        out.append('|---|---|---|')
        for name, f in floors.items():
            out.append(f'| {name} | {f["value"]} | {"yes" if f["pass"] else "**no**"} |')
    out.append('')
    return out


_STYLE = {
    'exact': ('C0', 'o', '-'), 'exact-noskip': ('C0', 's', '--'),
    'implicit': ('C1', 'v', '-'), 'penalty': ('C2', '^', '-'),
    'scipy-LSODA-penalised': ('C3', 'D', '-'), 'scipy-Radau-penalised': ('C4', 'P', '-'),
    'scipy-LSODA-tanh': ('C5', 'X', ':'), 'scipy-Radau-tanh': ('C6', '*', ':'),
}
FLOOR_ERR = 1e-17   # where exact zeros are drawn on the log axis


def _front(pts: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The work-precision front of (error, time) points: each kept point is cheaper than every
    point with a smaller error (what the series costs to reach at most that error)."""
    front: list[tuple[float, float]] = []
    for err, t in sorted(pts):
        if not front or t < front[-1][1]:
            front.append((err, t))
    return front


def plot_work_precision(result: dict, path: Path) -> None:
    """Log-log wall time against error, one column per scene (rows: displacement, position)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    scenes = [s for s in result['scenes'].values() if not s.get('error')]
    n = max(len(scenes), 1)
    fig, axes = plt.subplots(2, n, figsize=(4.2 * n, 7.5), squeeze=False)
    for col, scene in enumerate(scenes):
        for row, measure in enumerate(('displacement', 'position')):
            ax = axes[row][col]
            for series in SERIES:
                pts = [(max(_f(r[f'err_{measure}']), FLOOR_ERR), _f(r['time']))
                       for r in scene['runs'] if r['series'] == series and r['status'] == 'ok']
                pts = sorted(p for p in pts if math.isfinite(p[0]) and math.isfinite(p[1]))
                if not pts:
                    continue
                c, m, ls = _STYLE.get(series, ('k', '.', '-'))
                ax.plot([p[0] for p in pts], [p[1] for p in pts], color=c, marker=m,
                        linestyle='none', markersize=5, alpha=0.45)
                front = _front(pts)
                ax.plot([p[0] for p in front], [p[1] for p in front], color=c, marker=m,
                        linestyle=ls, label=series, markersize=5)
            ax.set_xscale('log')
            ax.set_yscale('log')
            for thr in THRESHOLDS:
                ax.axvline(thr, color='0.85', linewidth=0.8, zorder=0)
            ax.set_title(f'{scene["name"]}' if row == 0 else '', fontsize=10)
            ax.set_xlabel(f'{measure} error [m]')
            if col == 0:
                ax.set_ylabel('wall time [s] (median of 3)')
            ax.grid(True, which='major', alpha=0.3)
    handles, labels = [], []
    for ax in axes.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    if handles:
        fig.legend(handles, labels, loc='lower center', ncol=4, fontsize=8)
    fig.suptitle('crawler_sim work-precision: every run (faint) and each series\' front '
                 '(errors against exact at its tightest tolerance; 1e-17 = exact zero)',
                 fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)
