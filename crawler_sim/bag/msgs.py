"""rclpy messages of a recording, built from plain numbers (no rclpy.init needed).

The node (``crawler_sim/ros/messages.py``) uses the same builders: JointState names ``body_i`` /
``linkage_j`` with an empty frame id, Int8MultiArray / Float64MultiArray without layout, Odometry
of the centre of mass in frame ``odom`` with child ``base_link`` and identity orientation. All
times are integer nanoseconds of sim time (see :mod:`crawler_sim.bag.clock`).
"""
from __future__ import annotations

from array import array
from functools import lru_cache
from typing import Any, Sequence

from numpy.typing import ArrayLike

from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int8MultiArray, Int32MultiArray, String
import yaml
from crawler_sim.core.simtime import from_stamp, split_ns

ODOM_FRAME = 'odom'
BASE_FRAME = 'base_link'


def stamp_from_ns(t_ns: int) -> Time:
    """Sim time in integer nanoseconds to ``builtin_interfaces/Time`` (the one conversion)."""
    sec, nanosec = split_ns(t_ns)
    return Time(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Time) -> int:
    """Inverse of :func:`stamp_from_ns`."""
    return from_stamp(stamp.sec, stamp.nanosec)


@lru_cache(maxsize=None)
def linkage_names(n: int) -> tuple[str, ...]:
    """``linkage_0`` ... ``linkage_{n-1}``."""
    return tuple(f'linkage_{j}' for j in range(n))


@lru_cache(maxsize=None)
def body_names(p: int) -> tuple[str, ...]:
    """``body_0`` ... ``body_{p-1}``."""
    return tuple(f'body_{i}' for i in range(p))


def _f64(values: np.ndarray | Sequence[float]) -> array:
    if isinstance(values, np.ndarray):
        out = array('d')
        out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
        return out
    return array('d', values)


def joint_state(t_ns: int, names: Sequence[str], position: ArrayLike, velocity: ArrayLike,
                effort: ArrayLike) -> JointState:
    """A JointState stamped ``t_ns`` [ns]; all arrays have ``len(names)`` entries."""
    msg = JointState()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.name = list(names)
    msg.position = _f64(position)
    msg.velocity = _f64(velocity)
    msg.effort = _f64(effort)
    return msg


# Array-level builders: the node (from a core ``State``) and offline recording (from arrays)
# both go through these, so online and offline bags hold the same messages.

def body_states(t_ns: int, x: ArrayLike, v: ArrayLike, friction: ArrayLike) -> JointState:
    """``body_states``: names body_i, position x_i [m], velocity v_i [m/s], effort = friction
    force the ground exerts on body i [N]."""
    return joint_state(t_ns, body_names(len(x)), x, v, friction)


def joint_states(t_ns: int, lengths: ArrayLike, rates: ArrayLike,
                 linkage_force: ArrayLike) -> JointState:
    """``joint_states``: names linkage_j, position l_j [m], velocity l_j' [m/s], effort = linkage
    force [N] (positive pushes the bodies apart)."""
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, rates, linkage_force)


def contact_states(contact: ArrayLike) -> Int8MultiArray:
    """``contact_states``: +1 sliding forward, 0 stuck, -1 sliding backward, per body (no stamp:
    Int8MultiArray has no header; it is published in the same tick as ``body_states``)."""
    msg = Int8MultiArray()
    msg.data = array('b', np.asarray(contact, dtype=np.int8).tobytes())
    return msg


def centre_of_mass(x: ArrayLike, v: ArrayLike, masses: ArrayLike) -> tuple[float, float]:
    """Centre of mass position X = sum m_i x_i / M [m] and velocity V [m/s]."""
    m = np.asarray(masses, dtype=np.float64)
    total = float(m.sum())
    return (float(m @ np.asarray(x, dtype=np.float64)) / total,
            float(m @ np.asarray(v, dtype=np.float64)) / total)


def odometry(t_ns: int, x: ArrayLike, v: ArrayLike, masses: ArrayLike) -> Odometry:
    """``odom``: centre of mass X = sum m_i x_i / M and V along x, frame ``odom``, child
    ``base_link``. The line is the odom x axis (along the incline); orientation is identity."""
    msg = Odometry()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = ODOM_FRAME
    msg.child_frame_id = BASE_FRAME
    msg.pose.pose.position.x, msg.twist.twist.linear.x = centre_of_mass(x, v, masses)
    msg.pose.pose.orientation.w = 1.0
    return msg


def event_msg(body: int, old: int, new: int) -> Int32MultiArray:
    """A contact event for the bag's ``events`` topic: ``[body, old, new]`` (its log time is the
    event time)."""
    msg = Int32MultiArray()
    msg.data = array('i', [int(body), int(old), int(new)])
    return msg


def float64_array_msg(values: Sequence[float]) -> Float64MultiArray:
    """A ``Float64MultiArray`` of ``values`` (as ``linkage_cmd`` expects)."""
    msg = Float64MultiArray()
    msg.data = _f64(np.atleast_1d(np.asarray(values, dtype=np.float64)))
    return msg


def scene_string(scene: dict[str, Any]) -> String:
    """``crawler_sim/scene``: the scene as YAML text."""
    return String(data=yaml.safe_dump(scene, sort_keys=False, default_flow_style=None))
