"""package.xml names only rosdep keys that exist for the bag dependencies (issue 12).

The keys were checked by hand against ros/rosdistro rosdep/python.yaml: ``mcap-ros2-support``
and ``python3-rosbags-pip`` exist; ``python3-mcap``, ``python3-mcap-ros2-support`` and
``python3-rosbags`` do not (and were in package.xml before).
"""
from __future__ import annotations

from pathlib import Path
import xml.etree.ElementTree as ET

REPO = Path(__file__).resolve().parents[2]
NOT_IN_ROSDISTRO = {'python3-mcap', 'python3-mcap-ros2-support', 'python3-rosbags'}


def depends() -> set[str]:
    root = ET.parse(REPO / 'package.xml').getroot()
    tags = ('depend', 'exec_depend', 'test_depend', 'build_depend')
    return {el.text.strip() for tag in tags for el in root.iter(tag)}


def test_no_bag_dependency_uses_a_key_missing_from_rosdistro():
    assert not depends() & NOT_IN_ROSDISTRO


def test_the_bag_libraries_are_declared_with_their_rosdistro_keys():
    assert {'mcap-ros2-support', 'python3-rosbags-pip'} <= depends()
    requirements = (REPO / 'requirements.txt').read_text()
    for pip_name in ('mcap', 'mcap-ros2-support', 'rosbags'):
        assert any(line.split('>')[0].split('=')[0].strip() == pip_name
                   for line in requirements.splitlines()), pip_name
