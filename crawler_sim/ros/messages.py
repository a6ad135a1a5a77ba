"""Builders of the node's ROS messages from a core ``State`` (docs/ARCHITECTURE.md).

Every builder takes the sim time as integer nanoseconds ``t_ns``; :func:`stamp_from_ns` is the
one conversion point to ``builtin_interfaces/Time``. Float arrays go in as ``array.array('d')``
(no per-element checks even with ``ROS_PYTHON_CHECK_FIELDS=1``). The core ``State`` is duck-typed:
``x, v, friction, contact, linkage_force, lengths, rates`` (numpy arrays).
"""
from __future__ import annotations

from functools import lru_cache
import math
from typing import Any, Iterable, Mapping, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point
from nav_msgs.msg import Odometry
import numpy as np
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Int8MultiArray
from visualization_msgs.msg import Marker, MarkerArray

# The array-level builders live with the bag (offline recording needs them without the node).
from ..bag.cdr import Encoder, LayoutError
from ..bag.msgs import (BASE_FRAME, JOINT_GROUPS, ODOM_FRAME, ODOM_GROUPS, STAMP, body_names,
                        body_states, centre_of_mass, contact_states, event_msg,
                        float64_array_msg, joint_state, joint_states, linkage_names,
                        ns_from_stamp, odometry, stamp_from_ns)
from crawler_sim.bag import topics as T
from crawler_sim.core.trajectory import State
from crawler_sim.core.simtime import split_ns

__all__ = ['stamp_from_ns', 'ns_from_stamp', 'linkage_names', 'body_names', 'joint_states_msg',
           'body_states_msg', 'contact_states_msg', 'contacts_stamped_msg', 'odom_msg',
           'markers_msg',
           'diagnostics_msg', 'clock_msg', 'clock_cdr', 'applied_command_msg',
           'float64_array_msg', 'event_msg', 'centre_of_mass', 'OutputEncoder', 'ENCODED',
           'CONTACT_COLOURS',
           'ODOM_FRAME', 'BASE_FRAME']

#: RGBA per contact state: +1 sliding forward (blue), 0 stuck (green), -1 sliding backward (red).
CONTACT_COLOURS = {1: (0.15, 0.35, 0.95, 1.0), 0: (0.1, 0.75, 0.2, 1.0),
                   -1: (0.9, 0.15, 0.1, 1.0)}
_LINK_COLOUR = (0.6, 0.6, 0.6, 1.0)
BODY_SIZE = 0.04       # marker cube edge [m]
LINK_WIDTH = 0.008     # marker line width [m]


def joint_states_msg(state: State, t_ns: int) -> JointState:
    """``joint_states`` from a core ``State``."""
    return joint_states(t_ns, state.lengths, state.rates, state.linkage_force)


def body_states_msg(state: State, t_ns: int) -> JointState:
    """``body_states`` from a core ``State``."""
    return body_states(t_ns, state.x, state.v, state.friction)


def contacts_stamped_msg(state: State, t_ns: int) -> JointState:
    """``contacts``: the stamped alternative to ``contact_states`` within common_interfaces.

    One entry per body (name ``body_i``): position = contact state (+1 sliding forward, 0
    stuck, -1 sliding backward), velocity = body velocity [m/s], effort = friction force [N]
    (the sign convention of ``body_states``)."""
    return joint_state(t_ns, body_names(len(state.x)), np.asarray(state.contact, dtype=float),
                       state.v, state.friction)


def contact_states_msg(state: State) -> Int8MultiArray:
    """``contact_states`` from a core ``State``."""
    return contact_states(state.contact)


def odom_msg(state: State, masses: np.ndarray, t_ns: int, prefix: str = '') -> Odometry:
    """``odom`` from a core ``State`` (frames after ``prefix``: ``bag.msgs.frame_prefix``)."""
    return odometry(t_ns, state.x, state.v, masses, prefix)


