"""sim_node in-process: an isolated rclpy Context per test (its own domain id, discovery limited
to the context), real DDS, ticks called directly."""
from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int8MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from crawler_sim import Stepper
import crawler_sim.bag
from crawler_sim.ros import messages as M
from crawler_sim.core.actuator import Actuator
from crawler_sim.core.plant import Engine
from crawler_sim.bag.cdr import LayoutError, zero_padding
from crawler_sim.ros.gait_node import GaitNode
from crawler_sim.core.gaits import Cubic
from crawler_sim.ros.messages import CONTACT_COLOURS, ns_from_stamp
from crawler_sim.ros.sim_node import SimConfig, SimNode
from test.support.ros import (DEADLINE, THREE_BODY, Harness, cmd, next_domain_id,  # noqa: F401
                              param_values, point, ticks, trajectory)

# --------------------------------------------------------------------------- outputs

def test_outputs_follow_the_interface_and_carry_the_sim_time_stamp(ros):
    sim = ros.sim(masses=[1.0, 2.0, 1.5], friction=[3.0, 4.0, 2.0], method='implicit')
    js = ros.listen(JointState, 'joint_states')
    bs = ros.listen(JointState, 'body_states')
    cs = ros.listen(Int8MultiArray, 'contact_states')
    od = ros.listen(Odometry, 'odom')
    mk = ros.listen(MarkerArray, 'markers')
    ticks(sim, 10)                            # 1 kHz, outputs at 100 Hz: one set at t = 10 ms
    def stamped(box: list) -> bool:
        return bool(box) and ns_from_stamp(box[-1].header.stamp) == 10_000_000

    ros.until(lambda: stamped(js) and stamped(bs) and stamped(od) and cs and mk,
              'the outputs of t = 10 ms')
    st = sim.state
    b, j, o = bs[-1], js[-1], od[-1]
    assert list(b.name) == ['body_0', 'body_1', 'body_2']
    np.testing.assert_array_equal(b.position, st.x)
    np.testing.assert_array_equal(b.velocity, st.v)
    np.testing.assert_array_equal(b.effort, st.friction)
    assert list(j.name) == ['linkage_0', 'linkage_1']
    np.testing.assert_array_equal(j.position, st.lengths)
    np.testing.assert_array_equal(j.effort, st.linkage_force)
    assert list(cs[-1].data) == st.contact.tolist()
    m = np.array([1.0, 2.0, 1.5])
    assert o.header.frame_id == 'odom' and o.child_frame_id == 'base_link'
    assert o.pose.pose.position.x == pytest.approx(m @ st.x / m.sum(), abs=1e-15)
    markers = mk[-1].markers
    cubes = [x for x in markers if x.type == Marker.CUBE]
    lines = [x for x in markers if x.type == Marker.LINE_STRIP]
    assert len(cubes) == 3 and len(lines) == 2
    assert all(ns_from_stamp(x.header.stamp) == 10_000_000 for x in markers)
    stuck = CONTACT_COLOURS[0]
    assert all((c.color.r, c.color.g, c.color.b) == pytest.approx(stuck[:3]) for c in cubes)
    assert [c.pose.position.x for c in cubes] == pytest.approx(st.x.tolist())


def test_a_sensor_data_and_a_reliable_subscriber_both_receive(ros):
    sim = ros.sim()
    best_effort = ros.listen(JointState, 'body_states', qos_profile_sensor_data)
    reliable = ros.listen(JointState, 'body_states', 10)
    ticks(sim, 10)
    ros.until(lambda: best_effort and reliable, 'both subscribers to receive')


def test_the_publish_grid_is_every_output_but_the_named_off_grid_ones(ros, monkeypatch):
    """Issue 42: the grid was ``OUTPUTS[:-1]`` (diagnostics assumed last), so an output added
    at the end of the table left the grid and diagnostics joined it (SimNode failed to start:
    no encoder named diagnostics). The off-grid outputs are named (params.OFF_GRID)."""
    from crawler_sim.ros.sim import outputs as O
    from crawler_sim.ros.sim.params import OFF_GRID, OUTPUTS
    reordered = ('diagnostics',) + tuple(n for n in OUTPUTS if n != 'diagnostics')
    monkeypatch.setattr(O, 'OUTPUTS', reordered)
    sim = ros.sim()
    grid = [name for name, *_ in sim.outputs._grid]
    assert grid == [n for n in reordered if n not in OFF_GRID] and 'markers' in grid


def test_clock_is_published_at_every_publish_tick_only_when_asked(ros):
    sim = ros.sim(publish_clock=True, publish_rate=50.0, method='implicit')
    clocks = ros.listen(Clock, '/clock')
    ticks(sim, 60)
    ros.until(lambda: len(clocks) >= 3, 'three /clock messages')
    assert [ns_from_stamp(c.clock) for c in clocks][-3:] == [20_000_000, 40_000_000, 60_000_000]
    assert ros.obs.count_publishers('/clock') == 1
    sim.set_parameters([Parameter('publish_clock', value=False)])
    sim.tick()
    assert ros.obs.count_publishers('/clock') == 0


