"""Every message type crawler_sim records is read back, topic by topic, with equal values, by
rosbags' AnyReader, by mcap_ros2 and (for the state topics) by crawler_sim.bag.load, in a
process without AMENT_PREFIX_PATH (issue 12: recording works wherever rclpy works).

The child process writes the bag and reads it back; every comparison is an ``assert`` in the
child, and the parent checks its exit status and the per-topic counts it prints. Expected
values are the rclpy messages as built, walked field by field (no code under test involved).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parents[2]

CHILD = r'''
import json, math, os, sys, warnings
from pathlib import Path
assert 'AMENT_PREFIX_PATH' not in os.environ
import numpy as np
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int32MultiArray, Int8MultiArray, String
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray
from crawler_sim.bag import BagWriter, Recorder, load

out = Path(sys.argv[1])
expected = {}                               # topic -> list of rclpy messages as written


def add(writer, topic, type_name, msg, t_ns):
    assert writer.write(topic, type_name, msg, t_ns)
    expected.setdefault(topic, []).append(msg)


rec = Recorder.create(out, 'all', masses=[1.0, 2.0], scene={'masses': [1.0, 2.0]})
w = rec.writer
for i in range(5):
    t = 0.01 * i
    rec.record_state(t, [0.1 * i, 0.2 + i], [1.0, -1.0], [0.5, -0.5], [1, -1], [0.2], [0.01 * i],
                     [3.0])
    rec.record_command(t, [0.25 + i])
    rec.record_event(t, 1, 0, -1)
    traj = JointTrajectory(joint_names=['linkage_0'])
    for k in range(3):                      # empty effort: rclpy's surplus CDR tail
        traj.points.append(JointTrajectoryPoint(
            positions=[0.1 * k], velocities=[0.0], accelerations=[0.5],
            time_from_start=Duration(sec=k, nanosec=7)))
    add(w, '/linkage_trajectory', 'trajectory_msgs/msg/JointTrajectory', traj, 10 * i)
    add(w, '/empty_effort', 'sensor_msgs/msg/JointState',
        JointState(name=['a', 'b'], position=[1.0, float(i)], velocity=[2.0, 3.0]), 10 * i)
    add(w, '/crawler_sim/applied_command', 'sensor_msgs/msg/JointState',
        JointState(name=['linkage_0'], position=[0.25 + i], velocity=[0.0], effort=[0.0]), 10 * i)
    markers = MarkerArray(markers=[Marker(ns='bodies', id=k, type=Marker.CUBE) for k in range(2)])
    markers.markers[1].pose.position.x = float(i)
    add(w, '/markers', 'visualization_msgs/msg/MarkerArray', markers, 10 * i)
    add(w, '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', DiagnosticArray(status=[
        DiagnosticStatus(level=DiagnosticStatus.WARN, name='crawler_sim', message='m',
                         values=[KeyValue(key='sim_time', value=str(t))])]), 10 * i)
    add(w, '/clock', 'rosgraph_msgs/msg/Clock', Clock(clock=Time(sec=i, nanosec=5)), 10 * i)
rec.close()
bag = out / 'all'


def plain(value, ref):
    """``value`` (any reader's message) as builtins, walked along the rclpy message ``ref``."""
    if hasattr(ref, 'get_fields_and_field_types'):
        return {name: plain(getattr(value, name), getattr(ref, name))
                for name in ref.get_fields_and_field_types()}
    if isinstance(ref, (list, tuple)) and ref and hasattr(ref[0], 'get_fields_and_field_types'):
        assert len(value) == len(ref)
        return [plain(v, r) for v, r in zip(value, ref)]
    if isinstance(ref, bytes):              # a 'byte' field: rclpy b'\x01', others int 1
        return bytes(value) if isinstance(value, (bytes, bytearray)) else bytes([int(value)])
    if isinstance(ref, str):
        return value
    if isinstance(ref, (list, tuple)) and ref and isinstance(ref[0], str):
        return list(value)
    if hasattr(ref, '__len__'):
        return [float(v) for v in value]
    return float(value) if isinstance(ref, float) else value


from rclpy.serialization import deserialize_message
from crawler_sim.bag.schema import message_class

got = {'rosbags': {}, 'mcap_ros2': {}}
from rosbags.highlevel import AnyReader
with AnyReader([bag]) as reader:
    for conn, _, raw in reader.messages():
        got['rosbags'].setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
with open(bag / 'all_0.mcap', 'rb') as f:
    for _, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]) \
            .iter_decoded_messages(log_time_order=False):
        got['mcap_ros2'].setdefault(channel.topic, []).append(msg)

# the Recorder's own topics: expected messages are the written CDR read back by rclpy
from mcap.reader import make_reader as raw_reader
with open(bag / 'all_0.mcap', 'rb') as f:
    reader = raw_reader(f)
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        if channel.topic not in expected or channel.topic in (
                '/body_states', '/joint_states', '/contact_states', '/odom', '/linkage_cmd',
                '/events', '/crawler_sim/scene'):
            expected.setdefault(f'written:{channel.topic}', []).append(
                deserialize_message(message.data, message_class(schema.name)))
for topic in [t for t in expected if t.startswith('written:')]:
    expected[topic[len('written:'):]] = expected.pop(topic)

counts = {}
for topic, msgs in expected.items():
    for name, by_topic in got.items():
        assert len(by_topic[topic]) == len(msgs), (name, topic)
        for mine, theirs in zip(msgs, by_topic[topic]):
            assert plain(theirs, mine) == plain(mine, mine), (name, topic)
    counts[topic] = len(msgs)

run = load(bag)
assert len(run) == 5 and run.p == 2
np.testing.assert_array_equal(run.x[:, 0], [0.0, 0.1, 0.2, 0.1 * 3, 0.1 * 4])
np.testing.assert_array_equal(run.contact, [[1, -1]] * 5)
np.testing.assert_array_equal(run.commands.values[:, 0], [0.25, 1.25, 2.25, 3.25, 4.25])
np.testing.assert_array_equal(run.events.new, [-1] * 5)
print(json.dumps(counts))
'''


def test_every_recorded_type_reads_back_equal_in_all_three_readers_without_ament(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get('PYTHONPATH', ''))
    env.pop('AMENT_PREFIX_PATH', None)
    proc = subprocess.run([sys.executable, '-c', CHILD, str(tmp_path)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    counts = json.loads(proc.stdout.strip().splitlines()[-1])
    assert counts == {
        '/body_states': 5, '/joint_states': 5, '/contact_states': 5, '/odom': 5,
        '/linkage_cmd': 5, '/events': 5, '/crawler_sim/scene': 1,
        '/linkage_trajectory': 5, '/empty_effort': 5, '/crawler_sim/applied_command': 5,
        '/markers': 5, '/diagnostics': 5, '/clock': 5}
