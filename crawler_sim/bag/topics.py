"""Every topic crawler_sim uses, with its ROS type: the one table the nodes, the bag writer,
the offline recorder and the reader take names and types from.

A :class:`Topic` is named relative to the robot's namespace (``/<ns>/body_states`` or
``/body_states``); the reader matches topics by these suffixes, so any namespace works. A node's
private topic (``~/applied_command``) is named ``<node>/applied_command``: its suffix here uses
sim_node's default name ``crawler_sim``, and readers match it by its last part (:attr:`leaf`),
so a renamed node's bag reads too. ``/clock`` and ``/diagnostics`` are global.

======================  ===================================  =================================
topic (under the ns)    type                                 content
======================  ===================================  =================================
body_states             sensor_msgs/msg/JointState           names body_i; position x_i [m],
                                                             velocity v_i [m/s], effort =
                                                             friction on body i [N]
joint_states            sensor_msgs/msg/JointState           names linkage_j; position l_j [m],
                                                             velocity l_j' [m/s], effort =
                                                             linkage force [N]
contact_states          std_msgs/msg/Int8MultiArray          per body: +1 forward, 0 stuck,
                                                             -1 backward
contacts                sensor_msgs/msg/JointState           the same, stamped (position)
odom                    nav_msgs/msg/Odometry                centre of mass, frame odom,
                                                             child base_link
markers                 visualization_msgs/msg/MarkerArray   boxes coloured by contact
robot_description       std_msgs/msg/String                  the URDF (transient local)
linkage_cmd             std_msgs/msg/Float64MultiArray       input; recorded as applied (log
                                                             time = sim time it took effect)
linkage_trajectory      trajectory_msgs/msg/JointTrajectory  input; recorded as applied
crawler_sim/applied_command  sensor_msgs/msg/JointState      the command as applied, named
crawler_sim/plant_inputs     std_msgs/msg/String             the engine's journal (JSON per
                                                             input, see bag.inputs)
events                  std_msgs/msg/Int32MultiArray         one contact change: [body, old,
                                                             new], log time = event time
crawler_sim/scene       std_msgs/msg/String                  the scene as YAML (latched, once)
/clock                  rosgraph_msgs/msg/Clock              sim time at every publish tick
/diagnostics            diagnostic_msgs/msg/DiagnosticArray  the node's status
/tf                     tf2_msgs/msg/TFMessage               odom -> base_link (odom's pose;
                                                             not recorded)
======================  ===================================  =================================
"""
from __future__ import annotations

from typing import NamedTuple


class Topic(NamedTuple):
    """A topic name relative to the robot namespace, its ROS type, and the name a node
    declares it under when that differs (``~/x`` for a private topic, ``/x`` for a global
    one)."""

    suffix: str
    type: str
    declared: str = ''

    @property
    def node_name(self) -> str:
        """The name to give ``create_publisher``/``create_subscription`` (ROS resolves it)."""
        return self.declared or self.suffix

    @property
    def leaf(self) -> str:
        """The last part of the name (what a reader matches a private topic by)."""
        return self.suffix.rsplit('/', 1)[-1]

    def name(self, namespace: str = '') -> str:
        """Absolute topic name in ``namespace`` ('' or '/' for the root namespace)."""
        if self.declared.startswith('/'):
            return self.declared
        return f'{normalize_namespace(namespace)}/{self.suffix}'


_JOINT_STATE = 'sensor_msgs/msg/JointState'
_STRING = 'std_msgs/msg/String'

BODY_STATES = Topic('body_states', _JOINT_STATE)
JOINT_STATES = Topic('joint_states', _JOINT_STATE)
CONTACT_STATES = Topic('contact_states', 'std_msgs/msg/Int8MultiArray')
CONTACTS = Topic('contacts', _JOINT_STATE)
ODOM = Topic('odom', 'nav_msgs/msg/Odometry')
MARKERS = Topic('markers', 'visualization_msgs/msg/MarkerArray')
ROBOT_DESCRIPTION = Topic('robot_description', _STRING)
LINKAGE_CMD = Topic('linkage_cmd', 'std_msgs/msg/Float64MultiArray')
LINKAGE_TRAJECTORY = Topic('linkage_trajectory', 'trajectory_msgs/msg/JointTrajectory')
APPLIED_COMMAND = Topic('crawler_sim/applied_command', _JOINT_STATE, '~/applied_command')
PLANT_INPUTS = Topic('crawler_sim/plant_inputs', _STRING, '~/plant_inputs')
EVENTS = Topic('events', 'std_msgs/msg/Int32MultiArray')
SCENE = Topic('crawler_sim/scene', _STRING)
CLOCK = Topic('clock', 'rosgraph_msgs/msg/Clock', '/clock')
DIAGNOSTICS = Topic('diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', '/diagnostics')
#: sim_node's transform (``publish_tf``; not in :data:`OUTPUTS`, whose switched-on outputs a
#: recording session records: ``odom`` holds the same numbers)
TF = Topic('tf', 'tf2_msgs/msg/TFMessage', '/tf')

#: Topics :func:`crawler_sim.bag.load` reads, besides the scene.
STATE_TOPICS = (BODY_STATES, JOINT_STATES, CONTACT_STATES)
ALL_TOPICS = (BODY_STATES, JOINT_STATES, CONTACT_STATES, CONTACTS, ODOM, MARKERS,
              ROBOT_DESCRIPTION, LINKAGE_CMD, LINKAGE_TRAJECTORY, APPLIED_COMMAND, PLANT_INPUTS,
              EVENTS, SCENE, CLOCK, DIAGNOSTICS, TF)
#: sim_node's outputs on its publish grid, by the name of their ``publish_*`` parameter
OUTPUTS = {'joint_states': JOINT_STATES, 'body_states': BODY_STATES,
           'contact_states': CONTACT_STATES, 'contacts_stamped': CONTACTS, 'odom': ODOM,
           'markers': MARKERS, 'diagnostics': DIAGNOSTICS}

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