def test_a_switched_off_output_has_no_publisher_and_builds_no_message(ros, monkeypatch):
    sim = ros.sim(publish_markers=False, publish_odom=False, method='implicit')
    built = []
    monkeypatch.setattr(sim.outputs.encoder, 'markers', lambda *a: built.append(a))
    ticks(sim, 50)
    assert ros.obs.count_publishers('/markers') == 0
    assert ros.obs.count_publishers('/odom') == 0
    assert ros.obs.count_publishers('/body_states') == 1
    assert built == []
    assert sim.set_parameters([Parameter('publish_odom', value=True)])[0].successful
    sim.tick()
    assert ros.obs.count_publishers('/odom') == 1


# --------------------------------------------------------------------------- commands

def test_a_command_takes_effect_at_the_next_tick_and_is_echoed_with_that_time(ros):
    sim = ros.sim()
    applied = ros.listen(JointState, '/crawler_sim/applied_command')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ticks(sim, 7)
    ros.send(pub, cmd(0.15, 0.12), sim, 'commands_accepted')
    assert sim.state.lengths.tolist() == [0.1, 0.1]
    sim.tick()
    ros.until(lambda: applied, 'the applied command')
    assert ns_from_stamp(applied[0].header.stamp) == 7_000_000
    assert list(applied[0].position) == [0.15, 0.12]
    assert sim.state.rates[0] > 0 and sim.state.rates[1] > 0
    ticks(sim, 2000)
    np.testing.assert_allclose(sim.state.lengths, [0.15, 0.12], atol=1e-9)


def test_commands_are_taken_by_the_tick_never_by_the_executor(ros):
    sim = ros.sim()
    applied = ros.listen(JointState, '/crawler_sim/applied_command')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ticks(sim, 3)
    assert not any(ros.ex.can_execute(sub) for sub in (sim._cmd_sub, sim._traj_sub))
    assert not any(ros.ex.can_execute(h) for sub in (sim._cmd_sub, sim._traj_sub)
                   for h in sub.event_handlers)
    pub.publish(cmd(0.15, 0.12))
    end = time.monotonic() + 0.3
    ros.until(lambda: time.monotonic() > end, '0.3 s of spinning')   # delivered, not taken
    assert sim.counters['commands_accepted'] == 0
    sim.tick()                                  # takes it and applies it at its start (3 ms)
    assert sim.counters['commands_accepted'] == 1
    ros.until(lambda: applied, 'the applied command')
    assert ns_from_stamp(applied[0].header.stamp) == 3_000_000
    assert sim.engine.actuator.target == [0.15, 0.12]


@pytest.mark.parametrize('last', ['command', 'trajectory'])
def test_of_a_command_and_a_trajectory_in_one_tick_the_later_arrival_wins(ros, last):
    sim = ros.sim()
    cmd_pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    traj_pub = ros.publisher(JointTrajectory, 'linkage_trajectory')
    traj = trajectory(['linkage_0', 'linkage_1'], [point(0.5, [0.12, 0.13])])
    sends = [lambda: cmd_pub.publish(cmd(0.15, 0.12)), lambda: traj_pub.publish(traj)]
    if last == 'command':
        sends.reverse()
    for send in sends:
        send()
        end = time.monotonic() + 0.1
        ros.until(lambda: time.monotonic() > end, '0.1 s')
    sim.tick()
    assert sim.counters['commands_accepted'] == sim.counters['trajectories_accepted'] == 1
    following = sim.engine.actuator.trajectory is not None
    assert following == (last == 'trajectory')


@pytest.mark.parametrize('data,problem', [
    ((0.15,), 'expected 2 lengths'),
    ((0.15, 0.12, 0.1), 'expected 2 lengths'),
    ((0.15, math.nan), 'not finite'),
    ((math.inf, 0.1), 'not finite'),
    ((0.15, 0.9), 'outside [min_length, max_length]'),
    ((0.01, 0.1), 'outside [min_length, max_length]'),
])
def test_a_rejected_command_is_counted_named_and_leaves_the_previous_target(ros, data, problem):
    sim = ros.sim()
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.14, 0.11), sim, 'commands_accepted')
    ticks(sim, 5)
    ros.send(pub, cmd(*data), sim, 'commands_rejected')
    t_before = sim.sim_time_ns
    ticks(sim, 2000)
    assert sim.sim_time_ns == t_before + 2000 * 1_000_000
    np.testing.assert_allclose(sim.state.lengths, [0.14, 0.11], atol=1e-9)
    assert sim.counters['commands_accepted'] == 1
    assert problem in sim.last_rejection
    status = sim.diagnostics().status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert values['commands_rejected'] == '1'
    assert status.level == DiagnosticStatus.WARN and 'commands rejected' in status.message


def test_an_all_nan_command_means_no_command_yet(ros):
    sim = ros.sim()
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(math.nan, math.nan), sim, 'commands_no_value')
    ticks(sim, 100)
    assert sim.counters['commands_rejected'] == 0 and sim.counters['commands_accepted'] == 0
    assert sim.state.lengths.tolist() == [0.1, 0.1]


# --------------------------------------------------------------------------- trajectories

