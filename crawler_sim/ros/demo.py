"""The demo crawl (``make run``): sim_node driven by gait_node over real topics, on sim time.

``python -m crawler_sim.ros.demo [--duration 20] [--runs runs]``

1. finds the colcon-installed ``sim_node`` and ``gait_node`` through the ament index
   (``get_package_prefix('crawler_sim')/lib/crawler_sim/``, as ``ros2 run`` does);
2. starts them as processes (in the user's ``ROS_DOMAIN_ID``): the sim with its shipped
   two-body parameters (``config/ros/crawler_sim.yaml``), ``real_time_factor 0`` (as fast as
   the CPU allows), ``start_paused`` and recording to a new bag ``runs/crawl_<date>-<time>/``;
   the gait node on sim time, preloading the whole stroke as one trajectory stamped 0;
3. waits until the sim holds that trajectory, un-pauses it, follows ``/clock`` until the
   requested simulated time, pauses the sim and stops both with SIGINT. The same command
   stream at the same ticks: every run crawls the same distance;
4. prints a summary read back from the bag (distance crawled, mean speed, stick fraction per
   body, contact events, real-time factor, bag and plot paths) and writes the plot with
   ``crawler_sim.bag.plot``.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np

from crawler_sim.bag import topics as T
from crawler_sim.bag.files import open_new
from crawler_sim.ros.workspace import executable, share, workspace_env
from crawler_sim.core.simtime import from_stamp, to_ns, to_seconds

DEADLINE_CONNECT = 60.0     # wall s for discovery


class _Child:
    def __init__(self, name: str, args: list[str], env: dict, log: Path) -> None:
        self.name = name
        self.log = log
        self._file = open_new(log)       # never an existing file, never through a link
        self.popen = subprocess.Popen([str(executable(name)), '--ros-args', *args], env=env,
                                      stdout=self._file, stderr=subprocess.STDOUT)

    def stop(self, timeout: float = 10.0) -> int:
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGINT)
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            return self.popen.wait()
        finally:
            self._file.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='python -m crawler_sim.ros.demo', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=float, default=20.0, help='simulated seconds (20)')
    parser.add_argument('--runs', type=Path, default=Path('runs'), help='output directory')
    args = parser.parse_args(argv)
    if not args.duration > 0:
        parser.error('--duration must be > 0')

    domain = os.environ.get('ROS_DOMAIN_ID', '0')      # the user's: never overridden
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = workspace_env(dict(os.environ))
    name = time.strftime('crawl_%Y%m%d-%H%M%S')
    runs = args.runs.resolve()
    runs.mkdir(parents=True, exist_ok=True)
    bag = runs / name
    png = runs / f'{name}.png'
    sim_args = ['--params-file', str(share() / 'config' / 'ros' / 'crawler_sim.yaml'),
                '-p', 'real_time_factor:=0.0',
                '-p', 'start_paused:=true', '-p', 'diagnostics_period:=0.2',
                '-p', 'record:=true', '-p', f'record_dir:={runs}', '-p', f'record_name:={name}']
    print(f'crawler_sim demo: {args.duration:g} simulated seconds, ROS_DOMAIN_ID={domain}')
    children = [_Child('sim_node', sim_args, env, runs / f'{name}.sim_node.log'),
                _Child('gait_node', ['-p', 'use_sim_time:=true', '-p', 'mode:=trajectory',
                                     '-p', 'preload:=true', '-p', f'duration:={args.duration}'],
                       env, runs / f'{name}.gait_node.log')]
    try:
        wall, diag = _drive(args.duration, children)
    except KeyboardInterrupt:
        print('\ninterrupted')
        for child in reversed(children):
            child.stop()
        return 130
    except RuntimeError as exc:
        for child in reversed(children):
            child.stop()
        print(f'error: {exc}', file=sys.stderr)
        for child in children:
            print(f'--- {child.log}:\n' + child.log.read_text()[-2000:], file=sys.stderr)
        return 1
    codes = [child.stop() for child in reversed(children)]
    if any(codes):
        print(f'warning: exit codes {codes} (logs in {runs})', file=sys.stderr)
    _summary(bag, png, args.duration, wall, diag)
    return 0


def _drive(duration: float, children: list[_Child]) -> tuple[float, dict[str, str]]:
    """Connect, run the sim for ``duration`` sim seconds; return (wall s, last diagnostics)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import SetBool

    rclpy.init()
    node = Node('crawler_sim_demo')
    diag: dict[str, str] = {}
    sim_ns = [0]

    def on_diag(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.hardware_id == 'crawler_sim':
                diag.clear()
                diag.update({kv.key: kv.value for kv in status.values})

    def on_clock(msg: Clock) -> None:
        sim_ns[0] = from_stamp(msg.clock.sec, msg.clock.nanosec)

    node.create_subscription(DiagnosticArray, T.DIAGNOSTICS.node_name, on_diag, 10)
    node.create_subscription(Clock, T.CLOCK.node_name, on_clock, qos_profile_sensor_data)
    pause = node.create_client(SetBool, '/crawler_sim/pause')

    def spin_until(cond, what: str, timeout: float) -> None:
        end = time.monotonic() + timeout
        while not cond():
            for child in children:
                if child.popen.poll() is not None:
                    raise RuntimeError(f'{child.name} exited with {child.popen.returncode}')
            if time.monotonic() > end:
                raise RuntimeError(f'timed out after {timeout:g} s waiting for {what}')
            rclpy.spin_once(node, timeout_sec=0.05)

    def set_paused(value: bool) -> None:
        spin_until(pause.service_is_ready, 'the ~/pause service', DEADLINE_CONNECT)
        future = pause.call_async(SetBool.Request(data=value))
        spin_until(future.done, 'the ~/pause response', DEADLINE_CONNECT)

    try:
        # the gait node sends its whole stroke as one trajectory (stamp 0 = from the tick it is
        # applied) to the paused sim: the run starts only once it is there, so every run gets
        # the same command stream at the same ticks and crawls the same
        spin_until(lambda: int(diag.get('trajectories_accepted', 0)) >= 1,
                   'sim_node to receive the gait', DEADLINE_CONNECT)
        set_paused(False)
        start = time.monotonic()
        last_print = 0.0
        end_ns = to_ns(duration)

        tty = sys.stdout.isatty()
        cr = '\r' if tty else ''

        def done() -> bool:
            nonlocal last_print
            now = time.monotonic()
            if now - last_print > (0.5 if tty else 5.0):
                last_print = now
                print(f'{cr}  sim time {to_seconds(sim_ns[0]):6.2f} s / {duration:g} s',
                      end='' if tty else '\n', flush=True)
            return sim_ns[0] >= end_ns

        spin_until(done, f'{duration:g} simulated seconds', 60.0 + 20.0 * duration)
        wall = time.monotonic() - start
        set_paused(True)
        print(f'{cr}  sim time {to_seconds(sim_ns[0]):6.2f} s / {duration:g} s')
        final = dict(diag)
        spin_until(lambda: diag.get('paused') == 'true', 'the final diagnostics', 10.0)
        final = dict(diag)
        return wall, final
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _summary(bag: Path, png: Path, duration: float, wall: float, diag: dict[str, str]) -> None:
    from crawler_sim import bag as bags

    print(f'real-time factor: {duration / wall:.1f} ({duration:g} sim s in {wall:.2f} wall s)')
    try:
        run = bags.load(bag)
    except Exception as exc:  # the bag is optional for the figures below
        print(f'cannot read {bag}: {exc}')
        print(f'contact events: {diag.get("solver_events", "?")}')
        return
    keep = run.t <= duration + 1e-9
    t, x, contact = run.t[keep], run.x[keep], run.contact[keep]
    masses = np.asarray(run.scene.get('masses', np.ones(run.p)), dtype=float)
    com = x @ masses / masses.sum()
    distance = float(com[-1] - com[0])
    span = float(t[-1] - t[0]) if len(t) > 1 else float('nan')
    stick = (contact == 0).mean(axis=0)
    events = run.events.t
    n_events = int(np.count_nonzero(events <= duration + 1e-9))
    print(f'distance crawled (centre of mass): {distance * 1000:+.2f} mm in {span:.2f} s')
    print(f'mean speed: {distance / span * 1000:+.3f} mm/s')
    print('stick fraction per body: '
          + ', '.join(f'body_{i} {f:.1%}' for i, f in enumerate(stick)))
    print(f'contact events in the first {duration:g} s: {n_events} (the bag holds '
          f'{len(events)}, all the sim reported until it stopped: '
          f'{diag.get("solver_events", "?")}), method {diag.get("method", "?")}')
    print(f'bag: {bag}')
    try:
        print(f'plot: {bags.plot(bag, png)}')
    except Exception as exc:
        print(f'plot failed: {exc}')


if __name__ == '__main__':
    sys.exit(main())
