"""Every path of the core, measured side by side (issue 23 floors).

* exact, cost per event of each gait family against the Fourier gait's, p = 2 and p = 3 (the
  same run of this script; ratios), each over ``periods`` seconds (20: the periodic gaits'
  20 periods, a PiecewiseCubic of 5 ms pieces over as long), and the PiecewiseCubic over its
  first second (200 pieces, 9-11 events: the scene of earlier figures, where the fixed cost
  of a ``simulate`` call, printed as "set-up", is most of its run; also against the Fourier
  gait's first second, the same span);
* implicit and penalty with their default output (every step): steps per second, p = 2 and 3,
  on Scallop and bang-bang (PiecewiseParabolic.stroke) gaits, and the README's example;
* first use: a fresh interpreter's first ``simulate`` of each gait kind and method.

Each timing is a median in this process. The exact table's: rounds in which every gait runs in
turn, once after the others (cold: "cold x", its tables and code out of the caches) and three
times more (warm: the main figure, a gait run again as a loop or a sweep does; "net of the
set-up": each further event's cost, the call's fixed set-up taken off both sides), at least
``--repeats`` rounds and 1 s of them, so its ratios do not move with the load drifting between
runs; the others over ``--repeats`` runs after an untimed one.

    .venv/bin/python -m benchmarks.core_paths [--repeats 5] [--quick]
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import time

import numpy as np

import crawler_sim as cs
from crawler_sim.core.solvers.exact import ExactSolver

G = cs.gaits


MIN_ROUNDS_S = 1.0      # s of timed rounds of a side-by-side table at least


def _median(fn, repeats: int) -> float:
    fn()                                  # warm-up, not timed
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def _medians(fns: dict, repeats: int, block: int = 3) -> dict:
    """{name: (warm, cold)} median times [s] of each of ``fns`` run side by side: rounds in
    which each runs once after the others ran (cold: its tables and code left the caches),
    then ``block`` times more (warm: a gait run again, as a sweep or a loop does), at least
    ``repeats`` rounds and ``MIN_ROUNDS_S`` seconds of them. Ratios of medians so taken do
    not move with the machine's load drifting between the runs they compare."""
    times: dict = {k: ([], []) for k in fns}
    start, rounds = time.perf_counter(), 0
    while rounds < repeats or time.perf_counter() - start < MIN_ROUNDS_S:
        for k, fn in fns.items():
            warm, cold = times[k]
            for i in range(block + 1):
                t0 = time.perf_counter()
                fn()
                (warm if i else cold).append(time.perf_counter() - t0)
        rounds += 1
    return {k: (statistics.median(w), statistics.median(c)) for k, (w, c) in times.items()}


def families(p: int, seconds: float = 20.0) -> dict:
    """One gait per family for p bodies (period 1 s, lengths around 1 m; the PiecewiseCubic's
    5 ms pieces of random jerk cover ``seconds``, its first second apart)."""
    n = p - 1
    w = 2 * math.pi
    phase = -0.9 * np.arange(n)
    sc = G.Scallop(1.0, 0.25, 1.0, 0.2, phase, n_links=n)
    fns = (lambda t: 1.0 + 0.25 * np.sin(w * t + phase),
           lambda t: 0.25 * w * np.cos(w * t + phase),
           lambda t: -0.25 * w * w * np.sin(w * t + phase))
    if n == 1:
        fns = (lambda t: 1.0 + 0.25 * math.sin(w * t), lambda t: 0.25 * w * math.cos(w * t),
               lambda t: -0.25 * w * w * math.sin(w * t))
    tk = np.linspace(0.0, 1.0, 17)
    y = 1.0 + 0.25 * np.sin(w * tk[:, None] + phase)
    y[-1] = y[0]
    starts = np.arange(round(max(seconds, 1.0) / 0.005)) * 0.005
    pieces, l, v, a = [], np.full(n, 1.0), np.zeros(n), np.zeros(n)
    rng = np.random.default_rng(1)
    for t0 in starts:
        jerk = rng.uniform(-80, 80, n) - 40 * (l - 1.0) - 10 * v
        pieces.append(G.Cubic(t0, l, v, a, jerk))
        l, v, a = G.cubic_values(l, v, a, jerk, 0.005)
    return {
        'Fourier': G.Fourier(np.ones(n), (np.zeros((n, 2)), np.tile([0.25, 0.05], (n, 1))), 1.0),
        'Sinusoid': G.Sinusoid(1.0, 0.25, 1.0, phase, n_links=n),
        'Scallop': sc,
        'PiecewiseParabolic': G.PiecewiseParabolic.stroke(1.0, 0.25, 1.0, 0.3, n_links=n),
        'Spline': G.Spline(tk, y, periodic=True),
        'PiecewiseCubic': G.PiecewiseCubic(starts, pieces),
        'PiecewiseCubic 1 s': G.PiecewiseCubic(starts[:200], pieces[:200]),
        'Custom': G.Custom(*fns),
        'Custom jerk_bound': G.Custom(*fns, jerk_bound=0.25 * w ** 3),
        'Custom breakpoints': G.Custom(*fns, breakpoints=[0.25, 0.75]),
        'Custom period': G.Custom(*fns, period=1.0),
    }


