"""sim_node's simulation_interfaces services and action over real DDS (an in-process node in its
own context, ticks called directly unless a loop is started; crawler_sim/ros/sim/standard.py).

Expected numbers come from the set-up, not from the code under test: sim time is an integer
number of ticks of dt = 1 ms (integration_rate 1 kHz), publish ticks every 10 ticks; the three-body
scene starts at rest at x = (x0, x0 + 0.1, x0 + 0.2) m (initial_lengths 0.1 m); a body's state
is compared with what ``body_states`` publishes, and stepped states with a twin node ticked one
tick at a time.
"""
from __future__ import annotations

import json
from pathlib import Path
import sys

from ament_index_python.packages import get_package_share_directory
import numpy as np
import pytest
from rclpy.action import ActionClient
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Bounds, EntityCategory, Result, SimulationState, \
    SimulatorFeatures
from simulation_interfaces.srv import (GetEntities, GetEntitiesStates, GetEntityState,
                                       GetSimulationState, GetSimulatorFeatures,
                                       ResetSimulation, SetEntityState, SetSimulationState,
                                       StepSimulation)
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Vector3

from crawler_sim.core.plant import Engine
from crawler_sim.ros.messages import ns_from_stamp
from test.support.ros import cmd, ticks

NS = '/crawler_sim/'
TICK = 1_000_000            # ns: one tick at the default integration_rate (1 kHz)
#: each feature of the standard and the interfaces a simulator that lists it must serve (from
#: the comments of SimulatorFeatures.msg): the test's own reading, not the node's table
NEEDS = {
    SimulatorFeatures.SIMULATION_STATE_GETTING: ['get_simulation_state'],
    SimulatorFeatures.SIMULATION_STATE_SETTING: ['set_simulation_state'],
    SimulatorFeatures.SIMULATION_STATE_PAUSE: ['set_simulation_state'],
    SimulatorFeatures.STEP_SIMULATION_SINGLE: ['step_simulation'],
    SimulatorFeatures.STEP_SIMULATION_MULTIPLE: ['step_simulation'],
    SimulatorFeatures.STEP_SIMULATION_ACTION: ['simulate_steps'],
    SimulatorFeatures.SIMULATION_RESET: ['reset_simulation'],
    SimulatorFeatures.SIMULATION_RESET_STATE: ['reset_simulation'],
    SimulatorFeatures.ENTITY_STATE_GETTING: ['get_entity_state', 'get_entities_states'],
    SimulatorFeatures.ENTITY_STATE_SETTING: ['set_entity_state'],
}


def step(ros, steps: int):
    """One step_simulation call, sent once (a resent request would step twice)."""
    return ros.call(StepSimulation, NS + 'step_simulation', StepSimulation.Request(steps=steps),
                    attempts=1).result


def set_state(ros, state: int):
    return ros.call(SetSimulationState, NS + 'set_simulation_state',
                    SetSimulationState.Request(state=SimulationState(state=state))).result


def get_state(ros) -> int:
    got = ros.call(GetSimulationState, NS + 'get_simulation_state', GetSimulationState.Request())
    assert got.result.result == Result.RESULT_OK
    return got.state.state


def pause(ros, sim) -> None:
    assert ros.call(SetBool, NS + 'pause', SetBool.Request(data=True)).success and sim.paused


def test_the_features_list_exactly_the_interfaces_served(ros):
    sim = ros.sim()
    got = ros.call(GetSimulatorFeatures, NS + 'get_simulator_features',
                   GetSimulatorFeatures.Request()).features
    features = set(got.features)
    assert features == set(NEEDS), 'a feature listed that the test does not know, or missing'
    ros.until(lambda: any(n.endswith('simulate_steps/_action/send_goal') for n, _ in
                          ros.obs.get_service_names_and_types()), 'the action')
    served = {name[len(NS):].split('/')[0]: types
              for name, types in ros.obs.get_service_names_and_types_by_node(
                  sim.get_name(), sim.get_namespace())
              if name.startswith(NS)}
    standard = {name for name, types in served.items()
                if any(t.startswith('simulation_interfaces/') for t in types)}
    needed = {name for f in features for name in NEEDS[f]}
    # (the features service is mandatory and get_entities has no flag of its own)
    assert standard | {'simulate_steps'} == needed | {'get_simulator_features', 'get_entities'}
    assert 'simulate_steps' in served                 # its hidden services (_action/...)
    assert {'reset', 'pause', 'step'} <= set(served)  # the std_srvs ones keep working


