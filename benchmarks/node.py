"""Benchmark of the colcon-installed sim_node (prints figures; not a test).

    nice python -m benchmarks.node [--seconds 12] [--repeats 3] [--method exact]
                                    [--only flat,realtime,flood,huge]

(with the environment of ``make``: AMENT_PREFIX_PATH=install/crawler_sim:.venv, or a sourced
workspace). The seed's two-body default, integration at 1 kHz, every output at 100 Hz with a
subscriber (this process, taking raw bytes), the crawler moving: gait_node preloads its stroke
as one trajectory, so it costs no CPU during the run. Scenarios (issue 11 and 12 floors):

- ``flat``: real_time_factor 0: speed-up over real time (sim s per wall s, from the sim_time of
  successive /diagnostics and their arrival times). Floor >= 20x. Also the node's CPU per
  simulated second: on a machine with fewer free cores than busy processes (this one, the
  subscribers and gait_node all run flat out) the speed-up follows the share of a core the node
  gets, this figure does not.
- ``realtime``: real_time_factor 1: CPU of the sim_node process in % of one core (from /proc,
  after a warm-up) and tick lateness p99 (per diagnostics period: median period and worst).
  Floors <= 10 % and < 1 ms.
- ``flood``: real time while this process sends 1,000 invalid commands/s and 100 invalid
  trajectories/s: real-time factor and p99. Floors >= 0.95 and < 5 ms.
- ``huge``: real time; one valid 100k-point trajectory is sent: its intake time (parse and
  checks, reported by the node) and the real-time factor and p99 afterwards. Floor < 100 ms.
- ``record`` (not in the default list): alternated pairs of ``realtime`` runs without and with
  recording every output to a bag; the median extra CPU (issue 5's floor: at most 10 %).
- ``clock`` (not in the default list; issue 42): ``--runs`` runs each of 2 and 3 namespaced sims
  (``--robots``) started with random delays of 0-3 s while ``--load`` busy processes run, the
  /clock owner killed with SIGKILL mid-run (:func:`clock_run`). Floors, every run: no /clock
  message backwards, no sim frozen longer than 1.5 s, exactly one /clock publisher before the
  kill, the clock ticking again after it.

Each scenario runs ``--repeats`` times; the medians are printed, with a baseline measured in
this process: the core engine alone (actuator + exact solver, no ROS) flat out on the same
command stream, so the node's overhead reads as the ratio of the two speed-ups.
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import time


from crawler_sim.ros.workspace import executable, share, workspace_env

WARMUP = 3.0
GAIT_SECONDS = 600.0     # the preloaded stroke (30,000 points) outlasts any run


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process [s]."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def start(name: str, env: dict, *args: str) -> subprocess.Popen:
    return subprocess.Popen([str(executable(name)), '--ros-args', *args], env=env,
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


def engine_baseline(seconds: float = 3.0) -> float:
    """Speed-up of the core engine alone (no ROS) on the default two-body crawler driven by the
    default stroke, sampled at 50 Hz (sim s per wall s)."""
    from crawler_sim.core import gaits
    from crawler_sim.core.plant import Engine
    from crawler_sim.ros.sim.params import PARAMETERS, SimConfig
    cfg = SimConfig.from_values({k: v[0] for k, v in PARAMETERS.items()})
    gait = gaits.Scallop(0.1, 0.02, 2.0, 0.2, [0.0], n_links=1)
    engine = Engine(cfg.engine_config())
    n = round(seconds * 1000)
    t0 = time.perf_counter()
    for k in range(n):
        if k % 20 == 0:
            engine.command(gait.length(k / 1000).tolist())
        engine.tick()
    return seconds / (time.perf_counter() - t0)


def _huge_trajectory(n: int = 100_000):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    msg = JointTrajectory(joint_names=['linkage_0'])
    for k in range(n):
        pt = JointTrajectoryPoint(positions=[0.1 + 0.02 * math.sin(4 * math.pi * k / 1000)])
        pt.time_from_start.sec, pt.time_from_start.nanosec = divmod((k + 1) * 1_000_000,
                                                                    1_000_000_000)
        msg.points.append(pt)
    return msg


def run(scenario: str, seconds: float, method: str, env: dict,
        extra: tuple[str, ...] = (), bodies: int = 2) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray, Int8MultiArray
    from std_srvs.srv import SetBool
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    from visualization_msgs.msg import MarkerArray

    fast = scenario == 'flat'
    sim = start('sim_node', env, '--params-file',
                str(share() / 'config' / 'ros' / 'crawler_sim.yaml'),
                '-p', f'method:={method}', '-p', f'real_time_factor:={0.0 if fast else 1.0}',
                '-p', 'start_paused:=true', '-p', 'diagnostics_period:=1.0',
                *(('-p', f'masses:={[1.0] * bodies}') if bodies != 2 else ()), *extra)
    gait = start('gait_node', env, '-p', f'n_links:={bodies - 1}',
                 '-p', 'use_sim_time:=true', '-p', 'mode:=trajectory',
                 '-p', 'preload:=true', '-p', f'duration:={GAIT_SECONDS}', '-p', 'rate:=50.0')
    procs = [sim, gait]
    rclpy.init()
    node = Node('node_bench')
    diags: list[dict] = []
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: diags.append(
        {**{kv.key: kv.value for kv in m.status[0].values}, 'received': time.monotonic()}), 100)
    for typ, topic in ((JointState, 'body_states'), (JointState, 'joint_states'),
                       (Int8MultiArray, 'contact_states'), (JointState, 'contacts'),
                       (Odometry, 'odom'), (MarkerArray, 'markers'), (Clock, '/clock')):
        node.create_subscription(typ, topic, lambda m: None, 10, raw=True)
    pause = node.create_client(SetBool, '/crawler_sim/pause')
    cmd_pub = node.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
    traj_pub = node.create_publisher(JointTrajectory, 'linkage_trajectory', 10)
    bad_cmd = Float64MultiArray(data=[0.1, 0.1])              # wrong size
    bad_traj = JointTrajectory(joint_names=['linkage_0'])      # stamped far in the future
    bad_traj.header.stamp.sec = 200_000_000
    bad_traj.points = [JointTrajectoryPoint(positions=[0.1]) for _ in range(2)]
    bad_traj.points[1].time_from_start.nanosec = 1
    huge = _huge_trajectory() if scenario == 'huge' else None
    try:
        end = time.monotonic() + 60
        while not (diags and pause.service_is_ready()
                   and int(diags[-1].get('trajectories_accepted', 0)) >= 1):
            if time.monotonic() > end:
                raise RuntimeError('sim_node and gait_node did not come up within 60 s')
            rclpy.spin_once(node, timeout_sec=0.05)
        future = pause.call_async(SetBool.Request(data=False))
        while not future.done():
            rclpy.spin_once(node, timeout_sec=0.05)
        t0 = time.monotonic()
        n_diag0 = len(diags)
        cpu0 = w0 = d0 = None
        sent = 0
        while time.monotonic() - t0 < seconds:
            now = time.monotonic()
            if cpu0 is None and now - t0 >= WARMUP:
                cpu0, w0, d0 = cpu_seconds(sim.pid), now, len(diags)
                if huge is not None:
                    traj_pub.publish(huge)
            if scenario == 'flood' and cpu0 is not None:
                due = int((now - w0) * 1000)          # 1,000 commands/s, 100 trajectories/s
                while sent < due:
                    cmd_pub.publish(bad_cmd)
                    if sent % 10 == 0:
                        traj_pub.publish(bad_traj)
                    sent += 1
                rclpy.spin_once(node, timeout_sec=0.0)
                time.sleep(0.002)
            else:
                rclpy.spin_once(node, timeout_sec=0.05)
        cpu = (cpu_seconds(sim.pid) - cpu0) / (time.monotonic() - w0)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        stop(*reversed(procs))
    steady = diags[max(d0 + 1, n_diag0 + 1):]
    out = {'scenario': scenario, 'cpu_percent': 100 * cpu, 'sent': sent}
    if steady:
        p99 = [float(d['tick_lateness_p99_ms']) for d in steady]
        last = steady[-1]
        out.update(p99_median_ms=statistics.median(p99), p99_worst_ms=max(p99),
                   rtf=statistics.median(float(d['real_time_factor']) for d in steady),
                   events=int(last['solver_events']),
                   rejected=int(last['commands_rejected']) + int(last['trajectories_rejected']),
                   intake_ms=float(last['last_trajectory_intake_ms']),
                   traj_accepted=int(last['trajectories_accepted']))
    if fast and len(steady) > 1:
        first, last = steady[0], steady[-1]
        out['speedup'] = ((float(last['sim_time']) - float(first['sim_time']))
                          / (last['received'] - first['received']))
        # the node's own cost, whatever share of a core it got on a busy machine
        out['cpu_ms_per_sim_s'] = 1e3 * cpu / out['speedup']
    return out


#: a sim's time may stand still at most this long (wall s) in a ``clock`` run (issue 42)
MAX_FREEZE = 1.5


def _stamp_ns(data: bytes, offset: int = 4) -> int:
    """The header stamp [ns] of a message in little-endian CDR (offset 4: after the
    encapsulation header; a Clock is its stamp)."""
    import struct
    sec, nanosec = struct.unpack_from('<iI', data, offset)
    return sec * 1_000_000_000 + nanosec


def _runq_ns(pid: int) -> int:
    """Nanoseconds the main thread of process ``pid`` (a sim's loop) has spent runnable but
    waiting on the run queue (/proc/<pid>/schedstat, second field); 0 once it is gone."""
    try:
        return int(Path(f'/proc/{pid}/schedstat').read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return 0


def clock_run(env: dict, robots: int, seed: int, *, load: int = 2, max_delay: float = 3.0,
              after_kill: float = 4.0, stall: float = 0.0, tmp: Path | None = None) -> dict:
    """One run of the shared clock under stress: ``robots`` sims (namespaces /r1...,
    real_time_factor 1) started in random order with random delays (``seed``) while ``load``
    busy processes run; once every sim has published for 3 s, the /clock owner (the one
    publisher the graph shows) is killed with SIGKILL; the survivors run ``after_kill`` s more
    and are stopped with SIGINT. ``stall`` > 0: the survivors are stopped (SIGSTOP) from 0.1 s
    before the kill until ``stall`` s after it, as the kernel of a loaded machine leaves a
    runnable process waiting on the run queue, across the owner's last messages.
    Measured from the DDS source timestamps of what this process receives (not its own,
    possibly starved, loop): /clock messages that went backwards, the longest time each sim's
    body_states stamp stood still (``max_freeze``; a stretch over which this process missed
    some of the sim's messages, told by their sequence numbers, is not a freeze: it goes to
    ``unobserved``), the longest /clock silence after the kill (and after the SIGCONT:
    ``silence_after_cont``), /clock publishers before the kill, exit codes, tracebacks; and
    how long the kernel kept each sim's loop waiting on the run queue during its longest
    freeze (``freeze_runq``, from /proc/<pid>/schedstat read as this process runs: a lower
    bound)."""
    import random
    import tempfile
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from crawler_sim.ros.sim.taken import LoopTakenGroup

    rng = random.Random(seed)
    names = [f'r{k + 1}' for k in range(robots)]
    delays = sorted((rng.uniform(0.0, max_delay), ns) for ns in rng.sample(names, robots))
    busy = [subprocess.Popen([sys.executable, '-c', 'while 1: pass']) for _ in range(load)]
    ctx = Context()
    rclpy.init(context=ctx, domain_id=int(env.get('ROS_DOMAIN_ID', '0')))
    node = Node('clock_observer', context=ctx)
    group = LoopTakenGroup()
    takes = {}
    for topic, typ in [('/clock', Clock)] + [(f'/{ns}/body_states', JointState) for ns in names]:
        sub = node.create_subscription(typ, topic, lambda _m: None, 1000, raw=True,
                                       callback_group=group)
        takes[topic] = (sub.handle.take_message, typ, [])
    procs: dict[str, subprocess.Popen] = {}
    errs: dict[str, Path] = {}
    tmpdir = tempfile.TemporaryDirectory() if tmp is None else None
    where = Path(tmpdir.name) if tmpdir is not None else tmp

    runq: dict[str, list[tuple[int, int]]] = {ns: [] for ns in names}

    def drain() -> None:
        for take, typ, got in takes.values():
            msg = take(typ, True)
            while msg is not None:
                got.append((msg[1]['source_timestamp'], _stamp_ns(msg[0]),
                            msg[1]['publication_sequence_number']))
                msg = take(typ, True)
        for ns, p in procs.items():
            runq[ns].append((time.time_ns(), _runq_ns(p.pid)))

    def wait(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            drain()
            time.sleep(0.01)

    out: dict = {'robots': robots, 'seed': seed, 'delays': [round(d, 2) for d, _ in delays]}
    try:
        t0 = time.monotonic()
        for delay, ns in delays:
            while time.monotonic() - t0 < delay:
                drain()
                time.sleep(0.01)
            errs[ns] = where / f'{ns}_{seed}.err'
            procs[ns] = subprocess.Popen(
                [str(executable('sim_node')), '--ros-args', '-r', f'__ns:=/{ns}', '-p',
                 f'masses:={[1.0] * (names.index(ns) + 2)}', '-p', 'diagnostics_period:=0.5'],
                env=env, stdout=subprocess.DEVNULL, stderr=open(errs[ns], 'w'))
        end = time.monotonic() + 60.0
        ready = None
        while True:
            drain()
            now = time.monotonic()
            if all(takes[f'/{ns}/body_states'][2] for ns in names):
                ready = ready or now
                if now - ready >= 3.0:
                    break
            if now > end:
                raise RuntimeError(f'not every sim published within 60 s: {out}')
            time.sleep(0.01)
        pubs = [info.node_namespace.strip('/')
                for info in node.get_publishers_info_by_topic('/clock')]
        out['publishers_before_kill'] = len(pubs)
        owner = pubs[0] if pubs else names[0]
        out['killed'] = owner
        out['loadavg'] = round(os.getloadavg()[0], 1)
        survivors = [ns for ns in names if ns != owner]
        if stall:
            for ns in survivors:
                procs[ns].send_signal(signal.SIGSTOP)
            wait(0.1)
        procs[owner].kill()
        kill_ns = time.time_ns()      # (after it: what the owner sent before is not after)
        if stall:
            wait(stall)
            for ns in survivors:
                procs[ns].send_signal(signal.SIGCONT)
            cont_ns = time.time_ns()
        wait(after_kill)
        codes = {}
        stop_ns = time.time_ns()
        for ns, p in procs.items():
            if ns != owner:
                p.send_signal(signal.SIGINT)
        for ns, p in procs.items():
            try:
                codes[ns] = p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                codes[ns] = 'hung'
        drain()
    finally:
        for p in list(procs.values()) + busy:
            if p.poll() is None:
                p.kill()
                p.wait()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    clock = takes['/clock'][2]
    stamps = [t for _, t, _ in clock]
    out['clock_messages'] = len(stamps)
    out['backwards'] = sum(b < a for a, b in zip(stamps, stamps[1:]))
    after = sorted(src for src, _, _ in clock if src > kill_ns)
    out['clock_silence_after_kill'] = ((after[0] - kill_ns) / 1e9 if after else math.inf)
    if stall:
        later = [src for src in after if src > cont_ns]
        out['silence_after_cont'] = round((later[0] - cont_ns) / 1e9 if later else math.inf, 3)

    def waited(ns: str, a: int, b: int) -> float:
        """Run-queue wait of ns's loop between a and b [ns], a lower bound: between the
        samples inside, or between those around less the time outside (this process may have
        been kept off the CPU too, and sampled nothing inside)."""
        got = [(t, w) for t, w in runq[ns] if w]
        inside = [w for t, w in got if a <= t <= b]
        low = (inside[-1] - inside[0]) / 1e9 if len(inside) > 1 else 0.0
        before = [(t, w) for t, w in got if t <= a]
        after = [(t, w) for t, w in got if t >= b]
        if before and after:
            (t0, w0), (t1, w1) = before[-1], after[0]
            low = max(low, (w1 - w0 - (a - t0) - (t1 - b)) / 1e9)
        return low
    freeze, unobserved, freeze_runq = {}, {}, {}
    for ns in names:
        if ns == owner:
            continue
        got = sorted(takes[f'/{ns}/body_states'][2])
        # the longest wall time (publisher's clock) between two states of increasing stamps
        # (a stretch in which messages of the sim's were missed here is not one: it published)
        longest, missed, at, last_src, last_t, last_seq = 0.0, 0.0, (0, 0), None, None, None
        gap = False
        for src, t, seq in got:
            gap = gap or (last_seq is not None and seq > last_seq + 1)
            last_seq = seq
            if last_t is None or t > last_t:
                if last_src is not None:
                    if gap:
                        missed = max(missed, (src - last_src) / 1e9)
                    elif (src - last_src) / 1e9 > longest:
                        longest, at = (src - last_src) / 1e9, (last_src, src)
                last_src, last_t, gap = src, t, False
        if last_src is not None and (stop_ns - last_src) / 1e9 > longest:
            longest, at = (stop_ns - last_src) / 1e9, (last_src, stop_ns)   # still at the end
        freeze[ns] = round(longest, 3)
        unobserved[ns] = round(missed, 3)
        freeze_runq[ns] = round(waited(ns, *at), 3)
    out['max_freeze'] = freeze
    out['unobserved'] = unobserved
    out['freeze_runq'] = freeze_runq
    out['codes'] = {ns: c for ns, c in codes.items() if ns != owner}
    text = {ns: errs[ns].read_text() for ns in names}
    out['tracebacks'] = [ns for ns, t in text.items() if 'Traceback' in t]
    out['followers_warn'] = sum('WARN' in line and 'this node follows it' in line
                                for t in text.values() for line in t.splitlines())
    # the survivors' takeovers (one WARN line each): after the kill, one takes over
    out['takeovers'] = sum('this node publishes /clock from' in line
                           for ns, t in text.items() if ns != owner for line in t.splitlines())
    if tmpdir is not None:
        tmpdir.cleanup()
    out['ok'] = (out['backwards'] == 0 and out['publishers_before_kill'] == 1
                 and all(f <= MAX_FREEZE for f in freeze.values())
                 and out['clock_silence_after_kill'] <= MAX_FREEZE
                 and all(c == 0 for c in out['codes'].values()) and not out['tracebacks'])
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=12.0, help='wall seconds per run')
    parser.add_argument('--repeats', type=int, default=3, help='runs per scenario (median)')
    parser.add_argument('--method', default='exact', help='exact | implicit | penalty')
    parser.add_argument('--only', default='flat,realtime,flood,huge',
                        help='comma-separated scenarios')
    parser.add_argument('--bodies', type=int, default=2,
                        help='number of bodies p (1 kg each; 2: the seed\'s crawler, 0.5 and 1 kg)')
    parser.add_argument('--runs', type=int, default=20, help='clock: runs per number of sims')
    parser.add_argument('--robots', default='2,3', help='clock: numbers of sims')
    parser.add_argument('--load', type=int, default=2, help='clock: busy processes')
    parser.add_argument('--stall', type=float, default=0.0,
                        help='clock: survivors stopped from 0.1 s before the kill to this long '
                             'after it (as a starved process)')
    parser.add_argument('--logs', type=Path, default=None,
                        help="clock: keep each sim's stderr in this folder (<ns>_<seed>.err)")
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = workspace_env(dict(os.environ))
    # the nodes run this checkout's crawler_sim (the one the baseline imports), not the one the
    # colcon install's build/ links to: a worktree measures its own code
    here = str(Path(__file__).resolve().parents[1])
    env['PYTHONPATH'] = os.pathsep.join([here, env.get('PYTHONPATH', '')]).rstrip(os.pathsep)
    base = statistics.median(engine_baseline() for _ in range(3))
    print(f'sim_node benchmark: {args.bodies} bodies, method {args.method}, 1 kHz integration, '
          f'every output at 100 Hz with a subscriber, {args.seconds:g} s per run, median of '
          f'{args.repeats}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}')
    print(f'  baseline (this process): core engine alone flat out {base:.1f}x real time')
    for scenario in args.only.split(','):
        if scenario == 'clock':
            # (run it in a ROS domain of its own: a node of another session publishing /clock
            # in the same domain is a foreign clock to these sims)
            for robots in (int(r) for r in args.robots.split(',')):
                runs = []
                for k in range(args.runs):
                    try:
                        if args.logs is not None:
                            args.logs.mkdir(parents=True, exist_ok=True)
                        r = clock_run(env, robots, seed=1000 * robots + k, load=args.load,
                                      stall=args.stall, tmp=args.logs)
                    except RuntimeError as exc:           # a sim that never published
                        r = {'ok': False, 'error': str(exc), 'max_freeze': {},
                             'backwards': 0, 'clock_messages': 0,
                             'clock_silence_after_kill': math.inf}
                    runs.append(r)
                    print(f'    {"PASS" if r["ok"] else "FAIL"} {r}', flush=True)
                ok = sum(r['ok'] for r in runs)
                freeze = max(f for r in runs for f in r['max_freeze'].values())
                loads = [r['loadavg'] for r in runs if 'loadavg' in r] or [math.nan]
                print(f'  clock    | {robots} sims, {args.load} busy processes (load average '
                      f'{min(loads):.1f}-{max(loads):.1f}): {ok}/{len(runs)} '
                      f'runs pass; backwards {sum(r["backwards"] for r in runs)} of '
                      f'{sum(r["clock_messages"] for r in runs)} /clock messages; longest freeze '
                      f'{freeze:.2f} s; longest /clock silence after the kill '
                      f'{max(r["clock_silence_after_kill"] for r in runs):.2f} s '
                      f'(floor: 20/20, 0, <= {MAX_FREEZE} s)', flush=True)
            continue
        if scenario == 'record':
            import tempfile
            extra = []
            with tempfile.TemporaryDirectory() as tmp:
                for k in range(args.repeats):
                    base = run('realtime', args.seconds, args.method, env)
                    rec = run('realtime', args.seconds, args.method, env, extra=(
                        '-p', 'record:=true', '-p', f'record_dir:={tmp}',
                        '-p', f'record_name:=bag{k}'))
                    extra.append(rec['cpu_percent'] / base['cpu_percent'] - 1.0)
            print(f'  record   | recording every output adds {100 * statistics.median(extra):.1f} '
                  f'% to the node\'s CPU time (median of {len(extra)} alternated pairs: '
                  f'{", ".join(f"{100 * e:+.1f}" for e in extra)} %; floor 10 %)', flush=True)
            continue
        runs = [run(scenario, args.seconds, args.method, env, bodies=args.bodies)
                for _ in range(args.repeats)]

        def med(key: str) -> float:
            vals = [r[key] for r in runs if key in r]
            return statistics.median(vals) if vals else float('nan')
        parts = [f'{scenario:8s}', f'CPU {med("cpu_percent"):5.1f} % of one core']
        if scenario == 'flat':
            parts.append(f'speed-up {med("speedup"):.2f}x (engine alone {base:.1f}x: '
                         f'ratio {med("speedup") / base:.2f}; floor 20x)')
            parts.append(f'node CPU {med("cpu_ms_per_sim_s"):.1f} ms per sim s (a whole core '
                         f'would give {1e3 / med("cpu_ms_per_sim_s"):.0f}x)')
        else:
            parts.append(f'real-time factor {med("rtf"):.3f}, tick lateness p99 '
                         f'{med("p99_median_ms"):.3f} ms (worst period '
                         f'{max(r.get("p99_worst_ms", math.nan) for r in runs):.3f} ms)')
        if scenario == 'flood':
            parts.append(f'{med("sent"):.0f} bad commands sent, {med("rejected"):.0f} rejections'
                         ' counted')
        if scenario == 'huge':
            parts.append(f'100k-point trajectory intake {med("intake_ms"):.1f} ms '
                         f'(accepted in {sum(r.get("traj_accepted", 0) >= 2 for r in runs)}'
                         f'/{len(runs)} runs)')
        print('  ' + ' | '.join(parts), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
