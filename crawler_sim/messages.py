"""Builders of the node's ROS messages from a core ``State`` (docs/ARCHITECTURE.md).

Every builder takes the sim time as integer nanoseconds ``t_ns``; :func:`stamp_from_ns` is the
one conversion point to ``builtin_interfaces/Time``. Float arrays go in as ``array.array('d')``
(no per-element checks even with ``ROS_PYTHON_CHECK_FIELDS=1``). The core ``State`` is duck-typed:
``x, v, friction, contact, linkage_force, lengths, rates`` (numpy arrays).
"""
from __future__ import annotations

from array import array
from functools import lru_cache
import struct
from typing import Any, Iterable, Mapping, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point
from nav_msgs.msg import Odometry
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Float64MultiArray, Int8MultiArray, Int32MultiArray
from visualization_msgs.msg import Marker, MarkerArray

__all__ = ['stamp_from_ns', 'ns_from_stamp', 'linkage_names', 'body_names', 'joint_states_msg',
           'body_states_msg', 'contact_states_msg', 'odom_msg', 'markers_msg',
           'diagnostics_msg', 'clock_msg', 'clock_cdr', 'applied_command_msg',
           'float64_array_msg', 'event_msg', 'centre_of_mass', 'OutputEncoder', 'OUTPUT_TYPES',
           'CONTACT_COLOURS',
           'ODOM_FRAME', 'BASE_FRAME']

ODOM_FRAME = 'odom'
BASE_FRAME = 'base_link'

#: RGBA per contact state: +1 sliding forward (blue), 0 stuck (green), -1 sliding backward (red).
CONTACT_COLOURS = {1: (0.15, 0.35, 0.95, 1.0), 0: (0.1, 0.75, 0.2, 1.0),
                   -1: (0.9, 0.15, 0.1, 1.0)}
_LINK_COLOUR = (0.6, 0.6, 0.6, 1.0)
BODY_SIZE = 0.04       # marker cube edge [m]
LINK_WIDTH = 0.008     # marker line width [m]


def stamp_from_ns(t_ns: int) -> Time:
    """Sim time in integer nanoseconds to ``builtin_interfaces/Time`` (the one conversion)."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def ns_from_stamp(stamp: Time) -> int:
    """Inverse of :func:`stamp_from_ns`."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


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


def joint_state(t_ns: int, names: Sequence[str], position, velocity, effort) -> JointState:
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

def body_states(t_ns: int, x, v, friction) -> JointState:
    """``body_states``: names body_i, position x_i [m], velocity v_i [m/s], effort = friction
    force the ground exerts on body i [N]."""
    return joint_state(t_ns, body_names(len(x)), x, v, friction)


def joint_states(t_ns: int, lengths, rates, linkage_force) -> JointState:
    """``joint_states``: names linkage_j, position l_j [m], velocity l_j' [m/s], effort = linkage
    force [N] (positive pushes the bodies apart)."""
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, rates, linkage_force)


def contact_states(contact) -> Int8MultiArray:
    """``contact_states``: +1 sliding forward, 0 stuck, -1 sliding backward, per body (no stamp:
    Int8MultiArray has no header; it is published in the same tick as ``body_states``)."""
    msg = Int8MultiArray()
    msg.data = array('b', np.asarray(contact, dtype=np.int8).tobytes())
    return msg


def centre_of_mass(x, v, masses) -> tuple[float, float]:
    """Centre of mass position X = sum m_i x_i / M [m] and velocity V [m/s]."""
    m = np.asarray(masses, dtype=np.float64)
    total = float(m.sum())
    return (float(m @ np.asarray(x, dtype=np.float64)) / total,
            float(m @ np.asarray(v, dtype=np.float64)) / total)


def odometry(t_ns: int, x, v, masses) -> Odometry:
    """``odom``: centre of mass X = sum m_i x_i / M and V along x, frame ``odom``, child
    ``base_link``. The line is the odom x axis (along the incline); orientation is identity."""
    msg = Odometry()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.header.frame_id = ODOM_FRAME
    msg.child_frame_id = BASE_FRAME
    msg.pose.pose.position.x, msg.twist.twist.linear.x = centre_of_mass(x, v, masses)
    msg.pose.pose.orientation.w = 1.0
    return msg


def joint_states_msg(state, t_ns: int) -> JointState:
    """``joint_states`` from a core ``State``."""
    return joint_states(t_ns, state.lengths, state.rates, state.linkage_force)


def body_states_msg(state, t_ns: int) -> JointState:
    """``body_states`` from a core ``State``."""
    return body_states(t_ns, state.x, state.v, state.friction)


def contact_states_msg(state) -> Int8MultiArray:
    """``contact_states`` from a core ``State``."""
    return contact_states(state.contact)


def odom_msg(state, masses: np.ndarray, t_ns: int) -> Odometry:
    """``odom`` from a core ``State``."""
    return odometry(t_ns, state.x, state.v, masses)


