"""Random sim_node sessions through the ROS-free engine: count solver fallbacks and stalls.

    python -m benchmarks.node_sessions [--sessions 300] [--seconds 10] [--seed 0] [--method exact]

(issue 14: "Inside sim_node the exact method stalls in about 7 % of random 10 s sessions ... and
the node falls back to the implicit method for the rest of the run"; floor: 300 random 10 s
sessions with 0 solver fallbacks.)

Each session is what a node gets, run through ``crawler_sim.core.plant.Engine`` exactly as
``sim_node`` runs it (1 kHz ticks, sync every 10 ticks, the actuator model): a random crawler
(p = 2..5, masses and friction forces over two decades, some direction-dependent, some on a
slope) and a random command stream mixing step commands (``Engine.command``) at random times and
timed trajectories (``Engine.trajectory``, positions only, with velocities, or with velocities
and accelerations), e.g. two ordinary trajectories 2 s apart, a trajectory cut short by a step
command, bursts of steps at the tick rate. Commands are applied at tick boundaries, like the
node's subscriptions between ticks.

A fallback is a session whose engine recorded a failure (the exact solver raised, the engine
redid the interval with the implicit method and stays on it); a stall is a failure whose message
says "stalled". Also counted: non-finite states and exceptions that escaped the engine (crashes).
Prints the figures and the first failures with their seeds (rerun one with --only SEED).
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time

import numpy as np


from crawler_sim.core.actuator import ActuatorLimits  # noqa: E402
from crawler_sim.core.plant import Engine, EngineConfig, PreparedTrajectory  # noqa: E402
from crawler_sim.core.model import Crawler  # noqa: E402

DT_NS = 1_000_000          # 1 kHz, the node's default integration rate
PUBLISH_EVERY = 10         # 100 Hz outputs


def random_crawler(rng: np.random.Generator) -> Crawler:
    p = int(rng.integers(2, 6))
    m = 10.0 ** rng.uniform(-1, 1, p)
    f = m * 9.81 * rng.uniform(0.05, 1.0, p)
    fb = f * 10.0 ** rng.uniform(-0.5, 0.5, p) if rng.random() < 0.4 else None
    slope = float(rng.uniform(-0.3, 0.3)) if rng.random() < 0.25 else 0.0
    return Crawler(m, f, fb, slope=slope)


def command_stream(rng: np.random.Generator, n_links: int, l0: np.ndarray, seconds: float):
    """[(tick, kind, payload)] sorted by tick: ('step', lengths) or ('traj', (times, pos, vel,
    acc)) with times relative to the tick."""
    ticks_per_s = 1_000_000_000 // DT_NS
    out = []
    style = rng.choice(['two_trajectories', 'mixed', 'steps', 'burst'])
    if style == 'two_trajectories':
        starts = [float(rng.uniform(0.0, 1.0))]
        starts.append(starts[0] + 2.0)
        starts += list(np.arange(starts[1] + 2.0, seconds, 2.0))
        kinds = ['traj'] * len(starts)
    elif style == 'steps':
        starts = list(np.sort(rng.uniform(0.0, seconds, int(rng.integers(3, 30)))))
        kinds = ['step'] * len(starts)
    elif style == 'burst':
        t0 = float(rng.uniform(0, seconds / 2))
        starts = list(t0 + np.arange(int(rng.integers(10, 200))) * 1e-3)
        starts += list(np.sort(rng.uniform(t0, seconds, 5)))
        kinds = ['step'] * len(starts)
    else:
        starts = list(np.sort(rng.uniform(0.0, seconds, int(rng.integers(3, 12)))))
        kinds = [str(rng.choice(['step', 'traj'])) for _ in starts]
    for t, kind in zip(starts, kinds):
        tick = int(round(t * ticks_per_s))
        if kind == 'step':
            out.append((tick, 'step', (l0 + rng.uniform(-0.05, 0.05, n_links)).tolist()))
            continue
        n = int(rng.integers(2, 40))
        period = float(rng.uniform(0.2, 1.5))
        times = np.sort(rng.uniform(0.0, rng.uniform(0.5, 3.0), n))
        times = np.unique(np.round(times, 4))
        if times[0] <= 0.0:
            times = times[1:] if times.size > 1 else times + 0.01
        w = 2 * math.pi / period
        amp = rng.uniform(0.005, 0.04, n_links)
        ph = rng.uniform(0, 2 * math.pi, n_links)
        arg = w * times[:, None] + ph
        pos = l0 + amp * np.sin(arg)
        order = int(rng.choice([1, 3, 5]))
        vel = (amp * w * np.cos(arg)).tolist() if order >= 3 else None
        acc = (-amp * w * w * np.sin(arg)).tolist() if order >= 5 else None
        out.append((tick, 'traj', (times.tolist(), pos.tolist(), vel, acc)))
    return sorted(out, key=lambda c: c[0])


def session(seed: int, seconds: float, method: str) -> dict:
    rng = np.random.default_rng(seed)
    crawler = random_crawler(rng)
    n = crawler.p - 1
    l0 = rng.uniform(0.08, 0.15, n)
    limits = ActuatorLimits(bandwidth=float(rng.uniform(2, 20)),
                            max_speed=float(rng.uniform(0.1, 1.0)),
                            max_acceleration=float(rng.uniform(1, 20)))
    cfg = EngineConfig(crawler, method, DT_NS, PUBLISH_EVERY, l0.tolist(), 0.0, limits)
    eng = Engine(cfg)
    cmds = command_stream(rng, n, l0, seconds)
    n_ticks = int(round(seconds * 1e9 / DT_NS))
    k_cmd = 0
    finite = True
    wall = time.perf_counter()
    crash = None
    try:
        for tick in range(n_ticks):
            while k_cmd < len(cmds) and cmds[k_cmd][0] <= tick:
                _, kind, payload = cmds[k_cmd]
                k_cmd += 1
                if kind == 'step':
                    eng.command(payload)
                else:
                    times, pos, vel, acc = payload
                    eng.trajectory(PreparedTrajectory(
                        0, np.rint(np.asarray(times) * 1e9).astype(np.int64), np.asarray(pos),
                        None if vel is None else np.asarray(vel),
                        None if acc is None else np.asarray(acc)))
            if eng.tick():
                st = eng.stepper.state
                if not (np.all(np.isfinite(st.x)) and np.all(np.isfinite(st.v))):
                    finite = False
                eng.pop_events()
    except Exception as exc:       # the node would die here
        crash = f'{type(exc).__name__}: {exc}'
    return {'seed': seed, 'p': crawler.p, 'failures': list(eng.failures), 'finite': finite,
            'crash': crash, 'wall': time.perf_counter() - wall,
            'method': eng.stepper.method}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--sessions', type=int, default=300)
    ap.add_argument('--seconds', type=float, default=10.0)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--method', default='exact')
    ap.add_argument('--only', type=int, default=None, help='run just this seed, verbosely')
    args = ap.parse_args(argv)
    seeds = [args.only] if args.only is not None else range(args.seed, args.seed + args.sessions)
    results = []
    for k, s in enumerate(seeds):
        r = session(s, args.seconds, args.method)
        results.append(r)
        if args.only is not None:
            print(r)
        elif (k + 1) % 25 == 0:
            nf = sum(bool(x['failures']) for x in results)
            print(f'  {k + 1} sessions, {nf} with a fallback', flush=True)
    fallbacks = [r for r in results if r['failures']]
    stalls = [r for r in fallbacks if any('stall' in f for f in r['failures'])]
    crashes = [r for r in results if r['crash']]
    nonfinite = [r for r in results if not r['finite']]
    walls = [r['wall'] for r in results]
    print(f'sessions: {len(results)} x {args.seconds:g} s, method {args.method}, seeds '
          f'{args.seed}..{args.seed + len(results) - 1}')
    print(f'fallbacks to implicit: {len(fallbacks)} ({100 * len(fallbacks) / len(results):.1f} %)'
          f', of which stalls: {len(stalls)}')
    print(f'crashes (exception out of the engine): {len(crashes)}; sessions with a non-finite '
          f'state: {len(nonfinite)}')
    print(f'wall time per session: median {statistics.median(walls):.2f} s, max '
          f'{max(walls):.2f} s (real-time factor median '
          f'{args.seconds / statistics.median(walls):.1f})')
    slow = max(results, key=lambda r: r['wall'])
    print(f'slowest session: seed {slow["seed"]} (p = {slow["p"]}), {slow["wall"]:.2f} s')
    for r in (fallbacks + crashes)[:8]:
        first = r['failures'][0] if r['failures'] else r['crash']
        print(f'  seed {r["seed"]} (p = {r["p"]}): {first[:160]}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
