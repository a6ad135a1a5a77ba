"""sim_node outputs: publishers of the switched-on outputs and their CDR encoders.

Every output goes out as CDR bytes from a per-shape template (``messages.OutputEncoder``): one
serialisation serves the publisher and the bag, and no rclpy message is built per tick. An
output is encoded only when someone takes it (a subscriber, or the bag); the subscriber counts
are read from rclpy at most every :data:`COUNT_PERIOD` publish ticks, as each query costs a few
microseconds and a late subscriber then misses at most that many messages.

``robot_description`` (std_msgs/String, the URDF of :func:`.model.robot_description`) is not on
the grid: it goes out once with transient-local durability (depth 1, the robot_state_publisher
convention, so a subscriber that joins later still gets it) at the first :meth:`Outputs.sync`
and again whenever the model changes (number of bodies, masses, linkage limits).
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Int8MultiArray, String
from visualization_msgs.msg import MarkerArray

from crawler_sim.bag import topics as T
from crawler_sim.ros import messages as M
from .model import robot_description
from .tf import TfBroadcaster, frame_prefix, load_tf_message
from .params import OFF_GRID, OUTPUTS

if TYPE_CHECKING:
    from rclpy.node import Node

    from .params import SimConfig

__all__ = ['Outputs', 'CLASSES', 'COUNT_PERIOD', 'DESCRIPTION_QOS']

#: message class of each output (its topic and type: ``crawler_sim.bag.topics.OUTPUTS``)
CLASSES: dict[str, type] = {
    'joint_states': JointState, 'body_states': JointState, 'contact_states': Int8MultiArray,
    'contacts_stamped': JointState, 'odom': Odometry, 'markers': MarkerArray,
    'diagnostics': DiagnosticArray,
}
COUNT_PERIOD = 16       # publish ticks between two reads of the subscriber counts
#: the robot model's QoS (its topic is relative: it lives in the robot's namespace, as
#: robot_state_publisher's does): reliable, transient local, depth 1 (the latest description
#: only, kept for late subscribers)
DESCRIPTION_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Outputs:
    """The node's output publishers (created and destroyed as ``publish_*`` change)."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self.pubs: dict[str, Any] = {}
        self.clock_pub = None
        self._clock_owner = True          # False: another node owns /clock (.clock)
        #: no /clock below this sim time [ns] (a sim that took the clock over continues from
        #: the last time heard)
        self.clock_floor = 0
        self.clock_last_ns = -1           # the latest /clock published [ns] (-1: none yet)
        self.clock_wall = 0.0             # when (perf_counter s)
        # odom names the frames /tf does (prefixed in a namespace, bag.msgs.frame_prefix)
        self.encoder = M.OutputEncoder(frame_prefix(node.get_namespace()))
        # (name, topic, publisher, encode, publish_raw) on the publish grid, and those with a
        # subscriber
        self._grid: list[tuple] = []
        self._takers: list[tuple] = []
        self._countdown = 0
        self.description_pub = node.create_publisher(String, T.ROBOT_DESCRIPTION.node_name,
                                                      DESCRIPTION_QOS)
        self._model_key: tuple | None = None     # what the published description was made of
        #: the URDF last published on ``robot_description`` ('' before the first sync)
        self.description = ''
        # /tf odom -> base_link at every publish tick while publish_tf (None when switched off,
        # or without tf2_msgs: why in tf_missing)
        self._tf_message, self.tf_missing = load_tf_message()
        self.tf: TfBroadcaster | None = None

    def sync(self, cfg: SimConfig) -> bool:
        """Create the publishers of switched-on outputs, destroy those switched off; publish
        ``robot_description`` if the model of ``cfg`` differs from the one last published.
        Return whether it did (:attr:`description` is then the new URDF, e.g. to record)."""
        self._cfg = cfg
        changed = self._sync_description(cfg)
        node = self._node
        for name in OUTPUTS:
            on = bool(getattr(cfg, 'publish_' + name))
            if on and name not in self.pubs:
                self.pubs[name] = node.create_publisher(CLASSES[name],
                                                        T.OUTPUTS[name].node_name, 10)
            elif not on and name in self.pubs:
                node.destroy_publisher(self.pubs.pop(name))
        if cfg.publish_tf and self.tf is None and self._tf_message is not None:
            self.tf = TfBroadcaster(node, self._tf_message, self.encoder.centre_of_mass)
        elif not cfg.publish_tf and self.tf is not None:
            self.tf.destroy()
            self.tf = None
        enc = self.encoder
        # publish_raw of the pybind handle: rclpy's Publisher.publish adds a type check and a
        # `with handle` guard (about 5 us) per message; the handles live as long as the node
        self._grid = [(name, T.OUTPUTS[name], self.pubs[name], getattr(enc, name),
                       self.pubs[name].handle.publish_raw)
                      for name in OUTPUTS if name in self.pubs and name not in OFF_GRID]
        self._countdown = 0
        own_clock = cfg.publish_clock and self._clock_owner
        if own_clock and self.clock_pub is None:
            self.clock_pub = node.create_publisher(Clock, T.CLOCK.node_name, 10)
            self._clock_raw = self.clock_pub.handle.publish_raw
        elif not own_clock and self.clock_pub is not None:
            node.destroy_publisher(self.clock_pub)
            self.clock_pub = None
        return changed

    def set_clock_owner(self, own: bool, floor_ns: int = 0) -> None:
        """Publish /clock (``own``, from sim time ``floor_ns`` on) or not (another node owns
        it); the publisher is created or destroyed at once."""
        self._clock_owner = own
        self.clock_floor = floor_ns
        if own:          # (the clock heard up to now counts as published: no yield to it)
            self.clock_last_ns = max(self.clock_last_ns, floor_ns)
        self.sync(self._cfg)

    def publish_clock_again(self) -> None:
        """Publish the latest /clock again (an owner's keep-alive while paused or paced
        slowly: the followers tell a dead owner by its silence)."""
        if self.clock_pub is not None and self.clock_last_ns >= 0:
            self._clock_raw(M.clock_cdr(self.clock_last_ns))
            self.clock_wall = time.perf_counter()

    def _sync_description(self, cfg) -> bool:
        """Publish the URDF of ``cfg``'s crawler when what it is made of changed: p and the
        masses (which also set the mimic multipliers of the base chain), and the linkage
        limits. Parameter changes that leave the model alone publish nothing: a transient-local
        message is what every late subscriber gets, so it changes only with the model."""
        key = (tuple(float(m) for m in cfg.crawler.masses), float(cfg.min_length),
               float(cfg.max_length), float(cfg.limits.max_speed))
        if key == self._model_key:
            return False
        masses, lo, hi, speed = key
        self.description = robot_description(len(masses), masses, min_length=lo,
                                             max_length=hi, max_speed=speed)
        self.description_pub.publish(String(data=self.description))
        self._model_key = key
        return True

    def warm_up(self, state: Any, t_ns: int, masses: Sequence[float],
                lengths: Sequence[float]) -> None:
        """Encode every grid output of ``state`` and an applied command of ``lengths`` once, so
        that the templates are built before the loop runs (the node's warm-up)."""
        for _name, _topic, _pub, encode, _raw in self._grid:
            encode(state, t_ns, masses)
        self.encoder.applied_command(list(lengths), t_ns)
        self.encoder.fast = self.encoder.slow = 0

    def topics(self) -> list[T.Topic]:
        """The grid outputs this node publishes."""
        return [topic for _name, topic, *_ in self._grid]

    def publish(self, state: Any, t_ns: int, masses: Sequence[float],
                record: Callable[[T.Topic, bytes, int], None] | None = None) -> None:
        """Publish /clock and every output taken by someone at sim time ``t_ns``; ``state`` is
        a core ``State`` or its :class:`crawler_sim.ros.messages.Row` (or a callable returning
        one, called only if someone takes an output); ``record`` (Topic, bytes, t_ns) gets
        each output before it is published, so what a subscriber has seen is in the bag."""
        if self.clock_pub is not None and t_ns >= self.clock_floor:
            self._clock_raw(M.clock_cdr(t_ns))
            self.clock_last_ns = t_ns
            self.clock_wall = time.perf_counter()
        if self.tf is not None:
            self.tf.publish(state, t_ns, masses)
        if record is not None:
            takers = self._grid
        else:
            self._countdown -= 1
            if self._countdown <= 0:
                self._countdown = COUNT_PERIOD
                self._takers = [g for g in self._grid if g[2].get_subscription_count() > 0]
            takers = self._takers
        if not takers:
            return
        st = state() if callable(state) else state
        for _name, topic, _pub, encode, publish_raw in takers:
            data = encode(st, t_ns, masses)
            if record is not None:
                record(topic, data, t_ns)
            publish_raw(data)

    def refresh(self) -> None:
        """Read the subscriber counts at the next publish tick (e.g. after a reset)."""
        self._countdown = 0
        if self.tf is not None:
            self.tf.refresh()
