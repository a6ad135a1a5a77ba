"""Custom gaits on short runs (issue 39): the cost of a run, sampling included, against the
built-in twin (a ``Fourier`` gait with the same coefficients), side by side in one process.

The gait of ``/work/shared/repro/edges/custom_short_run_cost.py``: 4 linkages (p = 5), 3 sines
each, ``jerk_bound`` given. Rows: the twin; a Custom gait of array functions
(``vectorized=True``, the floor of issue 39: a 2-period run within 3x the twin's total
time, side by side; printed PASS/FAIL; longer runs reported); of scalar numpy functions (the ratio and the calls of
each function per period reported); each without and with ``period=``. A fresh gait per run (its sampling is part of the run); CPU time
(``time.process_time``), the rows alternated, the median of ``--repeats`` runs; the largest
|x(T) - x_twin(T)| over the bodies. Then the twin and the vectorized row again, each run
``--repeats`` times in a row (back to back: warm caches, where the twin is cheapest).

    .venv/bin/python -m benchmarks.custom_cost [--repeats 15] [--periods 2 20]
"""
from __future__ import annotations

import argparse
import math
import statistics
import time
from typing import Callable

import numpy as np

import crawler_sim as cs

M = [0.32214265481906457, 1.3233142477828612, 0.3460440348196062, 0.5635376329751753,
     1.0795513567903388]
FP = [2.6962780458717375, 3.562737424176275, 0.6092766923305023, 2.1147750461498003,
      5.67442938436786]
FM = [0.7920362322531921, 2021.4032743892803, 0.11927776910765632, 0.017840544333890644,
      2.458213103405838]
A = np.array([[0.22271111969134033, 0.07214619556481011, 0.06892247506199921],
              [0.23053789872154304, 0.05413146969154331, 0.05732419573985716],
              [0.02884240038015743, 0.0072050712420788495, 0.004485965644187733],
              [0.2471649314188581, 0.11022752092137182, 0.019720056389155062]])
PH = np.array([[-0.0, 4.848969643964019, 2.672618798939015],
               [-6.20168000981606, 5.3053060589282985, 6.192937433835675],
               [-12.40336001963212, 2.8339158062921928, 0.8476768586308779],
               [-18.60504002944818, 1.138614384227177, 6.08477897437436]])
F = 2.2860994859374246
W = 2.0 * math.pi * F
K = np.arange(1, 4)
JB = [7885.608649147642, 6553.618036865727, 615.2630482871951, 4923.8656154366145]


class Counted:
    """A function that counts its calls (``calls``) and the times it was asked for
    (``points``)."""

    def __init__(self, fn: Callable) -> None:
        self.fn, self.calls, self.points = fn, 0, 0

    def __call__(self, t):
        self.calls += 1
        self.points += np.size(t)
        return self.fn(t)


def scalar_fns() -> tuple[Callable, Callable, Callable]:
    """l, l', l'' of one float time, (4,) each (the repro's lambdas)."""
    return (lambda t: 1.0 + (A * np.sin(K * W * t + PH)).sum(1),
            lambda t: (A * K * W * np.cos(K * W * t + PH)).sum(1),
            lambda t: -(A * (K * W) ** 2 * np.sin(K * W * t + PH)).sum(1))


def vector_fns() -> tuple[Callable, Callable, Callable]:
    """l, l', l'' of times (n,), (n, 4) each: the same sums over the 3 harmonics."""
    def arg(t):
        return K * W * np.asarray(t)[:, None, None] + PH          # (n, 4, 3)
    return (lambda t: 1.0 + (A * np.sin(arg(t))).sum(2),
            lambda t: (A * K * W * np.cos(arg(t))).sum(2),
            lambda t: -(A * (K * W) ** 2 * np.sin(arg(t))).sum(2))


def fourier() -> cs.gaits.Fourier:
    return cs.gaits.Fourier([1.0] * 4, (A * np.sin(PH), A * np.cos(PH)), F)


