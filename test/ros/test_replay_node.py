"""replay_node, the colcon-built executable found through the ament index, as its own process.

Real DDS between processes on this host, in the session's ROS_DOMAIN_ID (conftest.py). Every
wait has a deadline. replay_node is started with ``wait_for_subscribers:=1`` and
``start_paused:=true`` and resumed through ``~/pause`` only once both sides have discovered each
other: a publisher that has matched a reader can still publish before that reader has matched
it, and then a reliable sample arrives late (after the next heartbeat), which would spoil the
timing checks.
"""
from __future__ import annotations

from pathlib import Path
import signal
import time

from ament_index_python.packages import get_package_share_directory
from builtin_interfaces.msg import Duration as BuiltinDuration
from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray
import yaml

from crawler_sim.bag import BagWriter, load
from crawler_sim.ros.messages import diagnostics_msg, ns_from_stamp, stamp_from_ns
from crawler_sim.ros.replay_node import publish_period_ns, shift_stamps

from test.support.ros import PROCESS_DEADLINE as DEADLINE, Proc, diagnostics_values

RATE = 5.0
# (log time [s], topic, payload): commands and body states at known, uneven log times
CMDS = [(1.0, [0.10, 0.11]), (1.5, [0.12, 0.13]), (2.0, [0.14, 0.15]), (3.0, [0.16, 0.17]),
        (4.0, [0.18, 0.19])]
STATES = [(1.25, [0.0, 0.1, 0.2]), (3.5, [0.01, 0.11, 0.21])]


def ns(t: float) -> int:
    return round(t * 1e9)


def make_bag(path: Path) -> Path:
    """A small bag: /linkage_cmd at CMDS times, /body_states at STATES times, and the scene."""
    w = BagWriter(path, scene={'masses': [1.0, 1.0, 1.0]})
    events = [(t, '/linkage_cmd', 'std_msgs/msg/Float64MultiArray', Float64MultiArray(data=d))
              for t, d in CMDS]
    for t, x in STATES:
        msg = JointState(name=['body_0', 'body_1', 'body_2'], position=x,
                         velocity=[0.5 * v for v in x], effort=[-1.0, 0.0, 1.0])
        msg.header.stamp = stamp_from_ns(ns(t))
        events.append((t, '/body_states', 'sensor_msgs/msg/JointState', msg))
    for t, topic, type_name, msg in sorted(events, key=lambda e: e[0]):
        w.write(topic, type_name, msg, ns(t))
    w.close()
    return path


class Received:
    """Messages of one topic with their monotonic arrival times."""

    def __init__(self, peer, cls, topic: str, depth: int = 1000) -> None:
        self.msgs: list = []
        self.wall: list[float] = []
        peer.node.create_subscription(cls, topic, self._on, depth)

    def _on(self, msg) -> None:
        self.msgs.append(msg)
        self.wall.append(time.monotonic())

    def __len__(self) -> int:
        return len(self.msgs)


def replay(tmp_path: Path, env: dict, *params: str) -> Proc:
    args: list[str] = []
    for p in ('wait_for_subscribers:=1', 'start_paused:=true') + params:
        args += ['-p', p]
    proc = Proc(tmp_path, env, 'replay_node', *args)
    return proc


def resume_when_discovered(peer, topics: list[str]) -> None:
    """Resume replay_node once the peer's graph shows its publisher on every topic."""
    peer.until(lambda: all(peer.node.count_publishers(t) >= 1 for t in topics),
               f'replay_node publishers on {topics}')
    assert peer.call(SetBool, '/replay_node/pause', SetBool.Request(data=False)).success


def wait_exit(peer, proc: Proc, timeout: float = DEADLINE) -> tuple[int, str]:
    """Spin the peer until ``proc`` exits on its own; its exit code and stderr."""
    peer.until(lambda: proc.popen.poll() is not None, 'replay_node to exit', timeout)
    return proc.stop()


