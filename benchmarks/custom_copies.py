"""Differential check of the Custom gait's compiled path: a built-in gait (Scallop, Fourier,
Sinusoid) run with its rigorous bounds against the same functions as ``Custom`` lambdas, which
the solver samples into Chebyshev pieces (``crawler_sim/core/solvers/proxy.py``).

Random two- to four-body scenes (masses and frictions over two decades, direction-dependent
friction in half of them, v0 != 0 in 30 %), 1-4 periods, 9 samples; a case is bad when the two
runs differ by more than 1e-10 m anywhere, or either raises.

    .venv/bin/python -m benchmarks.custom_copies --cases 300 --seed 1
    .venv/bin/python -m benchmarks.custom_copies --cases 300 --seed 77 --min-asymmetry 0.001
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

import crawler_sim as cs

G = cs.gaits


def _case(rng: np.random.Generator, k: int, r_min: float):
    p = int(rng.integers(2, 5))
    n = p - 1
    m = 10 ** rng.uniform(-1, 1, p)
    f = 10 ** rng.uniform(-1, 1, p)
    fb = f * (10 ** rng.uniform(-0.5, 0.5, p) if rng.random() < 0.5 else 1)
    crawler = cs.Crawler(m, f, friction_backward=fb)
    mean, amp = rng.uniform(0.5, 1.5, n), rng.uniform(0.05, 0.3, n)
    freq = float(rng.uniform(0.5, 3))
    if k % 3 == 0:
        r = float(10 ** rng.uniform(math.log10(r_min), math.log10(0.5)))
        g = G.Scallop(mean, amp, freq, r, rng.uniform(0, 2 * math.pi, n))
    elif k % 3 == 1:
        K = int(rng.integers(2, 6))
        a = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
        b = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
        g = G.Fourier(mean, (a, b), freq)
    else:
        g = G.Sinusoid(mean, amp, freq, rng.uniform(0, 2 * math.pi, n))
    T = float(rng.uniform(1, 4)) / freq
    v0 = float(rng.normal(0, 0.3)) if rng.random() < 0.3 else 0.0
    return crawler, g, T, v0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--cases', type=int, default=300)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--min-asymmetry', type=float, default=0.02,
                    help='smallest Scallop asymmetry drawn (log-uniform up to 0.5)')
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    bad, worst, t0 = 0, 0.0, time.perf_counter()
    for k in range(args.cases):
        crawler, g, T, v0 = _case(rng, k, args.min_asymmetry)
        copy = G.Custom(lambda t, g=g: g.at(t)[0], lambda t, g=g: g.at(t)[1],
                        lambda t, g=g: g.at(t)[2])
        te = np.linspace(0.0, T, 9)
        try:
            a = cs.simulate(crawler, g, T, t_eval=te, v0=v0).x
            b = cs.simulate(crawler, copy, T, t_eval=te, v0=v0).x
        except Exception as exc:  # noqa: BLE001 (a failure of either run is a result)
            bad += 1
            print(f'case {k}: {type(g).__name__} {type(exc).__name__}: {exc}')
            continue
        err = float(np.max(np.abs(a - b)))
        worst = max(worst, err)
        if err > 1e-10:
            bad += 1
            print(f'case {k}: {type(g).__name__} differs by {err:.3g} m')
    print(f'cases {args.cases}, bad {bad}, largest difference {worst:.3g} m, '
          f'{time.perf_counter() - t0:.0f} s')


if __name__ == '__main__':
    main()
