"""``replay_node``: publish a bag's topics with their original timing (like ``ros2 bag play``).

Run it like sim_node: ``ros2 run crawler_sim replay_node --ros-args -p bag:=runs/NAME``.
The raw CDR messages are read from the bag's MCAP file(s) with :mod:`crawler_sim.bag`, turned
back into rclpy messages of their recorded type (``pkg/msg/Type``) and published on their
recorded (absolute) topic names, each at wall time ``t0 + (log_time - start) / rate``. Before
each batch of messages that share a log time, ``/clock`` (rosgraph_msgs/Clock) is published with
that log time, so ``use_sim_time`` nodes follow the bag's time. Use ROS remapping
(``-r /linkage_cmd:=/other``) to publish a topic under another name.

Looping: sim time continues, ``/clock`` never goes backwards. Pass k (k = 0, 1, 2, ...) of the
bag publishes everything shifted by k * (D + P) of sim time, where

* D [ns] is the span of one pass: from the start point (start of the bag + ``start_offset``) to
  the last log time played;
* P [ns] is one publish period: the most common spacing between consecutive distinct log times
  played (ties: the shortest), i.e. 1/publish_rate for a sim_node bag; 1 s when only one log
  time is played.

The shift applies to ``/clock``, to every ``builtin_interfaces/Time`` in a replayed message
(header stamps, the stamps of each marker, a recorded ``/clock``: found from the message type,
at any depth), and to the ``sim_time`` value of a ``/diagnostics`` status. Two exceptions keep
their meaning: a zero stamp in a ``trajectory_msgs`` message ("start on receipt") stays zero, and
durations (``time_from_start``, marker lifetimes) are relative, so they are not shifted. Data
fields (positions, commands, the plant_inputs journal) are published as recorded. At the seam,
``/clock`` steps from the last log time of pass k to the first of pass k + 1: forward by P plus
the gap between the start point and the first message played; the wall clock waits that step /
``rate``, so pacing is continuous across the seam (a pass shorter than 0.1 s of wall time is
stretched to 0.1 s, so a tiny bag at a high rate does not loop hot; sim time is unaffected).

Parameters
----------
bag : str
    Bag directory or ``.mcap`` file (required).
rate : float
    Playback speed factor (> 0; 2 plays twice as fast). Default 1.
loop : bool
    Start again from ``start_offset`` at the end of the bag, with sim time continued (see
    Looping above). Default false.
start_offset : float
    Seconds of log time after the start of the bag at which playback starts (>= 0).
publish_clock : bool
    Publish ``/clock`` with the log time of every batch (plus the shift of the pass when
    looping). Default true.
topics : string array
    Topics to play (e.g. ``['/linkage_cmd']`` to drive a live sim_node with a recorded
    controller). Default: every topic of the bag except the latched scene topic.
wait_for_subscribers : int
    Before playing, wait until every publisher (``/clock`` included) has at least this many
    matched subscribers, so that nothing is lost to discovery. Default 0 (start at once).
start_paused : bool
    Start paused before the first message; ``~/pause`` (std_srvs/SetBool, false) starts it.

Service ``~/pause`` (std_srvs/SetBool): true pauses, false resumes; paused time does not count,
so the spacing of the messages is kept.

A recorded message that cannot be deserialised, and a request rclpy cannot convert, are skipped,
counted and reported (a WARN line and a ``/diagnostics`` status ``<node>: input`` at most once
per second, ``crawler_sim.ros.rejections``); the rest plays on. SIGINT/SIGTERM stop it between
two messages.

Exit codes: 0 at the end of the bag (or on SIGINT/SIGTERM), 2 for a missing or unreadable bag or
invalid parameters (one line on stderr, no traceback).
"""
from __future__ import annotations

from bisect import bisect_left
from collections import Counter
from dataclasses import dataclass
from functools import lru_cache
from importlib import import_module
import sys
import threading
import time
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
from mcap.records import Channel, Schema
from rcl_interfaces.msg import ParameterDescriptor
import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from rosidl_parser.definition import AbstractNestedType, NamespacedType
from std_srvs.srv import SetBool

from crawler_sim.bag import BagError, bag_files
from crawler_sim.bag.mcapfile import Batch, scan
from crawler_sim.bag.schema import message_class, parse_qos_yaml
from crawler_sim.bag import topics as T
from crawler_sim.bag.topics import SCENE, split_topic
from crawler_sim.ros.messages import ns_from_stamp, stamp_from_ns
from crawler_sim.ros.rejections import stop_on_signals, UnreadableInput
from crawler_sim.core.simtime import NS_PER_S, to_ns, to_seconds

