"""The crawler's robot model: a URDF for p bodies, published by sim_node as ``robot_description``.

Pure Python (``xml.etree``, no ROS import), so the model can be generated, tested and saved
without a ROS installation: ``python -c "from crawler_sim.ros.sim.model import
robot_description; print(robot_description(3, [1.0, 2.0, 1.5]))" > crawler.urdf``.

Frames (all on the line the crawler moves along: x forward/uphill, z up, y to the left; the odom
x axis is along the incline, as in ``odom`` and ``markers``):

- ``base_link`` (the root, massless): the **centre of mass** X = sum m_i x_i / M of the bodies,
  the frame whose pose ``odom`` reports (``child_frame_id`` ``base_link``, pose X along x,
  identity orientation). The base is floating: the URDF has no ``odom`` link; the transform
  odom -> base_link is ``odom``'s pose.
- ``body_i`` (i = 0..p-1): body i's point mass, at x_i on the line. A box of edge
  ``body_size`` [m] (visual and collision) stands on the line above it, as the ``markers``
  cubes do (centre ``body_size/2`` above the frame); the inertial is at the frame origin (where
  the simulated point mass is, so the model's centre of mass is ``base_link``) with mass m_i and
  the inertia of a uniform cube of that edge, m_i a^2/6 [kg m^2] (a positive-definite inertia
  for the tools that need one; the simulation has none).
- joint ``linkage_j`` (j = 0..p-2, prismatic along +x, parent ``body_j``, child ``body_{j+1}``,
  zero origin): its position is the linkage length l_j = x_{j+1} - x_j [m], exactly what
  ``joint_states`` publishes under that name, so robot_state_publisher fed with sim_node's
  ``joint_states`` places ``body_{j+1}`` at l_j ahead of ``body_j``. Limits: [min_length,
  max_length] [m], velocity ``max_speed`` [m/s], effort 0 (URDF requires the attribute; the
  linkages are kinematic, they take whatever force the commanded motion needs, and 0 is the
  value urdfdom stores for an unset limit).
- joints ``com_offset_j`` (j = 0..p-2, prismatic along +x, **mimic** ``linkage_j`` with
  multiplier -c_j, c_j = (m_{j+1} + ... + m_{p-1}) / M): a chain from ``base_link`` through the
  massless links ``com_offset_j_link`` to ``body_0``. Their sum is the offset of body 0 from the
  centre of mass, x_0 - X = -sum_j c_j l_j (from X = sum_i m_i (x_0 + l_0 + ... + l_{i-1}) / M),
  a function of the joint positions and masses only, so no joint state beyond ``linkage_j`` is
  needed: robot_state_publisher computes mimic joints itself. With the ``odom`` pose as the
  odom -> base_link transform every body is drawn at its simulated x_i. (The multipliers depend
  on the masses: sim_node publishes a new description when they change.)

Numbers are written with ``repr`` (shortest round-trip), so a parser reads back the very floats
given here.
"""
from __future__ import annotations

import math
from typing import Sequence
import xml.etree.ElementTree as ET

__all__ = ['robot_description', 'BASE_LINK', 'BODY_SIZE', 'ROBOT_NAME', 'body_link',
           'linkage_joint', 'com_offset_joint', 'com_offsets']

#: the root link: the centre of mass, ``odom``'s child frame (crawler_sim.bag.msgs.BASE_FRAME)
BASE_LINK = 'base_link'
#: edge of each body's box [m] (crawler_sim.ros.messages.BODY_SIZE: the markers' cubes)
BODY_SIZE = 0.04
#: the URDF's robot name
ROBOT_NAME = 'crawler'
# the plant's defaults (crawler_sim.core.plant.config.PARAMETERS), for a call without them
_MIN_LENGTH, _MAX_LENGTH, _MAX_SPEED = 0.02, 0.5, 0.5
_GREY = '0.6 0.6 0.6 1'     # the markers' linkage colour


def body_link(i: int) -> str:
    """Link of body i: ``body_i`` (the names of ``body_states``)."""
    return f'body_{i}'


def linkage_joint(j: int) -> str:
    """Joint of linkage j: ``linkage_j`` (the names of ``joint_states``)."""
    return f'linkage_{j}'


def com_offset_joint(j: int) -> str:
    """Joint j of the chain base_link -> body_0 (mimics ``linkage_j``): ``com_offset_j``."""
    return f'com_offset_{j}'


def com_offsets(masses: Sequence[float]) -> list[float]:
    """c_j = (m_{j+1} + ... + m_{p-1}) / M for j = 0..p-2: x_0 - X = -sum_j c_j l_j."""
    m = [float(x) for x in masses]
    total = sum(m)
    return [sum(m[j + 1:]) / total for j in range(len(m) - 1)]


def _num(x: float) -> str:
    return repr(float(x))


