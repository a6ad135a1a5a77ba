"""sim_node's Fast DDS profile (issue 42): when it applies, that Fast DDS reads it, and that what
goes through a writer under it arrives unchanged.

The profile changes a protocol timer of the writers (nack suppression), never the bytes, QoS
or order of what is published: a reliable subscriber in another process gets every raw message
as sent, in order.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

from crawler_sim.ros.sim.main import FASTDDS_PROFILE, use_fastdds_profile

#: one writer and one reliable reader in two processes; the reader prints what it took
ECHO = r'''
import sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
rclpy.init()
node = rclpy.create_node('profile_reader')
got = []
node.create_subscription(JointState, 'profile_echo', got.append,
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE),
                         raw=True)
print('ready', flush=True)
n = int(sys.argv[1])
end = time.monotonic() + 60
while len(got) < n and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.1)
for data in got:
    print('D', data.hex(), flush=True)
'''
WRITE = r'''
import sys, time
from types import SimpleNamespace
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from crawler_sim.ros import messages as M
import numpy as np
rclpy.init()
node = rclpy.create_node('profile_writer')
pub = node.create_publisher(JointState, 'profile_echo',
                            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
end = time.monotonic() + 60
while pub.get_subscription_count() < 1 and time.monotonic() < end:
    time.sleep(0.05)
enc = M.OutputEncoder()
for k in range(int(sys.argv[1])):
    x = np.array([0.1 * k, -2.5e-3 * k])
    data = enc.body_states(SimpleNamespace(x=x, v=3 * x, friction=-x), k * 10_000_000)
    print('D', data.hex(), flush=True)
    pub.handle.publish_raw(data)
time.sleep(2.0)
'''


def test_the_profile_applies_by_default_and_with_fast_dds_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)         # (no DEFAULT_FASTRTPS_PROFILES.xml there)
    env: dict[str, str] = {}
    assert use_fastdds_profile(env) == str(FASTDDS_PROFILE)
    assert env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(FASTDDS_PROFILE)}
    env = {'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp', 'RMW_FASTRTPS_USE_QOS_FROM_XML': '0'}
    assert use_fastdds_profile(env) == str(FASTDDS_PROFILE)
    assert env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(FASTDDS_PROFILE)


@pytest.mark.parametrize('user', [
    {'FASTRTPS_DEFAULT_PROFILES_FILE': '/somewhere/mine.xml'},
    {'FASTDDS_DEFAULT_PROFILES_FILE': '/somewhere/mine.xml'},
    {'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'},
    {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
])
def test_a_users_own_choice_is_left_alone(tmp_path, monkeypatch, user):
    monkeypatch.chdir(tmp_path)
    env = dict(user)
    assert use_fastdds_profile(env) == ''
    assert env == user


def test_a_profile_file_in_the_working_directory_is_left_alone(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env: dict[str, str] = {}
    (tmp_path / 'DEFAULT_FASTRTPS_PROFILES.xml').write_text('<profiles/>')
    assert use_fastdds_profile(env) == '' and env == {}


def _data(out: str) -> list[str]:
    return [line[2:] for line in out.splitlines() if line.startswith('D ')]


def _run(profile: Path, n: int, cwd: Path) -> tuple[list[str], list[str], str]:
    """What the writer sent and the reader took (hex), and the rest of both processes' output
    (Fast DDS logs its errors on stdout)."""
    env = {**os.environ, 'FASTRTPS_DEFAULT_PROFILES_FILE': str(profile)}
    reader = subprocess.Popen([sys.executable, '-c', ECHO, str(n)], env=env, cwd=cwd,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    log = []
    try:
        for line in reader.stdout:          # up to 'ready': the subscription exists
            if line.strip() == 'ready':
                break
            log.append(line)
        writer = subprocess.run([sys.executable, '-c', WRITE, str(n)], env=env, cwd=cwd,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                timeout=120)
        out, _ = reader.communicate(timeout=120)
    finally:
        if reader.poll() is None:
            reader.kill()
    log += [line for line in (writer.stdout + out).splitlines() if not line.startswith('D ')]
    return _data(writer.stdout), _data(out), '\n'.join(log)


def test_fast_dds_reads_the_profile_and_reliable_messages_arrive_as_sent(tmp_path):
    sent, taken, err = _run(FASTDDS_PROFILE, 300, tmp_path)
    assert 'XMLPARSER' not in err and 'Error' not in err, err
    assert len(sent) == 300
    assert taken == sent                     # every message, its bytes, in order


def test_a_profile_fast_dds_cannot_read_is_reported(tmp_path):
    # the check above would see a profile Fast DDS refuses
    broken = tmp_path / 'broken.xml'
    broken.write_text(FASTDDS_PROFILE.read_text().replace('</nanosec>', '</nano>'))
    _sent, _taken, err = _run(broken, 1, tmp_path)
    assert 'XMLPARSER' in err
