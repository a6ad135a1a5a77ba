"""Out of the box: the seed's two-body crawler, one length, /clock, Jazzy conventions (issue 12).

In-process over DDS (the Harness of test_node.py), plus the shipped files: parameter files,
scene files kept apart, the launch file (parsed, not run: launch is not installable here).
"""
from __future__ import annotations

import ast
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
import yaml

from crawler_sim.ros.messages import ns_from_stamp
from crawler_sim.ros.sim import PARAMETERS, SimNode
from crawler_sim.ros.args import ArgsError as ParamsFileError, check_params_files
from test.support.ros import cmd, Harness, ticks  # noqa: F401

REPO = Path(__file__).resolve().parents[2]
G = 9.81


def test_the_defaults_are_the_seed_two_bodies_and_one_linkage(ros):
    sim = ros.sim(seed=True)
    cfg = sim.config
    assert (cfg.p, cfg.n_links) == (2, 1)
    crawler = cfg.crawler.to_dict()
    assert crawler['masses'] == [0.5, 1.0]
    # friction coefficient 0.3 on flat ground: f_i = 0.3 m_i g, by hand
    assert crawler['friction'] == pytest.approx([0.3 * 0.5 * G, 0.3 * 1.0 * G], rel=1e-15)
    assert crawler['friction_backward'] == crawler['friction']
    assert ros.obs.count_publishers('/clock') == 1          # /clock by default, as Gazebo


def test_a_one_length_command_drives_it_and_two_lengths_are_rejected(ros):
    sim = ros.sim(seed=True)
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.15, 0.12), sim, 'commands_rejected')
    assert 'expected 1 lengths' in sim.last_rejection
    ros.send(pub, cmd(0.15), sim, 'commands_accepted')
    ticks(sim, 2000)
    # after 2 s the actuator (5 Hz bandwidth) has reached the target: x_1 - x_0 = 0.15 m
    assert sim.state.lengths.tolist() == pytest.approx([0.15], abs=1e-9)


def test_a_single_masses_change_sets_the_number_of_bodies(ros):
    sim = ros.sim(seed=True)
    result = sim.set_parameters([Parameter('masses', value=[1.0, 1.0, 1.0])])[0]
    assert result.successful, result.reason
    sim.tick()
    assert (sim.config.p, sim.config.n_links) == (3, 2)
    assert sim.state.lengths.tolist() == [0.1, 0.1]        # initial_lengths: one entry for all
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.12, 0.08), sim, 'commands_accepted')


def test_clock_carries_the_sim_time_of_every_publish_tick(ros):
    sim = ros.sim(seed=True, method='implicit')
    clocks = ros.listen(Clock, '/clock')
    ticks(sim, 30)
    ros.until(lambda: len(clocks) >= 3, 'three /clock messages')
    assert [ns_from_stamp(c.clock) for c in clocks][-3:] == [10_000_000, 20_000_000, 30_000_000]


def test_diagnostics_names_carry_the_namespace(ros):
    a = SimNode(context=ros.ctx, namespace='robot1')
    b = SimNode(context=ros.ctx, namespace='robot2')
    ros.nodes += [a, b]
    names = {n.diagnostics().status[0].name for n in (a, b)}
    assert names == {'/robot1/crawler_sim: simulation', '/robot2/crawler_sim: simulation'}
    diags = ros.listen(DiagnosticArray, '/diagnostics')
    a.publish_diagnostics(0.0)
    ros.until(lambda: diags, 'a diagnostics message')
    assert diags[-1].status[0].name == '/robot1/crawler_sim: simulation'


def test_contacts_is_a_stamped_alternative_to_contact_states(ros):
    sim = ros.sim(seed=True, method='implicit')
    contacts = ros.listen(JointState, 'contacts')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.3), sim, 'commands_accepted')
    ticks(sim, 100)
    ros.until(lambda: contacts and ns_from_stamp(contacts[-1].header.stamp) == 100_000_000,
              'contacts at t = 0.1 s')
    msg = contacts[-1]
    st = sim.state
    assert list(msg.name) == ['body_0', 'body_1']
    assert list(msg.position) == st.contact.astype(float).tolist()
    assert set(msg.position) <= {-1.0, 0.0, 1.0}
    np.testing.assert_array_equal(msg.velocity, st.v)
    np.testing.assert_array_equal(msg.effort, st.friction)


