"""sim_node flat out with its default outputs, each taken by a minimal rclpy subscriber in one
other process (issue 42's floor: at least 2x the factor before, measured in the same run).

    nice python -m benchmarks.node_flat_out [--baseline REV] [--seconds 10] [--repeats 5]
                                            [--real-time-factor 0]
                                            [--candidate-env VAR=VALUE ...]

(with the environment of ``make``: AMENT_PREFIX_PATH=install/crawler_sim:.venv.) The colcon
install's sim_node runs the code of a source tree (PYTHONPATH first): ``--baseline REV`` is
checked out as a git worktree under ``--workdir`` (its compiled core copied from this checkout
when the Cython sources are the same, else built in place), and runs of the baseline and of this
checkout (or ``--candidate REV``, another worktree: e.g. ``HEAD``, without the working tree's
uncommitted edits) alternate, so both see the same machine. Run it in a ROS domain of its own
(``ROS_DOMAIN_ID``): another sim_node or subscriber in the domain would take part.

Each run: sim_node with the packaged parameters, ``real_time_factor:=0`` and every output at its
default (on), the seed's crawler moving on gait_node's preloaded stroke (one trajectory, no CPU
during the run); one subscriber process (:data:`SUBSCRIBER`) subscribes to every grid output,
``/clock`` and ``/tf`` with their message classes (rclpy converts each message to Python, as a
minimal subscriber does); this process takes ``/diagnostics`` only. Figures, after a warm-up:
the speed-up (sim s per wall s, from the sim_time of successive diagnostics and their arrival
times) and the node's CPU per simulated second (utime + stime of its process, /proc), which does
not depend on the share of a core the node gets on a busy machine (2 cores here: the node and
the subscriber each want one). Medians of ``--repeats`` runs per tree.

``--real-time-factor 1`` runs the same setting paced at real time instead: the figure is then
the node's CPU in % of a core (the speed-up stays 1). ``--candidate-env VAR=VALUE`` sets a
variable for the candidate's sim_node only: one tree with and without a setting, e.g.
``--baseline HEAD --candidate HEAD --candidate-env RMW_FASTRTPS_PUBLICATION_MODE=ASYNCHRONOUS``.

Each tree's sim_node configures Fast DDS as that tree's code does (from a478df3 on, its writer
profile ``crawler_sim/ros/sim/fastdds_profile.xml``, unless this environment names a profile
of its own in ``FASTRTPS_DEFAULT_PROFILES_FILE``: then both trees run with that one).
"""
from __future__ import annotations

import argparse
import filecmp
import os
from pathlib import Path
import shutil
import statistics
import subprocess
import sys
import time

from benchmarks.node import cpu_seconds, start, stop
from crawler_sim.ros.workspace import workspace_env

HERE = Path(__file__).resolve().parents[1]
WARMUP = 3.0
GAIT_SECONDS = 3600.0       # the preloaded stroke (180,000 points) outlasts any run at 100x

#: the subscriber process: one subscription per default output with its message class
SUBSCRIBER = r'''
import rclpy
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Int8MultiArray
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy
rclpy.init()
node = rclpy.create_node('flat_out_subscriber')
taken = [0]
def cb(msg):
    taken[0] += 1
for typ, topic in ((JointState, 'joint_states'), (JointState, 'body_states'),
                   (Int8MultiArray, 'contact_states'), (JointState, 'contacts'),
                   (Odometry, 'odom'), (MarkerArray, 'markers'), (Clock, '/clock')):
    node.create_subscription(typ, topic, cb, 10)
node.create_subscription(TFMessage, '/tf', cb, QoSProfile(
    depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
try:
    rclpy.spin(node)
except Exception:
    pass
'''


def _compiled(tree: Path) -> list[Path]:
    return sorted(p.relative_to(tree) for p in (tree / 'crawler_sim').rglob('*.so'))