def test_step_simulation_of_50_advances_clock_by_exactly_50_ticks_and_a_step_is_a_tick(ros):
    sim = ros.sim(publish_clock=True)
    # the same plant ticked one tick at a time by the core's engine, no ROS (the command taken
    # before the first tick, as the node takes it)
    twin = Engine(sim.config.engine_config(), 0)
    twin.command([0.2, 0.05])
    clocks = ros.listen(Clock, '/clock')
    states = ros.listen(JointState, 'body_states')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 20)
    pause(ros, sim)
    start = sim.sim_time_ns
    assert start == 20 * TICK
    ros.until(lambda: clocks and ns_from_stamp(clocks[-1].clock) == start, 'the clock at 20 ms')

    got = step(ros, 50)
    assert got.result == Result.RESULT_OK, got.error_message
    assert sim.sim_time_ns == start + 50 * TICK
    ros.until(lambda: ns_from_stamp(clocks[-1].clock) == start + 50 * TICK, '/clock at +50 ticks')
    for _ in range(70):
        twin.tick()
    np.testing.assert_array_equal(sim.state.x, twin.state.x)

    # 7 ticks end off the publish grid (every 10 ticks): /clock and the state go out there too
    got = step(ros, 7)
    assert got.result == Result.RESULT_OK
    end = start + 57 * TICK
    ros.until(lambda: ns_from_stamp(clocks[-1].clock) == end, '/clock at the last step')
    ros.until(lambda: any(ns_from_stamp(s.header.stamp) == end for s in states),
              'the state at the last step')
    for _ in range(7):
        twin.tick()
    at_end = next(s for s in states if ns_from_stamp(s.header.stamp) == end)
    assert list(at_end.position) == twin.state.x.tolist()
    assert sim.paused                                   # stepping leaves it paused


def test_step_simulation_is_refused_while_playing_and_for_zero_steps(ros):
    sim = ros.sim()
    t0 = sim.sim_time_ns
    playing = step(ros, 5)
    assert playing.result == Result.RESULT_OPERATION_FAILED and 'not paused' in playing.error_message
    pause(ros, sim)
    zero = step(ros, 0)
    assert zero.result == Result.RESULT_OPERATION_FAILED and 'steps must be in [1, ' in \
        zero.error_message
    assert sim.sim_time_ns == t0


def test_simulation_state_playing_paused_stopped_and_the_refused_ones(ros):
    sim = ros.sim(initial_position=1.0)
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 300)
    assert get_state(ros) == SimulationState.STATE_PLAYING
    assert set_state(ros, SimulationState.STATE_PAUSED).result == Result.RESULT_OK
    assert sim.paused and get_state(ros) == SimulationState.STATE_PAUSED
    assert set_state(ros, SimulationState.STATE_PAUSED).result == \
        SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    t = sim.sim_time_ns
    assert set_state(ros, SimulationState.STATE_STOPPED).result == Result.RESULT_OK
    # stopped = paused and at rest where it started; sim time goes on from where it was
    assert sim.paused and sim.sim_time_ns == t
    np.testing.assert_allclose(sim.state.x, [1.0, 1.1, 1.2], atol=1e-15)
    assert get_state(ros) == SimulationState.STATE_STOPPED
    assert set_state(ros, SimulationState.STATE_PAUSED).result == \
        SetSimulationState.Response.INCORRECT_TRANSITION
    assert set_state(ros, SimulationState.STATE_PLAYING).result == Result.RESULT_OK
    assert not sim.paused and get_state(ros) == SimulationState.STATE_PLAYING
    for refused in (SimulationState.STATE_QUITTING, SimulationState.STATE_NO_WORLD,
                    SimulationState.STATE_LOADING_WORLD):
        assert set_state(ros, refused).result == Result.RESULT_FEATURE_UNSUPPORTED
    assert not sim.paused
    # ~/pause and the standard agree
    pause(ros, sim)
    assert get_state(ros) == SimulationState.STATE_PAUSED