def test_replay_publishes_every_message_in_order_with_its_timing_and_clock(
        ament_env, peer, tmp_path):
    bag = make_bag(tmp_path / 'bag')
    cmds = Received(peer, Float64MultiArray, '/linkage_cmd')
    states = Received(peer, JointState, '/body_states')
    clock = Received(peer, Clock, '/clock')
    proc = replay(tmp_path, ament_env, f'bag:={bag}', f'rate:={RATE}')
    try:
        resume_when_discovered(peer, ['/linkage_cmd', '/body_states', '/clock'])
        peer.until(lambda: len(cmds) >= 1, 'the first command')
        scene_publishers = peer.node.count_publishers('/crawler_sim/scene')
        code, err = wait_exit(peer, proc)
        peer.until(lambda: len(cmds) >= len(CMDS) and len(states) >= len(STATES)
                   and len(clock) >= 7, 'every message')
    finally:
        proc.kill()
    assert code == 0 and 'Traceback' not in err, err
    assert scene_publishers == 0          # the latched scene is not played by default

    # every message, in order, with the same content
    assert [list(m.data) for m in cmds.msgs] == [d for _, d in CMDS]
    assert [(ns_from_stamp(m.header.stamp), list(m.position), list(m.velocity), list(m.effort))
            for m in states.msgs] == [(ns(t), x, [0.5 * v for v in x], [-1.0, 0.0, 1.0])
                                      for t, x in STATES]
    # /clock: the log time of every batch, in order
    times = sorted({t for t, _ in CMDS} | {t for t, _ in STATES})
    assert [ns_from_stamp(m.clock) for m in clock.msgs] == [ns(t) for t in times]
    # paced at `rate`: the wall span of the commands is their log-time span / RATE, not the
    # span at rate 1 (RATE times longer). A figure, printed, not asserted: a busy host delays
    # single arrivals by tenths of a second (issue 37: no wall-clock assertion in the tests)
    expect = np.array([(t - CMDS[0][0]) / RATE for t, _ in CMDS])
    got = np.array(cmds.wall) - cmds.wall[0]
    clock_got = np.array(clock.wall) - clock.wall[0]
    clock_expect = np.array([(t - times[0]) / RATE for t in times])
    print(f'\nreplay pacing: commands over {got[-1]:.3f} s (schedule {expect[-1]:.3f} s, off it '
          f'by <= {np.max(np.abs(got - expect)):.3f} s), /clock over {clock_got[-1]:.3f} s '
          f'(schedule {clock_expect[-1]:.3f} s)')


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_start_offset_skips_earlier_messages_loop_repeats_and_a_signal_ends_it_cleanly(
        ament_env, peer, tmp_path, sig):
    bag = make_bag(tmp_path / 'bag')
    cmds = Received(peer, Float64MultiArray, '/linkage_cmd')
    clock = Received(peer, Clock, '/clock')
    # start 1.9 s after the bag's start (1.0 s): the commands at 3.0 and 4.0 s remain
    proc = replay(tmp_path, ament_env, f'bag:={bag.resolve() / "bag_0.mcap"}', 'rate:=5',
                  'loop:=true', 'start_offset:=1.9', "topics:=['/linkage_cmd']")
    try:
        resume_when_discovered(peer, ['/linkage_cmd', '/clock'])
        peer.until(lambda: len(cmds) >= 5 and len(clock) >= 5, 'three loops')
        body_publishers = peer.node.count_publishers('/body_states')
        assert proc.popen.poll() is None      # still looping
        code, err = proc.stop(sig)
    finally:
        proc.kill()
    assert code == 0 and 'Traceback' not in err, err
    assert body_publishers == 0               # topics: only /linkage_cmd is played
    later = [d for t, d in CMDS if t >= 2.9]
    assert [list(m.data) for m in cmds.msgs[:5]] == (later * 3)[:5]
    # sim time continues: a pass spans the start point (2.9 s) to the last command (4.0 s), and
    # the one spacing of the commands played (3.0 -> 4.0 s) is the publish period
    step = (ns(4.0) - ns(2.9)) + (ns(4.0) - ns(3.0))
    assert [ns_from_stamp(m.clock) for m in clock.msgs[:5]] == [
        ns(3.0), ns(4.0), ns(3.0) + step, ns(4.0) + step, ns(3.0) + 2 * step]