def worktree(rev: str, workdir: Path) -> Path:
    """A git worktree of ``rev`` under ``workdir`` (made once; reused when at ``rev``), with
    this checkout's compiled extensions copied in when their sources are the same."""
    sha = subprocess.run(['git', '-C', str(HERE), 'rev-parse', rev], check=True,
                         capture_output=True, text=True).stdout.strip()
    path = workdir / f'tree-{sha[:10]}'
    if not path.exists():
        workdir.mkdir(parents=True, exist_ok=True)
        subprocess.run(['git', '-C', str(HERE), 'worktree', 'add', '--detach', str(path), sha],
                       check=True, capture_output=True)
    for so in _compiled(HERE):
        stem = so.name.split('.')[0]
        sources = [s for s in (HERE / so.parent).glob(stem + '.p*') if s.suffix in
                   ('.pyx', '.pxd')] + list((HERE / so.parent).glob('*.pxd'))
        same = all((path / s.relative_to(HERE)).is_file()
                   and filecmp.cmp(s, path / s.relative_to(HERE), shallow=False)
                   for s in sources)
        if not same:
            subprocess.run([sys.executable, 'setup.py', 'build_ext', '--inplace'], cwd=path,
                           check=True, capture_output=True)
            break
        if not (path / so).exists():
            shutil.copy2(HERE / so, path / so)
    return path