@pytest.mark.parametrize('scope, code, resets', [
    (ResetSimulation.Request.SCOPE_STATE, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_ALL, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_DEFAULT, Result.RESULT_OK, True),
    (ResetSimulation.Request.SCOPE_TIME, Result.RESULT_FEATURE_UNSUPPORTED, False),
    (ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE,
     Result.RESULT_FEATURE_UNSUPPORTED, False),
    (ResetSimulation.Request.SCOPE_SPAWNED, Result.RESULT_FEATURE_UNSUPPORTED, False),
])
def test_reset_scopes(ros, scope, code, resets):
    """State resets put the bodies back at x0 + (0, 0.1, 0.2) m; sim time never goes back (the
    shared /clock), so a scope asking for it is refused and changes nothing."""
    sim = ros.sim(initial_position=1.0)
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 500)
    moved = sim.state.x.copy()
    assert not np.allclose(moved, [1.0, 1.1, 1.2])
    got = ros.call(ResetSimulation, NS + 'reset_simulation',
                   ResetSimulation.Request(scope=scope)).result
    assert got.result == code, got.error_message
    assert sim.sim_time_ns == 500 * TICK
    if resets:
        np.testing.assert_allclose(sim.state.x, [1.0, 1.1, 1.2], atol=1e-15)
    else:
        assert 'SCOPE_TIME' in got.error_message or 'spawned' in got.error_message
        np.testing.assert_array_equal(sim.state.x, moved)


def test_entities_are_the_bodies_with_the_published_state(ros):
    sim = ros.sim(initial_position=1.0)
    states = ros.listen(JointState, 'body_states')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 250)                                 # ends on a publish tick (every 10)
    ros.until(lambda: states and ns_from_stamp(states[-1].header.stamp) == 250 * TICK,
              'the state at 250 ms')
    published = states[-1]

    got = ros.call(GetEntities, NS + 'get_entities', GetEntities.Request())
    assert got.result.result == Result.RESULT_OK
    assert list(got.entities) == ['body_0', 'body_1', 'body_2'] == list(published.name)
    req = GetEntities.Request()
    req.filters.filter = 'body_[12]$'
    assert list(ros.call(GetEntities, NS + 'get_entities', req).entities) == ['body_1', 'body_2']

    all_states = ros.call(GetEntitiesStates, NS + 'get_entities_states',
                          GetEntitiesStates.Request())
    assert all_states.result.result == Result.RESULT_OK
    assert [s.pose.position.x for s in all_states.states] == list(published.position)
    assert [s.twist.linear.x for s in all_states.states] == list(published.velocity)
    for s in all_states.states:
        assert ns_from_stamp(s.header.stamp) == 250 * TICK and s.header.frame_id == 'odom'
        assert (s.pose.position.y, s.pose.position.z, s.pose.orientation.w) == (0.0, 0.0, 1.0)

    one = ros.call(GetEntityState, NS + 'get_entity_state', GetEntityState.Request(entity='body_1'))
    assert one.result.result == Result.RESULT_OK
    assert one.state.pose.position.x == published.position[1]
    missing = ros.call(GetEntityState, NS + 'get_entity_state',
                       GetEntityState.Request(entity='body_3'))
    assert missing.result.result == Result.RESULT_NOT_FOUND and 'body_3' in \
        missing.result.error_message

    # a sphere around body_0 (radius 0.05 m: body_1 is ~0.1 m away) selects body_0 only
    req = GetEntitiesStates.Request()
    req.filters.bounds = Bounds(type=Bounds.TYPE_SPHERE,
                                points=[Vector3(x=published.position[0]), Vector3(x=0.05)])
    assert list(ros.call(GetEntitiesStates, NS + 'get_entities_states', req).entities) == \
        ['body_0']
    req.filters.bounds = Bounds(type=Bounds.TYPE_BOX, points=[Vector3(), Vector3(x=1.0)])
    assert ros.call(GetEntitiesStates, NS + 'get_entities_states', req).result.result == \
        Result.RESULT_FEATURE_UNSUPPORTED
    req = GetEntities.Request()
    req.filters.categories = [EntityCategory(category=EntityCategory.CATEGORY_ROBOT)]
    assert ros.call(GetEntities, NS + 'get_entities', req).result.result == \
        Result.RESULT_FEATURE_UNSUPPORTED
    req = GetEntities.Request()
    req.filters.filter = 'body_[('
    bad = ros.call(GetEntities, NS + 'get_entities', req).result
    assert bad.result == Result.RESULT_OPERATION_FAILED and 'filters.filter' in bad.error_message