# --------------------------------------------------------------------------- shipped files

ROS_FILES = sorted((REPO / 'config' / 'ros').glob('*.yaml'))
SCENE_FILES = sorted((REPO / 'config' / 'scenes').glob('*.yaml'))


def _node_params(path: Path) -> dict:
    return yaml.safe_load(path.read_text())['crawler_sim']['ros__parameters']


def test_the_shipped_parameter_files_name_only_declared_parameters():
    assert [p.name for p in ROS_FILES] == ['chain_3body.yaml', 'crawler_sim.yaml']
    for path in ROS_FILES:
        unknown = set(_node_params(path)) - set(PARAMETERS)
        assert not unknown, (path, unknown)
    # crawler_sim.yaml says every value in it is the declared default
    for name, value in _node_params(REPO / 'config' / 'ros' / 'crawler_sim.yaml').items():
        assert value == PARAMETERS[name][0] or list(value) == PARAMETERS[name][0], name


def test_chain_3body_gives_three_bodies(ros):
    from crawler_sim.ros.sim.params import SimConfig
    values = {k: v[0] for k, v in PARAMETERS.items()}
    values.update(_node_params(REPO / 'config' / 'ros' / 'chain_3body.yaml'))
    cfg = SimConfig.from_values(values)
    assert (cfg.p, cfg.n_links) == (3, 2)
    assert cfg.crawler.to_dict()['friction_backward'] == pytest.approx([0.5 * G] * 3)


@pytest.mark.parametrize('path', SCENE_FILES, ids=lambda p: p.name)
def test_a_scene_file_is_refused_as_a_parameter_file_with_a_clear_reason(path):
    with pytest.raises(ParamsFileError, match='not a ROS 2 parameter file.*scene file'):
        check_params_files(['sim_node', '--ros-args', '--params-file', str(path)])


def test_parameter_files_pass_and_missing_ones_are_named(tmp_path):
    for path in ROS_FILES:
        check_params_files(['--ros-args', '--params-file', str(path)])
    with pytest.raises(ParamsFileError, match='cannot read parameter file .*nope.yaml'):
        check_params_files(['--params-file', str(tmp_path / 'nope.yaml')])
    bad = tmp_path / 'bad.yaml'
    bad.write_text('crawler_sim: [unclosed\n')
    with pytest.raises(ParamsFileError, match='not valid YAML'):
        check_params_files(['--params-file', str(bad)])


def test_the_launch_file_parses_and_starts_sim_node_and_gait_node_on_sim_time():
    path = REPO / 'launch' / 'crawler_sim.launch.py'
    tree = ast.parse(path.read_text())
    funcs = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert 'generate_launch_description' in funcs
    nodes = [c for c in ast.walk(tree) if isinstance(c, ast.Call)
             and getattr(c.func, 'id', None) == 'Node']
    kw = [{k.arg: k.value for k in c.keywords} for c in nodes]
    assert sorted(ast.literal_eval(k['executable']) for k in kw) == ['gait_node', 'sim_node']
    assert {ast.literal_eval(k['package']) for k in kw} == {'crawler_sim'}
    strings = {c.value for c in ast.walk(tree) if isinstance(c, ast.Constant)
               and isinstance(c.value, str)}
    # the parameter file it points at: config/ros/<default> exists, and gait_node on sim time
    assert {'config', 'ros', 'crawler_sim.yaml', 'use_sim_time'} <= strings
    assert (REPO / 'config' / 'ros' / 'crawler_sim.yaml').is_file()
    setup = (REPO / 'setup.py').read_text()
    assert "glob('launch/*.launch.py')" in setup and "glob('config/ros/*.yaml')" in setup
    assert '<exec_depend>launch_ros</exec_depend>' in (REPO / 'package.xml').read_text()