def run(tree: Path, seconds: float, env: dict, real_time_factor: float = 0.0,
        sim_env: dict | None = None) -> dict:
    """One run of the sim_node of source tree ``tree`` (flat out unless ``real_time_factor``;
    ``sim_env``: variables for sim_node only)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.context import Context
    from rclpy.node import Node
    from std_srvs.srv import SetBool

    env = dict(env)
    env['PYTHONPATH'] = os.pathsep.join([str(tree), env.get('PYTHONPATH', '')]).rstrip(
        os.pathsep)
    # the tree's own parameters file: an older tree's node refuses keys added since
    sim = start('sim_node', {**env, **(sim_env or {})}, '--params-file',
                str(tree / 'config' / 'ros' / 'crawler_sim.yaml'),
                '-p', f'real_time_factor:={float(real_time_factor)}',
                '-p', 'start_paused:=true')
    gait = start('gait_node', env, '-p', 'n_links:=1', '-p', 'use_sim_time:=true',
                 '-p', 'mode:=trajectory', '-p', 'preload:=true',
                 '-p', f'duration:={GAIT_SECONDS}', '-p', 'rate:=50.0')
    sub = subprocess.Popen([sys.executable, '-c', SUBSCRIBER], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node('flat_out_bench', context=ctx)
    diags: list[dict] = []
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diags.append(
        {**{kv.key: kv.value for kv in m.status[0].values}, 'received': time.monotonic()}), 100)
    pause = node.create_client(SetBool, '/crawler_sim/pause')
    from rclpy.executors import SingleThreadedExecutor
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        end = time.monotonic() + 60
        while not (diags and pause.service_is_ready()
                   and int(diags[-1].get('trajectories_accepted', 0)) >= 1
                   and node.count_publishers('/clock') >= 1
                   and node.count_subscribers('markers') >= 1):
            if time.monotonic() > end:
                raise RuntimeError('sim_node, gait_node and the subscriber did not come up '
                                   'within 60 s')
            ex.spin_once(timeout_sec=0.05)
        time.sleep(1.0)            # the subscriber's other readers matched too
        future = pause.call_async(SetBool.Request(data=False))
        ex.spin_until_future_complete(future, timeout_sec=10)
        t0 = time.monotonic()
        cpu0 = w0 = None
        d0 = 0
        while time.monotonic() - t0 < seconds:
            if cpu0 is None and time.monotonic() - t0 >= WARMUP:
                cpu0, w0, d0 = cpu_seconds(sim.pid), time.monotonic(), len(diags)
                sub0 = cpu_seconds(sub.pid)
            ex.spin_once(timeout_sec=0.05)
        wall = time.monotonic() - w0
        cpu = (cpu_seconds(sim.pid) - cpu0) / wall
        sub_cpu = (cpu_seconds(sub.pid) - sub0) / wall
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        stop(sub, gait, sim)
    steady = diags[d0 + 1:]
    if len(steady) < 2:
        raise RuntimeError(f'{len(steady)} diagnostics reports after the warm-up')
    first, last = steady[0], steady[-1]
    speedup = ((float(last['sim_time']) - float(first['sim_time']))
               / (last['received'] - first['received']))
    return {'speedup': speedup, 'cpu_percent': 100 * cpu, 'cpu_ms_per_sim_s': 1e3 * cpu / speedup,
            'subscriber_percent': 100 * sub_cpu}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--baseline', default=None,
                        help='git revision to compare with (a worktree under --workdir)')
    parser.add_argument('--candidate', default=None,
                        help='git revision measured against it (default: this checkout)')
    parser.add_argument('--workdir', default='/tmp/crawler_sim_flat_out', type=Path)
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds per run')
    parser.add_argument('--repeats', type=int, default=5, help='runs per tree (median)')
    parser.add_argument('--real-time-factor', type=float, default=0.0,
                        help='0: flat out (the default); e.g. 1: paced at real time')
    parser.add_argument('--candidate-env', action='append', default=[], metavar='VAR=VALUE',
                        help="a variable of the candidate's sim_node only (repeatable)")
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = workspace_env(dict(os.environ))
    sim_env = dict(item.split('=', 1) for item in args.candidate_env)
    trees: dict[str, tuple[Path, dict]] = {}
    if args.baseline:
        trees['before ' + args.baseline] = (worktree(args.baseline, args.workdir), {})
    trees['after ' + (args.candidate or 'this checkout')
          + ''.join(f' {item}' for item in args.candidate_env)] = (
        worktree(args.candidate, args.workdir) if args.candidate else HERE, sim_env)
    pace = (f'real_time_factor {args.real_time_factor:g}' if args.real_time_factor > 0
            else 'flat out')
    print(f'sim_node {pace}, default outputs, one subscriber process taking each; '
          f'{args.seconds:g} s per run, median of {args.repeats}, {os.cpu_count()} CPUs, '
          f'load {os.getloadavg()[0]:.1f}', flush=True)
    results: dict[str, list[dict]] = {name: [] for name in trees}
    for k in range(args.repeats):            # alternated: both trees see the same machine
        for name, (tree, extra) in trees.items():
            r = run(tree, args.seconds, env, args.real_time_factor, extra)
            results[name].append(r)
            print(f'    run {k + 1} {name}: {r["speedup"]:.1f}x real time, '
                  f'{r["cpu_ms_per_sim_s"]:.1f} ms CPU per sim s, '
                  f'{r["cpu_percent"]:.1f} % of a core (the subscriber '
                  f'{r["subscriber_percent"]:.0f} %)', flush=True)
    med = {name: {key: statistics.median(r[key] for r in runs) for key in runs[0]}
           for name, runs in results.items()}
    for name, m in med.items():
        print(f'  {name:30s} speed-up {m["speedup"]:5.1f}x | node CPU '
              f'{m["cpu_ms_per_sim_s"]:5.1f} ms per sim s | {m["cpu_percent"]:.1f} % of a core '
              f'(the subscriber {m["subscriber_percent"]:.0f} %)')
    if len(med) == 2:
        (_, b), (_, a) = med.items()
        print(f'  ratio after/before: speed-up {a["speedup"] / b["speedup"]:.2f}x, '
              f'CPU per sim s {b["cpu_ms_per_sim_s"] / a["cpu_ms_per_sim_s"]:.2f}x less'
              + (f', % of a core {b["cpu_percent"] / a["cpu_percent"]:.2f}x less'
                 if args.real_time_factor > 0 else ' (floor: speed-up >= 2x)'))
    print(f'  load at the end {os.getloadavg()[0]:.1f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