def test_set_entity_state_refuses_what_imposed_lengths_forbid(ros):
    sim = ros.sim(initial_position=1.0)
    ticks(sim, 10)
    before = sim.state.x.copy()

    def set_(entity='body_1', x=1.1, y=0.0, w=1.0, vx=0.0):
        req = SetEntityState.Request(entity=entity)
        req.state.pose.position.x, req.state.pose.position.y = x, y
        req.state.pose.orientation.w = w
        req.state.twist.linear.x = vx
        return ros.call(SetEntityState, NS + 'set_entity_state', req).result

    assert set_().result == Result.RESULT_OK                      # the current state: no change
    moved = set_(x=1.3)
    assert moved.result == Result.RESULT_OPERATION_FAILED
    assert 'imposed' in moved.error_message and 'body_1' in moved.error_message
    assert set_(vx=0.5).result == Result.RESULT_OPERATION_FAILED
    assert set_(y=0.2).result == SetEntityState.Response.INVALID_POSE
    assert set_(w=0.0).result == SetEntityState.Response.INVALID_POSE
    assert set_(entity='wheel').result == Result.RESULT_NOT_FOUND
    np.testing.assert_array_equal(sim.state.x, before)


def _send_goal(ros, client, steps: int, feedback: list):
    ros.until(client.server_is_ready, 'the simulate_steps action server')
    sent = client.send_goal_async(SimulateSteps.Goal(steps=steps),
                                  feedback_callback=lambda fb: feedback.append(fb.feedback))
    ros.until(sent.done, 'the goal response')
    handle = sent.result()
    assert handle.accepted
    return handle


def test_simulate_steps_gives_feedback_each_step_and_ends_paused(ros):
    sim = ros.sim(publish_clock=True)
    clocks = ros.listen(Clock, '/clock')
    ticks(sim, 10)
    pause(ros, sim)
    client = ActionClient(ros.obs, SimulateSteps, NS + 'simulate_steps')
    # the feedback topic read directly, keeping the whole burst: rclpy's ActionClient takes one
    # message per executor turn and drops the rest once the goal has ended
    feedback: list = []
    ros.obs.create_subscription(SimulateSteps.Impl.FeedbackMessage,
                                NS + 'simulate_steps/_action/feedback',
                                lambda m: feedback.append(m.feedback), QoSProfile(depth=100))
    handle = _send_goal(ros, client, 25, [])
    result = handle.get_result_async()
    ros.until(result.done, 'the result')
    assert result.result().status == GoalStatus.STATUS_SUCCEEDED
    assert result.result().result.result.result == Result.RESULT_OK
    assert sim.sim_time_ns == 35 * TICK and sim.paused
    ros.until(lambda: len(feedback) == 25, f'a feedback per step (got {len(feedback)})')
    assert [(f.completed_steps, f.remaining_steps) for f in feedback] == \
        [(k, 25 - k) for k in range(1, 26)]
    ros.until(lambda: ns_from_stamp(clocks[-1].clock) == 35 * TICK, '/clock at the last step')


def test_simulate_steps_can_be_cancelled_and_is_refused_while_playing(ros):
    sim = ros.sim()
    client = ActionClient(ros.obs, SimulateSteps, NS + 'simulate_steps')
    refused = _send_goal(ros, client, 5, [])
    result = refused.get_result_async()
    ros.until(result.done, 'the refusal')
    assert result.result().status == GoalStatus.STATUS_ABORTED
    assert result.result().result.result.result == Result.RESULT_OPERATION_FAILED
    assert sim.sim_time_ns == 0

    pause(ros, sim)
    feedback: list = []
    handle = _send_goal(ros, client, 10**9, feedback)
    ros.until(lambda: len(feedback) >= 20, 'some steps')
    cancel = handle.cancel_goal_async()
    ros.until(cancel.done, 'the cancel response')
    result = handle.get_result_async()
    ros.until(result.done, 'the result')
    assert result.result().status == GoalStatus.STATUS_CANCELED
    done_steps = sim.sim_time_ns // TICK
    assert 20 <= done_steps < 10**9
    assert f'{done_steps} of {10**9} steps' in result.result().result.result.error_message
    assert sim.paused