def test_a_recorded_run_is_read_topic_by_topic_by_rosbags_mcap_ros2_and_load(
        ros, tmp_path, monkeypatch):
    import crawler_sim.bag as bags
    from crawler_sim.ros.sim.intake import linkage_names
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    # the writer takes message definitions from the installed packages or rosbags' typestore:
    # recording must work without the ament index
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    sim = ros.sim(seed=True, record=True, record_dir=str(tmp_path), record_name='run')
    assert sim.recorder.on, sim.recorder.error
    cmd_pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    traj_pub = ros.publisher(JointTrajectory, 'linkage_trajectory')
    ticks(sim, 5)
    ros.send(cmd_pub, cmd(0.14), sim, 'commands_accepted')
    ticks(sim, 200)
    traj = JointTrajectory(joint_names=list(linkage_names(1)))
    for k, length in enumerate((0.12, 0.09, 0.11)):
        pt = JointTrajectoryPoint(positions=[length])
        pt.time_from_start.sec, pt.time_from_start.nanosec = 0, (k + 1) * 100_000_000
        traj.points.append(pt)
    ros.send(traj_pub, traj, sim, 'trajectories_accepted')
    ticks(sim, 500)
    sim.close()
    mcap = next((tmp_path / 'run').glob('*.mcap'))

    with AnyReader([mcap]) as reader:
        counts_rosbags: dict[str, int] = {}
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)          # every message, in full
            counts_rosbags[conn.topic] = counts_rosbags.get(conn.topic, 0) + 1
    counts_mcap: dict[str, int] = {}
    with open(mcap, 'rb') as f:
        for _, channel, _, _ in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages():
            counts_mcap[channel.topic] = counts_mcap.get(channel.topic, 0) + 1
    assert counts_rosbags == counts_mcap
    for topic in ('/body_states', '/joint_states', '/contacts', '/odom', '/markers',
                  '/linkage_cmd', '/linkage_trajectory', '/crawler_sim/applied_command'):
        assert counts_rosbags.get(topic, 0) >= 1, (topic, counts_rosbags)
    # 705 ticks called directly: t = 10 ms ... 700 ms (the loop, not run here, adds t = 0)
    assert counts_rosbags['/body_states'] == 70
    run = bags.load(tmp_path / 'run')
    assert len(run.t) == 70 and run.x.shape == (70, 2)
    assert [list(c) for c in run.commands.values] == [[0.14]]


def test_a_new_bag_holds_every_recorded_channel_before_the_first_tick(ros, tmp_path):
    """A run killed before its first chunk must still name its topics: the node declares every
    topic it records when the bag is created (read back with mcap's own summary-less reader)."""
    from mcap.records import Channel
    from mcap.stream_reader import StreamReader
    sim = ros.sim(seed=True, record=True, record_dir=str(tmp_path), record_name='early')
    topics = set()
    try:
        mcap = next((tmp_path / 'early').glob('*.mcap'))
        with open(mcap, 'rb') as f:    # the writer is still open: no footer, no summary yet
            try:
                for rec in StreamReader(f, skip_magic=False).records:
                    if isinstance(rec, Channel):
                        topics.add(rec.topic)
            except Exception:          # the end of what is on disk so far: expected
                pass
    finally:
        sim.close()
    for topic in ('/body_states', '/joint_states', '/linkage_cmd', '/linkage_trajectory',
                  '/crawler_sim/applied_command', '/diagnostics'):
        assert topic in topics, (topic, sorted(topics))


@pytest.mark.parametrize('name', ['../x', '/tmp/abs', 'a/b', '..', 'sp ace'])
def test_a_record_name_outside_record_dir_is_refused_as_a_parameter(name):
    from crawler_sim.ros.sim.params import SimConfig
    values = {k: spec[0] for k, spec in PARAMETERS.items()}
    values['record_name'] = name
    with pytest.raises(ValueError, match='record_name'):
        SimConfig.from_values(values)


def test_gait_node_names_a_gait_file_it_cannot_play(tmp_path):
    from crawler_sim.ros.gait_node import gait_from_file
    bad = tmp_path / 'not_a_scene.yaml'
    bad.write_text('gait_node:\n  ros__parameters: {}\n')
    for path in (tmp_path / 'missing.yaml', bad):
        with pytest.raises(ValueError, match='gait_file'):
            gait_from_file(str(path))
