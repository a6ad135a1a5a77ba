"""The exact method's cost per event with stiction against the same scenes without (issue 40).

Random scenes of p = 2, 3 and 8 bodies (masses 0.5-2 kg, kinetic friction mu m g with mu in
0.05-0.4 forward and backward, a Sinusoid per linkage of amplitude 0.02-0.1 m, 1-2 Hz, random
phase: bodies stick and slip in turn), each run twice:
with static bounds drawn up to 2x the kinetic ones (each body and direction: x U(1, 2)) and with
static = kinetic (today's path). CPU time (``time.process_time``) of ``Stepper.advance`` over
[0, t_end] with the periodic skip off, divided by the segments integrated (each ends at an event
or a breakpoint); median of rounds in which the two variants run in turn in this process. The
floor: stiction within 1.5x of static = kinetic at every p.

    .venv/bin/python -m benchmarks.stiction [--repeats 7] [--scenes 6] [--t-end 20]
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import crawler_sim as cs

FLOOR = 1.5


def scenes(p: int, n: int, seed: int = 40) -> list[tuple[cs.Crawler, cs.Crawler, object]]:
    """n random (stiction crawler, the same with static = kinetic, gait) of p bodies."""
    rng = np.random.default_rng(seed + p)
    out = []
    for _ in range(n):
        # friction of the order of the linkages' inertial forces (m amplitude (2 pi freq)^2):
        # bodies stick and slip in turn, so Rule S decides at many events
        m = 10.0 ** rng.uniform(-0.3, 0.3, p)
        f, fb = (m * 9.81 * rng.uniform(0.05, 0.4, p) for _ in range(2))
        sticky = cs.Crawler(m, f, fb, static_friction=f * rng.uniform(1, 2, p),
                            static_friction_backward=fb * rng.uniform(1, 2, p))
        plain = cs.Crawler(m, f, fb)
        gait = cs.gaits.Sinusoid(mean=1.0, amplitude=rng.uniform(0.02, 0.1, p - 1),
                                 frequency=float(rng.uniform(1.0, 2.0)),
                                 phase=rng.uniform(0, 2 * np.pi, p - 1))
        out.append((sticky, plain, gait))
    return out


def run(crawler: cs.Crawler, gait, t_end: float) -> tuple[float, int, int]:
    """(CPU seconds, segments, instants where Rule S chose) of one exact run to t_end."""
    st = cs.Stepper(crawler, gait, periodic_skip=False)
    t0 = time.process_time()
    st.advance(t_end)
    return time.process_time() - t0, st.solver.n_segments, st.solver.n_choices


def measure(p: int, n_scenes: int, t_end: float, repeats: int) -> dict[str, float]:
    """{variant: median microseconds per segment} over rounds of every scene."""
    cases = scenes(p, n_scenes)
    per: dict[str, list[float]] = {'stiction': [], 'kinetic': []}
    segs: dict[str, int] = {}
    choices = 0
    for k in range(repeats + 1):
        for name, idx in (('stiction', 0), ('kinetic', 1)):
            cpu, n, choices = 0.0, 0, 0 if idx == 0 else choices
            for case in cases:
                c, s, ch = run(case[idx], case[2], t_end)
                cpu += c
                n += s
                choices += ch
            segs[name] = n
            if k:                   # the first round warms up
                per[name].append(1e6 * cpu / n)
    out = {name: statistics.median(v) for name, v in per.items()}
    out.update({f'{name}_segments': float(n) for name, n in segs.items()})
    out['choices'] = float(choices)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=7)
    ap.add_argument('--scenes', type=int, default=6)
    ap.add_argument('--t-end', type=float, default=20.0)
    args = ap.parse_args()
    print(f'{"p":>2} {"segments (stiction / kinetic)":>30} {"Rule S choices":>14} '
          f'{"us/event stiction":>18} {"us/event kinetic":>17} {"ratio":>6}')
    worst = 0.0
    for p in (2, 3, 8):
        r = measure(p, args.scenes, args.t_end, args.repeats)
        ratio = r['stiction'] / r['kinetic']
        worst = max(worst, ratio)
        segs = f'{int(r["stiction_segments"])} / {int(r["kinetic_segments"])}'
        print(f'{p:>2} {segs:>30} {int(r["choices"]):>14} {r["stiction"]:>18.2f} '
              f'{r["kinetic"]:>17.2f} {ratio:>6.2f}')
    print(f'worst ratio {worst:.2f} (floor: <= {FLOOR}) -> {"holds" if worst <= FLOOR else "FAILS"}')
    print(f'reproduce: .venv/bin/python -m benchmarks.stiction --repeats {args.repeats} '
          f'--scenes {args.scenes} --t-end {args.t_end:g}')


if __name__ == '__main__':
    main()
