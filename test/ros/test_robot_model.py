"""The robot model (issue 26): ``crawler_sim.ros.sim.model`` and sim_node's ``robot_description``.

The URDF is parsed with yourdfpy (PyPI), which refuses what urdfdom (robot_state_publisher's
parser) refuses (a joint to a missing link, a prismatic joint without limits) and computes
mimic joints as robot_state_publisher does. Forward kinematics is also chained by hand from the
parsed origins, axes and mimic tags, and compared with what the node publishes: body_states
relative to body_0, and odom (base_link, the centre of mass).
"""
from __future__ import annotations

import io
import subprocess
import sys
import time

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
import yourdfpy

from crawler_sim.bag.msgs import body_names, linkage_names
from crawler_sim.ros import messages as M
from crawler_sim.ros.messages import ns_from_stamp
from crawler_sim.ros.sim import model
from crawler_sim.ros.sim.model import robot_description
from crawler_sim.ros.sim.node import SimNode
from test.support.ros import cmd, Harness, ticks

#: what a late joiner such as RViz's RobotModel display (description topic) subscribes with
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
MASSES = [1.0, 2.0, 1.5]


def parse(text: str) -> yourdfpy.URDF:
    robot = yourdfpy.URDF.load(io.StringIO(text))
    assert robot.validate(), 'yourdfpy finds the URDF invalid'
    return robot


def body_links(robot: yourdfpy.URDF) -> list[str]:
    return [name for name in robot.link_map if name.startswith('body_')]


def linkage_joints(robot: yourdfpy.URDF) -> list[yourdfpy.Joint]:
    """The prismatic joints driven by joint_states (not mimics), in URDF order."""
    return [j for j in robot.robot.joints if j.type == 'prismatic' and j.mimic is None]


def hand_fk(robot: yourdfpy.URDF, positions: dict[str, float]) -> dict[str, np.ndarray]:
    """Pose (4x4) of every link in the root link's frame, chained from the URDF by hand:
    T(child) = T(parent) @ origin @ Translation(axis * q), q of a mimic joint =
    multiplier * q(its joint) + offset. No yourdfpy kinematics involved."""
    by_child = {j.child: j for j in robot.robot.joints}
    poses: dict[str, np.ndarray] = {}

    def pose(link: str) -> np.ndarray:
        if link not in poses:
            joint = by_child.get(link)
            if joint is None:                  # the root
                poses[link] = np.eye(4)
            else:
                q = 0.0
                if joint.type == 'prismatic':
                    if joint.mimic is not None:
                        q = (joint.mimic.multiplier * positions[joint.mimic.joint]
                             + joint.mimic.offset)
                    else:
                        q = positions[joint.name]
                else:
                    assert joint.type == 'fixed', joint.type
                slide = np.eye(4)
                slide[:3, 3] = np.asarray(joint.axis, dtype=float) * q
                origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin)
                poses[link] = pose(joint.parent) @ origin @ slide
        return poses[link]

    for name in robot.link_map:
        pose(name)
    return poses


def latest_description(ros: Harness, count: int = 1) -> list[str]:
    """A late subscriber (transient local) to robot_description; waits for ``count`` texts."""
    box = ros.listen(String, 'robot_description', LATCHED)
    ros.until(lambda: len(box) >= count, f'{count} robot_description message(s)')
    return box