def test_a_trajectory_is_followed_smoothly_to_its_last_point(ros):
    sim = ros.sim()
    pub = ros.publisher(JointTrajectory, 'linkage_trajectory')
    # joints given out of order: they are matched by name
    msg = trajectory(['linkage_1', 'linkage_0'],
                     [point(0.5, [0.12, 0.13], [0.0, 0.02]), point(1.0, [0.11, 0.14], [0, 0])])
    ros.send(pub, msg, sim, 'trajectories_accepted')
    ticks(sim, 500)
    np.testing.assert_allclose(sim.state.lengths, [0.13, 0.12], atol=2e-3)
    ticks(sim, 2500)
    np.testing.assert_allclose(sim.state.lengths, [0.14, 0.11], atol=1e-9)


@pytest.mark.parametrize('names,points,problem', [
    ([], [point(1.0, [])], 'empty joint_names'),
    (['linkage_0', 'arm'], [point(1.0, [0.1, 0.1])], "unknown joint 'arm'"),
    (['linkage_0'], [point(1.0, [0.1])], 'must list all 2 linkages'),
    (['linkage_0', 'linkage_0'], [point(1.0, [0.1, 0.1])], 'duplicate'),
    (['linkage_0', 'linkage_1'], [point(1.0, [0.1, 0.1]), point(1.0, [0.1, 0.2])],
     'not strictly increasing'),
    (['linkage_0', 'linkage_1'], [point(1.0, [0.1])], 'positions (1)'),
    (['linkage_0', 'linkage_1'], [point(1.0, [0.1, 0.1], [0.1, 0.0])], 'last trajectory point'),
    (['linkage_0', 'linkage_1'], [point(1.0, [0.1, 0.7])], 'outside [min_length'),
    (['linkage_0', 'linkage_1'], [point(1.0, [0.1, math.nan])], 'outside [min_length'),
])
def test_an_invalid_trajectory_is_rejected_with_the_reason(ros, names, points, problem):
    sim = ros.sim()
    pub = ros.publisher(JointTrajectory, 'linkage_trajectory')
    ros.send(pub, trajectory(names, points), sim, 'trajectories_rejected')
    assert problem in sim.last_rejection
    ticks(sim, 100)
    assert sim.state.lengths.tolist() == [0.1, 0.1]


def test_a_stamped_trajectory_that_already_ended_is_rejected(ros):
    sim = ros.sim()
    pub = ros.publisher(JointTrajectory, 'linkage_trajectory')
    ticks(sim, 2000)
    msg = trajectory(['linkage_0', 'linkage_1'], [point(0.5, [0.2, 0.2])], stamp_ns=1_000_000_000)
    ros.send(pub, msg, sim, 'trajectories_rejected')
    assert 'ends at 1.5 s' in sim.last_rejection


# --------------------------------------------------------------------------- parameters

@pytest.mark.parametrize('params,problem', [
    ([Parameter('friction', value=[1.0, 2.0])], 'friction: must have 1 or 3 entries'),
    ([Parameter('friction_backward', value=[1.0, 2.0, 3.0, 4.0])], 'friction_backward: must'),
    ([Parameter('publish_rate', value=2000.0)], 'must be <= integration_rate'),
    ([Parameter('integration_rate', value=1e7)], 'out of range'),
    ([Parameter('slope', value='steep')], 'slope must be a number'),
    ([Parameter('method', value='rk4')], 'method must be one of'),
    ([Parameter('initial_lengths', value=[0.1, 0.9])], 'outside [min_length, max_length]'),
    ([Parameter('min_length', value=0.6)], 'must be < max_length'),
    ([Parameter('masses', value=[1.0])], 'masses must list 2 to 64 bodies'),
    ([Parameter('masses', value=[1.0, 1.0, 1.0, 1.0])], 'initial_lengths must have 1 or 3'),
    ([Parameter('masses', value=[1.0, -1.0, 1.0])], 'masses[1]'),
    ([Parameter('record', value=True)], 'read-only'),
    ([Parameter('penalty', value=[0.0])], 'penalty must have 1 or 3 entries, each in [1e-06, 1e+15]'),
])
def test_an_invalid_parameter_is_rejected_with_a_reason_and_changes_nothing(ros, params,
                                                                           problem):
    sim = ros.sim()
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.14, 0.11), sim, 'commands_accepted')
    ticks(sim, 100)
    before = dict(sim.config.values)
    results = sim.set_parameters(params)
    assert not results[0].successful
    assert problem in results[0].reason
    ticks(sim, 2000)
    assert sim.config.values == before
    assert SimConfig.from_values(param_values(sim)).values == before
    np.testing.assert_allclose(sim.state.lengths, [0.14, 0.11], atol=1e-9)


def test_a_valid_change_applies_at_the_next_tick_from_the_current_state(ros):
    sim = ros.sim(friction=[3.0])
    ticks(sim, 100)
    x_before = sim.state.x.copy()
    # m g sin(0.5) = 4.70 N > 3 N of friction: every body slides downhill
    assert sim.set_parameters([Parameter('slope', value=0.5)])[0].successful
    assert sim.config.crawler.slope == 0.0      # not yet: at the next tick
    sim.tick()
    assert sim.config.crawler.slope == 0.5
    np.testing.assert_allclose(sim.state.x, x_before, atol=1e-5)   # no jump
    ticks(sim, 500)
    assert np.all(sim.state.v < 0) and np.all(sim.state.contact == -1)


