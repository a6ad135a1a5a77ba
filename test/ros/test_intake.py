"""sim_node intake without DDS: trajectory parsing, validation, rejection cost (issue 11: 1, 3,
4 and the command part of 9)."""
from __future__ import annotations

import math
import struct

from hypothesis import given, settings, strategies as hst
import numpy as np
import pytest
from rclpy.serialization import serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.core.actuator import TrajectoryReference
from crawler_sim.bag import trajarrays
from crawler_sim.ros.sim import intake
from crawler_sim.core.plant.inputs import check_command
from crawler_sim.ros.sim.intake import RejectionLog
from crawler_sim.bag.trajarrays import MAX_TRAJECTORY_POINTS, TrajectoryFormatError

LO, HI = 0.02, 0.5


def traj(n_pts: int, n_links: int = 1, vel: bool = False, acc: bool = False, frame: str = '',
         stamp_ns: int = 0, step_ns: int = 10_000_000, start_ns: int | None = None
         ) -> JointTrajectory:
    msg = JointTrajectory(joint_names=[f'linkage_{j}' for j in range(n_links)])
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    first = step_ns if start_ns is None else start_ns
    for k in range(n_pts):
        pt = JointTrajectoryPoint(positions=[0.1 + 1e-4 * k + 0.01 * j for j in range(n_links)])
        last = k == n_pts - 1
        if vel:
            pt.velocities = [0.0 if last else 0.01 * (k + j) for j in range(n_links)]
        if acc:
            pt.accelerations = [-0.5 * (k + j) for j in range(n_links)]
        pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(first + k * step_ns,
                                                                    1_000_000_000)
        msg.points.append(pt)
    return msg


# --------------------------------------------------------------------------- parsing

@pytest.mark.parametrize('n_links', [1, 2, 3])
@pytest.mark.parametrize('vel,acc', [(False, False), (True, False), (True, True)])
@pytest.mark.parametrize('frame', ['', 'ab', 'odom1'])      # shifts the point alignment
@pytest.mark.parametrize('n_pts', [0, 1, 2, 3, 8])
def test_the_numpy_parser_reads_what_rclpy_reads(n_links, vel, acc, frame, n_pts):
    # independent reference: rclpy's own deserialisation of the same bytes (from_message)
    msg = traj(n_pts, n_links, vel, acc, frame, stamp_ns=5_000_000_007)
    got = trajarrays.parse(serialize_message(msg))
    want = trajarrays.from_message(msg)
    assert got.stamp_ns == 5_000_000_007 == want.stamp_ns
    assert got.joint_names == want.joint_names
    np.testing.assert_array_equal(got.tfs_ns, want.tfs_ns)
    np.testing.assert_array_equal(got.positions, want.positions)
    for field in ('velocities', 'accelerations'):
        a, b = getattr(got, field), getattr(want, field)
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_array_equal(a, b)


def test_points_of_different_shapes_are_refused_without_rclpys_per_point_parse():
    msg = traj(3, 1)
    msg.points[1].velocities = [0.0]
    with pytest.raises(TrajectoryFormatError, match='points differ'):
        trajarrays.parse(serialize_message(msg))
    reason, prepared = intake.prepare(serialize_message(msg), 1, LO, HI, 0, 3600.0)
    assert prepared is None and 'points differ' in reason


@pytest.mark.parametrize('names,positions,problem', [
    (['linkage_0'], 1001, 'mismatch between joint_names size (1) and positions (1001)'),
    (['linkage_0', 'linkage_1'], 1, "unknown joint 'linkage_1' (expected linkage_0)"),
    (['elbow'], 1, "unknown joint 'elbow'"),
])
def test_a_message_that_breaks_the_head_rules_is_refused_before_its_points_are_read(
        names, positions, problem):
    """Issue 25: an 80 MB trajectory (10k points x 1001 positions) cost 0.5-1.2 s of the sim
    loop. The head (names, the first point's sizes) is checked before any point: the parser
    never reads the rest, so a message whose remaining bytes are garbage is refused the same."""
    msg = JointTrajectory(joint_names=names)
    pt = JointTrajectoryPoint(positions=[0.1] * positions)
    pt.time_from_start.sec = 1
    msg.points = [pt] * 3
    data = serialize_message(msg)
    head = len(data) - 2 * (len(data) - 40) // 3            # cut into the second point
    garbage = data[:head] + b'\xff' * (len(data) - head)
    for raw in (data, garbage):
        reason, prepared = intake.prepare(raw, 1, LO, HI, 0, 3600.0)
        assert prepared is None and problem in reason, reason


