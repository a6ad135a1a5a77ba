"""A trajectory stamped 0 ("start when applied") is recorded with the absolute stamp of the tick
that applied it; every other byte is the received message's."""
from __future__ import annotations

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.ros.sim.recording import applied_trajectory


def trajectory(points: int, sec: int = 0, nanosec: int = 0) -> JointTrajectory:
    msg = JointTrajectory(joint_names=['linkage_0'])
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = 'base_link'
    for k in range(points):
        msg.points.append(JointTrajectoryPoint(positions=[0.1 + 0.001 * k]))
        msg.points[-1].time_from_start.sec = k
    return msg


@pytest.mark.parametrize('points', [0, 1, 300])
def test_a_trajectory_stamped_0_is_recorded_with_the_stamp_of_its_tick(points):
    raw = serialize_message(trajectory(points))
    t_ns = 12 * 10**9 + 345_678_901
    out = applied_trajectory(raw, 0, t_ns)
    assert deserialize_message(out, JointTrajectory) == trajectory(points, 12, 345_678_901)
    assert out[:4] == raw[:4] and out[12:] == raw[12:]


def test_a_stamped_trajectory_is_recorded_as_received():
    raw = serialize_message(trajectory(3, 5, 7))
    assert applied_trajectory(raw, 5_000_000_007, 9 * 10**9) is raw


def test_bytes_that_are_not_plain_little_endian_cdr_are_recorded_as_received():
    raw = b'\x7f\x01\x00\x00' + serialize_message(trajectory(1))[4:]   # intake reads byte 1 only
    assert applied_trajectory(raw, 0, 10**9) == raw
