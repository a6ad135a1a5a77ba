"""The chain of issue 24: optimize -> gait_node (as the file's header says) -> sim_node, live.

    python -m benchmarks.chain [--scenes A.yaml ...] [--families scallop ...]
        [--pacing paced flat] [--maxiter 3] [--popsize 4] [--keep DIR]

(needs `make build`: the nodes are run from the colcon install, as `ros2 run` runs them.)

For every scene and stroke family: ``crawler-sim optimize SCENE --family F -o best.yaml``
(scored as the node runs it, the default), then ``sim_node --ros-args --params-file
best_sim.yaml`` (recording; paced at real time, or flat out) and ``gait_node --ros-args
--params-file best.yaml``, exactly the two commands the written files' headers give. Once the
sim took the preloaded trajectory (at sim time t_a, read from the bag's plant_inputs journal),
the run goes on for ``--periods`` stroke periods; the steady crawl speed is the centre of mass's
mean speed over the second half of them, [t_a + P/2 T, t_a + P T] (the window the optimiser's
figure uses when the run is not exactly periodic). Printed per run: predicted and measured speed,
their relative difference (floor: within 1 %), and ``crawler-sim replay`` of the bag (floor:
max |dx| = 0).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

from crawler_sim.ros.workspace import executable, workspace_env

REPO = Path(__file__).resolve().parents[1]

SCENES = ('config/scenes/scallop_2body.yaml', 'config/scenes/wave_3body.yaml',
          'config/scenes/slope_climb.yaml')
FAMILIES = ('scallop', 'stroke', 'fourier')


def optimize(scene: Path, family: str, out: Path, maxiter: int, popsize: int) -> dict:
    cmd = [sys.executable, '-m', 'crawler_sim.cli', 'optimize', str(scene), '--family', family,
           '--maxiter', str(maxiter), '--popsize', str(popsize), '-o', str(out), '--json']
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, check=True)
    return json.loads(proc.stdout)


def live(out: Path, pacing: str, periods: int, period: float, bag_dir: Path, name: str,
         env: dict) -> Path:
    """Run sim_node and gait_node from the optimiser's files; the bag's path."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    sim_file = out.with_name(out.stem + '_sim.yaml')
    rtf = '1.0' if pacing == 'paced' else '0.0'
    logs = [open(bag_dir / f'{name}.{n}.log', 'w') for n in ('sim', 'gait')]
    sim = subprocess.Popen([str(executable('sim_node')), '--ros-args', '--params-file',
                            str(sim_file), '-p', 'record:=true', '-p', f'record_dir:={bag_dir}',
                            '-p', f'record_name:={name}', '-p', f'real_time_factor:={rtf}',
                            '-p', 'diagnostics_period:=0.2'], env=env, stdout=logs[0],
                           stderr=subprocess.STDOUT)
    gait = subprocess.Popen([str(executable('gait_node')), '--ros-args', '--params-file',
                             str(out)], env=env, stdout=logs[1], stderr=subprocess.STDOUT)
    rclpy.init()
    node = Node('chain_bench')
    state = {'accepted': 0, 'sim_ns': 0}

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            for kv in st.values:
                if kv.key == 'trajectories_accepted':
                    state['accepted'] = int(kv.value)

    def on_clock(msg: Clock) -> None:
        state['sim_ns'] = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
    node.create_subscription(Clock, '/clock', on_clock, qos_profile_sensor_data)
    try:
        end = time.monotonic() + 120.0
        while state['accepted'] < 1:
            if time.monotonic() > end or sim.poll() is not None or gait.poll() is not None:
                raise RuntimeError(f'{name}: the sim did not take the trajectory')
            rclpy.spin_once(node, timeout_sec=0.05)
        # the sim took it before the diagnostics said so; a /clock received after that (not
        # one still in flight) is at or after t_a
        seen = time.monotonic() + 0.3
        while time.monotonic() < seen:
            rclpy.spin_once(node, timeout_sec=0.05)
        goal = state['sim_ns'] + round(((periods + 1) * period + 1.0) * 1e9)
        end = time.monotonic() + 60.0 + 3.0 * periods * period
        while state['sim_ns'] < goal:
            if time.monotonic() > end:
                raise RuntimeError(f'{name}: sim time did not reach {goal / 1e9} s')
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        for proc in (gait, sim):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
            proc.wait(timeout=20)
        for f in logs:
            f.close()
    return bag_dir / name


def measure(bag_path: Path, period: float, periods: int) -> tuple[float, float]:
    """(measured steady speed [m/s], replay max |dx| [m]) of a recorded chain run."""
    from crawler_sim import bag
    from crawler_sim.bag.inputs import load_inputs
    from crawler_sim.cli import _replay
    from crawler_sim.sweep.metrics import window_speed

    run = bag.load(bag_path)
    t_a = next(i.t_ns for i in load_inputs(bag_path, run.namespace).inputs
               if i.kind == 'trajectory') / 1e9
    m = np.asarray(run.scene['masses'], dtype=float)
    com = run.x @ m / m.sum()
    speed = window_speed(run.t, com, t_a + periods / 2 * period, t_a + periods * period)
    res = _replay(run, None, 0.0)
    return speed, res['max_position_error']


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--scenes', nargs='+', default=list(SCENES))
    ap.add_argument('--families', nargs='+', default=list(FAMILIES))
    ap.add_argument('--pacing', nargs='+', default=['paced', 'flat'])
    ap.add_argument('--maxiter', type=int, default=3)
    ap.add_argument('--popsize', type=int, default=4)
    ap.add_argument('--periods', type=int, default=12)
    ap.add_argument('--keep', type=Path, help='keep files and bags here')
    args = ap.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    # a domain of its own: another sim on the host would answer the waits below
    os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))
    env = workspace_env(dict(os.environ))
    work = args.keep or Path(tempfile.mkdtemp(prefix='chain_bench_'))
    work.mkdir(parents=True, exist_ok=True)
    print(f'{"scene":<22} {"family":<8} {"pacing":<6} {"predicted":>12} {"measured":>12} '
          f'{"diff":>9} {"replay |dx|":>12}')
    worst = 0.0
    for scene in args.scenes:
        for family in args.families:
            tag = f'{Path(scene).stem}_{family}'
            out = work / f'{tag}.yaml'
            res = optimize(REPO / scene, family, out, args.maxiter, args.popsize)
            predicted = res['best']['mean_speed']
            from crawler_sim.core.scene import load_scene
            period = load_scene(work / f'{tag}_scene.yaml').gait.period
            for pacing in args.pacing:
                path = live(out, pacing, args.periods, period, work, f'{tag}_{pacing}', env)
                speed, dx = measure(path, period, args.periods)
                diff = (speed - predicted) / abs(predicted)
                worst = max(worst, abs(diff))
                print(f'{Path(scene).stem:<22} {family:<8} {pacing:<6} '
                      f'{predicted * 1e3:9.4f} mm/s {speed * 1e3:9.4f} mm/s {diff:+9.2e} '
                      f'{dx:12.3g}', flush=True)
    print(f'worst relative difference {worst:.3g} (floor 1e-2); files in {work}')
    return 0 if worst <= 1e-2 else 1


if __name__ == '__main__':
    raise SystemExit(main())