# ------------------------------------------------------------- loop: sim time continues

LOOP_PERIOD = ns(0.2)                                        # the looped bag's publish grid
LOOP_TIMES = [ns(1.0) + i * LOOP_PERIOD for i in range(6)]   # log times [ns], 1.0 ... 2.0 s
LOOP_X = [[0.001 * i, 0.1 + 0.002 * i, 0.2 + 0.003 * i] for i in range(len(LOOP_TIMES))]
LOOP_CMDS = {1: [0.10, 0.11], 4: [0.12, 0.13]}               # grid index -> command
# body states are stamped at acquisition, 5 ms before they were logged: a stamp copied from
# /clock (or a clock copied from a stamp) cannot pass for the shifted recorded stamp
ACQUISITION_LAG = ns(0.005)


def make_loop_bag(path: Path) -> Path:
    """/body_states on a regular 0.2 s grid (LOOP_X), /linkage_cmd at two grid points."""
    w = BagWriter(path, scene={'masses': [1.0, 1.0, 1.0]})
    for i, (t, x) in enumerate(zip(LOOP_TIMES, LOOP_X)):
        msg = JointState(name=['body_0', 'body_1', 'body_2'], position=x,
                         velocity=[2.0 * v for v in x], effort=[0.5, 0.0, -0.5])
        msg.header.stamp = stamp_from_ns(t - ACQUISITION_LAG)
        w.write('/body_states', 'sensor_msgs/msg/JointState', msg, t)
        if i in LOOP_CMDS:
            w.write('/linkage_cmd', 'std_msgs/msg/Float64MultiArray',
                    Float64MultiArray(data=LOOP_CMDS[i]), t)
    w.close()
    return path


