"""The shipped RViz config and Foxglove layout point at what sim_node really publishes (issue 12).

Neither viewer can run here (no display, Foxglove is a desktop/web app), so the files are parsed
and every reference in them is checked against the node's own tables: each topic is one the node
publishes, each plotted field exists in that topic's message type (from the rosidl type support),
each frame is the node's fixed frame, and the marker namespaces are the ones the markers carry.
A renamed topic, field or frame breaks these tests, not the user's first session.
"""
from __future__ import annotations

import json
from pathlib import Path
import re

from sensor_msgs.msg import JointState
import yaml

from crawler_sim.ros import messages as M
from crawler_sim.bag import topics as T
from crawler_sim.ros.sim.outputs import CLASSES

VIZ = Path(__file__).resolve().parents[2] / 'config' / 'viz'
#: topic -> message class, as the node's default (root namespace) publishes them
PUBLISHED = {T.OUTPUTS[name].name(): cls for name, cls in CLASSES.items()}
PUBLISHED[T.APPLIED_COMMAND.name()] = JointState       # '~/applied_command'


def _displays(node):
    if isinstance(node, dict):
        if 'Class' in node:
            yield node
        for v in node.values():
            yield from _displays(v)
    elif isinstance(node, list):
        for v in node:
            yield from _displays(v)


def test_the_rviz_config_shows_the_node_markers_in_its_fixed_frame():
    cfg = yaml.safe_load((VIZ / 'crawler_sim.rviz').read_text())
    assert cfg['Visualization Manager']['Global Options']['Fixed Frame'] == M.ODOM_FRAME
    markers = [d for d in _displays(cfg) if d['Class'] == 'rviz_default_plugins/MarkerArray']
    assert len(markers) == 1
    topic = markers[0]['Topic']['Value']
    # relative, as the node publishes it: rviz2 -r __ns:=/r1 shows the robot of /r1 (issue 42)
    assert not topic.startswith('/'), topic
    assert PUBLISHED.get('/' + topic) is CLASSES['markers'], topic
    # the namespaces it enables are those the node's markers carry
    msg = M.markers_msg(_two_body_state(), 0)
    assert set(markers[0]['Namespaces']) == {m.ns for m in msg.markers}


def _two_body_state():
    import numpy as np
    from types import SimpleNamespace
    return SimpleNamespace(x=np.array([0.0, 0.1]), v=np.zeros(2), contact=np.zeros(2, np.int8),
                           lengths=np.array([0.1]), t=0.0)


def _field_exists(cls, path: str) -> bool:
    """'position[0]' or 'header.stamp' on a rosidl message class."""
    for part in path.split('.'):
        name = re.sub(r'\[\d+\]$', '', part)
        types = cls.get_fields_and_field_types()
        if name not in types:
            return False
        t = re.sub(r'^sequence<(.*)>$', r'\1', types[name])
        if '/' in t:        # a nested message, e.g. builtin_interfaces/Time
            pkg, typ = t.split('/')
            cls = getattr(__import__(f'{pkg}.msg', fromlist=[typ]), typ)
    return True


def test_every_topic_and_field_of_the_foxglove_layout_is_published_by_the_node():
    layout = json.loads((VIZ / 'crawler_sim.foxglove.json').read_text())
    panels = layout['configById']
    paths = [p['value'] for panel in panels.values() for p in panel.get('paths', [])]
    assert paths, 'no plotted message paths'
    for path in paths:
        topic, _, field = path.partition('.')
        assert topic in PUBLISHED, (path, sorted(PUBLISHED))
        assert _field_exists(PUBLISHED[topic], field), path
    three_d = [p for k, p in panels.items() if k.startswith('3D!')]
    assert three_d and all(set(p['topics']) <= set(PUBLISHED) for p in three_d)
    assert all(p['followTf'] == M.ODOM_FRAME for p in three_d)
    for k, p in panels.items():
        if k.startswith('RawMessages!'):
            assert p['topicPath'].split('.')[0] in PUBLISHED, p


def test_the_output_classes_are_the_types_of_the_topic_table():
    """outputs.CLASSES (message classes to create publishers) and bag.topics (type names to
    record) name each output's type twice: they must agree."""
    for name, cls in CLASSES.items():
        package = cls.__module__.split('.')[0]
        assert f'{package}/msg/{cls.__name__}' == T.OUTPUTS[name].type, name
    assert set(CLASSES) == set(T.OUTPUTS)
