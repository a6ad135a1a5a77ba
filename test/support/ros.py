"""The ROS side of the tests: an in-process sim_node on real DDS (``Harness``), the colcon-installed
executables as processes (``Proc``, ``Peer``), message builders and domain ids.

The fixtures that use these (``ros``, ``ament_env``, ``peer``) are in test/ros/conftest.py.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import signal
import subprocess
from typing import Any

from ament_index_python.packages import get_package_prefix, get_package_share_directory
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.ros.sim_node import SimNode
from test.support.domains import next_domain_id     # noqa: F401 - ids no other session holds
from test.support.spinning import Spinning


DEADLINE = 10.0   # wall s for any single wait (discovery, a service call)
#: the scene of most tests here: three 1 kg bodies, 3 N of friction each, two 0.1 m linkages
THREE_BODY = {'masses': [1.0, 1.0, 1.0], 'friction': [3.0], 'friction_backward': [3.0],
              'initial_lengths': [0.1, 0.1], 'publish_clock': False}


class Harness(Spinning):
    """One context, one executor, the node under test and an observer node."""

    deadline = DEADLINE

    def __init__(self) -> None:
        self.ctx = Context()
        # discovery OFF: this context's participant talks only to itself (over DDS), so parallel
        # test sessions on the host cannot interfere whatever their domain ids
        saved = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')
        os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'
        try:
            rclpy.init(context=self.ctx, domain_id=next_domain_id())
        finally:
            os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = saved or 'LOCALHOST'
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.obs = self.client_node = Node('observer', context=self.ctx)
        self.ex.add_node(self.obs)
        self.nodes: list[SimNode] = []
        self.others: list[Node] = []
        self.received: dict[str, list] = {}

    def sim(self, seed: bool = False, **params: Any) -> SimNode:
        """A SimNode; unless ``seed``, on the three-body scene these tests were written for
        (the defaults are the seed's two bodies, tested in test_defaults.py)."""
        if not seed:
            params = {**THREE_BODY, **params}
        node = SimNode(context=self.ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.ex.add_node(node)
        self.nodes.append(node)
        return node

    def listen(self, msg_type, topic: str, qos=100) -> list:
        box = self.received.setdefault(topic + str(id(qos)), [])
        sub = self.obs.create_subscription(msg_type, topic, box.append, qos)
        self.until(lambda: sub.get_publisher_count() > 0, f'a publisher on {topic}')
        return box

    def publisher(self, msg_type, topic: str):
        pub = self.obs.create_publisher(msg_type, topic, 10)
        self.until(lambda: pub.get_subscription_count() > 0, f'a subscriber on {topic}')
        return pub


    def send(self, pub, msg, node: SimNode, counter: str, before: int | None = None) -> None:
        """Publish and wait until the node counted it under ``counter``. The node's loop takes
        commands at every tick; here, without a loop, they are taken as they arrive."""
        start = node.counters[counter] if before is None else before
        pub.publish(msg)
        self.until(lambda: node.take_inputs() >= 0 and node.counters[counter] > start,
                   f'{counter} to increase')

    def close(self) -> None:
        for node in self.nodes:
            node.stop()
        self.ex.shutdown()
        for node in self.nodes:
            node.close()
            node.destroy_node()
        for node in self.others:
            node.destroy_node()
        self.obs.destroy_node()
        rclpy.shutdown(context=self.ctx)


def cmd(*values: float) -> Float64MultiArray:
    return Float64MultiArray(data=[float(v) for v in values])


def ticks(node: SimNode, n: int) -> None:
    for _ in range(n):
        node.tick()


def point(t: float, pos, vel=None, acc=None) -> JointTrajectoryPoint:
    pt = JointTrajectoryPoint(positions=[float(x) for x in pos])
    if vel is not None:
        pt.velocities = [float(x) for x in vel]
    if acc is not None:
        pt.accelerations = [float(x) for x in acc]
    sec = math.floor(t)
    pt.time_from_start = Duration(sec=sec, nanosec=round((t - sec) * 1e9))
    return pt


def trajectory(names, points, stamp_ns: int = 0) -> JointTrajectory:
    msg = JointTrajectory(joint_names=list(names), points=list(points))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return msg


PROCESS_DEADLINE = 20.0    # wall s for any single wait on a process


def executable(name: str) -> Path:
    """What `ros2 run crawler_sim <name>` runs: <prefix>/lib/crawler_sim/<name>."""
    found = [p for p in (Path(get_package_prefix('crawler_sim')) / 'lib' / 'crawler_sim').iterdir()
             if p.name == name and os.access(p, os.X_OK)]
    assert len(found) == 1, f'{name} not found exactly once'
    return found[0]


class Proc:
    """A child process with its output in files (no pipe can fill up and block it)."""

    def __init__(self, tmp: Path, env: dict, name: str, *ros_args: str) -> None:
        stem, k = name, 0
        while (tmp / f'{stem}.out').exists():     # several processes of one executable
            k += 1
            stem = f'{name}_{k}'
        self.out = open(tmp / f'{stem}.out', 'w+')
        self.err = open(tmp / f'{stem}.err', 'w+')
        self.popen = subprocess.Popen([str(executable(name)), '--ros-args', *ros_args],
                                      env=env, stdout=self.out, stderr=self.err)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 10.0) -> tuple[int, str]:
        if self.popen.poll() is None:
            self.popen.send_signal(sig)
        try:
            code = self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
            raise AssertionError(f'process did not exit within {timeout} s of signal {sig}')
        self.err.seek(0)
        return code, self.err.read()

    def kill(self) -> None:
        if self.popen.poll() is None:
            self.popen.kill()
            self.popen.wait()


class Peer(Spinning):
    """The test's own node, in the session domain with host-wide discovery."""

    deadline = PROCESS_DEADLINE

    def __init__(self) -> None:
        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
        self.node = self.client_node = Node('test_peer', context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)


    def close(self) -> None:
        self.ex.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.ctx)


#: the three-body scene of the process tests (friction forces given in N)
PROCESS_THREE_BODY = {'masses': [1.0, 1.0, 1.0], 'friction': [3.0], 'friction_backward': [3.0]}


def config_file(name: str = 'crawler_sim.yaml') -> Path:
    return Path(get_package_share_directory('crawler_sim')) / 'config' / 'ros' / name


def sim_args(method: str, *extra: str, three_body: bool = True) -> list[str]:
    scene = ([a for k, v in PROCESS_THREE_BODY.items() for a in ('-p', f'{k}:={v}')]
             if three_body else [])
    return ['--params-file', str(config_file()), *scene, '-p', f'method:={method}',
            '-p', 'real_time_factor:=0.0', '-p', 'start_paused:=true',
            '-p', 'diagnostics_period:=0.2', *extra]


def diagnostics_values(msg: DiagnosticArray) -> dict[str, str]:
    return {kv.key: kv.value for kv in msg.status[0].values}



def param_values(node) -> dict[str, Any]:
    """sim_node's parameter values by name (rclpy's public get_parameter)."""
    from crawler_sim.ros.sim_node import PARAMETERS
    return {name: node.get_parameter(name).value for name in PARAMETERS}