def _xyz(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> str:
    return f'{_num(x)} {_num(y)} {_num(z)}'


def _box_link(robot: ET.Element, name: str, mass: float, size: float) -> None:
    link = ET.SubElement(robot, 'link', name=name)
    inertial = ET.SubElement(link, 'inertial')
    ET.SubElement(inertial, 'origin', xyz=_xyz(), rpy=_xyz())
    ET.SubElement(inertial, 'mass', value=_num(mass))
    i = mass * size * size / 6.0          # uniform cube about its centre
    ET.SubElement(inertial, 'inertia', ixx=_num(i), ixy='0', ixz='0', iyy=_num(i), iyz='0',
                  izz=_num(i))
    for kind in ('visual', 'collision'):
        el = ET.SubElement(link, kind)
        ET.SubElement(el, 'origin', xyz=_xyz(z=0.5 * size), rpy=_xyz())
        geometry = ET.SubElement(el, 'geometry')
        ET.SubElement(geometry, 'box', size=_xyz(size, size, size))
        if kind == 'visual':
            ET.SubElement(el, 'material', name='body')


def _prismatic(robot: ET.Element, name: str, parent: str, child: str, lower: float,
               upper: float, velocity: float, mimic: tuple[str, float] | None = None) -> None:
    joint = ET.SubElement(robot, 'joint', name=name, type='prismatic')
    ET.SubElement(joint, 'parent', link=parent)
    ET.SubElement(joint, 'child', link=child)
    ET.SubElement(joint, 'origin', xyz=_xyz(), rpy=_xyz())
    ET.SubElement(joint, 'axis', xyz=_xyz(1.0))
    ET.SubElement(joint, 'limit', lower=_num(lower), upper=_num(upper), effort='0',
                  velocity=_num(velocity))
    if mimic is not None:
        ET.SubElement(joint, 'mimic', joint=mimic[0], multiplier=_num(mimic[1]), offset='0')


def robot_description(p: int, masses: Sequence[float] | None = None, *,
                      min_length: float = _MIN_LENGTH, max_length: float = _MAX_LENGTH,
                      max_speed: float = _MAX_SPEED, body_size: float = BODY_SIZE,
                      name: str = ROBOT_NAME) -> str:
    """The URDF (XML text) of a crawler of ``p`` bodies (see the module docstring for frames).

    ``masses`` [kg]: p positive values (default 1 kg each); ``min_length`` < ``max_length``
    [m] and ``max_speed`` [m/s] become the ``linkage_j`` limits; ``body_size`` [m] is the
    edge of each body's box. ValueError for anything else (a URDF that robot_state_publisher
    would refuse is never produced).
    """
    p = int(p)
    if p < 1:
        raise ValueError(f'p must be >= 1 body, got {p}')
    m = [1.0] * p if masses is None else [float(x) for x in masses]
    if len(m) != p:
        raise ValueError(f'masses must list p = {p} values, got {len(m)}')
    if not all(math.isfinite(x) and x > 0 for x in m):
        raise ValueError(f'masses must be finite and > 0 [kg], got {m}')
    if not (math.isfinite(min_length) and math.isfinite(max_length)
            and min_length < max_length):
        raise ValueError(f'need finite min_length < max_length [m], got {min_length}, '
                         f'{max_length}')
    for label, value in (('max_speed', max_speed), ('body_size', body_size)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f'{label} must be finite and > 0, got {value}')

    robot = ET.Element('robot', name=name)
    ET.SubElement(ET.SubElement(robot, 'material', name='body'), 'color', rgba=_GREY)
    ET.SubElement(robot, 'link', name=BASE_LINK)
    # base_link (centre of mass) -> body_0: the mimic chain (module docstring); one body: the
    # centre of mass is the body itself
    c = com_offsets(m)
    parent = BASE_LINK
    if p == 1:
        joint = ET.SubElement(robot, 'joint', name=com_offset_joint(0), type='fixed')
        ET.SubElement(joint, 'parent', link=BASE_LINK)
        ET.SubElement(joint, 'child', link=body_link(0))
    for j in range(p - 1):
        child = body_link(0) if j == p - 2 else com_offset_joint(j) + '_link'
        if child != body_link(0):
            ET.SubElement(robot, 'link', name=child)
        # the joint's position is -c_j l_j, within -c_j [max_length, min_length]
        _prismatic(robot, com_offset_joint(j), parent, child, -c[j] * max_length,
                   -c[j] * min_length, c[j] * max_speed, (linkage_joint(j), -c[j]))
        parent = child
    for i in range(p):
        _box_link(robot, body_link(i), m[i], body_size)
    for j in range(p - 1):
        _prismatic(robot, linkage_joint(j), body_link(j), body_link(j + 1), min_length,
                   max_length, max_speed)
    ET.indent(robot)
    return ('<?xml version="1.0"?>\n<!-- crawler_sim: generated by crawler_sim.ros.sim.model '
            f'for p = {p} bodies -->\n' + ET.tostring(robot, encoding='unicode') + '\n')