def test_a_point_count_above_the_limit_is_refused_from_the_header_alone():
    # header (stamp 0, empty frame), one name, then a point count of limit + 1 and no points
    body = struct.pack('<iII4x', 0, 0, 1) + struct.pack('<I', 1) + struct.pack('<I', 10) \
        + b'linkage_0\x00\x00\x00' + struct.pack('<I', MAX_TRAJECTORY_POINTS + 1)
    with pytest.raises(TrajectoryFormatError, match='at most 1000000'):
        trajarrays.parse(b'\x00\x01\x00\x00' + body)


@settings(max_examples=200, deadline=None)
@given(hst.binary(max_size=300), hst.integers(0, 299))
def test_garbage_and_truncated_bytes_give_a_format_error_or_arrays_never_a_crash(junk, cut):
    good = serialize_message(traj(4, 2, vel=True))
    for data in (b'\x00\x01\x00\x00' + junk, good[:cut], good[:cut] + junk):
        try:
            trajarrays.parse(data)
        except TrajectoryFormatError:
            pass


def test_a_100k_point_trajectory_parses_to_the_same_arrays():
    msg = traj(100_000, 1)
    got = trajarrays.parse(serialize_message(msg))
    assert got.positions.shape == (100_000, 1)
    assert got.positions[-1, 0] == msg.points[-1].positions[0]
    assert got.tfs_ns[-1] == 100_000 * 10_000_000


# --------------------------------------------------------------------------- validation

def prepare(msg, t_ns=0, n_links=1, lead=3600.0):
    return intake.prepare(serialize_message(msg), n_links, LO, HI, t_ns, lead)


def test_the_2e8_stamp_with_points_1ns_apart_is_rejected_not_a_crash():
    # issue 11 point 1: stamp.sec = 2e8, two points 1 ns apart
    msg = traj(2, 1, stamp_ns=200_000_000 * 1_000_000_000, step_ns=1, start_ns=0)
    reason, prepared = prepare(msg, t_ns=1_000_000_000)
    assert prepared is None and 'ahead of the sim time' in reason
    # even with the lead allowed, times that round together are refused (float seconds:
    # 2e8 s and 2e8 s + 1 ns are the same double, spacing 3e-8 s there)
    assert 200_000_000.0 + 1e-9 == 200_000_000.0
    msg = traj(2, 1, stamp_ns=0, step_ns=1, start_ns=200_000_000 * 1_000_000_000)
    reason, prepared = prepare(msg, t_ns=0, lead=1e6)
    assert prepared is None and 'round to the same float' in reason


def test_a_wall_clock_stamp_on_sim_time_is_rejected_with_the_reason():
    wall = 1_795_000_000 * 1_000_000_000       # 2026 in ns since 1970
    reason, _ = prepare(traj(3, 1, stamp_ns=wall), t_ns=12_000_000_000)
    assert 'ahead of the sim time 12 s' in reason and 'max_trajectory_lead' in reason
    # within the lead it is accepted (a trajectory for later)
    reason, prepared = prepare(traj(3, 1, stamp_ns=60_000_000_000), t_ns=12_000_000_000)
    assert reason is None and prepared is not None


@pytest.mark.parametrize('mutate,problem', [
    (lambda m: setattr(m, 'joint_names', []), 'empty joint_names'),
    (lambda m: setattr(m, 'joint_names', ['linkage_7']), 'unknown joint'),
    (lambda m: m.points[1].time_from_start.__setattr__('sec', 0), 'not strictly increasing'),
    (lambda m: m.points[2].positions.__setitem__(0, math.nan), 'outside [min_length'),
    (lambda m: m.points[0].positions.__setitem__(0, 0.9), 'outside [min_length'),
    (lambda m: [p.effort.append(1.0) for p in m.points], 'effort'),
])
def test_invalid_trajectories_are_rejected_with_the_reason(mutate, problem):
    msg = traj(3, 1, step_ns=1_000_000_000)
    mutate(msg)
    reason, prepared = prepare(msg)
    assert prepared is None and problem in reason


def test_a_last_point_still_moving_is_rejected():
    msg = traj(3, 1, vel=True)
    msg.points[-1].velocities = [0.1]
    assert 'last trajectory point' in prepare(msg)[0]


