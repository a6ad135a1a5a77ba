"""Random recorded sim_node sessions, for the replay floor (issue 24): a real SimNode in-process
on real DDS (its own context, discovery off), driven by a random mix of every plant input.

A session: a random crawler (p = 2..4, friction by coefficients or forces, a slope sometimes)
and method, recording on; then, between runs of ticks, random actions: commands and
trajectories (stamped 0 or absolute; positions only, with velocities, with accelerations;
empty) published on the node's topics, rejected commands, parameter changes (p, friction,
method, actuator limits, tick and publish rates), pauses and resumes through the ``~/pause``
service, resets through ``~/reset``, and reads of the state between publish ticks (an
integration cut off the grid). ``run_session`` returns the bag's path.

    PYTHONPATH=. python test/ros/sessions.py   # see benchmarks/replay_sessions.py for the floor
"""
from __future__ import annotations

import os
from pathlib import Path

from builtin_interfaces.msg import Duration
import numpy as np
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.ros.sim_node import SimNode

ACTIONS = ('command', 'command', 'trajectory', 'trajectory', 'bad_command', 'parameters',
           'pause', 'reset', 'peek', 'empty_trajectory')


def _points(rng: np.random.Generator, n_links: int, lo: float, hi: float) -> list:
    n = int(rng.integers(1, 30))
    times = np.cumsum(rng.uniform(0.005, 0.2, n))
    mid = rng.uniform(lo + 0.02, hi - 0.02, n_links)
    amp = rng.uniform(0.0, 0.015, n_links)
    w = rng.uniform(2.0, 20.0)
    order = int(rng.choice([1, 3, 5]))
    pts = []
    for k, t in enumerate(times):
        pos = mid + amp * np.sin(w * t + np.arange(n_links))
        pt = JointTrajectoryPoint(positions=pos.tolist())
        last = k == n - 1
        if order >= 3:
            pt.velocities = ([0.0] * n_links if last else
                             (amp * w * np.cos(w * t + np.arange(n_links))).tolist())
        if order >= 5:
            pt.accelerations = (-amp * w * w * np.sin(w * t + np.arange(n_links))).tolist()
        sec = int(t)
        pt.time_from_start = Duration(sec=sec, nanosec=int(round((t - sec) * 1e9)))
        pts.append(pt)
    return pts


def _parameters(rng: np.random.Generator, node: SimNode) -> list[Parameter]:
    cfg = node.config
    choice = rng.choice(['p', 'friction', 'mu', 'method', 'limits', 'rates', 'slope'])
    if choice == 'p':
        p = int(rng.integers(2, 5))
        out = [Parameter('masses', value=rng.uniform(0.3, 2.0, p).tolist())]
        for name in ('friction', 'friction_backward'):   # per-body lists follow p
            if len(cfg.values[name]) > 1:
                out.append(Parameter(name, value=rng.uniform(0.5, 5.0, 1).tolist()))
        return out
    if choice == 'friction':
        return [Parameter('friction', value=rng.uniform(0.5, 5.0, 1).tolist()),
                Parameter('friction_backward', value=rng.uniform(0.5, 5.0, 1).tolist())]
    if choice == 'mu':
        empty = Parameter.Type.DOUBLE_ARRAY
        return [Parameter('friction', empty, []), Parameter('friction_backward', empty, []),
                Parameter('mu', value=[float(rng.uniform(0.1, 0.6))])]
    if choice == 'method':
        return [Parameter('method', value=str(rng.choice(['exact', 'implicit', 'exact'])))]
    if choice == 'limits':
        return [Parameter('actuator_bandwidth', value=float(rng.uniform(2.0, 15.0))),
                Parameter('actuator_max_speed', value=float(rng.uniform(0.2, 1.0)))]
    if choice == 'rates':
        rate = float(rng.choice([500.0, 1000.0, 2000.0]))
        return [Parameter('integration_rate', value=rate),
                Parameter('publish_rate', value=float(rng.choice([50.0, 100.0, 250.0])))]
    return [Parameter('slope', value=float(rng.uniform(-0.2, 0.2)))]