def exact_per_event(p: int, repeats: int, periods: float) -> list[dict]:
    rng = np.random.default_rng(p)
    m = rng.uniform(0.5, 2.0, p)
    crawler = cs.Crawler(m, rng.uniform(0.5, 2.0, p) * m)
    rows, runs = [], {}
    fam = families(p, periods)
    # the first second of the Fourier gait too: the same span as the PiecewiseCubic's first
    # second, so their costs per event carry the same share of a call's set-up
    fam['Fourier 1 s'] = fam['Fourier']
    for name, gait in fam.items():
        t_end = {'PiecewiseCubic': periods - 0.001}.get(name, 0.999 if name.endswith(' 1 s')
                                                        else periods)
        # the search's evaluations of the gait per event: the part of the cost that the
        # machine's noise does not move
        solver = ExactSolver(crawler, gait, periodic_skip=False)
        solver.advance(t_end)
        n_ev = max(len(solver.events), 1)
        runs[name] = (lambda g=gait, te=t_end: cs.simulate(crawler, g, te, t_eval=[0.0, te],
                                                           periodic_skip=False))
        rows.append({'p': p, 'gait': name, 'events': n_ev,
                     'evals_per_event': solver.n_evals / n_ev})
    # the fixed cost of one call: a run of 1 us of the Fourier gait (no event)
    four = families(p, 1.0)['Fourier']
    runs['set-up'] = lambda: cs.simulate(crawler, four, 1e-6, t_eval=[0.0, 1e-6],
                                         periodic_skip=False)
    times = _medians(runs, repeats)
    for r in rows:
        r['time_s'], r['cold_time_s'] = times[r['gait']]
        r['us_per_event'] = 1e6 * r['time_s'] / r['events']
    base = next(r for r in rows if r['gait'] == 'Fourier')
    setup = times['set-up'][0]
    for r in rows:
        r['ratio_vs_fourier'] = r['us_per_event'] / base['us_per_event']
        r['cold_ratio_vs_fourier'] = (r['cold_time_s'] / r['events']) / (
            base['cold_time_s'] / base['events'])
        # net of a call's set-up (gait-independent): what each further event costs, the
        # figure for a run of few events (the PiecewiseCubic's first second)
        r['net_ratio_vs_fourier'] = ((r['time_s'] - setup) / r['events']) / (
            (base['time_s'] - setup) / base['events'])
    short = next(r for r in rows if r['gait'] == 'Fourier 1 s')
    for r in rows:
        if r['gait'].endswith(' 1 s'):
            r['same_span_ratio'] = r['us_per_event'] / short['us_per_event']
    rows.append({'p': p, 'gait': 'set-up', 'events': 0, 'time_s': times['set-up'][0],
                 'cold_time_s': times['set-up'][1], 'us_per_event': math.nan,
                 'evals_per_event': math.nan, 'ratio_vs_fourier': math.nan,
                 'cold_ratio_vs_fourier': math.nan, 'net_ratio_vs_fourier': math.nan})
    return rows


