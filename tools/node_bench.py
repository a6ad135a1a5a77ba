"""Benchmark of the colcon-installed sim_node (prints figures; not a test).

    python tools/node_bench.py [--seconds 15] [--method exact] [--record [--pairs 3]]
                               [--clock-observer]

(with the environment of ``make``: AMENT_PREFIX_PATH=install/crawler_sim:.venv, or a sourced
workspace). Three runs of the default 3-body scene, integration at 1 kHz, every output at 100 Hz:

1. real time (real_time_factor 1), at rest under a constant command;
2. real time, driven by ``gait_node`` (the scallop stroke at 50 Hz of commands);
3. as fast as possible (real_time_factor 0, publish_clock, gait_node on sim time).

For 1 and 2: CPU use of the sim_node process in % of one core (from /proc, after a 3 s warm-up)
and tick lateness (p99 per diagnostics period, from /diagnostics: median and worst period; late
ticks counted as starting more than one tick period after their deadline). For 3: the speed-up
over real time (sim seconds per wall second, from the sim_time of successive /diagnostics
messages and their arrival times; ``--clock-observer`` measures it on /clock instead, whose
every message costs this process ~0.2 ms of CPU taken from the node on a small machine), and
the CPU use of gait_node, which shares the cores. With ``--record``: ``--pairs`` (3) alternated
pairs of real-time runs with a subscriber on every output, without and with the bag, their
median figures and the median CPU time that recording adds (issue 5's floor: at most 10 %).
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from crawler_sim.ros.demo import _executable, _share, _workspace_env  # noqa: E402

WARMUP = 3.0


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process [s]."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def start(name: str, env: dict, *args: str) -> subprocess.Popen:
    return subprocess.Popen([str(_executable(name)), '--ros-args', *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def stop(*procs: subprocess.Popen) -> None:
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()


def run(label: str, seconds: float, method: str, *, rtf: float, gait: bool, env: dict,
        extra: tuple[str, ...] = (), listen: bool = False, clock_observer: bool = False) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import SetBool

    fast = rtf == 0.0
    sim = start('sim_node', env, '--params-file', str(_share() / 'config' / 'crawler_sim.yaml'),
                '-p', f'method:={method}', '-p', f'real_time_factor:={rtf}',
                '-p', f'publish_clock:={"true" if fast else "false"}',
                '-p', 'integration_rate:=1000.0', '-p', 'publish_rate:=100.0',
                '-p', 'start_paused:=true', '-p', 'diagnostics_period:=1.0', *extra)
    procs = [sim]
    if gait:
        procs.append(start('gait_node', env, '-p', f'use_sim_time:={"true" if fast else "false"}'))
    rclpy.init()
    node = Node('node_bench')
    diags: list[dict] = []
    clock: list[tuple[float, int]] = []
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diags.append(
        {**{kv.key: kv.value for kv in m.status[0].values}, 'received': time.monotonic()}), 100)
    if fast and clock_observer:
        # every /clock message costs this Python process ~0.2 ms: on 2 cores that is CPU taken
        # from the node being measured, so by default the speed-up comes from /diagnostics
        node.create_subscription(Clock, '/clock', lambda m: clock.append(
            (time.monotonic(), m.clock.sec * 10**9 + m.clock.nanosec)),
            qos_profile_sensor_data)
    if listen:     # every output has a subscriber, so every message is built and sent
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Int8MultiArray
        from visualization_msgs.msg import MarkerArray
        for typ, topic in ((JointState, 'body_states'), (JointState, 'joint_states'),
                           (Int8MultiArray, 'contact_states'), (Odometry, 'odom'),
                           (MarkerArray, 'markers')):
            node.create_subscription(typ, topic, lambda m: None, 10)
    pause = node.create_client(SetBool, '/crawler_sim/pause')
    try:
        end = time.monotonic() + 60
        while not (diags and pause.service_is_ready() and (not gait or int(
                diags[-1].get('linkage_cmd_publishers', 0)) >= 1)):
            if time.monotonic() > end:
                raise RuntimeError('sim_node did not come up within 60 s')
            rclpy.spin_once(node, timeout_sec=0.05)
        future = pause.call_async(SetBool.Request(data=False))
        while not future.done():
            rclpy.spin_once(node, timeout_sec=0.05)
        t0 = time.monotonic()
        n_diag0 = len(diags)
        cpu0 = None
        while time.monotonic() - t0 < seconds:
            rclpy.spin_once(node, timeout_sec=0.05)
            if cpu0 is None and time.monotonic() - t0 >= WARMUP:
                cpu0, w0, d0 = cpu_seconds(sim.pid), time.monotonic(), len(diags)
                gait0 = cpu_seconds(procs[1].pid) if gait else 0.0
        cpu = (cpu_seconds(sim.pid) - cpu0) / (time.monotonic() - w0)
        cpu_gait = ((cpu_seconds(procs[1].pid) - gait0) / (time.monotonic() - w0)
                    if gait else 0.0)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        stop(*reversed(procs))
    steady = diags[max(d0, n_diag0 + 1):]
    out = {'label': label, 'cpu_percent': 100 * cpu, 'gait_cpu_percent': 100 * cpu_gait}
    if steady:
        p99 = [float(d['tick_lateness_p99_ms']) for d in steady]
        out.update(p99_median_ms=statistics.median(p99), p99_worst_ms=max(p99),
                   late_ticks=int(steady[-1]['late_ticks']) - int(steady[0]['late_ticks']),
                   rtf=statistics.median(float(d['real_time_factor']) for d in steady),
                   events=int(steady[-1]['solver_events']))
    if fast and len(clock) > 2:
        half = [c for c in clock if c[0] - clock[0][0] >= WARMUP]
        if len(half) > 1:
            out['speedup'] = (half[-1][1] - half[0][1]) / 1e9 / (half[-1][0] - half[0][0])
    elif fast and len(steady) > 1:      # sim time over wall time between diagnostics messages
        first, last = steady[0], steady[-1]
        out['speedup'] = ((float(last['sim_time']) - float(first['sim_time']))
                          / (last['received'] - first['received']))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=15.0, help='wall seconds per run')
    parser.add_argument('--method', default='exact', help='exact | implicit | penalty')
    parser.add_argument('--record', action='store_true',
                        help='also measure the CPU cost of recording every output to a bag')
    parser.add_argument('--pairs', type=int, default=3,
                        help='with --record: alternated runs without / with the bag')
    parser.add_argument('--clock-observer', action='store_true',
                        help='measure the flat-out speed-up on /clock (a subscriber that costs '
                        'CPU on the same cores) instead of from /diagnostics')
    args = parser.parse_args()
    os.environ['ROS_DOMAIN_ID'] = str(os.getpid() % 100 + 1)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = _workspace_env(dict(os.environ))
    print(f'sim_node benchmark: method {args.method}, 1 kHz integration, outputs at 100 Hz, '
          f'{args.seconds:g} s per run, {os.cpu_count()} CPUs')
    rows = [run('real time, at rest', args.seconds, args.method, rtf=1.0, gait=False, env=env),
            run('real time, gait_node', args.seconds, args.method, rtf=1.0, gait=True, env=env),
            run('flat out, gait_node', args.seconds, args.method, rtf=0.0, gait=True, env=env,
                clock_observer=args.clock_observer)]
    pairs: list[tuple[dict, dict]] = []
    if args.record:
        import tempfile
        # A node at ~13 % of a core varies by +-1.5 points from run to run on a shared machine,
        # as much as recording costs: alternate the two runs and take medians.
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(args.pairs):
                base = run('outputs listened', args.seconds, args.method, rtf=1.0, gait=True,
                           env=env, listen=True)
                rec = run('outputs listened + bag', args.seconds, args.method, rtf=1.0,
                          gait=True, env=env, listen=True,
                          extra=('-p', 'record:=true', '-p', f'record_dir:={tmp}/{k}'))
                pairs.append((base, rec))
        rows += [_median_row(p[0] for p in pairs), _median_row(p[1] for p in pairs)]
    for r in rows:
        parts = [f'{r["label"]:22s}', f'CPU {r["cpu_percent"]:5.1f} % of one core']
        if 'p99_median_ms' in r and not r['label'].startswith('flat'):
            parts.append(f'tick lateness p99 {r["p99_median_ms"]:.3f} ms (worst period '
                         f'{r["p99_worst_ms"]:.3f} ms), late ticks {r["late_ticks"]}')
        if 'rtf' in r:
            parts.append(f'real-time factor {r["rtf"]:.2f}')
        if 'speedup' in r:
            where = '/clock' if args.clock_observer else '/diagnostics'
            parts.append(f'speed-up {r["speedup"]:.2f}x (on {where}), gait_node CPU '
                         f'{r["gait_cpu_percent"]:.1f} %')
        print('  ' + ' | '.join(parts))
    if args.record:
        extra = [rec['cpu_percent'] / base['cpu_percent'] - 1.0 for base, rec in pairs]
        print(f'  recording adds {100 * statistics.median(extra):.1f} % to the node\'s CPU time '
              f'(median of {len(pairs)} alternated pairs: '
              f'{", ".join(f"{100 * e:+.1f}" for e in extra)} %; floor: 10 %)')
    return 0


def _median_row(runs) -> dict:
    """One row of the medians of several runs' figures (worst-period lateness: the worst)."""
    runs = list(runs)
    out = dict(runs[0])
    for key in ('cpu_percent', 'p99_median_ms', 'late_ticks', 'rtf'):
        if all(key in r for r in runs):
            out[key] = statistics.median(r[key] for r in runs)
    if all('p99_worst_ms' in r for r in runs):
        out['p99_worst_ms'] = max(r['p99_worst_ms'] for r in runs)
    if len(runs) > 1:
        out['label'] = f'{out["label"]} (median of {len(runs)})'
    return out


if __name__ == '__main__':
    sys.exit(main())