__all__ = ['ReplayError', 'ReplayNode', 'Recording', 'Track', 'read_bag', 'publish_period_ns',
           'shift_stamps', 'main']

NODE_NAME = 'replay_node'
QUEUE_DEPTH = 100          # publisher history: bursts at a high rate are not dropped
MAX_WAIT_SLICE = 0.1       # s: longest single wait, so parameter services stay responsive
ACK_TIMEOUT = 2.0          # s to wait at the end for reliable subscribers to acknowledge
SINGLE_TIME_PERIOD_NS = NS_PER_S   # loop period P [ns] of a bag with one log time to play


class ReplayError(ValueError):
    """Invalid parameters or a bag that cannot be played (one-line message)."""


@dataclass(frozen=True)
class Track:
    """One topic of the bag to publish."""

    topic: str
    type_name: str
    cls: type
    qos: QoSProfile


@dataclass
class Recording:
    """Messages to play, sorted by log time: ``log_times[i]``, ``topics[i]``, ``data[i]`` (CDR)."""

    tracks: dict[str, Track]
    log_times: list[int]
    topics: list[str]
    data: list[bytes]
    start_ns: int          # first log time of the whole bag (all topics)
    end_ns: int


def _qos(metadata: dict[str, str]) -> QoSProfile:
    """Publisher QoS from the recorded ``offered_qos_profiles`` (reliability and durability)."""
    profiles = parse_qos_yaml(metadata.get('offered_qos_profiles', ''))
    first = profiles[0] if profiles and isinstance(profiles[0], dict) else {}
    best_effort = first.get('reliability') == 'best_effort'
    latched = first.get('durability') == 'transient_local'
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=QUEUE_DEPTH,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _is_scene(topic: str) -> bool:
    return split_topic(topic, SCENE.suffix) is not None


def read_bag(path: str, topics: list[str] | None = None,
             warn: Callable[[str], Any] | None = None) -> Recording:
    """Read the messages of ``topics`` (absolute names; None: all but the scene) from a bag.

    Raises :class:`BagError` / :class:`ReplayError` with a one-line message. ``warn(text)``
    receives non-fatal problems (a truncated file, a topic whose type is not installed).
    """
    warn = warn or (lambda text: None)
    wanted = None if topics is None else {'/' + t.lstrip('/') for t in topics}
    tracks: dict[str, Track] = {}
    skipped: dict[str, str] = {}
    seen: set[str] = set()
    entries: list[tuple[int, int, str, bytes]] = []
    start_ns: int | None = None
    end_ns: int | None = None
    for file_index, path_i in enumerate(bag_files(path)):
        per_topic: dict[str, list[tuple[int, bytes]]] = {}

        def want(channel: Channel, schema: Schema | None,
                 per_topic: dict = per_topic) -> Callable[[Batch], None] | None:
            topic = channel.topic
            seen.add(topic)
            if (wanted is None and _is_scene(topic)) or (wanted is not None
                                                         and topic not in wanted):
                return None
            if channel.message_encoding != 'cdr' or schema is None:
                skipped[topic] = f'encoding {channel.message_encoding!r} is not cdr'
                return None
            if topic not in tracks:
                try:
                    cls = message_class(schema.name)
                except (BagError, ValueError) as exc:
                    skipped[topic] = str(exc)
                    return None
                tracks[topic] = Track(topic, schema.name, cls, _qos(dict(channel.metadata)))
            store: list[tuple[int, bytes]] = []
            per_topic[topic] = store          # a re-scan of the file replaces the first attempt

            def sink(batch: Batch) -> None:
                for i, t in enumerate(batch.log_times.tolist()):
                    store.append((t, batch.data(i)))
            return sink

        result = scan(path_i, want)
        if result.truncated:
            warn(f'{path_i}: {result.stop_reason}; playing the messages before the damage')
        if result.start_ns is not None:
            start_ns = result.start_ns if start_ns is None else min(start_ns, result.start_ns)
            end_ns = result.end_ns if end_ns is None else max(end_ns, result.end_ns)
        for topic, store in per_topic.items():
            entries.extend((t, file_index, topic, d) for t, d in store)
    if wanted is not None:
        missing = sorted(wanted - seen)
        if missing:
            raise ReplayError(f'{path}: no topic {", ".join(missing)} in the bag '
                              f'(it has {", ".join(sorted(seen)) or "no topics"})')
        bad = sorted(t for t in wanted if t in skipped)
        if bad:
            raise ReplayError(f'{path}: cannot play {bad[0]}: {skipped[bad[0]]}')
    for topic, reason in sorted(skipped.items()):
        warn(f'skipping {topic}: {reason}')
    entries.sort(key=lambda e: (e[0], e[1]))      # stable: file order within equal log times
    if not entries or start_ns is None:
        raise ReplayError(f'{path}: no messages to play')
    return Recording(tracks, [e[0] for e in entries], [e[2] for e in entries],
                     [e[3] for e in entries], start_ns, end_ns)


