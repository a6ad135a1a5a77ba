"""Messages of a recording, built from plain numbers (no rclpy.init needed, no ROS needed).

Each builder returns an rclpy message when ROS is installed (what the node publishes) and
rosbags' typestore dataclass of the same type otherwise (:mod:`crawler_sim.bag.rosmsg`): the
same fields, the same CDR. The node (``crawler_sim/ros/messages.py``) uses the same builders:
JointState names ``body_i`` / ``linkage_j`` with an empty frame id, Int8MultiArray /
Float64MultiArray without layout, Odometry of the centre of mass in frame ``odom`` with child
``base_link`` (prefixed in a namespace, :func:`frame_prefix`) and identity orientation. All
times are integer nanoseconds of sim time (see
:mod:`crawler_sim.bag.clock`).
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
import yaml

from crawler_sim.core.simtime import from_stamp, split_ns

from .rosmsg import new, numbers
from .topics import BODY_STATES, CONTACT_STATES, EVENTS, LINKAGE_CMD, ODOM, SCENE

# the types of the messages built here (bag.topics spells every topic's type)
TIME = 'builtin_interfaces/msg/Time'
JOINT_STATE = BODY_STATES.type
ODOMETRY = ODOM.type
INT8_ARRAY = CONTACT_STATES.type
INT32_ARRAY = EVENTS.type
FLOAT64_ARRAY = LINKAGE_CMD.type
STRING = SCENE.type

ODOM_FRAME = 'odom'
BASE_FRAME = 'base_link'


def frame_prefix(namespace: str) -> str:
    """The prefix of a robot's frames: '' in the root namespace, ``r1/`` in ``/r1`` (``/a/b``
    gives ``a/b/``): ``/tf`` is one global topic, so two robots must never claim the same frame
    (robot_state_publisher's ``frame_prefix`` convention). ``odom`` and ``/tf`` name the same
    frames."""
    ns = namespace.strip('/')
    return f'{ns}/' if ns else ''

# The numeric fields that change from one message of a run to the next, in groups adjacent in
# the CDR bytes (the ``groups`` of :class:`crawler_sim.bag.cdr.Encoder`): everything else of a
# message (names, frames, sequence lengths) is its shape's template.
STAMP = ('header.stamp.sec', 'header.stamp.nanosec')
JOINT_GROUPS = (STAMP, ('position',), ('velocity',), ('effort',))
ODOM_GROUPS = (STAMP, ('pose.pose.position.x',), ('twist.twist.linear.x',))
DATA_GROUPS = (('data',),)


def stamp_from_ns(t_ns: int) -> Any:
    """Sim time in integer nanoseconds to ``builtin_interfaces/Time`` (the one conversion)."""
    sec, nanosec = split_ns(t_ns)
    stamp = new(TIME)
    stamp.sec, stamp.nanosec = sec, nanosec
    return stamp


def ns_from_stamp(stamp: Any) -> int:
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


def joint_state(t_ns: int, names: Sequence[str], position: ArrayLike, velocity: ArrayLike,
                effort: ArrayLike) -> Any:
    """A JointState stamped ``t_ns`` [ns]; all arrays have ``len(names)`` entries."""
    msg = new(JOINT_STATE)
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.name = list(names)
    msg.position = numbers(JOINT_STATE, position, np.float64)
    msg.velocity = numbers(JOINT_STATE, velocity, np.float64)
    msg.effort = numbers(JOINT_STATE, effort, np.float64)
    return msg


# Array-level builders: the node (from a core ``State``) and offline recording (from arrays)
# both go through these, so online and offline bags hold the same messages.

def body_states(t_ns: int, x: ArrayLike, v: ArrayLike, friction: ArrayLike) -> Any:
    """``body_states``: names body_i, position x_i [m], velocity v_i [m/s], effort = friction
    force the ground exerts on body i [N]."""
    return joint_state(t_ns, body_names(len(x)), x, v, friction)


def joint_states(t_ns: int, lengths: ArrayLike, rates: ArrayLike,
                 linkage_force: ArrayLike) -> Any:
    """``joint_states``: names linkage_j, position l_j [m], velocity l_j' [m/s], effort = linkage
    force [N] (positive pushes the bodies apart)."""
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, rates, linkage_force)


def contact_states(contact: ArrayLike) -> Any:
    """``contact_states``: +1 sliding forward, 0 stuck, -1 sliding backward, per body (no stamp:
    Int8MultiArray has no header; it is published in the same tick as ``body_states``)."""
    msg = new(INT8_ARRAY)
    msg.data = numbers(INT8_ARRAY, contact, np.int8)
    return msg


def centre_of_mass(x: ArrayLike, v: ArrayLike, masses: ArrayLike) -> tuple[float, float]:
    """Centre of mass position X = sum m_i x_i / M [m] and velocity V [m/s]."""
    m = np.asarray(masses, dtype=np.float64)
    total = float(m.sum())
    return (float(m @ np.asarray(x, dtype=np.float64)) / total,
            float(m @ np.asarray(v, dtype=np.float64)) / total)


def centre_of_mass_rows(x: ArrayLike, v: ArrayLike, masses: ArrayLike
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`centre_of_mass` of every row of ``x`` and ``v`` (N, p), bit for bit: the same
    dot product per row (a matrix product may sum in another order, or fuse, and differ in
    the last bit from what the node publishes)."""
    m = np.asarray(masses, dtype=np.float64)
    total = float(m.sum())
    dot = m.dot
    xs = np.asarray(x, dtype=np.float64)
    vs = np.asarray(v, dtype=np.float64)
    com_x = np.fromiter((dot(row) for row in xs), np.float64, len(xs)) / total
    com_v = np.fromiter((dot(row) for row in vs), np.float64, len(vs)) / total
    return com_x, com_v


def odometry(t_ns: int, x: ArrayLike, v: ArrayLike, masses: ArrayLike,
             prefix: str = '') -> Any:
    """``odom``: centre of mass X = sum m_i x_i / M and V along x, frame ``odom``, child
    ``base_link`` (each after ``prefix``: :func:`frame_prefix`). The line is the odom x axis
    (along the incline); orientation is identity."""
    msg = new(ODOMETRY)
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = prefix + ODOM_FRAME
    msg.child_frame_id = prefix + BASE_FRAME
    msg.pose.pose.position.x, msg.twist.twist.linear.x = centre_of_mass(x, v, masses)
    msg.pose.pose.orientation.w = 1.0
    return msg


def event_msg(body: int, old: int, new_state: int) -> Any:
    """A contact event for the bag's ``events`` topic: ``[body, old, new]`` (its log time is the
    event time)."""
    msg = new(INT32_ARRAY)
    msg.data = numbers(INT32_ARRAY, [int(body), int(old), int(new_state)], np.int32)
    return msg


def float64_array_msg(values: Sequence[float]) -> Any:
    """A ``Float64MultiArray`` of ``values`` (as ``linkage_cmd`` expects)."""
    msg = new(FLOAT64_ARRAY)
    msg.data = numbers(FLOAT64_ARRAY, np.atleast_1d(np.asarray(values, dtype=np.float64)),
                       np.float64)
    return msg


def scene_string(scene: dict[str, Any]) -> Any:
    """``crawler_sim/scene``: the scene as YAML text."""
    msg = new(STRING)
    msg.data = yaml.safe_dump(scene, sort_keys=False, default_flow_style=None)
    return msg
