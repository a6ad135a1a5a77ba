"""Bag benchmarks (print figures).

    python -m benchmarks.bag [--steps 360000] [--dir /tmp/bag_hour]
    python -m benchmarks.bag --hostile --kill [--kills 30]
    python -m benchmarks.bag --writer [--messages 200000]
    python -m benchmarks.bag --encode [--bodies 3]
    python -m benchmarks.bag --offline [--t-end 20]

Default: writes a synthetic bag with the node's topics (p = 3, one state per 10 ms of sim time:
one hour = 360,000 steps, about 1.4 million messages) once, then times ``load`` five times (wall
and CPU, median and best) and checks the arrays against the written ones. Floor (issue 5): 2 s.

``--hostile``: for each crafted file of :mod:`crawler_sim.bag.crafted` (1 MB) and for a real
recording, ``load``/``info``/``recover`` in a fresh process each: peak traced allocation
(tracemalloc, after a warm-up call) and peak RSS growth, against the file size. Floor (issue
11): under 4x the file size.

``--kill``: a recorder process writes one state per 10 ms of wall time (sim time = wall time
since it created the bag) and is killed with SIGKILL at a uniformly random moment in the first
3 s (so a third of the kills fall in the first second); the loss is the kill time minus the last
state on disk. Floor (issue 11): <= 1 s at any moment.

``--writer``: us per recorded message of the MCAP writers, in one process, alternating:
``mcap.writer.Writer.add_message`` against :class:`crawler_sim.bag.mcapwriter.McapWriter`
(the same messages: 150 bytes of noise on 5 channels, 1 MiB zstd chunks, into memory; finish
included). The figure the McapWriter module doc quotes; no floor.

``--encode``: us per message of each output of the node (p bodies, a new state each message):
:class:`crawler_sim.ros.messages.OutputEncoder` (the one CDR encoder,
:class:`crawler_sim.bag.cdr.Encoder`) against building the message and
``serialize_message``, which is what it replaces; no floor.

``--offline``: the README's recorded offline run (issue 43), ``crawler-sim simulate
config/scenes/slope_climb.yaml --method implicit --dt 1e-4 --out DIR`` (200,001 samples),
then ``plot`` and ``export --csv``/``--parquet`` of that bag, each step in CPU seconds in this
process (imports done first), median of 3 with the best: the simulation, the recording
(``record_trajectory``, columnar), ``load``, the figure (drawn and saved) and the tables
(frames and written). Floors (issue 43): recording at most 2 s beyond the run; plot and
export under 2 s each.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import random
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

from crawler_sim.bag import load, record_arrays


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


# ---------------------------------------------------------------- --kill

def child_record(record_dir: str) -> None:
    """The recorder that --kill kills: one state per 10 ms, sim time = wall time since t0."""
    from crawler_sim.bag import Recorder
    rec = Recorder.create(record_dir, 'run', masses=[1.0, 1.0], scene={'masses': [1.0, 1.0]})
    t0 = time.monotonic()
    print('created', repr(t0), flush=True)
    while True:
        t = time.monotonic() - t0
        rec.record_state(t, [t, t + 0.1], [1.0, 1.0], [0.0, 0.0], [1, 1], [0.1], [0.0], [0.0])
        print(repr(t), flush=True)          # recorded (returned from the writer)
        time.sleep(0.01)


def kill_once(where: Path, delay: float) -> tuple[float, float]:
    """SIGKILL the recorder ``delay`` s after it created its bag.

    Returns (loss of the run, loss of recorded states) [s]: the kill time, and the last state
    the recorder had written, minus the last state on disk. They differ when the machine
    starves the recorder (states not produced are not lost by the bag).
    """
    from crawler_sim.bag import load
    env = dict(os.environ)
    env.pop('AMENT_PREFIX_PATH', None)
    proc = subprocess.Popen([sys.executable, '-m', 'benchmarks.bag', '--child',
                             str(where)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        t0 = float(proc.stdout.readline().split()[1])
        time.sleep(max(0.0, t0 + delay - time.monotonic()))
        proc.send_signal(signal.SIGKILL)
        t_kill = time.monotonic() - t0          # CLOCK_MONOTONIC is system-wide on Linux
    finally:
        proc.kill()
        proc.wait()
    printed = [float(line) for line in proc.stdout.read().split()]   # all written before the kill
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        run = load(where / 'run')
    on_disk = float(run.t[-1]) if len(run) else 0.0
    return t_kill - on_disk, (printed[-1] if printed else 0.0) - on_disk


def bench_kill(kills: int, seed: int) -> dict:
    rng = random.Random(seed)
    losses, recorded, first = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(kills):
            delay = rng.uniform(0.0, 3.0)
            loss, lost_recorded = kill_once(Path(tmp) / f'k{k}', delay)
            losses.append(loss)
            recorded.append(lost_recorded)
            if delay < 1.0:
                first.append(loss)
    return {'kills': kills, 'median_s': statistics.median(losses), 'worst_s': max(losses),
            'over_1s': sum(x > 1.0 for x in losses), 'first_second_kills': len(first),
            'first_second_worst_s': max(first) if first else None,
            'recorded_median_s': statistics.median(recorded), 'recorded_worst_s': max(recorded),
            'recorded_over_1s': sum(x > 1.0 for x in recorded)}


# ---------------------------------------------------------------- --writer

def writer_us_per_message(make, messages: int, size: int = 150, channels: int = 5) -> float:
    """us per message of ``make(stream)``'s add_message (and finish) for ``messages``
    messages of ``size`` bytes, round robin over ``channels`` channels, 10 ms apart."""
    import io
    rng = np.random.default_rng(1)
    payloads = [rng.integers(0, 256, size=size, dtype=np.uint8).tobytes() for _ in range(64)]
    w = make(io.BytesIO())
    w.start(profile='ros2', library='benchmark')
    sid = w.register_schema('a/msg/B', 'ros2msg', b'float64 x')
    ids = [w.register_channel(f'/t{k}', 'cdr', sid, {}) for k in range(channels)]
    t0 = time.perf_counter()
    for i in range(messages):
        t = i * 10_000_000
        w.add_message(ids[i % channels], t, payloads[i & 63], t)
    w.finish()
    return (time.perf_counter() - t0) / messages * 1e6


def bench_writer(messages: int, rounds: int = 3) -> dict[str, float]:
    """Median us per message of each writer over ``rounds`` alternated runs."""
    from mcap.writer import CompressionType, Writer
    from crawler_sim.bag.mcapwriter import McapWriter
    makers = {'mcap.writer.Writer': lambda out: Writer(out, compression=CompressionType.ZSTD),
              'McapWriter': lambda out: McapWriter(out)}
    times: dict[str, list[float]] = {name: [] for name in makers}
    for _ in range(rounds):
        for name, make in makers.items():
            times[name].append(writer_us_per_message(make, messages))
    return {name: statistics.median(t) for name, t in times.items()}


# ---------------------------------------------------------------- --encode

def bench_encode(bodies: int, states: int = 200, rounds: int = 5) -> dict[str, tuple[float, float]]:
    """``{output: (us per message with OutputEncoder, with builder + serialize_message)}``,
    medians over ``rounds`` alternated runs of ``states`` random states."""
    from types import SimpleNamespace
    from rclpy.serialization import serialize_message
    from crawler_sim.ros import messages as M
    rng = np.random.default_rng(1)
    p = bodies
    masses = np.ones(p)
    rows = [M.Row(SimpleNamespace(
        x=rng.normal(size=p), v=rng.normal(size=p), friction=rng.normal(size=p),
        lengths=rng.normal(size=p - 1), rates=rng.normal(size=p - 1),
        linkage_force=rng.normal(size=p - 1),
        contact=rng.integers(-1, 2, size=p).astype(np.int8))) for _ in range(states)]
    builders = {'joint_states': lambda s, t: M.joint_states_msg(s, t),
                'body_states': lambda s, t: M.body_states_msg(s, t),
                'contact_states': lambda s, t: M.contact_states_msg(s),
                'contacts_stamped': lambda s, t: M.contacts_stamped_msg(s, t),
                'odom': lambda s, t: M.odom_msg(s, masses, t),
                'markers': lambda s, t: M.markers_msg(s, t)}
    enc = M.OutputEncoder()
    fast: dict[str, list[float]] = {name: [] for name in builders}
    slow: dict[str, list[float]] = {name: [] for name in builders}
    fast['clock'], slow['clock'] = [], []
    for _ in range(rounds):
        for name, build in builders.items():
            encode = getattr(enc, name)
            t0 = time.perf_counter()
            for i, row in enumerate(rows):
                encode(row, i * 10_000_000, masses)
            fast[name].append((time.perf_counter() - t0) / states * 1e6)
            t0 = time.perf_counter()
            for i, row in enumerate(rows):
                serialize_message(build(row.source, i * 10_000_000))
            slow[name].append((time.perf_counter() - t0) / states * 1e6)
        t0 = time.perf_counter()
        for i in range(states):
            M.clock_cdr(i * 10_000_000)
        fast['clock'].append((time.perf_counter() - t0) / states * 1e6)
        t0 = time.perf_counter()
        for i in range(states):
            serialize_message(M.clock_msg(i * 10_000_000))
        slow['clock'].append((time.perf_counter() - t0) / states * 1e6)
    assert enc.slow == 0
    return {name: (statistics.median(fast[name]), statistics.median(slow[name]))
            for name in fast}


# ---------------------------------------------------------------- --hostile

def child_measure(func_name: str, path: str) -> None:
    """Print JSON: peak traced bytes and RSS growth of one call, after a warm-up call."""
    import resource
    import tracemalloc
    from crawler_sim import bag
    func = {'load': bag.load, 'info': bag.info, 'recover': bag.recover}[func_name]

    def call(k: int):
        args = (path,) if func_name != 'recover' else (path, f'{path}.recovered{k}')
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                out = func(*args)
            return 'ok' + (f' ({len(out)} states)' if func_name == 'load' else '')
        except bag.BagError as exc:
            return f'BagError: {str(exc)[-90:]}'
    from rclpy.serialization import deserialize_message  # noqa: F401 - imported up front
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t = time.perf_counter()
    result = call(0)              # first call: RSS growth (includes lazily imported modules)
    wall = time.perf_counter() - t
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss0
    tracemalloc.start()
    call(1)                       # second call: traced allocations only
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(json.dumps({'peak': peak, 'rss': rss, 'wall': wall, 'result': result}))


def bench_hostile() -> list[dict]:
    from crawler_sim.bag import record_arrays
    from test.support import crafted
    from test.support.synthetic import synthetic_arrays
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = {name: build(Path(tmp) / f'{name}.mcap') for name, build in crafted.FILES.items()}
        a = synthetic_arrays(20_000, 2, seed=7)
        masses = a.pop('masses')
        record_arrays(Path(tmp) / 'real', **a, masses=masses)
        files['real recording (20k states)'] = Path(tmp) / 'real' / 'real_0.mcap'
        for name, path in files.items():
            for func in ('load', 'info', 'recover'):
                out = subprocess.run([sys.executable, '-m', 'benchmarks.bag',
                                      '--measure', func, str(path)], capture_output=True,
                                     text=True, timeout=600)
                if out.returncode != 0:
                    rows.append({'file': name, 'func': func, 'error': out.stderr[-300:]})
                    continue
                row = json.loads(out.stdout.strip().splitlines()[-1])
                row.update(file=name, func=func, size=path.stat().st_size)
                rows.append(row)
    return rows


def print_hostile(rows: list[dict]) -> None:
    print(f'{"file":28s} {"call":8s} {"size MB":>8s} {"peak MB":>8s} {"x size":>7s} '
          f'{"maxRSS+":>8s} {"wall s":>7s}  result')
    for r in rows:
        if 'error' in r:
            print(f'{r["file"]:28s} {r["func"]:8s} CRASH {r["error"]}')
            continue
        print(f'{r["file"]:28s} {r["func"]:8s} {r["size"] / 1e6:8.2f} {r["peak"] / 1e6:8.2f} '
              f'{r["peak"] / r["size"]:7.2f} {r["rss"] / 1e6:8.2f} {r["wall"]:7.2f}  '
              f'{r["result"]}')


def bench_offline(t_end: float, rounds: int = 3) -> dict[str, list[float]]:
    """CPU seconds of each step of the README's recorded offline run (see the module doc)."""
    from crawler_sim.bag.plot import figure, save
    from crawler_sim.core.scene import load_scene, scene_to_dict
    from crawler_sim.bag import record_trajectory
    try:
        from crawler_sim.sweep.tables import export_bag
    except ImportError:                     # pandas is optional: no table figures then
        export_bag = None
    scene = load_scene(Path(__file__).resolve().parents[1] / 'config' / 'scenes'
                       / 'slope_climb.yaml').with_run(method='implicit', t_end=t_end, dt=1e-4)
    times: dict[str, list[float]] = {}
    clock = time.process_time
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            out = Path(tmp) / f'climb{k}'
            c0 = clock()
            tr = scene.simulate()
            c1 = clock()
            record_trajectory(out, tr, scene=scene_to_dict(scene))
            c2 = clock()
            run = load(out)
            c3 = clock()
            save(figure(run, 'climb'), Path(tmp) / f'climb{k}.png')
            c4 = clock()
            steps = {'simulate': c1 - c0, 'record': c2 - c1, 'load': c3 - c2,
                     'plot (load + figure)': c4 - c2, 'samples': len(tr.t)}
            if export_bag is not None:
                export_bag(out, Path(tmp) / f'climb{k}.csv', 'csv')
                c5 = clock()
                export_bag(out, Path(tmp) / f'climb{k}.parquet', 'parquet')
                c6 = clock()
                steps.update({'export csv': c5 - c4, 'export parquet': c6 - c5})
            for name, value in steps.items():
                times.setdefault(name, []).append(value)
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--steps', type=int, default=360_000, help='states (100 Hz: 360000 = 1 h)')
    ap.add_argument('--dir', default='/tmp/crawler_sim_bag_hour', help='where to write the bag')
    ap.add_argument('--hostile', action='store_true', help='memory on crafted files')
    ap.add_argument('--kill', action='store_true', help='SIGKILL loss of a recording')
    ap.add_argument('--kills', type=int, default=30, help='kills for --kill')
    ap.add_argument('--writer', action='store_true',
                    help='us per message: mcap.writer.Writer against McapWriter')
    ap.add_argument('--messages', type=int, default=200_000, help='messages for --writer')
    ap.add_argument('--encode', action='store_true',
                    help='us per output message: OutputEncoder against serialize_message')
    ap.add_argument('--bodies', type=int, default=3, help='bodies for --encode')
    ap.add_argument('--offline', action='store_true',
                    help='CPU of recording, plotting, exporting the README\'s offline run')
    ap.add_argument('--t-end', type=float, default=20.0, help='run length for --offline [s]')
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--child', help=argparse.SUPPRESS)
    ap.add_argument('--measure', nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child_record(args.child)
        return 0
    if args.measure:
        child_measure(*args.measure)
        return 0
    if args.offline:
        times = bench_offline(args.t_end)
        samples = times.pop('samples')[0]
        print(f'slope_climb, implicit, dt 1e-4, t_end {args.t_end:g} s: {samples} samples '
              '(CPU s, median of 3, best)')
        for name, values in times.items():
            print(f'  {name:22s} {statistics.median(values):7.3f} {min(values):7.3f}')
        floors = {'record': 2.0, 'plot (load + figure)': 2.0, 'export csv': 2.0,
                  'export parquet': 2.0}
        ok = True
        for name, floor in floors.items():
            if name in times:
                median = statistics.median(times[name])
                print(f'{name}: {median:.3f} s CPU, floor {floor:g} s: '
                      f'{"PASS" if median <= floor else "FAIL"}')
                ok = ok and median <= floor
        return 0 if ok else 1
    if args.encode:
        print(f'{"output":18s} {"OutputEncoder":>14s} {"serialize_message":>18s}  '
              f'(us per message, p = {args.bodies}, median of 5)')
        for name, (fast, slow) in bench_encode(args.bodies).items():
            print(f'{name:18s} {fast:14.2f} {slow:18.2f}')
        return 0
    if args.writer:
        for name, us in bench_writer(args.messages).items():
            print(f'{name:20s} {us:6.2f} us per message ({args.messages} messages, median of 3)')
        return 0
    if args.hostile or args.kill:
        ok = True
        if args.hostile:
            rows = bench_hostile()
            print_hostile(rows)
            worst = max((r['peak'] / r['size'] for r in rows if 'error' not in r), default=0)
            crashed = sum('error' in r for r in rows)
            print(f'hostile: worst peak {worst:.2f}x the file size, {crashed} crashes; floor 4x')
            ok = ok and worst < 4 and not crashed
        if args.kill:
            res = bench_kill(args.kills, args.seed)
            print(f'SIGKILL at random moments in the first 3 s ({res["kills"]} kills, '
                  f'{res["first_second_kills"]} in the first second): loss median '
                  f'{res["median_s"]:.3f} s, worst {res["worst_s"]:.3f} s (first second: '
                  f'{res["first_second_worst_s"] or 0:.3f} s), {res["over_1s"]} over 1 s; '
                  'floor 1 s')
            print(f'  of the states the recorder had written: loss median '
                  f'{res["recorded_median_s"]:.3f} s, worst {res["recorded_worst_s"]:.3f} s, '
                  f'{res["recorded_over_1s"]} over 1 s (the rest: the recorder starved of CPU)')
            ok = ok and res['over_1s'] == 0
        return 0 if ok else 1
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