def _colour(rgba: tuple[float, float, float, float]) -> ColorRGBA:
    return ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def markers_msg(state: State, t_ns: int, *, frame_id: str = ODOM_FRAME) -> MarkerArray:
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
                    hardware_id: str = 'crawler_sim',
                    error: Iterable[str] = ()) -> DiagnosticArray:
    """``/diagnostics``: one status; level ERROR with the reasons in ``message`` (errors first)
    when ``error`` is non-empty, WARN when only ``warn`` is, else OK. Values are stringified in
    the given order."""
    errors = list(error)
    reasons = errors + list(warn)
    status = DiagnosticStatus()
    status.level = (DiagnosticStatus.ERROR if errors else
                    DiagnosticStatus.WARN if reasons else DiagnosticStatus.OK)
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


_CLOCK = Encoder(Clock(), T.CLOCK.type, (('clock.sec', 'clock.nanosec'),)).encode


def clock_cdr(t_ns: int) -> bytes:
    """``/clock`` at sim time ``t_ns`` [ns] already serialised (what
    ``serialize_message(clock_msg(t_ns))`` returns): a publisher sends bytes without converting
    a Python message."""
    return _CLOCK(split_ns(t_ns))


def applied_command_msg(t_ns: int, lengths: Sequence[float]) -> JointState:
    """``~/applied_command``: the target lengths [m] that took effect at the tick starting at
    ``t_ns`` (names linkage_j, position = targets; velocity and effort are zeros, filled because
    rosbags cannot read a JointState whose trailing arrays are empty)."""
    zeros = [0.0] * len(lengths)
    return joint_state(t_ns, linkage_names(len(lengths)), lengths, zeros, zeros)


class Row:
    """The numbers of a core ``State`` as Python lists (``contact`` as ints), converted once per
    publish tick and shared by every encoder (each ``tolist`` of a p-entry array costs about as
    much as packing it). ``source`` is the state itself (the builders of a shape's first message
    take it), ``x_array``/``v_array`` its arrays for the centre of mass."""

    __slots__ = ('x', 'v', 'friction', 'contact', 'linkage_force', 'lengths', 'rates',
                 'x_array', 'v_array', 'source')

    def __init__(self, state: State) -> None:
        self.source = state
        self.x_array, self.v_array = state.x, state.v
        self.x = _floats(state.x)
        self.v = _floats(state.v)
        self.friction = _floats(state.friction)
        self.linkage_force = _floats(state.linkage_force)
        self.lengths = _floats(state.lengths)
        self.rates = _floats(state.rates)
        contact = state.contact
        self.contact = (contact.tolist() if isinstance(contact, np.ndarray)
                        else [int(c) for c in contact])

    def finite(self) -> bool:
        """Whether every published number of the state is finite."""
        isfinite = math.isfinite
        return all(map(isfinite, self.x + self.v + self.friction + self.linkage_force
                       + self.lengths + self.rates))


