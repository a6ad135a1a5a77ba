"""``/tf``: the transform odom -> base_link of sim_node, at every publish tick.

``odom`` (nav_msgs/Odometry) gives the pose of ``base_link`` (the centre of mass X = sum m_i x_i
/ M, on the odom x axis, identity orientation) but a pose on a topic does not place a frame:
robot_state_publisher and RViz read the tree from ``/tf``. This publishes the same pose as a
transform, stamped with the same sim time, from the same numbers (``crawler_sim.bag.msgs
.centre_of_mass``), so ``/tf`` and ``odom`` agree at every publish tick.

Frames. In the root namespace they are ``odom`` and ``base_link``, as in ``odom``. ``/tf`` is one
global topic, so a robot in namespace ``/r1`` gets ``r1/odom`` -> ``r1/base_link`` (the
``frame_prefix`` convention of robot_state_publisher: run it there with ``-p frame_prefix:=r1/``)
and two robots never claim the same frame.

Cost: the message goes out as CDR bytes (``bag.cdr.Encoder``: the first message serialised
once, then the stamp and x packed into its bytes, published raw as the other outputs are: the
rclpy message's conversion to C cost about as much as all six other outputs' encodings), the
centre of mass from the output encoder (``OutputEncoder.centre_of_mass``, ``odom``'s own
numbers), sent only while someone subscribes (the count is read every ``COUNT_PERIOD`` publish
ticks, as for the other outputs). A paused node republishes its state: the same stamp is not
sent again (tf2 would warn TF_REPEATED_DATA each time) except to a subscriber that joined since.
Switched by ``publish_tf``; not recorded (outside the output table ``bag.topics.OUTPUTS``, whose
switched-on outputs a session records): the bag's ``odom`` holds the same numbers.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Sequence

from geometry_msgs.msg import TransformStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from crawler_sim.bag import topics as T
from crawler_sim.bag.cdr import Encoder, LayoutError
from crawler_sim.bag.msgs import BASE_FRAME, ODOM_FRAME, STAMP, frame_prefix
from crawler_sim.core.simtime import split_ns

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = ['TfBroadcaster', 'TF_QOS', 'frame_prefix', 'load_tf_message']

#: tf2_ros's TransformBroadcaster QoS (DynamicBroadcasterQoS): reliable, volatile, depth 100
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
COUNT_PERIOD = 16       # publish ticks between two reads of the subscriber count


def load_tf_message() -> tuple[type | None, str]:
    """``(tf2_msgs.msg.TFMessage, '')``, or ``(None, why)`` when the package is not installed
    (a plain pip install: ``make build`` builds it, tools/build_interfaces.py)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError as exc:
        return None, f'tf2_msgs is not installed ({exc})'
    return TFMessage, ''


#: the changing fields of the transform (stamp, x), adjacent groups in its CDR bytes
_TF_GROUPS = (tuple('transforms.0.' + f for f in STAMP),
              ('transforms.0.transform.translation.x',))


class TfBroadcaster:
    """Publishes odom -> base_link (prefixed in a namespace) on ``/tf``; ``centre_of_mass``
    (state, masses) -> (X, V) is ``odom``'s (``OutputEncoder.centre_of_mass``)."""

    def __init__(self, node: Node, tf_message: type,
                 centre_of_mass: Callable[[Any, Sequence[float]], tuple[float, float]]) -> None:
        prefix = frame_prefix(node.get_namespace())
        self.parent, self.child = prefix + ODOM_FRAME, prefix + BASE_FRAME
        self._node = node
        self._pub = node.create_publisher(tf_message, T.TF.node_name, TF_QOS)
        self._com = centre_of_mass
        tr = TransformStamped()
        tr.header.frame_id = self.parent
        tr.child_frame_id = self.child
        tr.transform.rotation.w = 1.0
        self._msg = tf_message(transforms=[tr])
        try:
            pack = Encoder(self._msg, T.TF.type, _TF_GROUPS).encode
            publish_raw = self._pub.handle.publish_raw
            #: the CDR bytes of the transform at ``t_ns`` [ns] with translation x [m]
            self.encode = lambda t_ns, x: pack(split_ns(t_ns), (x,))
            self._send = lambda t_ns, x: publish_raw(pack(split_ns(t_ns), (x,)))
        except LayoutError:         # a TFMessage the walker cannot read: rclpy converts it
            self.encode = None
            self._send = self._send_message
        self._countdown = 0
        self._count = 0             # subscribers at the latest read
        self._last_ns = -1          # sim time of the latest transform sent [ns]

    def _send_message(self, t_ns: int, x: float) -> None:
        tr = self._msg.transforms[0]
        tr.header.stamp.sec, tr.header.stamp.nanosec = split_ns(t_ns)
        tr.transform.translation.x = x
        self._pub.publish(self._msg)

    def destroy(self) -> None:
        """Destroy the publisher (``publish_tf`` switched off)."""
        self._node.destroy_publisher(self._pub)

    def publish(self, state: Any, t_ns: int, masses: Sequence[float]) -> None:
        """Send the transform at sim time ``t_ns`` [ns] of ``state`` (a core ``State`` or its
        ``Row``: ``x`` and ``v`` per body [m, m/s]; or a callable returning one, called only
        if someone subscribes)."""
        if t_ns == self._last_ns:
            # the same time again (the paused node republishes): tf2 listeners reject a repeated
            # stamp with a TF_REPEATED_DATA warning each time, so it goes only to a subscriber
            # that joined since
            count = self._pub.get_subscription_count()
            joined, self._count = count > self._count, count
            if not joined:
                return
        else:
            self._countdown -= 1
            if self._countdown <= 0:
                self._countdown = COUNT_PERIOD
                self._count = self._pub.get_subscription_count()
            if not self._count:
                return
        if callable(state):
            state = state()
        self._send(t_ns, self._com(state, masses)[0])
        self._last_ns = t_ns

    def refresh(self) -> None:
        """Read the subscriber count at the next publish tick."""
        self._countdown = 0