def test_without_the_package_the_node_starts_without_the_services(ros, monkeypatch):
    """A plain pip install has no simulation_interfaces: sim_node runs, without them."""
    for name in [m for m in sys.modules if m.startswith('simulation_interfaces')]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, 'simulation_interfaces', None)   # import fails
    sim = ros.sim()
    assert sim.standard is None
    ticks(sim, 10)
    assert sim.sim_time_ns == 10 * TICK
    names = [n for n, _ in ros.obs.get_service_names_and_types_by_node(sim.get_name(), '/')]
    assert NS + 'reset' in names and NS + 'step_simulation' not in names


def test_the_installed_sim_node_process_answers_every_service_and_the_action(ament_env, peer,
                                                                            tmp_path):
    """The colcon-installed executable in its own process (the interface packages found as
    `make build` leaves them): every service answers, step_simulation(50) moves /clock by
    exactly 50 ticks, the action runs."""
    from test.support.ros import Proc
    sim = Proc(tmp_path, ament_env, 'sim_node', '-p', 'start_paused:=true')
    try:
        clocks = []
        peer.node.create_subscription(Clock, '/clock', clocks.append, 100)
        peer.until(lambda: clocks, 'the /clock of the paused sim')
        t0 = ns_from_stamp(clocks[-1].clock)
        requests = {'get_simulator_features': GetSimulatorFeatures.Request(),
                    'get_simulation_state': GetSimulationState.Request(),
                    'set_simulation_state': SetSimulationState.Request(
                        state=SimulationState(state=SimulationState.STATE_PAUSED)),
                    'reset_simulation': ResetSimulation.Request(
                        scope=ResetSimulation.Request.SCOPE_STATE),
                    'get_entities': GetEntities.Request(),
                    'get_entity_state': GetEntityState.Request(entity='body_0'),
                    'get_entities_states': GetEntitiesStates.Request(),
                    'set_entity_state': SetEntityState.Request(entity='nothing')}
        types = {'get_simulator_features': GetSimulatorFeatures,
                 'get_simulation_state': GetSimulationState,
                 'set_simulation_state': SetSimulationState, 'reset_simulation': ResetSimulation,
                 'get_entities': GetEntities, 'get_entity_state': GetEntityState,
                 'get_entities_states': GetEntitiesStates, 'set_entity_state': SetEntityState}
        answers = {name: peer.call(types[name], NS + name, req) for name, req in requests.items()}
        assert len(answers['get_simulator_features'].features.features) == len(NEEDS)
        assert answers['get_simulation_state'].state.state == SimulationState.STATE_PAUSED
        assert answers['set_simulation_state'].result.result == \
            SetSimulationState.Response.ALREADY_IN_TARGET_STATE
        assert answers['get_entities'].entities == ['body_0', 'body_1']       # the seed
        assert answers['set_entity_state'].result.result == Result.RESULT_NOT_FOUND
        assert all(a.result.result == Result.RESULT_OK for name, a in answers.items()
                   if name in ('reset_simulation', 'get_entity_state', 'get_entities_states'))

        got = peer.call(StepSimulation, NS + 'step_simulation', StepSimulation.Request(steps=50),
                        attempts=1).result
        assert got.result == Result.RESULT_OK, got.error_message
        peer.until(lambda: ns_from_stamp(clocks[-1].clock) == t0 + 50 * TICK, '/clock + 50 ticks')

        client = ActionClient(peer.node, SimulateSteps, NS + 'simulate_steps')
        handle = _send_goal(peer, client, 5, [])
        result = handle.get_result_async()
        peer.until(result.done, 'the action result')
        assert result.result().status == GoalStatus.STATUS_SUCCEEDED
        peer.until(lambda: ns_from_stamp(clocks[-1].clock) == t0 + 55 * TICK, '/clock + 5 more')
    finally:
        code, err = sim.stop()
    assert code == 0, err


