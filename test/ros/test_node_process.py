"""The colcon-built executables, found through the ament index, each run as its own process.

Real DDS between processes on this host, in the session's ROS_DOMAIN_ID (conftest.py). Every
wait has a deadline; nothing sleeps for a fixed time.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
import warnings

from ament_index_python.packages import get_package_prefix, get_package_share_directory
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
import numpy as np
import pytest
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool

from crawler_sim import Stepper
from crawler_sim.core.actuator import Actuator
from crawler_sim.core.gaits import Cubic
from crawler_sim.ros.messages import ns_from_stamp
from crawler_sim.ros.sim_node import PARAMETERS, SimConfig
from test.support.ros import (PROCESS_DEADLINE, PROCESS_THREE_BODY, Peer, Proc,  # noqa: F401
                              config_file, diagnostics_values, executable, sim_args)

def test_the_package_is_registered_in_the_ament_index_with_its_executables(ament_env,
                                                                         colcon_install):
    prefix = Path(get_package_prefix('crawler_sim'))
    assert prefix == colcon_install / 'crawler_sim'
    for name in ('sim_node', 'gait_node'):
        assert executable(name).parent == prefix / 'lib' / 'crawler_sim'
    share = Path(get_package_share_directory('crawler_sim'))
    assert (share / 'package.xml').is_file()
    for name in ('ros/crawler_sim.yaml', 'ros/chain_3body.yaml', 'scenes/scallop_2body.yaml',
                 'viz/crawler_sim.rviz', 'viz/crawler_sim.foxglove.json'):
        assert (share / 'config' / name).is_file(), name
    assert (share / 'launch' / 'crawler_sim.launch.py').is_file()
    # `crawler-sim` on PATH once the workspace is sourced: colcon puts <prefix>/bin on PATH
    tool = prefix / 'bin' / 'crawler-sim'
    assert os.access(tool, os.X_OK)
    proc = subprocess.run([str(tool), '--help'], env=ament_env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0 and 'simulate' in proc.stdout, proc.stderr


@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_the_sim_process_matches_the_offline_solution_and_runs_faster_than_real_time(
        ament_env, peer, tmp_path, method):
    sim = Proc(tmp_path, ament_env, 'sim_node', *sim_args(method))
    try:
        node = peer.node
        states: list[JointState] = []
        applied: list[JointState] = []
        diags: list[DiagnosticArray] = []
        clock_wall: list[tuple[int, float]] = []
        node.create_subscription(JointState, 'body_states', states.append, 100000)
        sensor: list[JointState] = []
        node.create_subscription(JointState, 'body_states', sensor.append,
                                 qos_profile_sensor_data)
        node.create_subscription(JointState, '/crawler_sim/applied_command', applied.append, 100)
        node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
        node.create_subscription(Clock, '/clock', lambda m: clock_wall.append(
            (ns_from_stamp(m.clock), time.monotonic())), qos_profile_sensor_data)
        pub = node.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
        peer.until(lambda: pub.get_subscription_count() > 0 and diags and int(
            diagnostics_values(diags[-1])['clock_subscribers']) >= 1, 'the sim to connect')
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success

        plan = [  # (sim time [s] after which to act, action)
            (0.5, [0.15, 0.12]),
            (2.0, [0.15]),                        # wrong size: rejected
            (2.2, [0.06, math.nan]),              # NaN: rejected
            (2.4, [0.06, 0.9]),                   # out of range: rejected
            (4.0, [0.06, 0.16]),
            (6.5, [0.12, 0.07]),
        ]
        bad_param = None
        now_ns = lambda: clock_wall[-1][0] if clock_wall else 0  # noqa: E731
        for t_act, data in plan:
            peer.until(lambda: now_ns() >= t_act * 1e9, f'sim time {t_act} s')
            n_applied = len(applied)
            pub.publish(Float64MultiArray(data=[float(x) for x in data]))
            if t_act in (0.5, 4.0, 6.5):
                # a valid command: wait for its echo, else a late peer could send the next one
                # before a tick took this one (the latest command wins, as in ros2_control)
                peer.until(lambda: len(applied) > n_applied, 'the applied command')
            if t_act == 2.4:   # a rejected parameter set, sent through the ROS service
                friction = ParameterMsg(name='friction', value=ParameterValue(
                    type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[1.0, 2.0]))
                bad_param = peer.call(SetParameters, '/crawler_sim/set_parameters',
                                      SetParameters.Request(parameters=[friction]))
        peer.until(lambda: now_ns() >= 10e9, 'sim time 10 s', timeout=60.0)
        # let the body states catch up (a busy peer lags behind the flat-out sim)
        peer.until(lambda: states and ns_from_stamp(states[-1].header.stamp) > 10e9,
                   'body states past 10 s', timeout=60.0)
        t_start = clock_wall[0][1]
        t_ten = next(w for t, w in clock_wall if t >= 10e9)
        # a report made after the tick that applied the last command, so it counts every
        # command: flat out the sim is past 10 s long before the peer sends the last ones, and
        # a report from before their tick (received before their echoes) counts fewer
        last_applied_ns = max(ns_from_stamp(m.header.stamp) for m in applied)
        peer.until(lambda: len(diags) >= 2 and ns_from_stamp(diags[-1].header.stamp) > max(
            last_applied_ns, 10_000_000_000), 'diagnostics after the last command and 10 s')
        code, err = sim.stop(signal.SIGINT)
    finally:
        sim.kill()

    assert code == 0 and 'Traceback' not in err, err
    # speed is a benchmark figure (benchmarks/node.py), not a test assertion
    print(f'\n{method}: 10 sim s in {t_ten - t_start:.2f} wall s')

    assert not bad_param.results[0].successful
    assert 'friction: must have 1 or 3 entries' in bad_param.results[0].reason
    values = diagnostics_values(diags[-1])
    assert (values['commands_accepted'], values['commands_rejected']) == ('3', '3'), values
    assert sensor, 'the SensorData subscriber received nothing'

    # offline: the same commands at the same ticks through the same actuator and the core
    schedule = {ns_from_stamp(m.header.stamp): list(m.position) for m in applied}
    assert len(schedule) == 3
    assert [v for _, v in sorted(schedule.items())] == [[0.15, 0.12], [0.06, 0.16], [0.12, 0.07]]
    values = {k: v[0] for k, v in PARAMETERS.items()}
    values.update(PROCESS_THREE_BODY, method=method)
    cfg = SimConfig.from_values(values)
    dt_ns = cfg.dt_ns
    act = Actuator(cfg.initial_lengths, dt_ns / 1e9, cfg.limits)
    st = Stepper(cfg.crawler, Cubic(0.0, list(cfg.initial_lengths), 0.0, 0.0, 0.0), method,
                 t0=0.0, x0=cfg.initial_position, v0=0.0, dt=dt_ns / 1e9)
    published = {ns_from_stamp(m.header.stamp): m for m in states
                 if ns_from_stamp(m.header.stamp) <= 10_000_000_000}
    # 100 Hz for 10 s. Flat out (~25x real time) a Python subscriber that also takes every
    # /clock message can fall behind on a busy machine and lose some (the publisher keeps the
    # last 10): what matters is that those received match and cover the whole run.
    assert len(published) > 300
    assert {t // 1_000_000_000 for t in published} >= set(range(10))
    worst = 0.0
    moved = 0.0
    for k in range(10_000):
        t0_ns = k * dt_ns
        if t0_ns in schedule:
            act.set_target(schedule[t0_ns])
        st.advance((t0_ns + dt_ns) / 1e9, act.step(t0_ns / 1e9, (t0_ns + dt_ns) / 1e9))
        msg = published.get(t0_ns + dt_ns)
        if msg is not None:
            s = st.state
            for got, want in ((msg.position, s.x), (msg.velocity, s.v), (msg.effort, s.friction)):
                worst = max(worst, float(np.max(np.abs(np.asarray(got) - want))))
            moved = max(moved, float(np.max(np.abs(s.x - [0.0, 0.1, 0.2]))))
    assert moved > 0.01                  # the commands did move the bodies
    assert worst <= 1e-9, f'published states differ from the offline solution by {worst}'


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_sim_node_exits_cleanly_on_a_signal_and_closes_its_bag(ament_env, peer, tmp_path, sig):
    sim = Proc(tmp_path, ament_env, 'sim_node', '-p', 'method:=implicit', '-p', 'record:=true',
               '-p', f'record_dir:={tmp_path}', '-p', 'record_name:=bag')
    try:
        states: list[JointState] = []
        peer.node.create_subscription(JointState, 'body_states', states.append, 10)
        peer.until(lambda: states, 'body_states from the process')   # it runs
        code, err = sim.stop(sig)
    finally:
        sim.kill()
    assert code == 0, err
    assert 'Traceback' not in err and 'Error' not in err, err
    bag = pytest.importorskip('crawler_sim.bag')
    assert (tmp_path / 'bag' / 'metadata.yaml').is_file()      # written only by close()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        run = bag.load(tmp_path / 'bag')
    assert not [w for w in caught if 'footer' in str(w.message)]   # the file was finished
    assert len(run) > 0 and run.t[0] == 0.0


def test_invalid_parameters_at_start_give_one_line_and_exit_code_1(ament_env, tmp_path):
    sim = Proc(tmp_path, ament_env, 'sim_node', '-p', 'friction:=[1.0, 2.0, 3.0]')
    try:
        code = sim.popen.wait(timeout=PROCESS_DEADLINE)
    finally:
        sim.kill()
    sim.err.seek(0)
    err = sim.err.read()
    assert code == 1
    assert 'friction: must have 1 or 2 entries' in err and 'Traceback' not in err


def test_a_scene_file_as_params_file_gives_one_clear_line_and_exit_code_2(ament_env,
                                                                          tmp_path):
    scene = config_file().parents[1] / 'scenes' / 'scallop_2body.yaml'
    sim = Proc(tmp_path, ament_env, 'sim_node', '--params-file', str(scene))
    try:
        code = sim.popen.wait(timeout=PROCESS_DEADLINE)
    finally:
        sim.kill()
    sim.err.seek(0)
    err = sim.err.read()
    assert code == 2, err
    assert 'is not a ROS 2 parameter file' in err and 'scene file' in err
    assert 'Traceback' not in err and 'rcl' not in err.replace('crawler_sim', '')


def test_gait_node_drives_the_sim_on_sim_time(ament_env, peer, tmp_path):
    # paced at 4x real time, not flat out: a sim-time controller in Python gets fewer turns per
    # sim second the faster the sim runs, and on a busy CI machine flat out can starve it
    sim = Proc(tmp_path, ament_env, 'sim_node', *sim_args('implicit', '-p',
                                                           'real_time_factor:=4.0',
                                                           three_body=False))
    gait = Proc(tmp_path, ament_env, 'gait_node', '-p', 'use_sim_time:=true')
    try:
        diags: list[DiagnosticArray] = []
        states: list[JointState] = []
        peer.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
        peer.node.create_subscription(JointState, 'body_states', states.append, 100000)
        peer.until(lambda: diags and int(
            diagnostics_values(diags[-1])['linkage_cmd_publishers']) >= 1 and int(
            diagnostics_values(diags[-1])['clock_subscribers']) >= 1, 'gait_node to connect')
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success
        peer.until(lambda: states and ns_from_stamp(states[-1].header.stamp) >= 6e9,
                   'sim time 6 s', timeout=60.0)
        peer.until(lambda: float(diagnostics_values(diags[-1])['sim_time']) >= 6.0,
                   'diagnostics at 6 s')
        codes = [gait.stop(signal.SIGINT), sim.stop(signal.SIGINT)]
    finally:
        gait.kill()
        sim.kill()
    for code, err in codes:
        assert code == 0 and 'Traceback' not in err, err
    values = diagnostics_values(diags[-1])
    # 50 Hz of sim time for 6 s is 300 commands; some are lost to start-up and latency
    assert int(values['commands_accepted']) > 100 and values['commands_rejected'] == '0'
    # the seed's two bodies: one linkage, its length = x_1 - x_0
    lengths = np.array([np.diff(m.position) for m in states])
    assert lengths.shape[1] == 1
    assert lengths.max() - lengths.min() > 0.03          # the stroke is played (2 x 0.02 m)
    x = np.array([m.position for m in states])
    assert np.ptp(x, axis=0).min() > 5e-3                  # and every body moves


def test_the_demo_crawls_the_same_every_time_in_the_users_domain(ament_env, tmp_path):
    # the demo (make run) twice: the gait is preloaded as one trajectory into the paused sim, so
    # both runs get the same command stream at the same ticks and record the same states
    from crawler_sim import bag
    env = dict(ament_env, ROS_DOMAIN_ID=os.environ['ROS_DOMAIN_ID'], MPLBACKEND='Agg')
    runs = []
    for k in range(2):
        out = tmp_path / f'runs{k}'
        proc = subprocess.run([sys.executable, '-m', 'crawler_sim.ros.demo', '--duration', '2',
                               '--runs', str(out)], env=env, capture_output=True, text=True,
                              timeout=240)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}' in proc.stdout   # not overridden
        runs.append(bag.load(next(p for p in out.iterdir() if p.is_dir())))
    a, b = runs
    n = min(np.count_nonzero(a.t <= 2.0), np.count_nonzero(b.t <= 2.0))
    assert n > 150
    np.testing.assert_array_equal(a.t[:n], b.t[:n])
    np.testing.assert_array_equal(a.x[:n], b.x[:n])
    assert a.x[n - 1, 0] - a.x[0, 0] > 1e-3          # and it crawls forward


def _run_to_exit(proc: Proc) -> tuple[int, str]:
    try:
        code = proc.popen.wait(timeout=PROCESS_DEADLINE)
    finally:
        proc.kill()
    proc.err.seek(0)
    return code, proc.err.read()


@pytest.mark.parametrize('args,code,line', [
    (['-p', 'gait:=scalop'], 1, "gait must be one of scallop, sinusoid, got 'scalop'"),
    (['-p', 'n_links:=-2'], 1, 'n_links must be in [0, 63], got -2'),
    (['-p', 'amplitude:=-1.0'], 1, 'amplitude must be in [0, 100] m, got -1.0'),
    (['-p', 'amplitude:=abc'], 1, "amplitude must be a number in [0, 100] m, got 'abc'"),
    (['-p', 'frequncy:=1.0', '-p', 'n_links:=1'], 1,
     'frequncy is not a parameter of gait_node (did you mean frequency?)'),
    (['-p', 'mode:=trajectory', '-p', 'preload:=true'], 1,
     'preload needs mode trajectory and a duration > 0'),
    # 1.5 M points (1.7 GB) that sim_node would refuse; 1e9 s died allocating 373 GiB
    (['-p', 'n_links:=1', '-p', 'mode:=trajectory', '-p', 'preload:=true', '-p',
      'duration:=30000.0'], 1, 'makes 1500002 points per trajectory, more than sim_node takes'),
    (['-p', 'n_links:=1', '-p', 'mode:=trajectory', '-p', 'preload:=true', '-p',
      'duration:=1e9'], 1, 'more than sim_node takes (1000000)'),
    (['-r', '__ns:=/bad-name'], 2, "invalid ROS arguments: Couldn't parse remap rule"),
])
def test_gait_node_names_a_bad_parameter_in_one_line(ament_env, tmp_path, args, code, line):
    got, err = _run_to_exit(Proc(tmp_path, ament_env, 'gait_node', *args))
    assert got == code, err
    assert line in err and 'Traceback' not in err
    assert len([ln for ln in err.splitlines() if 'cannot start' in ln]) == 1


@pytest.mark.parametrize('name', ['gait_node', 'sim_node'])
def test_a_params_file_outside_ros_args_is_reported_not_ignored(ament_env, tmp_path, name):
    """``gait_node --params-file best.yaml`` (``--ros-args`` forgotten): rclpy would hand the
    arguments to the program, which ignores them and plays its defaults."""
    params = tmp_path / 'p.yaml'
    params.write_text('gait_node:\n  ros__parameters:\n    frequency: 1.0\n')
    proc = Proc(tmp_path, ament_env, name)
    proc.popen.kill()
    proc.popen.wait()
    proc.popen = subprocess.Popen([str(executable(name)), '--params-file', str(params)],
                                  env=ament_env, stdout=proc.out, stderr=proc.err)
    got, err = _run_to_exit(proc)
    assert got == 2, err
    assert 'ROS arguments go after --ros-args' in err and 'Traceback' not in err


def test_a_misspelt_sim_node_parameter_is_reported(ament_env, tmp_path):
    got, err = _run_to_exit(Proc(tmp_path, ament_env, 'sim_node', '-p', 'masess:=[1.0, 2.0]'))
    assert got == 1, err
    assert 'masess is not a parameter of crawler_sim (did you mean masses?)' in err


def test_gait_node_takes_the_number_of_linkages_from_the_running_sim(ament_env, peer,
                                                                      tmp_path):
    """No n_links: gait_node asks the sim (three bodies, two linkages) and sends two lengths,
    which the sim accepts (a single length would be rejected: 'expected 2 lengths')."""
    sim = Proc(tmp_path, ament_env, 'sim_node', '--params-file',
               str(config_file('chain_3body.yaml')), '-p', 'real_time_factor:=4.0',
               '-p', 'diagnostics_period:=0.2', '-p', 'publish_markers:=false')
    gait = Proc(tmp_path, ament_env, 'gait_node', '-p', 'use_sim_time:=true')
    try:
        diags: list[DiagnosticArray] = []
        peer.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
        peer.until(lambda: diags and int(
            diagnostics_values(diags[-1])['commands_accepted']) > 20, 'commands from gait_node',
            timeout=60.0)
        codes = [gait.stop(signal.SIGINT), sim.stop(signal.SIGINT)]
    finally:
        gait.kill()
        sim.kill()
    for code, err in codes:
        assert code == 0 and 'Traceback' not in err, err
    assert '2 linkage(s)' in codes[0][1] or '2 linkage(s)' in open(tmp_path /
                                                                   'gait_node.out').read()
    assert diagnostics_values(diags[-1])['commands_rejected'] == '0'


def test_an_optimised_stroke_crawls_live_as_predicted_and_its_bag_replays_exactly(
        ament_env, peer, tmp_path):
    """The chain of the docs over real DDS (issue 24): ``crawler-sim optimize`` -> the two files
    it writes -> sim_node and gait_node started exactly as their headers say (plus recording,
    flat out) -> the bag -> ``crawler-sim replay``. The measured steady speed (centre of mass
    over the second half of 12 periods after the sim took the trajectory) must be within 1 %
    of the printed prediction, and the replay must match bit for bit."""
    import json
    from crawler_sim import bag
    from crawler_sim.bag.inputs import load_inputs
    from crawler_sim.core.scene import load_scene
    from crawler_sim.sweep.metrics import window_speed
    repo = Path(__file__).resolve().parents[2]
    out = tmp_path / 'best_gait.yaml'
    opt = subprocess.run([sys.executable, '-m', 'crawler_sim.cli', 'optimize',
                          str(repo / 'config' / 'scenes' / 'scallop_2body.yaml'),
                          '--maxiter', '2', '--popsize', '3', '-o', str(out), '--json'],
                         capture_output=True, text=True, env=ament_env, timeout=600)
    assert opt.returncode == 0, opt.stderr
    predicted = json.loads(opt.stdout)['best']['mean_speed']
    header = out.read_text().splitlines()
    assert any('--params-file best_gait_sim.yaml' in ln for ln in header)
    period = load_scene(tmp_path / 'best_gait_scene.yaml').gait.period
    sim = Proc(tmp_path, ament_env, 'sim_node', '--params-file', str(tmp_path /
                                                                     'best_gait_sim.yaml'),
               '-p', 'record:=true', '-p', f'record_dir:={tmp_path}', '-p', 'record_name:=chain',
               '-p', 'real_time_factor:=0.0', '-p', 'diagnostics_period:=0.2')
    gait = Proc(tmp_path, ament_env, 'gait_node', '--params-file', str(out))
    try:
        diags: list[DiagnosticArray] = []
        peer.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
        peer.until(lambda: diags and int(
            diagnostics_values(diags[-1])['trajectories_accepted']) >= 1, 'the preload',
            timeout=60.0)
        after = float(diagnostics_values(diags[-1])['sim_time'])   # t_a is before this
        goal = after + 13 * period + 1.0
        peer.until(lambda: float(diagnostics_values(diags[-1])['sim_time']) > goal,
                   f'sim time {goal} s', timeout=120.0)
        codes = [gait.stop(signal.SIGINT), sim.stop(signal.SIGINT)]
    finally:
        gait.kill()
        sim.kill()
    for code, err in codes:
        assert code == 0 and 'Traceback' not in err, err
    run = bag.load(tmp_path / 'chain')
    t_a = next(i.t_ns for i in load_inputs(run.path).inputs if i.kind == 'trajectory') / 1e9
    m = np.asarray(run.scene['masses'])
    measured = window_speed(run.t, run.x @ m / m.sum(), t_a + 6 * period, t_a + 12 * period)
    assert abs(measured - predicted) <= 0.01 * abs(predicted), (measured, predicted)
    rep = subprocess.run([sys.executable, '-m', 'crawler_sim.cli', 'replay',
                          str(tmp_path / 'chain')], capture_output=True, text=True,
                         env=ament_env, timeout=600)
    assert rep.returncode == 0, rep.stdout + rep.stderr
    assert 'max |dx|  0 m' in rep.stdout and 'match' in rep.stdout


def test_sim_node_says_when_it_is_ready_and_when_it_pauses_resumes_or_resets(
        ament_env, peer, tmp_path):
    """Issue 26: one INFO line when ready (bodies, method, rates, pacing, clock, recording) and
    one per pause, resume and reset."""
    from std_srvs.srv import Trigger
    sim = Proc(tmp_path, ament_env, 'sim_node', '-p', 'start_paused:=true')

    def log() -> str:
        sim.err.flush()
        return (tmp_path / 'sim_node.err').read_text() + (tmp_path / 'sim_node.out').read_text()
    try:
        peer.until(lambda: 'ready:' in log(), 'the ready line')
        line = next(ln for ln in log().splitlines() if 'ready:' in ln)
        for part in ('2 bodies', '1 linkage(s): linkage_cmd takes 1 length(s)', 'method exact',
                     '1000 Hz ticks', 'outputs every 10 ticks', '1 x real time',
                     '/clock published', 'not recording', 'paused: ~/pause false starts it'):
            assert part in line, (part, line)
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=False)).success
        assert peer.call(Trigger, '/crawler_sim/reset', Trigger.Request()).success
        assert peer.call(SetBool, '/crawler_sim/pause', SetBool.Request(data=True)).success
        peer.until(lambda: all(w in log() for w in ('running at t =', 'reset to rest at t =',
                                                     'paused at t =')), 'the three lines')
        code, err = sim.stop(signal.SIGINT)
    finally:
        sim.kill()
    assert code == 0 and 'Traceback' not in err


@pytest.mark.parametrize('robots', [2, 3])
def test_several_namespaced_sims_share_one_monotonic_clock_and_keep_their_topics_apart(
        ament_env, peer, tmp_path, robots):
    """Issue 26: two crawlers in one domain (-r __ns:=/r1, /r2) both published /clock and 99 of
    507 clock messages went backwards. Started together, one owns /clock, the others follow it:
    every /clock received is >= the one before, each robot's body_states come from its own
    crawler (its own number of bodies), and exactly one node does not say it follows. The last
    one records, and its bag replays bit for bit from the time it joined."""
    from rosgraph_msgs.msg import Clock
    names = [f'r{k + 1}' for k in range(robots)]
    procs = [Proc(tmp_path, ament_env, 'sim_node', '-r', f'__ns:=/{ns}', '-p',
                  f'masses:=[{", ".join(["1.0"] * (k + 2))}]', '-p', 'real_time_factor:=2.0',
                  *(['-p', 'record:=true', '-p', f'record_dir:={tmp_path}', '-p',
                     'record_name:=follower'] if k == robots - 1 else []))
             for k, ns in enumerate(names)]
    clocks: list[int] = []
    states: dict[str, list] = {ns: [] for ns in names}
    peer.node.create_subscription(Clock, '/clock', lambda m: clocks.append(
        m.clock.sec * 1_000_000_000 + m.clock.nanosec), qos_profile_sensor_data)
    for ns in names:
        peer.node.create_subscription(JointState, f'/{ns}/body_states',
                                      states[ns].append, 1000)
    try:
        peer.until(lambda: len(clocks) > 400 and all(len(v) > 100 for v in states.values()),
                   'clock and states from every robot', timeout=60.0)
        codes = [p.stop(signal.SIGINT) for p in reversed(procs)]
    finally:
        for p in procs:
            p.kill()
    for code, err in codes:
        assert code == 0 and 'Traceback' not in err, err
    assert all(b >= a for a, b in zip(clocks, clocks[1:])), 'a /clock message went backwards'
    for k, ns in enumerate(names):
        assert {len(m.position) for m in states[ns]} == {k + 2}     # its own crawler
    errs = [e for _, e in codes]
    followers = sum('this node follows it' in e for e in errs)
    assert followers == robots - 1, errs
    rep = subprocess.run([sys.executable, '-m', 'crawler_sim.cli', 'replay',
                          str(tmp_path / 'follower')], capture_output=True, text=True,
                         env=ament_env, timeout=600)
    assert rep.returncode == 0 and 'max |dx|  0 m' in rep.stdout, rep.stdout + rep.stderr


def test_gait_node_follows_a_change_of_the_number_of_bodies_at_run_time(ament_env, peer,
                                                                         tmp_path):
    """Issue 43: the sim's masses set to three bodies while gait_node (no n_links) plays:
    gait_node's commands get two entries and the sim accepts them (before, it kept sending
    one length, every command rejected)."""
    sim = Proc(tmp_path, ament_env, 'sim_node', '-p', 'real_time_factor:=4.0',
               '-p', 'diagnostics_period:=0.2', '-p', 'publish_markers:=false')
    gait = Proc(tmp_path, ament_env, 'gait_node', '-p', 'use_sim_time:=true')
    try:
        diags: list[DiagnosticArray] = []
        sizes: list[int] = []
        peer.node.create_subscription(DiagnosticArray, '/diagnostics', diags.append, 100)
        peer.node.create_subscription(Float64MultiArray, 'linkage_cmd',
                                      lambda m: sizes.append(len(m.data)), 1000)
        count = lambda key, d: int(diagnostics_values(d)[key])  # noqa: E731
        peer.until(lambda: diags and count('commands_accepted', diags[-1]) > 20 and sizes,
                   'one-length commands from gait_node', timeout=60.0)
        assert sizes[-1] == 1
        masses = ParameterMsg(name='masses', value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[1.0, 1.0, 1.0]))
        reply = peer.call(SetParameters, '/crawler_sim/set_parameters',
                          SetParameters.Request(parameters=[masses]))
        assert reply.results[0].successful, reply.results[0].reason
        peer.until(lambda: sizes[-1] == 2, 'two-length commands from gait_node', timeout=60.0)
        first = len(diags)
        # the sim stops rejecting: a stretch of reports after the switch in which more than
        # 20 commands are accepted and none rejected (a few may be rejected around the change)
        peer.until(lambda: any(
            count('commands_accepted', diags[-1]) - count('commands_accepted', d) > 20
            and count('commands_rejected', diags[-1]) == count('commands_rejected', d)
            for d in diags[first:-1]), 'accepted two-length commands', timeout=60.0)
        codes = [gait.stop(signal.SIGINT), sim.stop(signal.SIGINT)]
    finally:
        gait.kill()
        sim.kill()
    for code, err in codes:
        assert code == 0 and 'Traceback' not in err, err
    assert set(sizes[sizes.index(2):]) == {2}         # never back to one length


@pytest.mark.parametrize('name,node,param', [('sim_node', 'crawler_sim', 'masses'),
                                             ('gait_node', 'gait_node', 'n_links'),
                                             ('replay_node', 'replay_node', 'bag')])
def test_help_prints_the_parameters_and_exits_0_before_ros_starts(ament_env, name, node,
                                                                   param):
    """Issue 43: ``sim_node --help`` was refused (exit 2, an argument outside --ros-args).
    It is answered before rclpy.init: a remap rule rcl would refuse does not matter."""
    proc = subprocess.run([str(executable(name)), '--help', '--ros-args', '-r',
                           '__ns:=/bad-name'], env=ament_env, capture_output=True, text=True,
                          timeout=PROCESS_DEADLINE * 3)
    assert proc.returncode == 0 and proc.stderr == '', proc.stderr
    assert proc.stdout.startswith(f'usage: {name} [-h]')
    assert f'Parameters of node {node} ' in proc.stdout
    assert f'\nParameter name: {param}\n  Type: ' in proc.stdout
