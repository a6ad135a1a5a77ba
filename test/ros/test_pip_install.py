"""`pip install .` (no colcon, no sourced workspace, no AMENT_PREFIX_PATH): sim_node records.

Issue 12: after a plain `pip install .` the node logged "set AMENT_PREFIX_PATH ..." and left an
unreadable file. Here the package is installed by pip into a fresh target directory (an isolated
build, as a user's `pip install .` does), its `sim_node` console script is run as a process with
only that directory on PYTHONPATH and no ament index at all, driven over real DDS with one length
on `linkage_cmd`, stopped with SIGINT, and its bag is read in full by rosbags, an independent
reader, topic by topic.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys

import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from test.support.ros import Peer

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def pip_target(tmp_path_factory) -> Path:
    target = tmp_path_factory.mktemp('pip') / 'site'
    proc = subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '--no-deps',
                           '--target', str(target), str(REPO)],
                          cwd=target.parent, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return target


def test_a_pip_installed_sim_node_records_a_bag_rosbags_reads_without_the_ament_index(
        pip_target, tmp_path):
    from rosbags.highlevel import AnyReader
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH', 'PYTHONPATH')}
    env['PYTHONPATH'] = str(pip_target)
    env['PYTHONUNBUFFERED'] = '1'
    # the installed copy runs, not this checkout
    probe = 'import crawler_sim; print(crawler_sim.__file__)'
    where = subprocess.run([sys.executable, '-c', probe], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=60)
    assert where.stdout.startswith(str(pip_target)), where.stdout + where.stderr
    out, err = open(tmp_path / 'sim.out', 'w+'), open(tmp_path / 'sim.err', 'w+')
    sim = subprocess.Popen([str(pip_target / 'bin' / 'sim_node'), '--ros-args',
                            '-p', 'record:=true', '-p', f'record_dir:={tmp_path}',
                            '-p', 'record_name:=pip_bag'],
                           cwd=tmp_path, env=env, stdout=out, stderr=err)
    peer = Peer()
    try:
        states: list[JointState] = []
        peer.node.create_subscription(JointState, 'body_states', states.append, 10)
        pub = peer.node.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
        peer.until(lambda: states, 'body_states from the pip-installed sim_node')
        assert len(states[-1].position) == 2          # the seed's two-body crawler
        peer.until(lambda: pub.get_subscription_count() >= 1, 'sim_node subscribed to linkage_cmd')
        n0 = len(states)
        pub.publish(Float64MultiArray(data=[0.14]))   # one length: the seed's linkage
        peer.until(lambda: len(states) > n0 + 50, 'states after the command')
        sim.send_signal(signal.SIGINT)
        code = sim.wait(timeout=30)
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait()
        peer.close()
    err.seek(0)
    log = err.read()
    out.seek(0)
    log += out.read()
    assert code == 0, log
    assert 'AMENT_PREFIX_PATH' not in log and 'recording stopped' not in log, log
    bag = tmp_path / 'pip_bag'
    assert (bag / 'metadata.yaml').is_file(), log
    with AnyReader([bag]) as reader:
        counts: dict[str, int] = {}
        for conn, _, raw in reader.messages():
            reader.deserialize(raw, conn.msgtype)          # every message, in full
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    for topic in ('/body_states', '/joint_states', '/contacts', '/linkage_cmd'):
        assert counts.get(topic, 0) >= 1, (topic, counts)
    assert counts['/linkage_cmd'] == 1