#: the topic (and so the ROS type) of each kind of message :class:`OutputEncoder` makes
ENCODED = {**T.OUTPUTS, 'applied_command': T.APPLIED_COMMAND, 'linkage_cmd': T.LINKAGE_CMD}
# the changing fields of each shape: one definition, shared with offline recording (bag.msgs)
_STAMP, _JOINTS, _ODOM = STAMP, JOINT_GROUPS, ODOM_GROUPS
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

    def __init__(self, prefix: str = '') -> None:
        from rclpy.serialization import serialize_message
        #: the frames' prefix of ``odom`` (``bag.msgs.frame_prefix`` of the node's namespace)
        self.prefix = prefix
        self._serialize, self._encoder_class, self._layout_error = (
            serialize_message, Encoder, LayoutError)
        self._encoders: dict[tuple, Any] = {}
        self._masses_of: Any = _MISSING       # the masses argument of the cached conversion
        self._masses: tuple = ()
        self._com_of: tuple = (_MISSING, _MISSING)     # (state, masses) of the latest com
        self._com = (0.0, 0.0)
        self.fast = 0
        self.slow = 0

    def encode(self, name: str, state: State | Row, t_ns: int,
               masses: Sequence[float] | None = None) -> bytes:
        """CDR bytes of output ``name`` (``joint_states``, ``body_states``, ``contact_states``,
        ``odom``, ``markers``) of core ``State`` at sim time ``t_ns`` [ns]; ``odom`` needs the
        body ``masses`` [kg]."""
        return getattr(self, name)(state, t_ns, masses)

    def joint_states(self, state: State | Row, t_ns: int,
                     masses: Sequence[float] | None = None) -> bytes:
        return self._joints('joint_states', t_ns, state.lengths, state.rates,
                            state.linkage_force, lambda: joint_states_msg(_source(state), t_ns))

    def body_states(self, state: State | Row, t_ns: int,
                    masses: Sequence[float] | None = None) -> bytes:
        return self._joints('body_states', t_ns, state.x, state.v, state.friction,
                            lambda: body_states_msg(_source(state), t_ns))

    def contacts_stamped(self, state: State | Row, t_ns: int,
                         masses: Sequence[float] | None = None) -> bytes:
        contact = state.contact
        if type(contact) is not list:
            contact = np.asarray(contact, dtype=float)
        return self._joints('contacts_stamped', t_ns, contact, state.v, state.friction,
                            lambda: contacts_stamped_msg(_source(state), t_ns))

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

    def contact_states(self, state: State | Row, t_ns: int = 0,
                       masses: Sequence[float] | None = None) -> bytes:
        contact = state.contact
        if type(contact) is not list:
            contact = np.asarray(contact, dtype=np.int8).tolist()
        return self._encode(('contact_states', len(contact)), (('data',),), (contact,),
                            lambda: contact_states_msg(_source(state)))

    def odom(self, state: State | Row, t_ns: int,
             masses: Sequence[float] | None = None) -> bytes:
        com_x, com_v = self.centre_of_mass(state, masses)
        return self._encode(('odom',), _ODOM, (split_ns(t_ns), (com_x,), (com_v,)),
                            lambda: odom_msg(_source(state), masses, t_ns, self.prefix))

    def centre_of_mass(self, state: State | Row,
                       masses: Sequence[float] | None) -> tuple[float, float]:
        """``bag.msgs.centre_of_mass`` of ``state`` (its arithmetic, the masses converted once
        while the same object is passed): ``odom``'s pose and ``/tf``'s transform."""
        if state is self._com_of[0] and masses is self._com_of[1]:
            return self._com              # the same state again (odom, then /tf)
        x, v = getattr(state, 'x_array', state.x), getattr(state, 'v_array', state.v)
        if masses is self._masses_of:
            m, total = self._masses
            com = (float(m @ np.asarray(x, dtype=np.float64)) / total,
                   float(m @ np.asarray(v, dtype=np.float64)) / total)
        else:
            com = centre_of_mass(x, v, masses)
            if masses is not None:
                m = np.asarray(masses, dtype=np.float64)
                self._masses_of, self._masses = masses, (m, float(m.sum()))
        self._com_of, self._com = (state, masses), com
        return com

    def markers(self, state: State | Row, t_ns: int,
                masses: Sequence[float] | None = None) -> bytes:
        xs = _floats(state.x)
        contact = state.contact
        if type(contact) is not list:
            contact = contact.tolist()
        p = len(xs)
        stamp = split_ns(t_ns)
        values: list = []
        for i in range(p):
            values += (stamp, (xs[i],), CONTACT_COLOURS.get(int(contact[i]), _LINK_COLOUR))
        for j in range(p - 1):
            values += (stamp, (xs[j],), (xs[j + 1],))
        return self._encode(('markers', p), _marker_groups(p), values,
                            lambda: markers_msg(_source(state), t_ns))

    def _joints(self, kind: str, t_ns: int, position, velocity, effort, build) -> bytes:
        values = (split_ns(t_ns), _floats(position), _floats(velocity),
                  _floats(effort))
        return self._encode((kind, len(values[1])), _JOINTS, values, build)

    def _encode(self, key: tuple, groups, values, build) -> bytes:
        encoder = self._encoders.get(key, _MISSING)
        if encoder is _MISSING:                   # first message of this shape: the template
            try:
                encoder = self._encoder_class(build(), ENCODED[key[0]].type, groups)
            except self._layout_error:
                encoder = None                    # this shape always goes through the builder
            self._encoders[key] = encoder
        if encoder is None:
            self.slow += 1
            return self._serialize(build())
        self.fast += 1
        return encoder.encode(*values)


def _source(state):
    """The core ``State`` (or duck) behind a :class:`Row`, for the builders."""
    return state.source if type(state) is Row else state


def _floats(values) -> list[float]:
    if type(values) is list:
        return values
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
