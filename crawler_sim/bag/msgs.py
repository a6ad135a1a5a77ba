"""rclpy messages of a recording, built from plain numbers (no rclpy.init needed).

They follow the node's conventions (``crawler_sim/messages.py``): JointState names ``body_i`` /
``linkage_j`` with an empty frame id, Int8MultiArray / Float64MultiArray without layout, Odometry
of the centre of mass in frame ``odom`` with child ``base_link`` and identity orientation. All
times are integer nanoseconds of sim time (see :mod:`crawler_sim.bag.clock`).
"""
from __future__ import annotations

from array import array
from functools import lru_cache
from typing import Any, Sequence

from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
import numpy as np
from numpy.typing import ArrayLike
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int32MultiArray, Int8MultiArray, String
import yaml

from .clock import stamp

ODOM_FRAME = 'odom'
BASE_FRAME = 'base_link'


@lru_cache(maxsize=None)
def body_names(p: int) -> tuple[str, ...]:
    """``body_0`` ... ``body_{p-1}``."""
    return tuple(f'body_{i}' for i in range(p))


@lru_cache(maxsize=None)
def linkage_names(n: int) -> tuple[str, ...]:
    """``linkage_0`` ... ``linkage_{n-1}``."""
    return tuple(f'linkage_{j}' for j in range(n))


def _f64(values: ArrayLike) -> array:
    out = array('d')
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def _time(t_ns: int) -> Time:
    sec, nanosec = stamp(t_ns)
    return Time(sec=sec, nanosec=nanosec)


def joint_state(t_ns: int, names: Sequence[str], position: ArrayLike, velocity: ArrayLike,
                effort: ArrayLike) -> JointState:
    """A JointState stamped ``t_ns`` [ns]; all arrays have ``len(names)`` entries."""
    msg = JointState()
    msg.header.stamp = _time(t_ns)
    msg.name = list(names)
    msg.position = _f64(position)
    msg.velocity = _f64(velocity)
    msg.effort = _f64(effort)
    return msg


def body_states(t_ns: int, x: ArrayLike, v: ArrayLike, friction: ArrayLike) -> JointState:
    """``body_states``: x [m], v [m/s], friction on each body [N] (shape (p,) each)."""
    return joint_state(t_ns, body_names(len(x)), x, v, friction)


def joint_states(t_ns: int, lengths: ArrayLike, rates: ArrayLike,
                 linkage_force: ArrayLike) -> JointState:
    """``joint_states``: l_j [m], l_j' [m/s], linkage force [N] (shape (p-1,) each)."""
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, rates, linkage_force)


def contact_states(contact: ArrayLike) -> Int8MultiArray:
    """``contact_states``: +1 forward, 0 stuck, -1 backward per body (int8, shape (p,))."""
    msg = Int8MultiArray()
    msg.data = array('b', np.asarray(contact, dtype=np.int8).tobytes())
    return msg


def odometry(t_ns: int, x: ArrayLike, v: ArrayLike, masses: ArrayLike) -> Odometry:
    """``odom``: centre of mass X = sum m_i x_i / M [m] and V [m/s] along the odom x axis."""
    m = np.asarray(masses, dtype=np.float64)
    total = float(m.sum())
    msg = Odometry()
    msg.header.stamp = _time(t_ns)
    msg.header.frame_id = ODOM_FRAME
    msg.child_frame_id = BASE_FRAME
    msg.pose.pose.position.x = float(m @ np.asarray(x, dtype=np.float64)) / total
    msg.pose.pose.orientation.w = 1.0
    msg.twist.twist.linear.x = float(m @ np.asarray(v, dtype=np.float64)) / total
    return msg


def float64_array(values: ArrayLike) -> Float64MultiArray:
    """A Float64MultiArray (``linkage_cmd``) of ``values``."""
    msg = Float64MultiArray()
    msg.data = _f64(np.atleast_1d(values))
    return msg


def event(body: int, old: int, new: int) -> Int32MultiArray:
    """``events``: body ``body`` changed contact state from ``old`` to ``new``."""
    msg = Int32MultiArray()
    msg.data = array('i', [int(body), int(old), int(new)])
    return msg


def scene_string(scene: dict[str, Any]) -> String:
    """``crawler_sim/scene``: the scene as YAML text."""
    return String(data=yaml.safe_dump(scene, sort_keys=False, default_flow_style=None))
