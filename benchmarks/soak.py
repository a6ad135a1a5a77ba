"""A real-time soak of the colcon-installed sim_node under varied command streams (issue 25).

    python -m benchmarks.soak [--minutes 60] [--seed 0] [--method exact]

(environment of ``make``: AMENT_PREFIX_PATH=install/crawler_sim:.venv.) sim_node runs the seed's
two-body crawler at real time, recording nothing, while this process drives it over DDS with a
stream whose shape changes every 20 s: 100 Hz ``0.1 + 0.03 sin(pi t)`` set-points (the stream of
../shared/repro that made the exact solver run out of steps at t = 512 s), set-points of random
rate (20-500 Hz), amplitude and frequency with jittered timing, random steps, bursts at 1 kHz,
trajectories every 0.5-3 s (positions only, with velocities, with accelerations), and between
them hostile messages the node must refuse (NaN, wrong sizes, a trajectory with a 1e308
velocity, one with a velocity of 1e3 m/s that would drive the linkage out of
[min_length, max_length] between in-range points).

Printed at the end (floors: 0 fallbacks, 0 tick failures, 0 non-finite outputs, real-time factor
>= 0.95, RSS growth < 10 MB from minute 1 to the end): the node's counters from its last
/diagnostics, the smallest real-time factor of a diagnostics period, the worst tick lateness,
and the node's RSS at minute 1 and at the end. Exit code 1 when a floor is missed.
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import signal
import subprocess
import time

import numpy as np


from crawler_sim.ros.workspace import executable, workspace_env

SHAPES = ('repro', 'sine', 'steps', 'burst', 'trajectory', 'hostile')


def rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return math.nan


def trajectory(rng, now_ns: int, kind: str):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    msg = JointTrajectory(joint_names=['linkage_0'])
    n = int(rng.integers(5, 200))
    dt = float(rng.uniform(0.005, 0.05))
    w = float(rng.uniform(1.0, 15.0))
    amp = float(rng.uniform(0.0, 0.04))
    order = int(rng.choice([1, 3, 5]))
    for k in range(n):
        t = (k + 1) * dt
        pt = JointTrajectoryPoint(positions=[0.1 + amp * math.sin(w * t)])
        if order >= 3:
            pt.velocities = [0.0 if k == n - 1 else amp * w * math.cos(w * t)]
        if order >= 5:
            pt.accelerations = [-amp * w * w * math.sin(w * t)]
        pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(round(t * 1e9),
                                                                    1_000_000_000)
        msg.points.append(pt)
    if kind == 'huge_velocity':           # finite, absurd: refused
        mid = msg.points[len(msg.points) // 2]
        mid.velocities = [1e308] if mid.velocities else []
        if not mid.velocities:
            for p in msg.points:
                p.velocities = [0.0]
            mid.velocities = [1e308]
    elif kind == 'overshoot':             # in-range points, an interpolant far outside
        for p in msg.points:
            p.velocities = [0.0]
        msg.points[len(msg.points) // 2].velocities = [1e3]
    return msg


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--minutes', type=float, default=60.0)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--method', default='exact')
    args = ap.parse_args(argv)
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray
    from trajectory_msgs.msg import JointTrajectory

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))   # a domain of its own
    env = workspace_env(dict(os.environ))
    sim = subprocess.Popen([str(executable('sim_node')), '--ros-args', '-p',
                            f'method:={args.method}', '-p', 'diagnostics_period:=1.0',
                            '-p', 'publish_markers:=false'], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rclpy.init()
    node = Node('soak_driver')
    cmd = node.create_publisher(Float64MultiArray, 'linkage_cmd', 100)
    traj = node.create_publisher(JointTrajectory, 'linkage_trajectory', 10)
    diag: dict[str, str] = {}
    rtf: list[float] = []
    worst_late = [0.0]

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.hardware_id == 'crawler_sim':
                diag.clear()
                diag.update({kv.key: kv.value for kv in st.values})
                if float(diag.get('sim_time', 0)) > 5.0:
                    rtf.append(float(diag['real_time_factor']))
                    worst_late[0] = max(worst_late[0], float(diag['tick_lateness_max_ms']))

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
    rng = np.random.default_rng(args.seed)
    start = time.monotonic()
    end = start + args.minutes * 60.0
    rss_1 = math.nan
    shape, shape_end, next_send = 'repro', start + 20.0, start
    period, amp, freq = 0.01, 0.03, 0.5
    sent = 0
    try:
        while time.monotonic() < end and sim.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.0)
            now = time.monotonic()
            if math.isnan(rss_1) and now - start > 60.0:
                rss_1 = rss_mb(sim.pid)
            if now >= shape_end:
                shape = str(rng.choice(SHAPES))
                shape_end = now + 20.0
                period = 1.0 / float(rng.uniform(20.0, 500.0))
                amp, freq = float(rng.uniform(0.0, 0.06)), float(rng.uniform(0.1, 5.0))
            if now < next_send:
                time.sleep(min(next_send - now, 0.002))
                continue
            t = now - start
            if shape == 'repro':
                cmd.publish(Float64MultiArray(data=[0.1 + 0.03 * math.sin(math.pi * t)]))
                next_send = now + 0.01
            elif shape == 'sine':
                cmd.publish(Float64MultiArray(data=[0.1 + amp * math.sin(2 * math.pi * freq *
                                                                          t)]))
                next_send = now + period * float(rng.uniform(0.5, 1.5))     # jittered
            elif shape == 'steps':
                cmd.publish(Float64MultiArray(data=[float(rng.uniform(0.05, 0.2))]))
                next_send = now + float(rng.uniform(0.05, 2.0))
            elif shape == 'burst':
                for _ in range(int(rng.integers(10, 200))):
                    cmd.publish(Float64MultiArray(data=[float(rng.uniform(0.08, 0.12))]))
                next_send = now + float(rng.uniform(0.2, 2.0))
            elif shape == 'trajectory':
                traj.publish(trajectory(rng, 0, 'ok'))
                next_send = now + float(rng.uniform(0.5, 3.0))
            else:
                bad = [Float64MultiArray(data=[math.nan]), Float64MultiArray(data=[0.1, 0.1]),
                       Float64MultiArray(data=[math.inf])]
                cmd.publish(bad[int(rng.integers(0, 3))])
                traj.publish(trajectory(rng, 0, str(rng.choice(['huge_velocity',
                                                                  'overshoot']))))
                next_send = now + float(rng.uniform(0.05, 0.5))
            sent += 1
        alive = sim.poll() is None
        rss_end = rss_mb(sim.pid) if alive else math.nan
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        if sim.poll() is None:
            sim.send_signal(signal.SIGINT)
        err = sim.communicate(timeout=20)[1]
    counters = {k: int(diag.get(k, -1)) for k in ('solver_failures', 'tick_failures',
                                                  'nonfinite_outputs', 'commands_accepted',
                                                  'commands_rejected', 'trajectories_accepted',
                                                  'trajectories_rejected', 'late_ticks')}
    low = min(rtf) if rtf else math.nan
    growth = rss_end - rss_1
    print(f'{args.minutes:g} min at real time, method {args.method}, {sent} sends; sim_node '
          f'{"alive" if alive else "DIED"} (exit {sim.returncode})')
    print(f'counters: {counters}')
    print(f'real-time factor: min {low:.3f} (median {np.median(rtf) if rtf else math.nan:.3f}) '
          f'over {len(rtf)} periods; worst tick lateness {worst_late[0]:.1f} ms')
    print(f'RSS: {rss_1:.1f} MB at minute 1, {rss_end:.1f} MB at the end: '
          f'{growth:+.1f} MB')
    if 'Traceback' in err:
        print(err[-2000:])
    ok = (alive and counters['solver_failures'] == 0 and counters['tick_failures'] == 0
          and counters['nonfinite_outputs'] == 0 and low >= 0.95
          and (math.isnan(growth) or growth < 10.0))
    print('floors', 'met' if ok else 'MISSED')
    return 0 if ok else 1


if __name__ == '__main__':
    raise SystemExit(main())