def _colour(rgba: tuple[float, float, float, float]) -> ColorRGBA:
    return ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def markers_msg(state, t_ns: int, *, frame_id: str = ODOM_FRAME) -> MarkerArray:
    """``markers``: one CUBE per body (ns ``bodies``, id i) coloured by contact state (see
    :data:`CONTACT_COLOURS`), one LINE_STRIP per linkage (ns ``linkages``, id j) from body j to
    body j+1, slightly above the boxes' centres."""
    stamp = stamp_from_ns(t_ns)
    xs = state.x.tolist()
    contact = state.contact.tolist()
    out = MarkerArray()
    markers = []
    for i, x in enumerate(xs):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = frame_id
        m.ns = 'bodies'
        m.id = i
        m.type = Marker.CUBE
        m.action = Marker.ADD
        m.pose.position.x = x
        m.pose.position.z = 0.5 * BODY_SIZE
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = BODY_SIZE
        m.color = _colour(CONTACT_COLOURS.get(int(contact[i]), _LINK_COLOUR))
        markers.append(m)
    for j in range(len(xs) - 1):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = frame_id
        m.ns = 'linkages'
        m.id = j
        m.type = Marker.LINE_STRIP
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = LINK_WIDTH
        m.color = _colour(_LINK_COLOUR)
        m.points = [Point(x=xs[j], z=0.75 * BODY_SIZE), Point(x=xs[j + 1], z=0.75 * BODY_SIZE)]
        markers.append(m)
    out.markers = markers
    return out


def diagnostics_msg(t_ns: int, values: Mapping[str, object], *, warn: Iterable[str] = (),
                    name: str = 'crawler_sim: simulation',
                    hardware_id: str = 'crawler_sim') -> DiagnosticArray:
    """``/diagnostics``: one status; level WARN with the reasons in ``message`` when ``warn`` is
    non-empty, else OK. Values are stringified in the given order."""
    reasons = list(warn)
    status = DiagnosticStatus()
    status.level = DiagnosticStatus.WARN if reasons else DiagnosticStatus.OK
    status.name = name
    status.hardware_id = hardware_id
    status.message = '; '.join(reasons) if reasons else 'running'
    status.values = [KeyValue(key=str(k), value=_fmt(v)) for k, v in values.items()]
    msg = DiagnosticArray()
    msg.header.stamp = stamp_from_ns(t_ns)
    msg.status = [status]
    return msg


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f'{value:.6g}'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    return str(value)


def clock_msg(t_ns: int) -> Clock:
    """``/clock``: the sim time."""
    return Clock(clock=stamp_from_ns(t_ns))


#: CDR of rosgraph_msgs/Clock: encapsulation (plain CDR, little-endian), int32 sec, uint32 nanosec
_CLOCK_CDR = struct.Struct('<4siI')
_CDR_LE = b'\x00\x01\x00\x00'