def test_a_new_number_of_bodies_takes_effect_as_a_reset(ros):
    sim = ros.sim()
    bs = ros.listen(JointState, 'body_states')
    ticks(sim, 100)
    result = sim.set_parameters_atomically([
        Parameter('masses', value=[1.0, 1.0, 1.0, 1.0]),
        Parameter('initial_lengths', value=[0.1, 0.2, 0.1])])
    assert result.successful, result.reason
    ticks(sim, 10)
    np.testing.assert_allclose(sim.state.x, [0.0, 0.1, 0.3, 0.4], atol=1e-15)
    ros.until(lambda: bs and len(bs[-1].name) == 4, 'body_states of 4 bodies')


# --------------------------------------------------------------------------- services

def test_reset_returns_to_the_initial_state_and_sim_time_goes_on(ros):
    sim = ros.sim(initial_position=1.0)
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 1000)
    assert sim.state.lengths.tolist() != [0.1, 0.1]
    result = ros.call(Trigger, '/crawler_sim/reset', Trigger.Request())
    assert result.success and 't = 1.000000000 s' in result.message
    assert sim.sim_time_ns == 1_000_000_000
    x_reset = sim.state.x.copy()
    np.testing.assert_allclose(x_reset, [1.0, 1.1, 1.2], atol=1e-15)
    ticks(sim, 500)                       # the old command is gone: the crawler stays put
    np.testing.assert_array_equal(sim.state.x, x_reset)


def test_pause_stops_sim_time_and_resume_continues(ros):
    sim = ros.sim(real_time_factor=0.0)
    loop = threading.Thread(target=sim.run, daemon=True)
    loop.start()
    try:
        ros.until(lambda: sim.sim_time_ns > 50_000_000, 'the loop to run')
        result = ros.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=True))
        assert result.success and result.message.startswith('paused at t = ')
        t_paused = sim.sim_time_ns
        assert result.message == f'paused at t = {t_paused / 1e9:.9f} s'
        end = time.monotonic() + 0.3
        ros.until(lambda: time.monotonic() > end, '0.3 s')
        assert sim.sim_time_ns == t_paused
        result = ros.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False))
        assert result.success
        ros.until(lambda: sim.sim_time_ns > t_paused + 50_000_000, 'time to go on')
    finally:
        sim.stop()
        loop.join(timeout=5)
    assert not loop.is_alive()


# --------------------------------------------------------------------------- timing

def test_real_time_factor_paces_sim_time_against_the_wall_clock(ros):
    sim = ros.sim(real_time_factor=2.0, publish_rate=10.0)
    loop = threading.Thread(target=sim.run, daemon=True)
    start = time.monotonic()
    loop.start()
    ros.until(lambda: time.monotonic() - start > 0.6, '0.6 s of wall time')
    sim.stop()
    loop.join(timeout=5)
    wall = time.monotonic() - start
    # pacing never runs ahead of real_time_factor x wall time, whatever the load (flat out
    # this node runs several times faster); falling behind it is allowed only when it says so
    # (late ticks counted), so a busy machine cannot fail this test, a broken pacer can
    sim_s = sim.sim_time_ns / 1e9
    assert 0.0 < sim_s <= 2.0 * wall * 1.02 + 0.01
    assert sim_s >= 2.0 * wall * 0.85 or sim.counters['late_ticks'] > 0


@pytest.mark.parametrize('method', ['exact', 'implicit', 'penalty'])
def test_the_same_commands_at_the_same_ticks_give_bit_identical_states_and_match_offline(
        ros, method):
    schedule = {0: [0.15, 0.12], 700: [0.06, 0.2], 1500: [0.12, 0.08]}

    def drive(node: SimNode) -> list[np.ndarray]:
        pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
        out = []
        for k in range(2500):
            if k in schedule:         # over DDS, taken before the tick k (as the loop does)
                ros.send(pub, cmd(*schedule[k]), node, 'commands_accepted')
            node.tick()
            out.append(node.state.x.copy())
        ros.obs.destroy_publisher(pub)
        return out

    a = drive(ros.sim(method=method))
    b = drive(ros.sim(method=method))
    np.testing.assert_array_equal(np.array(a), np.array(b))
    # offline: the same actuator pieces fed to the core's Stepper
    cfg = SimConfig.from_values(param_values(ros.nodes[0]))
    act = Actuator(cfg.initial_lengths, cfg.dt_ns / 1e9, cfg.limits)
    st = Stepper(cfg.crawler, Cubic(0.0, list(cfg.initial_lengths), 0.0, 0.0, 0.0), method,
                 t0=0.0, x0=0.0, v0=0.0, dt=cfg.dt_ns / 1e9, penalty=cfg.penalty_n)
    for k in range(2500):
        if k in schedule:
            act.set_target(schedule[k])
        t0, t1 = k * cfg.dt_ns / 1e9, (k + 1) * cfg.dt_ns / 1e9
        st.advance(t1, act.step(t0, t1))
        np.testing.assert_array_equal(st.state.x, a[k])
    assert np.ptp(np.array(a)[:, 0]) > 1e-3           # the bodies did move