def test_the_reference_looks_up_segments_by_bisection_and_interpolates_linearly():
    # positions only: linear interpolation between points (joint_trajectory_controller); the
    # independent method is np.interp over the same knots
    n = 10_001
    times = np.arange(1, n + 1) * 1e-3
    pos = 0.1 + 0.05 * np.sin(times)
    ref = TrajectoryReference(0.0, [(0.1, 0.0, 0.0)], times.tolist(), pos[:, None].tolist())
    knots_t = np.concatenate([[0.0], times])
    knots_p = np.concatenate([[0.1], pos])
    for t in np.linspace(0.0, times[-1] - 1e-6, 997):
        assert ref(float(t))[0][0] == pytest.approx(np.interp(t, knots_t, knots_p), abs=1e-15)


# --------------------------------------------------------------------------- commands

def test_an_all_nan_command_of_the_wrong_size_is_rejected_for_its_size():
    assert 'expected 1 lengths' in check_command([math.nan, math.nan], 1, LO, HI)
    assert check_command([math.nan], 1, LO, HI) is None          # right size: no command
    assert 'not finite' in check_command([0.1, math.nan], 2, LO, HI)
    assert 'outside' in check_command([0.6], 1, LO, HI)


def test_rejections_are_counted_but_logged_at_most_once_per_period():
    now = [100.0]
    lines: list[str] = []
    counters: dict[str, int] = {}
    log = RejectionLog(counters, lines.append, period=1.0, clock=lambda: now[0])
    for _ in range(10_000):
        log.note('commands', 'linkage_cmd', 'expected 1 lengths')
    assert counters['commands_rejected'] == 10_000 and len(lines) == 1
    log.note('trajectories', 'linkage_trajectory', 'bad')     # its own period
    assert len(lines) == 2
    now[0] += 1.0
    log.note('commands', 'linkage_cmd', 'expected 1 lengths')
    assert len(lines) == 3
    assert '10000 rejected since the last message, 10001 in all' in lines[-1]


@pytest.mark.parametrize('n_pts,n_links,vel,acc', [(0, 1, False, False), (5, 1, False, False),
                                                   (3, 1, True, True), (4, 3, True, False)])
def test_the_recorded_trajectory_bytes_are_read_by_rosbags_and_rclpy(n_pts, n_links, vel, acc):
    # rclpy's buffer of a JointTrajectory carries unused bytes that rosbags refuses ("CDR
    # message size mismatch"): the node records the bytes the message uses
    from rclpy.serialization import deserialize_message
    from rosbags.typesys import get_typestore, Stores
    msg = traj(n_pts, n_links, vel, acc, stamp_ns=7)
    data = serialize_message(msg)
    reason, prepared = intake.prepare(data, n_links, LO, HI, 0, 3600.0)
    assert reason is None
    store = get_typestore(Stores.ROS2_JAZZY)
    got = store.deserialize_cdr(prepared.raw, 'trajectory_msgs/msg/JointTrajectory')
    assert len(got.points) == n_pts and list(got.joint_names) == list(msg.joint_names)
    assert deserialize_message(prepared.raw, JointTrajectory) == msg


@pytest.mark.parametrize('order', [1, 3, 5])
@pytest.mark.parametrize('first', [0.0, 0.013])
def test_the_array_reference_gives_the_same_floats_as_the_list_one(order, first):
    # from_arrays (the node's path, no per-point Python lists) against __init__ (the core's
    # original constructor): bit-identical r, r', r'' everywhere, including before the first
    # point (from the actuator's state) and after the last
    rng = np.random.default_rng(order)
    n, n_links = 200, 2
    times = first + np.cumsum(rng.uniform(1e-3, 2e-2, n))
    times[0] = first
    pos = rng.uniform(0.05, 0.2, (n, n_links))
    vel = rng.normal(size=(n, n_links)) if order >= 3 else None
    acc = rng.normal(size=(n, n_links)) if order >= 5 else None
    state = [(0.1, 0.2, -0.3), (0.12, -0.1, 0.5)]
    lists = TrajectoryReference(4.0, state, times.tolist(), pos.tolist(),
                                None if vel is None else vel.tolist(),
                                None if acc is None else acc.tolist())
    arrays = TrajectoryReference.from_arrays(4.0, state, times, pos, vel, acc)
    assert arrays.end_time == lists.end_time
    for t in np.concatenate([[3.9, 4.0], 4.0 + rng.uniform(0, times[-1] + 0.1, 500)]):
        assert arrays(float(t)) == lists(float(t))
