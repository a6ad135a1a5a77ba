"""Benchmark of ``crawler_sim.bag.load`` on a one-hour recording at 100 Hz (prints figures).

    python -m crawler_sim.bench.bag_bench [--steps 360000] [--dir /tmp/bag_hour]

Writes a synthetic bag with the node's topics (p = 3, one state per 10 ms of sim time: one hour
= 360,000 steps, about 1.4 million messages) once, then times ``load`` five times (wall and CPU,
median and best) and checks the arrays against the written ones. Floor (issue 5): under 2 s.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import statistics
import time

import numpy as np

from ..bag import load, record_arrays


def write_hour(out: Path, steps: int) -> dict:
    """Write the synthetic bag; returns the arrays written."""
    shutil.rmtree(out, ignore_errors=True)
    p = 3
    rng = np.random.default_rng(1)
    t = np.arange(steps) * 0.01
    arrays = {'t': t, 'x': np.cumsum(rng.normal(size=(steps, p)) * 1e-3, axis=0),
              'v': rng.normal(size=(steps, p)), 'friction': rng.normal(size=(steps, p)),
              'contact': rng.integers(-1, 2, size=(steps, p)).astype(np.int8),
              'lengths': rng.normal(size=(steps, p - 1)), 'rates': rng.normal(size=(steps, p - 1)),
              'linkage_force': rng.normal(size=(steps, p - 1))}
    w = record_arrays(out, **arrays, commands=(t[::500], arrays['lengths'][::500]),
                      scene={'p': p, 'masses': [1.0] * p}, masses=[1.0] * p)
    arrays['messages'] = w.message_count
    return arrays


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--steps', type=int, default=360_000, help='states (100 Hz: 360000 = 1 h)')
    ap.add_argument('--dir', default='/tmp/crawler_sim_bag_hour', help='where to write the bag')
    args = ap.parse_args(argv)
    out = Path(args.dir)
    t0 = time.perf_counter()
    ref = write_hour(out, args.steps)
    print(f'wrote {ref["messages"]} messages ({args.steps} states) in '
          f'{time.perf_counter() - t0:.1f} s to {out}')
    wall, cpu = [], []
    for _ in range(5):
        w0, c0 = time.perf_counter(), time.process_time()
        run = load(out)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    same = all(np.array_equal(getattr(run, k), ref[k])
               for k in ('x', 'v', 'friction', 'contact', 'lengths', 'linkage_force'))
    print(f'load: median wall {statistics.median(wall):.3f} s (best {min(wall):.3f} s), '
          f'median CPU {statistics.median(cpu):.3f} s; arrays identical: {same}; floor 2 s')
    return 0 if same else 1


if __name__ == '__main__':
    raise SystemExit(main())