def test_at_rest_the_stepper_gets_constant_pieces(ros, monkeypatch):
    sim = ros.sim()
    pieces = []
    stepper = sim.engine.stepper
    advance = stepper.advance
    monkeypatch.setattr(stepper, 'advance', lambda t1, g: (pieces.append(g), advance(t1, g)))
    ticks(sim, 20)
    assert all(p.is_constant(0.0, 1.0) for p in pieces)


# --------------------------------------------------------------------------- diagnostics

def test_diagnostics_report_the_figures_with_byte_levels(ros):
    # 100 Hz ticks: a tick is late only 10 ms after its deadline (a loaded test host is fine)
    # the paced loop runs a publish period's ticks back to back, so a diagnostics window must
    # span several publish periods (here 5) for its real-time factor to mean anything
    sim = ros.sim(diagnostics_period=0.5, integration_rate=100.0,
                  publish_rate=10.0)
    diags = ros.listen(DiagnosticArray, '/diagnostics')
    loop = threading.Thread(target=sim.run, daemon=True)
    loop.start()
    try:
        ros.until(lambda: len(diags) >= 2, 'two /diagnostics messages')
    finally:
        sim.stop()
        loop.join(timeout=5)
    status = diags[-1].status[0]
    assert status.level == DiagnosticStatus.OK and isinstance(status.level, bytes), status.message
    values = {kv.key: kv.value for kv in status.values}
    for key in ('real_time_factor', 'late_ticks', 'commands_accepted', 'commands_rejected',
                'solver_events', 'method', 'tick_lateness_p99_ms'):
        assert key in values
    assert values['method'] == 'exact' and values['solver_failures'] == '0'
    assert 0.5 < float(values['real_time_factor']) < 1.5


# --------------------------------------------------------------------------- recording

class FakeBag:
    instances: list['FakeBag'] = []

    def __init__(self, path, scene):
        self.path, self.scene, self.rows, self.closed, self.error = path, scene, [], False, None
        FakeBag.instances.append(self)

    @classmethod
    def create(cls, record_dir, record_name, *, scene, topics=None):
        bag = cls(f'{record_dir}/{record_name}', scene)
        bag.topics = topics
        return bag

    def write(self, topic, type_name, msg, t_ns):
        self.rows.append((topic, type_name, t_ns))

    def flush(self):
        pass

    def close(self):
        self.closed = True


def test_recording_writes_outputs_and_applied_commands_at_sim_time(ros, monkeypatch, tmp_path):
    FakeBag.instances = []
    monkeypatch.setattr(crawler_sim.bag, 'BagWriter', FakeBag, raising=False)
    sim = ros.sim(record=True, record_dir=str(tmp_path), record_name='b1')
    bag = FakeBag.instances[0]
    assert bag.path == str(tmp_path / 'b1') and bag.scene['masses'] == [1.0, 1.0, 1.0]
    ticks(sim, 3)
    ros.send(ros.publisher(Float64MultiArray, 'linkage_cmd'), cmd(0.15, 0.12), sim,
             'commands_accepted')
    ticks(sim, 17)
    topics = {(r[0], r[2]) for r in bag.rows}
    assert ('/linkage_cmd', 3_000_000) in topics
    assert ('/crawler_sim/applied_command', 3_000_000) in topics
    assert ('/body_states', 10_000_000) in topics and ('/body_states', 20_000_000) in topics
    sim.close()
    assert bag.closed


def test_a_failing_bag_stops_recording_but_not_the_simulation(ros, monkeypatch, tmp_path):
    class Broken(FakeBag):
        def write(self, *a):
            raise OSError('disk full')

    monkeypatch.setattr(crawler_sim.bag, 'BagWriter', Broken, raising=False)
    sim = ros.sim(record=True, record_dir=str(tmp_path))
    ticks(sim, 100)
    assert sim.sim_time_ns == 100_000_000
    status = sim.diagnostics().status[0]
    assert status.level == DiagnosticStatus.WARN and 'recording failed' in status.message


# --------------------------------------------------------------------------- gait_node

@pytest.mark.parametrize('mode,tolerance', [('command', 0.035), ('trajectory', 1e-3)])
def test_gait_node_plays_its_gait_on_sim_time(ros, mode, tolerance):
    sim = ros.sim(seed=True)              # the defaults of both: two bodies, one linkage
    # a stroke within the actuator's limits (|l'| <= 0.17 m/s, |l''| <= 1.2 m/s^2), so that
    # trajectory mode can play it exactly (the default stroke saturates the actuator)
    gait = GaitNode(context=ros.ctx, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('mode', value=mode),
        Parameter('frequency', value=1.0), Parameter('asymmetry', value=0.4),
        Parameter('n_links', value=1)])    # (asking the sim would block: it is not spun)
    ros.ex.add_node(gait)
    ros.others.append(gait)
    counter = 'commands_accepted' if mode == 'command' else 'trajectories_accepted'
    ros.until(lambda: gait.count_subscribers('linkage_cmd' if gait.mode == 'command' else 'linkage_trajectory') > 0, 'gait_node to connect')
    errors = []
    for k in range(4000):
        sim.tick()
        if k % 10 == 9:                        # let /clock reach the gait node, and it answer
            for _ in range(4):
                ros.ex.spin_once(timeout_sec=0.0)
        if k >= 2000 and gait.t0_ns is not None:
            t = (sim.sim_time_ns - gait.t0_ns) / 1e9
            errors.append(np.max(np.abs(sim.state.lengths - gait.gait.length(t))))
    assert sim.counters[counter] > (100 if mode == 'command' else 3)
    assert sim.counters['commands_rejected'] == sim.counters['trajectories_rejected'] == 0
    assert max(errors) < tolerance, max(errors)