def spin_for(ros: Harness, seconds: float) -> None:
    """Spin the harness's executor for ``seconds`` (to see that nothing more arrives)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        ros.ex.spin_once(timeout_sec=0.01)


# --------------------------------------------------------------------------- over DDS

def test_a_late_subscriber_gets_the_model_of_the_crawler_and_joint_states_drive_it(ros):
    sim = ros.sim(masses=MASSES, friction=[3.0, 4.0, 2.0], method='implicit')
    js = ros.listen(JointState, 'joint_states')
    ticks(sim, 10)                        # published long before anyone asks for the model
    ros.until(lambda: js, 'joint_states')
    box = latest_description(ros)
    assert len(box) == 1                  # depth 1: the current model only
    robot = parse(box[0].data)
    assert box[0].data == sim.outputs.description
    assert robot.base_link == 'base_link' == M.BASE_FRAME
    assert body_links(robot) == ['body_0', 'body_1', 'body_2']             # p links
    joints = linkage_joints(robot)
    assert len(joints) == 2                                                  # p - 1
    assert [j.name for j in joints] == list(js[-1].name) == ['linkage_0', 'linkage_1']
    assert [(j.parent, j.child) for j in joints] == [('body_0', 'body_1'), ('body_1', 'body_2')]
    assert robot.actuated_joint_names == list(js[-1].name)    # every other joint is a mimic
    masses = [robot.link_map[name].inertial.mass for name in body_links(robot)]
    assert masses == sim.config.crawler.masses.tolist() == MASSES
    # the only links with mass are the bodies (base_link and the base chain are frames)
    assert all(link.inertial is None for name, link in robot.link_map.items()
               if not name.startswith('body_'))
    size = model.BODY_SIZE
    for name in body_links(robot):
        visual = robot.link_map[name].visuals[0]
        np.testing.assert_array_equal(visual.geometry.box.size, [size] * 3)


def test_forward_kinematics_of_the_urdf_puts_the_bodies_where_the_node_says(ros):
    sim = ros.sim(masses=MASSES, friction=[3.0, 4.0, 2.0], method='implicit')
    js = ros.listen(JointState, 'joint_states')
    bs = ros.listen(JointState, 'body_states')
    od = ros.listen(Odometry, 'odom')
    box = latest_description(ros)
    ticks(sim, 5)
    ros.send(ros.publisher(Float64MultiArray, 'linkage_cmd'), cmd(0.16, 0.05), sim,
             'commands_accepted')
    ticks(sim, 295)                       # crawling: unequal lengths, bodies away from 0
    t_ns = sim.sim_time_ns                # 0.3 s: a publish tick

    def at_t(b: list) -> bool:
        return bool(b) and ns_from_stamp(b[-1].header.stamp) == t_ns

    ros.until(lambda: at_t(js) and at_t(bs) and at_t(od), 'the outputs of the last tick')
    robot = parse(box[-1].data)
    q = dict(zip(js[-1].name, js[-1].position))
    assert len(set(q.values())) == 2 and all(v > 0 for v in q.values())
    x = np.asarray(bs[-1].position)
    assert abs(x[0]) > 1e-3

    poses = hand_fk(robot, q)
    t0 = poses['body_0']
    for i, name in enumerate(body_names(3)):
        rel = np.linalg.inv(t0) @ poses[name]
        np.testing.assert_allclose(rel[:3, :3], np.eye(3), rtol=0, atol=0)
        np.testing.assert_allclose(rel[:3, 3], [x[i] - x[0], 0.0, 0.0], rtol=0, atol=1e-12)
    # base_link is the centre of mass, odom's child frame: body i sits at x_i - X from it
    com = od[-1].pose.pose.position.x
    for i, name in enumerate(body_names(3)):
        np.testing.assert_allclose(poses[name][:3, 3], [x[i] - com, 0.0, 0.0], rtol=0,
                                   atol=1e-12)
    # and yourdfpy's own kinematics (mimic joints as robot_state_publisher computes them)
    robot.update_cfg(q)
    for name in body_names(3):
        np.testing.assert_allclose(robot.get_transform(name, 'base_link'), poses[name],
                                   rtol=0, atol=1e-12)


def test_a_new_number_of_bodies_publishes_a_new_model(ros):
    sim = ros.sim(initial_lengths=[0.1])   # one length for every linkage: p may change alone
    box = latest_description(ros)
    assert body_links(parse(box[0].data)) == list(body_names(3))
    js = ros.listen(JointState, 'joint_states')
    assert sim.set_parameters([Parameter('masses', value=[1.0] * 4)])[0].successful
    ticks(sim, 10)                        # the change applies at the next tick
    ros.until(lambda: len(box) >= 2 and js and len(js[-1].name) == 3,
              'a second description and joint_states of 4 bodies')
    assert len(box) == 2
    robot = parse(box[-1].data)
    assert body_links(robot) == list(body_names(4))
    assert [j.name for j in linkage_joints(robot)] == list(js[-1].name) == list(linkage_names(3))
    assert [robot.link_map[n].inertial.mass for n in body_links(robot)] == [1.0] * 4
    # a subscriber joining now gets the 4-body model only
    late = ros.obs.create_subscription(String, 'robot_description', (fresh := []).append,
                                       LATCHED)
    ros.until(lambda: fresh, 'the description for a subscriber joining after the change')
    assert [m.data for m in fresh] == [box[-1].data]
    ros.obs.destroy_subscription(late)


def test_new_masses_publish_a_new_model_other_changes_and_reset_do_not(ros):
    sim = ros.sim()
    box = latest_description(ros)
    first = box[0].data
    assert sim.set_parameters([Parameter('slope', value=0.1)])[0].successful
    ticks(sim, 10)
    sim.reset()
    spin_for(ros, 0.3)
    assert len(box) == 1                  # neither the slope nor the reset changed the model
    assert sim.outputs.sync(sim.config) is False
    assert sim.set_parameters([Parameter('masses', value=[1.0, 2.0, 3.0])])[0].successful
    ticks(sim, 10)
    ros.until(lambda: len(box) >= 2, 'the description with the new masses')
    robot = parse(box[-1].data)
    assert box[-1].data != first
    assert [robot.link_map[n].inertial.mass for n in body_links(robot)] == [1.0, 2.0, 3.0]
    # the base chain follows the masses: c_0 = (2 + 3) / 6, c_1 = 3 / 6
    mimics = {j.name: j.mimic.multiplier for j in robot.robot.joints if j.mimic is not None}
    assert mimics == {'com_offset_0': -5.0 / 6.0, 'com_offset_1': -0.5}


def test_the_description_lives_in_the_robot_namespace(ros):
    sim = SimNode(context=ros.ctx, namespace='robot1', parameter_overrides=[
        Parameter('masses', value=[1.0, 2.0]), Parameter('publish_clock', value=False)])
    ros.ex.add_node(sim)
    ros.nodes.append(sim)
    box = ros.listen(String, '/robot1/robot_description', LATCHED)
    ros.until(lambda: box, '/robot1/robot_description')
    assert body_links(parse(box[0].data)) == ['body_0', 'body_1']
    names = dict(ros.obs.get_topic_names_and_types())
    assert '/robot_description' not in names
    assert names['/robot1/robot_description'] == ['std_msgs/msg/String']


# --------------------------------------------------------------------------- no DDS

@pytest.mark.parametrize('p', [1, 2, 3, 7, 64])
def test_the_urdf_is_valid_and_its_kinematics_is_the_crawler_s(p):
    rng = np.random.default_rng(p)
    masses = rng.uniform(0.1, 3.0, p).tolist()
    lengths = rng.uniform(0.02, 0.5, p - 1)
    robot = parse(robot_description(p, masses))
    assert body_links(robot) == list(body_names(p))
    assert [j.name for j in linkage_joints(robot)] == list(linkage_names(p - 1))
    x = np.concatenate([[0.0], np.cumsum(lengths)])             # body 0 at 0
    com = float(np.asarray(masses) @ x) / sum(masses)
    poses = hand_fk(robot, dict(zip(linkage_names(p - 1), lengths.tolist())))
    got = np.array([poses[name][0, 3] for name in body_names(p)])
    np.testing.assert_allclose(got, x - com, rtol=0, atol=1e-12)


def test_the_model_names_and_sizes_are_the_node_s():
    assert model.BASE_LINK == M.BASE_FRAME
    assert model.BODY_SIZE == M.BODY_SIZE
    assert [model.linkage_joint(j) for j in range(5)] == list(linkage_names(5))
    assert [model.body_link(i) for i in range(5)] == list(body_names(5))
    robot = parse(robot_description(2, min_length=0.03, max_length=0.4, max_speed=0.2))
    (joint,) = linkage_joints(robot)
    assert (joint.limit.lower, joint.limit.upper, joint.limit.velocity) == (0.03, 0.4, 0.2)
    inertia = robot.link_map['body_1'].inertial.inertia
    np.testing.assert_allclose(np.diag(inertia), [0.04 ** 2 / 6] * 3, rtol=1e-15)


@pytest.mark.parametrize('args, kwargs, problem', [
    ((0,), {}, 'p must be >= 1'),
    ((3, [1.0, 1.0]), {}, 'masses must list p = 3'),
    ((2, [1.0, 0.0]), {}, 'finite and > 0'),
    ((2, [1.0, float('nan')]), {}, 'finite and > 0'),
    ((2,), {'min_length': 0.5, 'max_length': 0.5}, 'min_length < max_length'),
    ((2,), {'body_size': 0.0}, 'body_size'),
    ((2,), {'max_speed': float('inf')}, 'max_speed'),
])
def test_an_impossible_model_is_refused_with_the_reason(args, kwargs, problem):
    with pytest.raises(ValueError, match=problem):
        robot_description(*args, **kwargs)


def test_nothing_of_ros_is_imported_by_the_model():
    """model.py alone (the package crawler_sim.ros.sim imports the node, hence rclpy): loaded
    from its file in a fresh interpreter, it imports no ROS module."""
    code = ('import importlib.util, sys\n'
            f'spec = importlib.util.spec_from_file_location("model", {model.__file__!r})\n'
            'mod = importlib.util.module_from_spec(spec); spec.loader.exec_module(mod)\n'
            'assert mod.robot_description(3).startswith("<?xml")\n'
            'print(sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "std_msgs", "sensor_msgs", "nav_msgs", "rosidl_runtime_py", '
            '"crawler_sim")))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == '[]'


def test_the_model_is_recorded_with_the_run_and_again_when_p_changes(tmp_path):
    """A bag holds the robot model of each part of the run (Foxglove draws it from the bag)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from crawler_sim.ros.sim_node import SimNode
    from rclpy.parameter import Parameter
    h = Harness()
    try:
        sim = SimNode(context=h.ctx, parameter_overrides=[
            Parameter('record', value=True), Parameter('record_dir', value=str(tmp_path)),
            Parameter('record_name', value='model')])
        h.nodes.append(sim)
        for _ in range(20):
            sim.tick()
        assert sim.set_parameters([Parameter('masses', value=[1.0, 1.0, 1.0])])[0].successful
        for _ in range(20):
            sim.tick()
    finally:
        h.close()
    urdfs = []
    for path in (tmp_path / 'model').glob('*.mcap'):
        with open(path, 'rb') as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, channel, _, msg in reader.iter_decoded_messages(
                    topics=['/robot_description']):
                urdfs.append(msg.data)
    assert len(urdfs) == 2
    assert urdfs[0].count('<link name="body_') == 2 and urdfs[1].count('<link name="body_') == 3