def run_session(seed: int, record_dir: Path, domain_id: int, actions: int = 25) -> Path:
    """One random session recorded under ``record_dir``; the bag's path."""
    rng = np.random.default_rng(seed)
    ctx = Context()
    saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
    try:
        rclpy.init(context=ctx, domain_id=domain_id)
    finally:
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved or 'LOCALHOST'
    p = int(rng.integers(2, 5))
    params = {'masses': rng.uniform(0.3, 2.0, p).tolist(), 'record': True,
              'record_dir': str(record_dir), 'record_name': f'session_{seed}',
              'method': str(rng.choice(['exact', 'exact', 'implicit', 'penalty'])),
              'publish_clock': False, 'publish_markers': False, 'publish_odom': False}
    if rng.random() < 0.5:
        params.update(friction=rng.uniform(0.5, 5.0, p).tolist(),
                      friction_backward=rng.uniform(0.5, 5.0, p).tolist())
    ex = SingleThreadedExecutor(context=ctx)
    node = SimNode(context=ctx, parameter_overrides=[Parameter(k, value=v)
                                                     for k, v in params.items()])
    peer = Node('session_peer', context=ctx)
    ex.add_node(node)
    ex.add_node(peer)
    cmd_pub = peer.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
    traj_pub = peer.create_publisher(JointTrajectory, 'linkage_trajectory', 10)
    try:
        _wait(ex, lambda: cmd_pub.get_subscription_count() and traj_pub.get_subscription_count())
        node.take_inputs()
        for _ in range(actions):
            n_ticks = int(rng.integers(1, 400))
            if not node.paused:
                for _ in range(n_ticks):
                    node.tick()
            _act(rng, str(rng.choice(ACTIONS)), node, ex, peer, cmd_pub, traj_pub)
        if node.paused:
            _call(ex, peer, SetBool, '/crawler_sim/pause', SetBool.Request(data=False))
        for _ in range(200):
            node.tick()
        return Path(node.bag_path)
    finally:
        node.close()
        ex.shutdown()
        node.destroy_node()
        peer.destroy_node()
        rclpy.shutdown(context=ctx)


def _wait(ex, cond, timeout: float = 10.0) -> None:
    import time
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError('timed out waiting for discovery')
        ex.spin_once(timeout_sec=0.01)


def _deliver(ex, node: SimNode, pub, msg, counters: tuple[str, ...]) -> None:
    """Publish ``msg`` and wait until the node has taken it (counted under ``counters``)."""
    before = sum(node.counters[c] for c in counters)
    pub.publish(msg)
    _wait(ex, lambda: node.take_inputs() >= 0
          and sum(node.counters[c] for c in counters) > before)


def _call(ex, peer: Node, srv_type, name: str, request):
    """Call the node's service over DDS (the executor spins both nodes)."""
    client = peer.create_client(srv_type, name)
    _wait(ex, client.service_is_ready)
    future = client.call_async(request)
    ex.spin_until_future_complete(future, timeout_sec=10.0)
    assert future.done(), f'no answer from {name}'
    peer.destroy_client(client)
    return future.result()


def _act(rng, action: str, node: SimNode, ex, peer: Node, cmd_pub, traj_pub) -> None:
    cfg = node.config
    n, lo, hi = cfg.n_links, cfg.min_length, cfg.max_length
    if action == 'command':
        msg = Float64MultiArray(data=rng.uniform(lo + 0.03, min(hi, 0.25), n).tolist())
        _deliver(ex, node, cmd_pub, msg, ('commands_accepted',))
    elif action == 'bad_command':
        msg = Float64MultiArray(data=[hi + 1.0] * n)
        _deliver(ex, node, cmd_pub, msg, ('commands_rejected',))
    elif action in ('trajectory', 'empty_trajectory'):
        msg = JointTrajectory(joint_names=[f'linkage_{j}' for j in range(n)][::-1])
        if action == 'trajectory':
            msg.points = _points(rng, n, lo, min(hi, 0.25))
            for pt in msg.points:     # joint order reversed: the node reorders by name
                pt.positions = pt.positions[::-1]
                pt.velocities = pt.velocities[::-1]
                pt.accelerations = pt.accelerations[::-1]
            if rng.random() < 0.4:    # absolute stamp, a little ahead of the sim time
                stamp = node.sim_time_ns + int(rng.integers(0, 50_000_000))
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        _deliver(ex, node, traj_pub, msg, ('trajectories_accepted', 'trajectories_rejected'))
    elif action == 'parameters':
        # atomically: a new p and per-body lists of that p are only valid together
        result = node.set_parameters_atomically(_parameters(rng, node))
        assert result.successful, result.reason
    elif action == 'pause':
        _call(ex, peer, SetBool, '/crawler_sim/pause', SetBool.Request(data=not node.paused))
    elif action == 'reset':
        _call(ex, peer, Trigger, '/crawler_sim/reset', Trigger.Request())
    elif action == 'peek':
        _ = node.state                # integrates up to now, between publish ticks
