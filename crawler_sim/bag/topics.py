"""Topic names and types of a crawler_sim recording (shared by node, writer and reader).

Names are relative to the robot's namespace: ``/<ns>/body_states`` or ``/body_states``. The reader
matches topics by these suffixes, so any namespace works.

=================  ==============================  ==========================================
suffix             type                            content
=================  ==============================  ==========================================
body_states        sensor_msgs/msg/JointState      names body_i; position x_i [m], velocity
                                                   v_i [m/s], effort = friction on body i [N]
joint_states       sensor_msgs/msg/JointState      names linkage_j; position l_j [m], velocity
                                                   l_j' [m/s], effort = linkage force [N]
contact_states     std_msgs/msg/Int8MultiArray     per body: +1 forward, 0 stuck, -1 backward
odom               nav_msgs/msg/Odometry           centre of mass, frame odom, child base_link
linkage_cmd        std_msgs/msg/Float64MultiArray  commands as applied (log time = sim time
                                                   at which they took effect), p-1 values
events             std_msgs/msg/Int32MultiArray    one contact change: [body, old, new],
                                                   log time = event time
crawler_sim/scene  std_msgs/msg/String             the scene as YAML (latched, once)
=================  ==============================  ==========================================
"""
from __future__ import annotations

from typing import NamedTuple


class Topic(NamedTuple):
    """A topic name relative to the robot namespace and its ROS type."""

    suffix: str
    type: str

    def name(self, namespace: str = '') -> str:
        """Absolute topic name in ``namespace`` ('' or '/' for the root namespace)."""
        return f'{normalize_namespace(namespace)}/{self.suffix}'


BODY_STATES = Topic('body_states', 'sensor_msgs/msg/JointState')
JOINT_STATES = Topic('joint_states', 'sensor_msgs/msg/JointState')
CONTACT_STATES = Topic('contact_states', 'std_msgs/msg/Int8MultiArray')
ODOM = Topic('odom', 'nav_msgs/msg/Odometry')
LINKAGE_CMD = Topic('linkage_cmd', 'std_msgs/msg/Float64MultiArray')
APPLIED_COMMAND = Topic('crawler_sim/applied_command', 'sensor_msgs/msg/JointState')
EVENTS = Topic('events', 'std_msgs/msg/Int32MultiArray')
SCENE = Topic('crawler_sim/scene', 'std_msgs/msg/String')

#: Topics :func:`crawler_sim.bag.load` reads, besides the scene.
STATE_TOPICS = (BODY_STATES, JOINT_STATES, CONTACT_STATES)
ALL_TOPICS = (BODY_STATES, JOINT_STATES, CONTACT_STATES, ODOM, LINKAGE_CMD, APPLIED_COMMAND,
              EVENTS, SCENE)

#: Name of the MCAP Metadata record holding the scene (values are JSON strings).
SCENE_METADATA = 'crawler_sim.scene'


def normalize_namespace(namespace: str | None) -> str:
    """'' for the root namespace, else '/a/b' (leading slash, no trailing slash)."""
    namespace = (namespace or '').strip('/')
    return f'/{namespace}' if namespace else ''


def split_topic(topic: str, suffix: str) -> str | None:
    """Namespace of ``topic`` if it ends with ``/suffix`` (e.g. '/crawler1'), else None."""
    tail = f'/{suffix}'
    if topic == tail:
        return ''
    if topic.endswith(tail):
        return topic[:-len(tail)]
    return None