def stepping(repeats: int, t_end: float) -> list[dict]:
    rows = []
    for p in (2, 3):
        n = p - 1
        crawler = cs.Crawler(np.linspace(1.0, 1.5, p), np.linspace(1.0, 2.0, p))
        for gname, gait in (('Scallop', G.Scallop(1.0, 0.25, 1.0, 0.2, n_links=n)),
                            ('bang-bang', G.PiecewiseParabolic.stroke(1.0, 0.25, 1.0, 0.3,
                                                                      n_links=n))):
            for method, kw in (('implicit', {}), ('penalty', {'penalty': 1e5})):
                dt = 1e-4
                t = _median(lambda: cs.simulate(crawler, gait, t_end, method, dt=dt, **kw),
                            repeats)
                rows.append({'p': p, 'gait': gname, 'method': method, 'dt': dt,
                             'steps': round(t_end / dt), 'time_s': t,
                             'steps_per_s': t_end / dt / t})
    return rows


def readme_example(repeats: int) -> float:
    crawler = cs.Crawler([1.0, 2.0], [0.5, 1.0])
    gait = G.Scallop(1.0, 0.3, 1.0, 0.2)
    return _median(lambda: cs.simulate(crawler, gait, 20.0, method='implicit', dt=1e-4),
                   repeats)


_FIRST = '''
import time; t0 = time.perf_counter()
import math, crawler_sim as cs
G = cs.gaits
w = 2 * math.pi
gaits = {{'Fourier': G.Fourier(1.0, ([0.0], [0.3]), 1.0), 'Scallop': G.Scallop(1.0, 0.3, 1.0, 0.2),
          'PiecewiseParabolic': G.PiecewiseParabolic.stroke(1.0, 0.3, 1.0, 0.3),
          'Custom': G.Custom(lambda t: 1 + 0.3 * math.sin(w * t), lambda t: 0.3 * w * math.cos(w * t),
                             lambda t: -0.3 * w * w * math.sin(w * t))}}
kw = {{'implicit': {{}}, 'penalty': {{'penalty': 1e5}}, 'exact': {{}}}}['{method}']
cs.simulate(cs.Crawler([1, 1], [0.5, 1]), gaits['{gait}'], 2.0, '{method}', **kw)
print(time.perf_counter() - t0)
'''


def first_use() -> list[dict]:
    rows = []
    for gait in ('Fourier', 'Scallop', 'PiecewiseParabolic', 'Custom'):
        for method in ('exact', 'implicit', 'penalty'):
            out = subprocess.run([sys.executable, '-c', _FIRST.format(gait=gait, method=method)],
                                 capture_output=True, text=True, check=True)
            rows.append({'gait': gait, 'method': method, 'first_simulate_s':
                         float(out.stdout.strip().splitlines()[-1])})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--quick', action='store_true', help='fewer periods and steps')
    args = ap.parse_args()
    periods = 5.0 if args.quick else 20.0
    report = {'exact': exact_per_event(2, args.repeats, periods)
              + exact_per_event(3, args.repeats, periods),
              'stepping': stepping(args.repeats, 2.0 if args.quick else 20.0),
              'readme_implicit_example_s': readme_example(args.repeats),
              'first_use': first_use()}
    for r in report['exact']:
        if r['gait'] == 'set-up':
            print(f"exact p={r['p']} set-up: a simulate call of 1 us, "
                  f"{1e6 * r['time_s']:.1f} us (cold {1e6 * r['cold_time_s']:.1f} us)")
            continue
        same = (f", x{r['same_span_ratio']:.2f} vs Fourier's first second"
                if 'same_span_ratio' in r else '')
        print(f"exact p={r['p']} {r['gait']:20s} {r['events']:6d} events "
              f"{r['us_per_event']:8.2f} us/event  x{r['ratio_vs_fourier']:.2f} vs Fourier  "
              f"(cold x{r['cold_ratio_vs_fourier']:.2f}, net of the set-up "
              f"x{r['net_ratio_vs_fourier']:.2f}{same})  "
              f"{r['evals_per_event']:5.1f} evaluations/event")
    for r in report['stepping']:
        print(f"{r['method']:8s} p={r['p']} {r['gait']:10s} {r['steps_per_s']:.3g} steps/s "
              f"(default output, every step; {r['steps']} steps in {r['time_s']:.3f} s)")
    print(f"README example simulate(..., 20.0, method='implicit', dt=1e-4): "
          f"{report['readme_implicit_example_s']:.3f} s")
    for r in report['first_use']:
        print(f"first use {r['gait']:20s} {r['method']:8s} {r['first_simulate_s']:.2f} s")
    print(json.dumps(report))


if __name__ == '__main__':
    main()