def test_gait_node_stops_taking_clock_once_its_preload_is_sent(ros):
    sim = ros.sim(seed=True)
    gait = GaitNode(context=ros.ctx, parameter_overrides=[
        Parameter('use_sim_time', value=True), Parameter('mode', value='trajectory'),
        Parameter('preload', value=True), Parameter('duration', value=2.0),
        Parameter('n_links', value=1)])
    ros.ex.add_node(gait)
    ros.others.append(gait)

    def clock_subs():
        return [s for s in gait.subscriptions if s.topic_name == '/clock']
    assert clock_subs()                          # use_sim_time: rclpy follows /clock
    ros.until(lambda: gait.sent == 1, 'the preload to go out')
    assert not clock_subs() and gait.sent == 1   # nothing on ROS time is left to do
    ros.until(lambda: sim.take_inputs() or sim.counters['trajectories_accepted'],
              'the sim to take the preload')
    assert sim.counters['trajectories_accepted'] == 1


# --------------------------------------------------------------------------- output bytes

def random_state(rng: np.random.Generator, p: int) -> SimpleNamespace:
    """A duck-typed core State with awkward numbers (signed zeros, huge, tiny, inf, NaN)."""
    def f(n: int) -> np.ndarray:
        x = rng.normal(size=n) * 10.0 ** rng.integers(-300, 300, size=n)
        x[rng.random(n) < 0.2] = rng.choice([0.0, -0.0, np.inf, np.nan])
        return x
    return SimpleNamespace(x=f(p), v=f(p), friction=f(p), lengths=f(p - 1), rates=f(p - 1),
                           linkage_force=f(p - 1),
                           contact=rng.integers(-1, 2, size=p).astype(np.int8))


@pytest.mark.parametrize('p', [2, 3, 7])
def test_output_bytes_equal_serialize_message_of_the_builders(p):
    rng = np.random.default_rng(p)
    enc = M.OutputEncoder()
    masses = rng.uniform(0.1, 10.0, size=p)
    builders = {'joint_states': lambda s, t: M.joint_states_msg(s, t),
                'body_states': lambda s, t: M.body_states_msg(s, t),
                'contact_states': lambda s, t: M.contact_states_msg(s),
                'odom': lambda s, t: M.odom_msg(s, masses, t),
                'markers': lambda s, t: M.markers_msg(s, t)}
    for k in range(6):
        st, t_ns = random_state(rng, p), int(rng.integers(0, 2**31 * 10**9))
        for name, build in builders.items():
            ref = serialize_message(build(st, t_ns))
            assert enc.encode(name, st, t_ns, masses) == zero_padding(ref, M.ENCODED[name].type)
        lengths = st.lengths.tolist()
        assert enc.applied_command(lengths, t_ns) == zero_padding(
            serialize_message(M.applied_command_msg(t_ns, lengths)), 'sensor_msgs/msg/JointState')
        assert enc.linkage_cmd(lengths) == zero_padding(
            serialize_message(M.float64_array_msg(lengths)), 'std_msgs/msg/Float64MultiArray')
    assert enc.slow == 0 and enc.fast == 6 * 7


@pytest.mark.parametrize('p', [2, 3, 7])
def test_a_row_of_a_state_encodes_the_bytes_of_the_state(p):
    """The node converts a state to lists once per publish tick (``M.Row``) and every encoder
    packs from them: the bytes are those of the builders' messages, first message of a shape
    (the template, built from the row's state) included, awkward numbers included."""
    rng = np.random.default_rng(10 + p)
    masses = rng.uniform(0.1, 10.0, size=p)
    builders = {'joint_states': lambda s, t: M.joint_states_msg(s, t),
                'body_states': lambda s, t: M.body_states_msg(s, t),
                'contact_states': lambda s, t: M.contact_states_msg(s),
                'contacts_stamped': lambda s, t: M.contacts_stamped_msg(s, t),
                'odom': lambda s, t: M.odom_msg(s, masses, t),
                'markers': lambda s, t: M.markers_msg(s, t)}
    from_rows, from_states = M.OutputEncoder(), M.OutputEncoder()
    for k in range(5):
        st, t_ns = random_state(rng, p), int(rng.integers(0, 2**31 * 10**9))
        row = M.Row(st)
        assert row.finite() == all(np.isfinite(a).all() for a in (
            st.x, st.v, st.friction, st.linkage_force, st.lengths, st.rates))
        for name, build in builders.items():
            ref = zero_padding(serialize_message(build(st, t_ns)), M.ENCODED[name].type)
            assert from_rows.encode(name, row, t_ns, masses) == ref, name
            assert from_states.encode(name, st, t_ns, masses) == ref, name
    assert from_rows.slow == 0 and from_rows.fast == 5 * 6


