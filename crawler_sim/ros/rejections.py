"""Input a node cannot use: counted, reported at most once per period, skipped; the node goes on.

One home for every node of the package (sim_node, gait_node, replay_node):

- :class:`RejectionLog` counts rejected inputs and writes one WARN line per period per kind
  (sim_node notes the commands and trajectories it refuses in it);
- :class:`SkippingExecutor` takes messages, service requests and responses like rclpy's
  ``SingleThreadedExecutor``, except that one it cannot take (rclpy fails to convert it into a
  Python message) is noted in a :class:`RejectionLog` and skipped, instead of ending the spin
  (and with it the node) with ``RuntimeError: Unable to convert call argument '0' to Python
  object``. A message rclpy's own field checks refuse does that (with
  ``ROS_PYTHON_CHECK_FIELDS=1`` a ``float32`` holding the largest float fails them);
- :func:`stop_on_signals` and :func:`spin`: SIGINT and SIGTERM only set an event, which the
  spin loop checks between two waits. rclpy's own handlers raise ``KeyboardInterrupt`` in the
  main thread, between any two bytecodes: when that is inside the constructor of a message
  rclpy is converting, pybind11 turns it into the same ``RuntimeError`` and the node exits with
  a traceback (issue 38 item 8: gait_node, stopped with SIGINT while it took /clock messages).
  sim_node's main has done the same since its loop had to stop between two ticks.

:class:`UnreadableInput` joins them for a node: the counter ``unreadable_messages``, a WARN line
and a ``/diagnostics`` status ``<node>: input`` (level WARN, with the count and the latest
reason) when a line is due.

A rejection costs microseconds: it is logged at most once per :data:`LOG_PERIOD` per kind with
the count since the last line, and the logger is not called at all in between (rclpy's logger
inspects its caller on every call, about 540 us, even when a throttle then drops the message).
"""
from __future__ import annotations

import signal
import threading
import time
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from crawler_sim.bag import topics as T
from crawler_sim.ros.messages import diagnostics_msg

__all__ = ['LOG_PERIOD', 'RejectionLog', 'SkippingExecutor', 'UnreadableInput', 'spin',
           'stop_on_signals']

LOG_PERIOD = 1.0     # wall s between two log lines about rejected input of one kind
SPIN_TIMEOUT = 0.5   # s, the longest wait of a spin (how soon a signal is seen)
UNREADABLE = 'unreadable'   # the kind noted (its counter: 'unreadable_rejected')


class RejectionLog:
    """Counts rejected inputs and logs at most once per ``period`` wall seconds per kind.

    ``note`` costs a dict update and one ``time.monotonic()`` call; the logger (about 540 us
    per call in rclpy) is called only when a line is due.
    """

    def __init__(self, counters: dict[str, int], warn: Callable[[str], Any],
                 period: float = LOG_PERIOD, clock: Callable[[], float] = time.monotonic) -> None:
        self.counters = counters
        self._warn = warn
        self._period = period
        self._clock = clock
        self._next: dict[str, float] = {}
        self._since: dict[str, int] = {}
        self.last = ''
        self.lines = 0            # log lines written

    def note(self, kind: str, topic: str, reason: str) -> None:
        """Count one rejected input of ``kind`` from ``topic``, and log it if a line is due."""
        key = kind + '_rejected'
        self.counters[key] = self.counters.get(key, 0) + 1
        self.last = f'{kind}: {reason}'
        self._since[kind] = self._since.get(kind, 0) + 1
        now = self._clock()
        if now >= self._next.get(kind, 0.0):
            n, self._since[kind] = self._since[kind], 0
            self._next[kind] = now + self._period
            self.lines += 1
            self._warn(f'{topic} rejected: {reason} ({n} rejected since the last message, '
                       f'{self.counters[key]} in all)')


class SkippingExecutor(SingleThreadedExecutor):
    """A ``SingleThreadedExecutor`` that skips what it cannot take: a message, a request or a
    response rclpy fails to convert is noted in ``rejections`` (kind ``unreadable_messages``,
    the entity's topic or service named) and dropped; every other callback runs as usual.

    It overrides the executor's three take hooks (``_take_subscription``, ``_take_service``,
    ``_take_client``: rclpy 7.1, Jazzy), the only places a received message is converted.
    """

    def __init__(self, rejections: RejectionLog, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.rejections = rejections

    def _skip(self, name: str, exc: Exception) -> None:
        self.rejections.note(UNREADABLE, name,
                             f'a message that cannot be converted was skipped '
                             f'({type(exc).__name__}: {exc})')

    def _take_subscription(self, sub: Any) -> Any:
        try:
            return super()._take_subscription(sub)
        except Exception as exc:  # noqa: BLE001 - one message must not end the node
            self._skip(sub.topic_name, exc)
            return None

    def _take_service(self, srv: Any) -> Any:
        try:
            return super()._take_service(srv)
        except Exception as exc:  # noqa: BLE001
            self._skip(srv.srv_name, exc)
            return None

    def _take_client(self, client: Any) -> Any:
        try:
            return super()._take_client(client)
        except Exception as exc:  # noqa: BLE001
            self._skip(client.srv_name, exc)
            return None


class UnreadableInput:
    """A node's record of the messages it could not read: ``counters``, a
    :class:`RejectionLog` and a ``/diagnostics`` publisher for its reports, and the
    :class:`SkippingExecutor` to spin the node with (``executor``)."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.counters: dict[str, int] = {}
        self._name = f'{node.get_fully_qualified_name()}: input'
        self._pub = node.create_publisher(DiagnosticArray, T.DIAGNOSTICS.node_name, 10)
        self.log = RejectionLog(self.counters, self._report)
        self.executor = SkippingExecutor(self.log, context=node.context)
        self.executor.add_node(node)

    @property
    def count(self) -> int:
        """Messages skipped so far."""
        return self.counters.get(UNREADABLE + '_rejected', 0)

    def note(self, name: str, reason: str) -> None:
        """One message of ``name`` (a topic, a service) that cannot be read: counted, and
        reported if a line is due. The caller skips it."""
        self.log.note(UNREADABLE, name, reason)

    def _report(self, line: str) -> None:
        """A line is due: WARN, and the same on /diagnostics."""
        self.node.get_logger().warning(line)
        t_ns = self.node.get_clock().now().nanoseconds
        self._pub.publish(diagnostics_msg(
            t_ns, {'unreadable_messages': self.count, 'last_unreadable': self.log.last},
            warn=[line], name=self._name, hardware_id=self.node.get_name()))


def stop_on_signals(stop: threading.Event | None = None) -> threading.Event:
    """``stop`` (default a new event), which SIGINT and SIGTERM set, and nothing else: they no
    longer raise ``KeyboardInterrupt`` nor shut rclpy down (the caller shuts down when the
    event is set). Call after ``rclpy.init`` (it replaces rclpy's handlers), from the main
    thread."""
    stop = threading.Event() if stop is None else stop
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.set())
    return stop


def spin(executor: SingleThreadedExecutor, stop: threading.Event) -> None:
    """Run ``executor``'s callbacks until ``stop`` is set or its context shuts down (a
    callback that raises, a bug, ends it: the caller reports it). A signal is seen within
    :data:`SPIN_TIMEOUT` s."""
    try:
        while not stop.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_TIMEOUT)
    except ExternalShutdownException:
        pass