def custom(vectorized: bool, period: bool, counters: list | None = None) -> cs.gaits.Custom:
    fns = vector_fns() if vectorized else scalar_fns()
    if counters is not None:
        fns = tuple(Counted(fn) for fn in fns)
        counters.extend(fns)
    return cs.gaits.Custom(*fns, jerk_bound=JB, period=1.0 / F if period else None,
                           vectorized=vectorized)


ROWS = {
    'Fourier (twin)': fourier,
    'Custom vectorized': lambda: custom(True, False),
    'Custom vectorized period=': lambda: custom(True, True),
    'Custom scalar': lambda: custom(False, False),
    'Custom scalar period=': lambda: custom(False, True),
}


def run(crawler: cs.Crawler, make: Callable, horizon: float) -> tuple[float, int, np.ndarray]:
    """CPU time of making the gait and one run of ``horizon`` [s], events, x(T)."""
    t0 = time.process_time()
    tr = cs.simulate(crawler, make(), horizon, t_eval=[0.0, horizon], periodic_skip=False)
    return time.process_time() - t0, len(tr.events), np.asarray(tr.x[-1])


def calls_per_period(crawler: cs.Crawler, vectorized: bool, period: bool,
                     nper: int) -> str:
    """Calls (and times asked for) of l, l', l'' per period of a run of ``nper`` periods."""
    counters: list = []
    g = custom(vectorized, period, counters)
    cs.simulate(crawler, g, nper / F, t_eval=[0.0, nper / F], periodic_skip=False)
    return ', '.join(f'{name} {c.calls / nper:.1f} calls ({c.points / nper:.0f} times)'
                     for name, c in zip(("l", "l'", "l''"), counters))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=15)
    ap.add_argument('--periods', type=int, nargs='+', default=[2, 20])
    args = ap.parse_args()
    crawler = cs.Crawler(M, FP, FM)
    floors: list[bool] = []
    for nper in args.periods:
        horizon = nper / F
        for make in ROWS.values():          # untimed: imports, first compilations
            run(crawler, make, horizon)
        res: dict[str, list] = {name: [] for name in ROWS}
        for _ in range(args.repeats):
            for name, make in ROWS.items():
                res[name].append(run(crawler, make, horizon))
        twin = statistics.median(r[0] for r in res['Fourier (twin)'])
        x_twin = res['Fourier (twin)'][0][2]
        print(f'{nper} periods (median of {args.repeats}, CPU time, sampling included):')
        for name, rs in res.items():
            t = statistics.median(r[0] for r in rs)
            print(f'  {name:27s} {t * 1e3:8.3f} ms  {t / twin:6.2f}x twin  {rs[0][1]:4d} events'
                  f'  |x(T) - twin| {np.max(np.abs(rs[0][2] - x_twin)):.1e} m')
        # the same runs back to back (each row's runs in a row: warm caches, the twin's
        # fixed cost at its smallest, the sampling's share at its largest)
        warm = {}
        for name in ('Fourier (twin)', 'Custom vectorized'):
            warm[name] = statistics.median(run(crawler, ROWS[name], horizon)[0]
                                           for _ in range(args.repeats))
        print(f'  back to back: Custom vectorized {warm["Custom vectorized"] * 1e3:.3f} ms, '
              f'twin {warm["Fourier (twin)"] * 1e3:.3f} ms: '
              f'{warm["Custom vectorized"] / warm["Fourier (twin)"]:.2f}x')
        ratio = statistics.median(r[0] for r in res['Custom vectorized']) / twin
        if nper <= 2:
            floors.append(ratio <= 3.0)
            print(f'  floor: Custom vectorized within 3x its twin side by side: {ratio:.2f}x '
                  f'{"PASS" if floors[-1] else "FAIL"}')
        else:
            print(f'  Custom vectorized / twin side by side: {ratio:.2f}x (no floor)')
        for vec in (True, False):
            for per in (False, True):
                print(f'  per period, {"vectorized" if vec else "scalar"}'
                      f'{" period=" if per else ""}: {calls_per_period(crawler, vec, per, nper)}')
    print(f'all floors: {"PASS" if all(floors) else "FAIL"}')


if __name__ == '__main__':
    main()