def publish_period_ns(log_times: list[int]) -> int:
    """One publish period P [ns] of sorted ``log_times`` [ns]: the most common spacing between
    consecutive distinct times (ties: the shortest); :data:`SINGLE_TIME_PERIOD_NS` for fewer
    than two distinct times.

    The most common spacing, not the smallest: in a sim_node bag an event or a command logged
    between two publish ticks makes a shorter, irregular spacing, while the publish grid
    (1/publish_rate) makes most of them.
    """
    distinct = sorted(set(log_times))
    gaps = Counter(b - a for a, b in zip(distinct, distinct[1:]))
    if not gaps:
        return SINGLE_TIME_PERIOD_NS
    return min(gaps, key=lambda gap: (-gaps[gap], gap))


# A plan of where a message type holds builtin_interfaces/Time: (field, kind, sub-plan) per
# field that can hold one. kind: 'time' (a Time), 'times' (a sequence of Time), 'msg' (a message
# holding Time somewhere), 'msgs' (a sequence of such messages).
_Plan = tuple[tuple[str, str, Any], ...]
_TIME = (('builtin_interfaces', 'msg'), 'Time')


@lru_cache(maxsize=None)
def _message_type(namespaces: tuple[str, ...], name: str) -> type:
    return getattr(import_module('.'.join(namespaces)), name)


@lru_cache(maxsize=None)
def _time_plan(cls: type) -> _Plan:
    """Where a message of class ``cls`` holds ``builtin_interfaces/Time``, from its IDL types
    (so any message type of any package is covered, at any depth)."""
    plan = []
    for field, slot_type in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):
        nested = isinstance(slot_type, AbstractNestedType)
        value_type = slot_type.value_type if nested else slot_type
        if not isinstance(value_type, NamespacedType):
            continue                     # numbers, strings and their arrays: no time in them
        key = (tuple(value_type.namespaces), value_type.name)
        if key == _TIME:
            plan.append((field, 'times' if nested else 'time', None))
            continue
        sub = _time_plan(_message_type(*key))
        if sub:
            plan.append((field, 'msgs' if nested else 'msg', sub))
    return tuple(plan)


def _shifted(stamp: Any, offset_ns: int, keep_zero: bool) -> Any:
    t_ns = ns_from_stamp(stamp)
    if keep_zero and t_ns == 0:
        return stamp
    return stamp_from_ns(t_ns + offset_ns)


def _apply_plan(msg: Any, plan: _Plan, offset_ns: int, keep_zero: bool,
                seen: set[int]) -> None:
    # A message built in Python may share one object between several fields (messages.
    # markers_msg gives every marker the same Time): Times are replaced by new ones, never
    # changed in place, and a shared sub-message is shifted once (``seen``: ids visited)
    if id(msg) in seen:
        return
    seen.add(id(msg))
    for field, kind, sub in plan:
        value = getattr(msg, field)
        if kind == 'time':
            setattr(msg, field, _shifted(value, offset_ns, keep_zero))
        elif kind == 'times':
            setattr(msg, field, [_shifted(t, offset_ns, keep_zero) for t in value])
        elif kind == 'msg':
            _apply_plan(value, sub, offset_ns, keep_zero, seen)
        else:
            for item in value:
                _apply_plan(item, sub, offset_ns, keep_zero, seen)


def shift_stamps(msg: Any, offset_ns: int) -> Any:
    """Shift every sim time that ``msg`` carries by ``offset_ns`` [ns], in place; return it.

    That is every ``builtin_interfaces/Time`` in it (header stamps, at any depth) and the
    ``sim_time`` value [s] of each status of a ``diagnostic_msgs/DiagnosticArray`` (sim_node's
    diagnostics). A zero stamp in a ``trajectory_msgs`` message stays zero: there it means
    "start on receipt", not sim time 0. Durations are relative and stay as they are.
    """
    if offset_ns == 0:
        return msg
    cls = type(msg)
    # JointTrajectory, MultiDOFJointTrajectory: header stamp 0 = start on receipt
    keep_zero = cls.__module__.split('.', 1)[0] == 'trajectory_msgs'
    _apply_plan(msg, _time_plan(cls), offset_ns, keep_zero, set())
    if isinstance(msg, DiagnosticArray):
        for status in msg.status:
            for item in status.values:
                if item.key != 'sim_time':
                    continue
                try:
                    t_s = float(item.value)
                except ValueError:
                    continue            # not a number: not sim_node's figure, left as is
                # the format sim_node writes it in (messages.diagnostics_msg)
                item.value = f'{t_s + to_seconds(offset_ns):.6g}'
    return msg


