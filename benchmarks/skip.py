"""periodic_skip on, off and the default (None: decided from the scene), side by side (issue 39).

Scallop strokes (2 Hz, 20 % extension) of p = 2, 3 and 8 bodies, runs of 10, 100 and 1,000 s;
CPU time of ``simulate`` (default output: 1001 samples plus every event), medians of rounds in
which the three settings run in turn in this process, the garbage of the runs before collected
ahead of each timed run (a 1,000 s run builds ~50,000 Event objects: without the collection a
full collection fell in the same setting's run of every round, +45 % there, whichever setting
ran third). The floor: the default never more than 1.1x the faster of on and off.

    .venv/bin/python -m benchmarks.skip [--repeats 9]
"""
from __future__ import annotations

import argparse
import gc
import statistics
import time

import numpy as np

import crawler_sim as cs

SETTINGS = (('on', True), ('off', False), ('default', None))


def scene(p: int) -> tuple[cs.Crawler, cs.gaits.Gait]:
    """p bodies of 0.5-1 kg on mu = 0.3, one Scallop stroke per linkage, phases spread."""
    crawler = cs.Crawler.from_coefficients(np.linspace(0.5, 1.0, p), 0.3)
    gait = cs.gaits.Scallop(mean=0.1, amplitude=0.02, frequency=2.0, asymmetry=0.2,
                            phase=np.linspace(0.0, -2.0, p - 1))
    return crawler, gait


def measure(p: int, t_end: float, repeats: int) -> dict[str, float]:
    """{setting: median CPU seconds} of ``simulate`` over [0, t_end]."""
    crawler, gait = scene(p)
    times: dict[str, list[float]] = {name: [] for name, _ in SETTINGS}
    for _ in range(repeats + 1):
        for name, skip in SETTINGS:
            gc.collect()            # the debt of the runs before is not this run's cost
            t0 = time.process_time()
            cs.simulate(crawler, gait, t_end, periodic_skip=skip)
            times[name].append(time.process_time() - t0)
    return {k: statistics.median(v[1:]) for k, v in times.items()}     # the first: warm-up


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=9)
    args = ap.parse_args()
    print(f'{"p":>2} {"t_end":>6} {"on ms":>9} {"off ms":>9} {"default ms":>10} '
          f'{"default / faster":>16}')
    worst = 0.0
    for p in (2, 3, 8):
        for t_end in (10.0, 100.0, 1000.0):
            m = measure(p, t_end, args.repeats if t_end < 1000 else max(3, args.repeats // 3))
            ratio = m['default'] / min(m['on'], m['off'])
            worst = max(worst, ratio)
            print(f'{p:2d} {t_end:6g} {m["on"] * 1e3:9.3f} {m["off"] * 1e3:9.3f} '
                  f'{m["default"] * 1e3:10.3f} {ratio:16.2f}', flush=True)
    print(f'worst default / faster: {worst:.2f} (floor 1.10)')


if __name__ == '__main__':
    main()