def test_a_state_with_a_non_finite_number_is_withheld_and_the_node_resets(ros, monkeypatch):
    sim = ros.sim()
    box = ros.listen(JointState, '/body_states')
    ticks(sim, 20)
    ros.until(lambda: len(box) >= 2, 'two body_states')
    real = Engine.state

    def broken(engine):               # finite x and v, a NaN friction
        st = real.fget(engine)
        return st._replace(friction=np.full_like(st.friction, np.nan))
    monkeypatch.setattr(Engine, 'state', property(broken))
    t_ns = sim.sim_time_ns
    ticks(sim, 20)
    assert sim.counters['nonfinite_outputs'] == 2
    monkeypatch.setattr(Engine, 'state', real)
    ticks(sim, 10)
    ros.until(lambda: ns_from_stamp(box[-1].header.stamp) == t_ns + 30_000_000,
              'body_states after the broken ones')
    assert all(math.isfinite(f) for m in box for f in m.effort)
    assert t_ns + 10_000_000 not in [ns_from_stamp(m.header.stamp) for m in box]


def test_an_output_without_a_template_goes_through_the_builder(monkeypatch):
    enc = M.OutputEncoder()
    monkeypatch.setattr(enc, '_encoder_class', lambda *a: (_ for _ in ()).throw(
        LayoutError('no template')))
    st = random_state(np.random.default_rng(0), 3)
    for _ in range(2):
        assert enc.body_states(st, 5) == serialize_message(M.body_states_msg(st, 5))
    assert enc.slow == 2 and enc.fast == 0


@pytest.mark.parametrize('t_ns', [0, 1, 999_999_999, 10**9, 2**31 * 10**9 - 1])
def test_clock_bytes_equal_serialize_message(t_ns):
    assert M.clock_cdr(t_ns) == serialize_message(M.clock_msg(t_ns))


def test_published_and_recorded_outputs_are_the_same_bytes_in_a_namespace(ros, tmp_path):
    sim = SimNode(context=ros.ctx, namespace='robot1', parameter_overrides=[
        Parameter('record', value=True), Parameter('record_dir', value=str(tmp_path)),
        Parameter('record_name', value='ns'), Parameter('masses', value=[1.0, 2.0, 0.5]),
        Parameter('friction', value=[1.0, 3.0, 2.0])])
    ros.ex.add_node(sim)
    ros.nodes.append(sim)
    types = {'joint_states': JointState, 'body_states': JointState,
             'contact_states': Int8MultiArray, 'odom': Odometry, 'markers': MarkerArray}
    boxes = {name: ros.listen(typ, f'/robot1/{name}') for name, typ in types.items()}
    ticks(sim, 5)
    ros.send(ros.publisher(Float64MultiArray, '/robot1/linkage_cmd'), cmd(0.16, 0.05), sim,
             'commands_accepted')
    ticks(sim, 300)
    ros.until(lambda: all(len(b) >= 30 for b in boxes.values()), 'the outputs of 0.3 s')
    sim.close()
    recorded = {name: [] for name in types}
    with open(tmp_path / 'ns' / 'ns_0.mcap', 'rb') as f:
        for _, channel, message in make_reader(f).iter_messages():
            name = channel.topic.rsplit('/', 1)[-1]
            if channel.topic == f'/robot1/{name}' and name in types:
                recorded[name].append(deserialize_message(message.data, types[name]))
    for name, box in boxes.items():
        assert len(recorded[name]) == 30                       # t = 10 ms, ..., 300 ms
        assert box == recorded[name][-len(box):], name          # what was sent is what was kept
    assert len({tuple(m.data) for m in boxes['contact_states']}) > 1   # the contacts changed


def test_two_sims_with_one_name_are_reported_not_silent(ros):
    """Issue 25: two sim_nodes in one namespace interleave body_states and share one
    diagnostics name. Each now counts the other and says so (WARN, naming the remedy)."""
    a, _ = ros.sim(), ros.sim()
    ros.until(lambda: node_values_of(a)['same_name_nodes'] >= 1, 'the graph to show both')
    status = a.diagnostics().status[0]
    assert status.level == DiagnosticStatus.WARN
    assert "other node(s) named /crawler_sim" in status.message
    assert 'own namespace' in status.message


def node_values_of(sim):
    """The node's figures as its /diagnostics report them."""
    return {kv.key: int(kv.value) if kv.key == 'same_name_nodes' else kv.value
            for kv in sim.diagnostics().status[0].values}