def test_a_loop_continues_sim_time_and_shifts_every_stamp_by_the_bag_duration_plus_a_period(
        ament_env, peer, tmp_path):
    bag = make_loop_bag(tmp_path / 'loop')
    # the step of sim time per pass, from the bag as written: its duration (metadata.yaml, as
    # `ros2 bag info` shows it) plus one publish period (its grid)
    duration = yaml.safe_load((bag / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']['duration']['nanoseconds']
    assert duration == LOOP_TIMES[-1] - LOOP_TIMES[0]
    step = duration + LOOP_PERIOD
    n = len(LOOP_TIMES)
    passes = 3                                                  # two seams
    states = Received(peer, JointState, '/body_states')
    cmds = Received(peer, Float64MultiArray, '/linkage_cmd')
    clock = Received(peer, Clock, '/clock')
    proc = replay(tmp_path, ament_env, f'bag:={bag}', f'rate:={RATE}', 'loop:=true')
    try:
        resume_when_discovered(peer, ['/body_states', '/linkage_cmd', '/clock'])
        peer.until(lambda: len(states) >= passes * n and len(clock) >= passes * n
                   and len(cmds) >= passes * len(LOOP_CMDS), f'{passes} passes of the bag')
        assert proc.popen.poll() is None                        # still looping
        code, err = proc.stop(signal.SIGINT)
    finally:
        proc.kill()
    assert code == 0 and 'Traceback' not in err, err

    def expected(times: list[int], count: int) -> list[int]:
        """``times`` shifted by k * step in pass k, for the first ``count`` messages."""
        return [times[j % len(times)] + (j // len(times)) * step for j in range(count)]

    # (a) /clock never goes backwards, and moves on by one publish period at each seam
    got_clock = [ns_from_stamp(m.clock) for m in clock.msgs]
    assert all(b > a for a, b in zip(got_clock, got_clock[1:])), got_clock
    assert [got_clock[k * n] - got_clock[k * n - 1] for k in range(1, passes)] == [
        LOOP_PERIOD] * (passes - 1)
    assert got_clock == expected(LOOP_TIMES, len(got_clock))
    # (b) the header stamps of pass k are the recorded ones + k * step
    recorded_stamps = [t - ACQUISITION_LAG for t in LOOP_TIMES]
    got_stamps = [ns_from_stamp(m.header.stamp) for m in states.msgs]
    assert got_stamps == expected(recorded_stamps, len(got_stamps))
    # (c) the data are the recorded ones in every pass
    assert [(list(m.position), list(m.velocity), list(m.effort)) for m in states.msgs] == [
        (x, [2.0 * v for v in x], [0.5, 0.0, -0.5])
        for x in (LOOP_X * (len(states) // n + 1))[:len(states)]]
    recorded_cmds = [LOOP_CMDS[i] for i in sorted(LOOP_CMDS)]
    assert [list(m.data) for m in cmds.msgs] == (
        recorded_cmds * (len(cmds) // len(recorded_cmds) + 1))[:len(cmds)]


def test_the_loop_shift_reaches_every_stamp_but_keeps_durations_and_zero_trajectory_stamps():
    """shift_stamps on messages with stamps at depth, durations and sim_node's diagnostics."""
    markers = MarkerArray(markers=[Marker(id=i) for i in range(3)])
    for i, m in enumerate(markers.markers):
        m.header.stamp = stamp_from_ns(ns(1.0) + i)
        m.lifetime = BuiltinDuration(sec=2)
    shift_stamps(markers, ns(10.0))
    assert [ns_from_stamp(m.header.stamp) for m in markers.markers] == [
        ns(11.0) + i for i in range(3)]
    assert all(m.lifetime == BuiltinDuration(sec=2) for m in markers.markers)
    # a trajectory stamped 0 starts on receipt (still so after the shift); a stamped one moves
    point = JointTrajectoryPoint(positions=[0.1], time_from_start=BuiltinDuration(sec=1))
    now = JointTrajectory(joint_names=['linkage_0'], points=[point])
    later = JointTrajectory(joint_names=['linkage_0'], points=[point])
    later.header.stamp = stamp_from_ns(ns(2.5))
    shift_stamps(now, ns(10.0))
    shift_stamps(later, ns(10.0))
    assert ns_from_stamp(now.header.stamp) == 0
    assert ns_from_stamp(later.header.stamp) == ns(12.5)
    assert later.points[0].time_from_start == BuiltinDuration(sec=1)
    diag = diagnostics_msg(ns(1.5), {'sim_time': 1.5, 'real_time_factor': 2.0})
    shift_stamps(diag, ns(10.0))
    assert ns_from_stamp(diag.header.stamp) == ns(11.5)
    assert diagnostics_values(diag) == {'sim_time': '11.5', 'real_time_factor': '2'}
    # the period: sim_node's 10 ms grid, with a contact event logged between two ticks
    grid = [ns(0.01) * i for i in range(5)]
    assert publish_period_ns(sorted(grid + [ns(0.013)])) == ns(0.01)


@pytest.mark.parametrize('case', ['missing', 'not_mcap', 'no_parameter', 'bad_rate'])
def test_a_bag_that_cannot_be_played_gives_one_clear_line_and_exit_code_2(
        ament_env, tmp_path, case):
    junk = tmp_path / 'junk.mcap'
    junk.write_text('not a bag\n')
    params = {'missing': [f'bag:={tmp_path / "nope"}'], 'not_mcap': [f'bag:={junk}'],
              'no_parameter': [], 'bad_rate': [f'bag:={make_bag(tmp_path / "bag")}',
                                               'rate:=0.0']}[case]
    expected = {'missing': 'no such file', 'not_mcap': 'not an MCAP file',
                'no_parameter': "parameter 'bag' is required", 'bad_rate': 'must be > 0'}[case]
    proc = Proc(tmp_path, ament_env, 'replay_node', *[a for p in params for a in ('-p', p)])
    try:
        code = proc.popen.wait(timeout=DEADLINE)
    finally:
        proc.kill()
    proc.err.seek(0)
    err = proc.err.read()
    assert code == 2, err
    assert 'Traceback' not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], err


# ----------------------------------------------------------- record a run, replay into a live sim

LIVE_RATE = 2.0  # a pace the live sim sustains with time to spare (flat out it runs ~5-10x)
PLAN = [(0.5, [0.15, 0.12]), (2.0, [0.06, 0.16]), (3.5, [0.12, 0.07])]   # (sim time [s], cmd)
SETTLE = 1.5     # sim s after a command by which the actuator has settled and every body sticks


def sim_params(*extra: str) -> list[str]:
    config = (Path(get_package_share_directory('crawler_sim')) / 'config' / 'ros'
              / 'chain_3body.yaml')      # three bodies: commands of two lengths
    args = ['--params-file', str(config)]
    for p in ('method:=exact', 'start_paused:=true', 'diagnostics_period:=0.2') + extra:
        args += ['-p', p]
    return args


def test_a_recorded_controller_replayed_into_a_live_sim_reproduces_the_run(
        ament_env, peer, tmp_path):
    # 1. record: sim_node flat out on its own /clock, the peer commands at known sim times
    # paced at 4x, not flat out: the peer acts on /clock, and a Python peer lagging behind a
    # flat-out sim on a busy host would send commands late and too close together, breaking
    # the at-rest premise of the final comparison (checked below)
    sim = Proc(tmp_path, ament_env, 'sim_node', *sim_params(
        'publish_clock:=true', 'real_time_factor:=4.0', 'record:=true',
        f'record_dir:={tmp_path}', 'record_name:=rec'))
    try:
        node = peer.node
        sim_clock = Received(peer, Clock, '/clock')
        applied = Received(peer, JointState, '/crawler_sim/applied_command')
        pub = node.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
        peer.until(lambda: pub.get_subscription_count() > 0, 'the recording sim to connect')
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success
        now = lambda: ns_from_stamp(sim_clock.msgs[-1].clock) if sim_clock.msgs else 0  # noqa
        for t_act, data in PLAN:
            peer.until(lambda: now() >= ns(t_act), f'sim time {t_act} s')
            n = len(applied)
            pub.publish(Float64MultiArray(data=data))
            peer.until(lambda: len(applied) > n, 'the applied command')
        t_end = ns_from_stamp(applied.msgs[-1].header.stamp) + ns(SETTLE)
        peer.until(lambda: now() >= t_end, 'the end of the recording')
        code, err = sim.stop(signal.SIGINT)
    finally:
        sim.kill()
    assert code == 0 and 'Traceback' not in err, err
    node.destroy_publisher(pub)         # the live sim below must only see replay_node's
    rec = load(tmp_path / 'rec')
    assert [list(v) for v in rec.commands.values] == [d for _, d in PLAN]
    assert np.ptp(rec.x[:, 0]) > 0.01                          # the commands moved the crawler

    # 2. replay only /linkage_cmd into a fresh sim_node (no recording, no /clock of its own,
    #    paced at the same speed as the replay so command spacing in sim time is preserved)
    live = Proc(tmp_path, ament_env, 'sim_node', *sim_params(
        'publish_clock:=false', f'real_time_factor:={LIVE_RATE}'))
    player = None
    try:
        live_applied = Received(peer, JointState, '/crawler_sim/applied_command')
        live_states = Received(peer, JointState, '/body_states', depth=100000)
        bag_clock = Received(peer, Clock, '/clock')
        diags = Received(peer, DiagnosticArray, '/diagnostics')
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success
        player = replay(tmp_path, ament_env, f'bag:={tmp_path / "rec"}', f'rate:={LIVE_RATE}',
                        "topics:=['/linkage_cmd']")
        peer.until(lambda: diags.msgs and int(diagnostics_values(diags.msgs[-1])[
            'linkage_cmd_publishers']) >= 1, 'the live sim to discover replay_node')
        resume_when_discovered(peer, ['/linkage_cmd', '/clock'])
        code, err = wait_exit(peer, player, timeout=60.0)
        assert code == 0 and 'Traceback' not in err, err
        peer.until(lambda: len(live_applied) >= len(PLAN), 'the live sim to apply every command')
        t_last = ns_from_stamp(live_applied.msgs[-1].header.stamp)
        peer.until(lambda: live_states.msgs and ns_from_stamp(
            live_states.msgs[-1].header.stamp) >= t_last + ns(SETTLE), 'the live sim to settle')
        code, err = live.stop(signal.SIGINT)
    finally:
        live.kill()
        if player is not None:
            player.kill()
    assert code == 0 and 'Traceback' not in err, err

    # the live sim applied the same commands in the same order ...
    assert [list(m.position) for m in live_applied.msgs] == [d for _, d in PLAN]
    # ... at the recorded spacing (sim time of the live sim vs log time of the bag; the live sim
    # is paced by the wall clock, so allow for delivery and scheduling jitter x LIVE_RATE)
    rec_t = np.array([ns(t) for t in rec.commands.t])
    live_t = np.array([ns_from_stamp(m.header.stamp) for m in live_applied.msgs])
    # the premise: every recorded command came with the crawler at rest (>= 1.2 s apart)
    assert np.min(np.diff(rec_t)) >= ns(1.2), rec_t
    # (a bound from the premise of the final-state check below, not a timing figure: the plan
    # leaves SETTLE = 1.5 s between commands and the crawler is at rest well within 1 s, so a
    # shift of 0.25 s, several times the jitter of a busy host x LIVE_RATE, keeps it valid)
    assert np.max(np.abs(np.diff(live_t) - np.diff(rec_t))) < ns(0.25), (live_t, rec_t)
    # /clock from replay_node carried the bag's log times of the commands
    assert [ns_from_stamp(m.clock) for m in bag_clock.msgs] == rec_t.tolist()
    # ... and ends in the recorded state. sim_node is not a /clock follower: a command lands at
    # the live sim's next tick, a few ms of sim time away from the recorded tick, so bit-for-bit
    # equality cannot be expected. But every command arrives with the crawler at rest (SETTLE
    # after the previous one: the 3rd-order actuator with 5 Hz bandwidth has decayed below
    # 1e-20 m and every body sticks), and the dynamics are time-invariant, so a shift of the
    # command time shifts the motion without changing where it ends. What remains is rounding
    # from where the exact solver cuts its segments (the 10 ms publish grid falls elsewhere in
    # the motion): ~1e-15 m per segment; 1e-9 m leaves ample margin and is far below the
    # 1e-2 m the crawler moves.
    final = next(m for m in live_states.msgs
                 if ns_from_stamp(m.header.stamp) >= t_last + ns(SETTLE))
    spacing = np.max(np.abs(np.diff(live_t) - np.diff(rec_t))) / 1e9
    diff = np.max(np.abs(np.asarray(final.position) - rec.x[-1]))
    print(f'\nlive replay: command spacing off by <= {spacing:.3f} s, final state by {diff:.2e} m')
    assert np.max(np.abs(rec.v[-1])) < 1e-12 and np.max(np.abs(np.asarray(final.velocity))) < 1e-12
    assert np.max(np.abs(np.asarray(final.position) - rec.x[-1])) < 1e-9, (final.position,
                                                                        rec.x[-1])
