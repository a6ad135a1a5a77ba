"""The replay floor of issue 24: random recorded sim_node sessions replay with max |dx| = 0.

    python -m benchmarks.replay_sessions [--sessions 50] [--seed 0]
        [--actions 25] [--bag runs/crawl_...]

Each session (``test/ros/sessions.py``) is a real SimNode on real DDS, recording, driven by a
random mix of commands, trajectories, parameter changes (p included), pauses, resets and
reads of the state between publish ticks; then ``crawler-sim replay``'s comparison runs on the
bag. ``--bag`` adds bags written elsewhere (e.g. by ``make run``). Prints per session the
inputs replayed and max |dx|, |dv|, and the worst over all (floor: 0).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import tempfile
import time

REPO = Path(__file__).resolve().parents[1]

from crawler_sim import bag  # noqa: E402
from crawler_sim.cli import _replay  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--sessions', type=int, default=50)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--actions', type=int, default=25)
    ap.add_argument('--bag', nargs='*', default=[], type=Path)
    args = ap.parse_args(argv)
    from test.support.sessions import run_session
    worst = 0.0
    rows = 0
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        start = time.perf_counter()
        for k in range(args.sessions):
            paths.append(run_session(args.seed + k, Path(tmp), 90 + k % 9, args.actions))
        wall = time.perf_counter() - start
        for path in [*paths, *args.bag]:
            run = bag.load(path)
            res = _replay(run, None, 0.0)
            err = max(res['max_position_error'], res['max_velocity_error'])
            worst = max(worst, err)
            rows += len(run.t)
            print(f'{path.name:<28} {len(run.t):6d} samples  {res["inputs"]:<90.90} '
                  f'max|dx| {res["max_position_error"]:.3g} max|dv| '
                  f'{res["max_velocity_error"]:.3g}')
    print(f'{args.sessions} sessions ({wall:.1f} s) + {len(args.bag)} bags, {rows} samples: '
          f'worst |dx|, |dv| = {worst:.3g} (floor 0)')
    return 0 if worst == 0.0 else 1


if __name__ == '__main__':
    raise SystemExit(main())