class ReplayNode(Node):
    """Publishes a :class:`Recording` against the wall clock; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        dynamic = ParameterDescriptor(dynamic_typing=True)     # accept 2 as well as 2.0
        self.declare_parameter('bag', '', ParameterDescriptor(
            description='Bag directory or .mcap file to play (required)'))
        self.declare_parameter('rate', 1.0, dynamic)
        self.declare_parameter('loop', False)
        self.declare_parameter('start_offset', 0.0, dynamic)
        self.declare_parameter('publish_clock', True)
        self.declare_parameter('topics', Parameter.Type.STRING_ARRAY)
        self.declare_parameter('wait_for_subscribers', 0)
        self.declare_parameter('start_paused', False)

        path = str(self.get_parameter('bag').value or '')
        if not path:
            raise ReplayError("parameter 'bag' is required (a bag directory or .mcap file)")
        self.rate = self._number('rate')
        if not self.rate > 0.0:
            raise ReplayError(f"parameter 'rate' must be > 0, got {self.rate}")
        offset = self._number('start_offset')
        if not offset >= 0.0:
            raise ReplayError(f"parameter 'start_offset' must be >= 0, got {offset}")
        self.loop = bool(self.get_parameter('loop').value)
        self.wait_for = int(self.get_parameter('wait_for_subscribers').value)
        self.paused = bool(self.get_parameter('start_paused').value)
        try:
            topics = list(self.get_parameter('topics').value) or None
        except ParameterUninitializedException:
            topics = None

        log = self.get_logger()
        self.rec = read_bag(path, topics, warn=log.warning)
        self.begin_ns = self.rec.start_ns + to_ns(offset)
        self.first = bisect_left(self.rec.log_times, self.begin_ns)
        if self.first == len(self.rec.log_times):
            duration = to_seconds(self.rec.end_ns - self.rec.start_ns)
            raise ReplayError(f'{path}: start_offset {offset} s is past the last message to '
                              f'play (the bag lasts {duration:.3f} s)')
        played = self.rec.log_times[self.first:]
        self.period_ns = publish_period_ns(played)
        # sim time a pass adds: its span from the start point plus one publish period, so the
        # next pass starts one period after this one ends and /clock keeps increasing
        self.loop_ns = played[-1] - self.begin_ns + self.period_ns
        self._t0: float | None = None     # wall time [s] of the start point of pass 0
        self.pubs = {name: self.create_publisher(t.cls, name, t.qos)
                     for name, t in self.rec.tracks.items()}
        self.clock_pub = (self.create_publisher(Clock, T.CLOCK.node_name, 10)
                          if self.get_parameter('publish_clock').value else None)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.stop = threading.Event()     # set: stop between two messages (main: by a signal)
        self.unreadable = UnreadableInput(self)
        log.info(f'playing {len(self.rec.log_times) - self.first} messages on '
                 f'{len(self.pubs)} topics from {path} (rate {self.rate}, loop {self.loop})')

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self.paused = bool(request.data)
        response.success = True
        response.message = 'paused' if self.paused else 'playing'
        return response

    def _number(self, name: str) -> float:
        value = self.get_parameter(name).value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ReplayError(f"parameter '{name}' must be a number, got {value!r}")
        return float(value)

    def all_publishers(self) -> list:
        return list(self.pubs.values()) + ([self.clock_pub] if self.clock_pub else [])

    def play(self, executor: SingleThreadedExecutor) -> None:
        """Wait for subscribers if asked, then play once (or forever with ``loop``, pass k
        shifted by k * :attr:`loop_ns` of sim time; see the module docstring)."""
        if self.wait_for > 0:
            self.get_logger().info(f'waiting for {self.wait_for} subscriber(s) per topic')
            while not self.stop.is_set() and not all(
                    p.get_subscription_count() >= self.wait_for for p in self.all_publishers()):
                executor.spin_once(timeout_sec=0.05)
        self._t0 = time.monotonic()
        loop_pass = 0
        while True:
            self.play_once(executor, loop_pass * self.loop_ns)
            if not self.loop or self.stop.is_set():
                break
            loop_pass += 1
            # a pass shorter than MAX_WAIT_SLICE of wall time (one batch at a high rate) is
            # stretched to it, so that a loop is never a hot loop; sim time is unaffected
            self._t0 += max(0.0, MAX_WAIT_SLICE - to_seconds(self.loop_ns) / self.rate)
        if self.stop.is_set():
            return
        deadline = Duration(seconds=ACK_TIMEOUT)
        for pub in self.all_publishers():     # let reliable subscribers get the last messages
            pub.wait_for_all_acked(deadline)

    def play_once(self, executor: SingleThreadedExecutor, offset_ns: int = 0) -> None:
        """Publish every message from ``start_offset`` to the end, each stamp shifted by
        ``offset_ns`` [ns] of sim time, paced by the wall clock.

        Log time t is due at wall time t0 + (t + offset_ns - start point) / rate, t0 being the
        wall time of pass 0's start point (moved on by pauses): one schedule for every pass, so
        the seam between two passes lasts the sim-time step / rate, as any other spacing.
        """
        rec, rate, stop = self.rec, self.rate, self.stop
        if self._t0 is None:
            self._t0 = time.monotonic()
        i, n = self.first, len(rec.log_times)
        while i < n:
            t_ns = rec.log_times[i]
            while True:
                if self.paused:              # paused time does not count
                    paused_at = time.monotonic()
                    while self.paused and not stop.is_set():
                        executor.spin_once(timeout_sec=MAX_WAIT_SLICE)
                    self._t0 += time.monotonic() - paused_at
                if stop.is_set():
                    return
                left = (self._t0 + to_seconds(t_ns + offset_ns - self.begin_ns) / rate
                        - time.monotonic())
                if left <= 0.0:
                    break
                executor.spin_once(timeout_sec=min(left, MAX_WAIT_SLICE))
            if self.clock_pub is not None:
                self.clock_pub.publish(Clock(clock=stamp_from_ns(t_ns + offset_ns)))
            while i < n and rec.log_times[i] == t_ns:
                topic = rec.topics[i]
                try:
                    msg = deserialize_message(rec.data[i], rec.tracks[topic].cls)
                except Exception as exc:  # noqa: BLE001 - damaged data: skip the message
                    self.unreadable.note(topic, f'the recorded message #{i} (log time {t_ns} '
                                         f'ns) cannot be deserialised ({type(exc).__name__}: '
                                         f'{exc}); skipped')
                else:
                    self.pubs[topic].publish(shift_stamps(msg, offset_ns))
                i += 1


#: replay_node's parameters for ``--help``: name -> (default, description, range or None);
#: the values ``ReplayNode`` declares (None: declared without a value)
HELP_PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None]] = {
    'bag': ('', 'Bag directory or .mcap file to play (required)', None),
    'rate': (1.0, 'Playback speed factor, > 0 (2 plays twice as fast)', None),
    'loop': (False, 'Start again from start_offset at the end of the bag, sim time continued',
             None),
    'start_offset': (0.0, 'Seconds of log time after the start of the bag at which playback '
                     'starts, >= 0', None),
    'publish_clock': (True, 'Publish /clock with the log time of every batch', None),
    'topics': (None, 'Topics to play (string array); not set: every topic of the bag except '
               'the latched scene topic', None),
    'wait_for_subscribers': (0, 'Before playing, wait until every publisher has at least this '
                             'many matched subscribers', None),
    'start_paused': (False, 'Start paused before the first message; ~/pause false starts it',
                     None),
}
HELP_SUMMARY = ('Publishes a bag\'s topics with their original timing (like ros2 bag play), '
                '/clock included; service ~/pause. Exit code 0 at the end of the bag, 2 for a '
                'missing or unreadable bag or invalid parameters.')


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run crawler_sim replay_node`` (``--help``: its parameters,
    exit 0, before rclpy starts)."""
    from crawler_sim.ros.args import print_help_and_exit
    print_help_and_exit(list(sys.argv if args is None else args), 'replay_node', NODE_NAME,
                        HELP_SUMMARY, HELP_PARAMETERS)
    rclpy.init(args=args)
    node: ReplayNode | None = None
    executor: SingleThreadedExecutor | None = None
    code = 0
    try:
        node = ReplayNode()
        executor = node.unreadable.executor
        stop_on_signals(node.stop)
        node.play(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (BagError, ReplayError) as exc:
        print(f'[replay_node] error: {exc}', file=sys.stderr, flush=True)
        code = 2
    except Exception as exc:
        if not rclpy.ok():
            pass                  # a signal shut ROS down in the middle of a publish
        elif node is None:        # e.g. a parameter override of the wrong type
            print(f'[replay_node] error: {exc}', file=sys.stderr, flush=True)
            code = 2
        else:
            raise
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if code:
        raise SystemExit(code)


if __name__ == '__main__':
    main()