def clock_cdr(t_ns: int) -> bytes:
    """``/clock`` already serialised (what ``serialize_message(clock_msg(t_ns))`` returns):
    a publisher sends bytes without converting a Python message."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return _CLOCK_CDR.pack(_CDR_LE, sec, nanosec)


def applied_command_msg(t_ns: int, lengths: Sequence[float]) -> JointState:
    """``~/applied_command``: the target lengths [m] that took effect at the tick starting at
    ``t_ns`` (names linkage_j, position = targets; velocity and effort are zeros, filled because
    rosbags cannot read a JointState whose trailing arrays are empty)."""
    zeros = [0.0] * len(lengths)
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, zeros, zeros)


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


#: ROS type of each output of the node (and of the inputs it records)
OUTPUT_TYPES = {
    'joint_states': 'sensor_msgs/msg/JointState',
    'body_states': 'sensor_msgs/msg/JointState',
    'contact_states': 'std_msgs/msg/Int8MultiArray',
    'odom': 'nav_msgs/msg/Odometry',
    'markers': 'visualization_msgs/msg/MarkerArray',
    'applied_command': 'sensor_msgs/msg/JointState',
    'linkage_cmd': 'std_msgs/msg/Float64MultiArray',
}
_STAMP = ('header.stamp.sec', 'header.stamp.nanosec')
_JOINTS = (_STAMP, ('position',), ('velocity',), ('effort',))
_MISSING = object()


class OutputEncoder:
    """The node's outputs as CDR bytes, ready to publish and to record.

    Building an rclpy message and converting it to C (``publish`` or ``serialize_message``) costs
    tens of microseconds per message; the outputs of a run differ only in numbers. So the first
    message of each shape (output and number of bodies) is built with the builders above and
    serialised, and becomes the template of a :class:`crawler_sim.bag.cdr.Encoder`; later
    messages of that shape are the template with their numbers packed in. The bytes equal
    ``serialize_message`` of the builder's message (padding bytes aside, zero here); where a
    template cannot be made, every message of that shape goes through the builder.
    ``fast`` and ``slow`` count the messages made each way.
    """

    def __init__(self) -> None:
        from rclpy.serialization import serialize_message
        from crawler_sim.bag.cdr import Encoder, LayoutError
        self._serialize, self._encoder_class, self._layout_error = (
            serialize_message, Encoder, LayoutError)
        self._encoders: dict[tuple, Any] = {}
        self.fast = 0
        self.slow = 0

    def encode(self, name: str, state, t_ns: int, masses=None) -> bytes:
        """CDR bytes of output ``name`` (``joint_states``, ``body_states``, ``contact_states``,
        ``odom``, ``markers``) of core ``State`` at sim time ``t_ns`` [ns]; ``odom`` needs the
        body ``masses`` [kg]."""
        return getattr(self, name)(state, t_ns, masses)

    def joint_states(self, state, t_ns: int, masses=None) -> bytes:
        return self._joints('joint_states', t_ns, state.lengths, state.rates,
                            state.linkage_force, lambda: joint_states_msg(state, t_ns))

    def body_states(self, state, t_ns: int, masses=None) -> bytes:
        return self._joints('body_states', t_ns, state.x, state.v, state.friction,
                            lambda: body_states_msg(state, t_ns))

    def applied_command(self, lengths: Sequence[float], t_ns: int) -> bytes:
        """``~/applied_command`` (see :func:`applied_command_msg`)."""
        zeros = [0.0] * len(lengths)
        return self._joints('applied_command', t_ns, lengths, zeros, zeros,
                            lambda: applied_command_msg(t_ns, lengths))

    def linkage_cmd(self, lengths: Sequence[float]) -> bytes:
        """A ``linkage_cmd`` as recorded (see :func:`float64_array_msg`)."""
        values = [float(x) for x in lengths]
        return self._encode(('linkage_cmd', len(values)), (('data',),), (values,),
                            lambda: float64_array_msg(values))

    def contact_states(self, state, t_ns: int = 0, masses=None) -> bytes:
        contact = np.asarray(state.contact, dtype=np.int8).tolist()
        return self._encode(('contact_states', len(contact)), (('data',),), (contact,),
                            lambda: contact_states_msg(state))

    def odom(self, state, t_ns: int, masses=None) -> bytes:
        com_x, com_v = centre_of_mass(state.x, state.v, masses)
        groups = (_STAMP, ('pose.pose.position.x',), ('twist.twist.linear.x',))
        return self._encode(('odom',), groups, (divmod(t_ns, 1_000_000_000), (com_x,), (com_v,)),
                            lambda: odom_msg(state, masses, t_ns))

    def markers(self, state, t_ns: int, masses=None) -> bytes:
        xs = state.x.tolist()
        contact = state.contact.tolist()
        p = len(xs)
        stamp = divmod(t_ns, 1_000_000_000)
        values: list = []
        for i in range(p):
            values += (stamp, (xs[i],), CONTACT_COLOURS.get(int(contact[i]), _LINK_COLOUR))
        for j in range(p - 1):
            values += (stamp, (xs[j],), (xs[j + 1],))
        return self._encode(('markers', p), _marker_groups(p), values,
                            lambda: markers_msg(state, t_ns))

    def _joints(self, kind: str, t_ns: int, position, velocity, effort, build) -> bytes:
        values = (divmod(t_ns, 1_000_000_000), _floats(position), _floats(velocity),
                  _floats(effort))
        return self._encode((kind, len(values[1])), _JOINTS, values, build)

    def _encode(self, key: tuple, groups, values, build) -> bytes:
        encoder = self._encoders.get(key, _MISSING)
        if encoder is _MISSING:                   # first message of this shape: the template
            try:
                encoder = self._encoder_class(build(), OUTPUT_TYPES[key[0]], groups)
            except self._layout_error:
                encoder = None                    # this shape always goes through the builder
            self._encoders[key] = encoder
        if encoder is None:
            self.slow += 1
            return self._serialize(build())
        self.fast += 1
        return encoder.encode(*values)


def _floats(values) -> list[float]:
    return values.tolist() if isinstance(values, np.ndarray) else [float(x) for x in values]


@lru_cache(maxsize=None)
def _marker_groups(p: int) -> tuple[tuple[str, ...], ...]:
    """Changing fields of :func:`markers_msg` for p bodies: per cube its stamp, x and colour; per
    line its stamp and the x of both ends."""
    groups: list[tuple[str, ...]] = []
    for i in range(p):
        m = f'markers.{i}.'
        groups += [tuple(m + f for f in _STAMP), (m + 'pose.position.x',),
                   tuple(m + 'color.' + c for c in 'rgba')]
    for j in range(p - 1):
        m = f'markers.{p + j}.'
        groups += [tuple(m + f for f in _STAMP), (m + 'points.0.x',), (m + 'points.1.x',)]
    return tuple(groups)