def test_get_parameters_over_the_full_list_returns_every_value(ros):
    """Issue 26: ``friction`` declared without a value made rclpy empty the whole reply (what
    ``ros2 param dump``, rqt and Foxglove ask). ListParameters, then one GetParameters of every
    name, over DDS."""
    from rcl_interfaces.srv import GetParameters, ListParameters
    sim = ros.sim(seed=True)
    names = ros.call(ListParameters, '/crawler_sim/list_parameters',
                     ListParameters.Request()).result.names
    assert 'friction' in names and 'masses' in names and len(names) >= 30
    values = ros.call(GetParameters, '/crawler_sim/get_parameters',
                      GetParameters.Request(names=list(names))).values
    assert len(values) == len(names)
    got = dict(zip(names, values))
    assert list(got['masses'].double_array_value) == [0.5, 1.0]
    assert got['friction'].type != 0                       # set (an empty array), not NOT_SET
    assert sim.config.values['friction'] == []


@pytest.mark.parametrize('param,expect', [
    (Parameter('real_time_factor', value=0), ('real_time_factor', 0.0)),     # README: "0"
    (Parameter('mu', value=0.4), ('mu', [0.4])),                             # one for all
    (Parameter('masses', value=[1, 1, 1]), ('masses', [1.0, 1.0, 1.0])),     # integers
    (Parameter('integration_rate', value=2000), ('integration_rate', 2000.0)),
])
def test_values_as_people_type_them_are_taken(ros, param, expect):
    sim = ros.sim(seed=True)
    result = sim.set_parameters([param])[0]
    assert result.successful, result.reason
    ticks(sim, 1)
    name, value = expect
    assert sim.config.values[name] == value
    if name == 'masses':
        assert sim.config.p == 3


def test_a_string_where_a_number_belongs_names_the_field(ros):
    sim = ros.sim(seed=True)
    result = sim.set_parameters([Parameter('slope', value='steep')])[0]
    assert not result.successful and 'slope must be a number in [-1.5, 1.5]' in result.reason


def test_step_advances_one_publish_period_while_paused_and_only_then(ros):
    """``~/step`` (std_srvs/Trigger) over DDS: paused at a publish tick, one step is
    publish_every ticks (10 ms at the defaults) and its state goes out stamped with that
    time; a running node refuses to step."""
    sim = ros.sim(seed=True)
    states = ros.listen(JointState, 'body_states')
    ticks(sim, 20)
    pause = ros.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=True))
    assert pause.success and sim.paused
    before = sim.sim_time_ns
    got = ros.call(Trigger, '/crawler_sim/step', Trigger.Request())
    assert got.success and sim.sim_time_ns == before + 10_000_000
    ros.until(lambda: states and ns_from_stamp(states[-1].header.stamp) == before + 10_000_000,
              'the stepped state')
    assert ros.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success
    refused = ros.call(Trigger, '/crawler_sim/step', Trigger.Request())
    assert not refused.success and 'not paused' in refused.message


def test_a_paused_node_keeps_its_state_visible_to_a_late_subscriber(ros):
    sim = ros.sim(seed=True, start_paused=True)
    thread = threading.Thread(target=sim.run, daemon=True)
    thread.start()
    try:
        clocks = ros.listen(Clock, '/clock')
        late = ros.listen(JointState, 'body_states')        # after the node published once
        ros.until(lambda: len(late) >= 2 and len(clocks) >= 2, 'republished state and clock')
        assert sim.paused and sim.sim_time_ns == 0
        assert all(ns_from_stamp(m.header.stamp) == 0 for m in late)
    finally:
        sim.stop()
        thread.join(timeout=10.0)


def test_diagnostics_warn_on_persistent_lateness_or_a_low_factor_not_on_two_late_ticks():
    from crawler_sim.ros.sim.diagnostics import Diagnostics, LATE_STREAK
    counters = dict.fromkeys(('ticks', 'late_ticks', 'commands_rejected',
                              'trajectories_rejected', 'solver_failures', 'nonfinite_outputs',
                              'tick_failures'), 0)
    d = Diagnostics(counters, 'x')
    paced = {'real_time_factor_target': 1.0, 'paused': False}

    def report(late: int, sim_s: float, wall_s: float, **kw):
        counters['ticks'] += round(sim_s * 1000)
        counters['late_ticks'] += late
        report.t += sim_s
        report.wall += wall_s
        return d.message(round(report.t * 1e9), dict(paced), report.wall, **kw).status[0]
    report.t, report.wall = 0.0, d._prev[1]
    assert report(2, 1.0, 1.0).level == DiagnosticStatus.OK           # two of 1000: noise
    for _ in range(LATE_STREAK - 2):
        assert report(1, 1.0, 1.0).level == DiagnosticStatus.OK
    status = report(1, 1.0, 1.0)
    assert status.level == DiagnosticStatus.WARN and 'in a row' in status.message
    assert report(0, 1.0, 1.0).level == DiagnosticStatus.OK
    assert report(50, 1.0, 1.0).level == DiagnosticStatus.WARN         # 5 % of the ticks
    slow = report(0, 0.5, 1.0)
    assert slow.level == DiagnosticStatus.WARN and 'real-time factor 0.5 below' in slow.message
    last = report(0, 0.01, 1.0, final=True)                               # shutdown
    assert last.level == DiagnosticStatus.OK
    assert dict((kv.key, kv.value) for kv in last.values)['real_time_factor'] == '0.5'