#: RIHS01 hashes of the standard's own definitions (ros-simulation/simulation_interfaces, branch
#: jazzy, 1.5.1: its .msg/.srv/.action files built with the same rosidl generators, 2026-11-28):
#: the installed package, ours or the real one, must have the same type hashes to talk with
#: clients built against the real package
STANDARD_HASHES = {
    'action/SimulateSteps': 'f0837c898e1219cd73bf4c041feab41e8c533e8e1057e982744dba7b093467eb',
    'msg/Bounds': 'e8624fe51f0f5548197542697d924c5699ac7198f1e4c68e50c3ca2af73f5b3f',
    'msg/EntityCategory': '43bdf7933fddf75f6970f7a8fe7078524355d821d390b3954bb46ac36c03dfe1',
    'msg/EntityFilters': '8e7b12e8ea062f14c55de4877221fe1b7cd9749665a7ad8a4ab855fc4b148303',
    'msg/EntityState': '2e0464a85eb80a939025075d6c20761eca6a4cb9d6baf2c0ba373467c8b598d0',
    'msg/Result': 'cf43a306adff3337a0a47143d8f5689933bc70a30478f13b077dc1fe3bc5ad17',
    'msg/SimulationState': 'bb9f87ccdd98fba113052a512d9801e84ce732d0a2b3c2b0cb281828de36e415',
    'msg/SimulatorFeatures': '8b101c8529bc0ea3dcf056078254768f39832b9ef0adaf93bd5cea96c0de3305',
    'msg/TagsFilter': '5c3efc51e8ed04c266c09cb4691ec95b964cd410558e01d8c83646b038826b45',
    'srv/GetEntities': 'cb90004c48cd50f37732fb008e22c34c261dd680a723bf0f85d8437ea4498bf7',
    'srv/GetEntitiesStates': '0a76170d0c1c90e1eaf805cfab78ea801d1f82df309a28c1f0fae4b570f19754',
    'srv/GetEntityState': '749c91f2a2353d98367b64f2995a0f5842ce92a08ec1ffb3e185540a91557fb5',
    'srv/GetSimulationState': '3362dcebee4b1afebbf9c4beee5c79c1455385aded62092a892d61fde8644f30',
    'srv/GetSimulatorFeatures': 'abb9439c8cf196722a469fb6c68b44b484f198c2a1356ac38849a29c2a20a794',
    'srv/ResetSimulation': '4ce285d7ff9b8ac70dcc95161f32bf54c05a6f4b13427990e41ab40c36c39646',
    'srv/SetEntityState': 'ca210e7d2b66629ae133c8e1edf5246e618106d75c78ed0556c0e7a33c59ee5e',
    'srv/SetSimulationState': 'a868b916dce49974f637ba252141258c4b07b0c06858b88af560e3eb6bfbcb30',
    'srv/StepSimulation': '913fe0653690ce6bf8f09f316e6a626747012e9fca31e26719910d417aa8565c',
}


@pytest.mark.parametrize('name', sorted(STANDARD_HASHES))
def test_the_installed_types_have_the_standards_hashes(name):
    share = Path(get_package_share_directory('simulation_interfaces'))
    hashes = {h['type_name']: h['hash_string']
              for h in json.loads((share / f'{name}.json').read_text())['type_hashes']}
    assert hashes[f'simulation_interfaces/{name}'] == 'RIHS01_' + STANDARD_HASHES[name]


def test_a_session_with_steps_replays_with_zero_difference(ros, tmp_path):
    """Steps while paused (ending on and off the publish grid, by the service and the action)
    are ticks like any other: the recorded bag replays bit for bit (``crawler-sim replay``
    runs the plant again from the recorded inputs; expected: the recorded states)."""
    from crawler_sim import bag
    from crawler_sim.cli import _replay
    sim = ros.sim(record=True, record_dir=str(tmp_path), record_name='stepped')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 30)
    pause(ros, sim)
    assert step(ros, 7).result == Result.RESULT_OK                   # ends off the grid
    ros.send(pub, cmd(0.05, 0.2), sim, 'commands_accepted')          # taken at the next step
    assert step(ros, 13).result == Result.RESULT_OK                  # back on the grid
    client = ActionClient(ros.obs, SimulateSteps, NS + 'simulate_steps')
    result = _send_goal(ros, client, 26, []).get_result_async()
    ros.until(result.done, 'the action result')
    assert sim.sim_time_ns == 76 * TICK
    assert set_state(ros, SimulationState.STATE_PLAYING).result == Result.RESULT_OK
    ticks(sim, 124)
    sim.close()
    run = bag.load(sim.bag_path)
    res = _replay(run, None, 0.0)
    assert res['max_position_error'] == 0.0 and res['max_velocity_error'] == 0.0, res
    assert res['match']
