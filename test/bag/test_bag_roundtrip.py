"""Write a run with crawler_sim.bag and read it back with three independent readers.

Readers: ``crawler_sim.bag.load`` (vectorized CDR), ``mcap_ros2``'s decoder (its own CDR
parser driven by the schema text in the file) and rosbags ``AnyReader`` (its own MCAP reader,
CDR parser and metadata.yaml parser). Every field of every message is compared, and counts are
asserted, so a reader that silently skips messages fails.
"""
from __future__ import annotations

from collections import Counter
import json
from pathlib import Path
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
from numpy.testing import assert_array_equal
import pytest
import yaml

from crawler_sim.bag import BagWriter, load, record_arrays, to_ns
from crawler_sim.bag import schema as bag_schema
from test.support.synthetic import synthetic_arrays

N, P = 250, 3
CMD_EVERY = 50
EVENTS = [(0.105, 1, 0, 1), (0.5, 2, 1, -1), (1.25, 0, -1, 0)]
SCENE = {'name': 'roundtrip', 'p': P, 'friction': {'f_plus': [1.0, 2.0, 3.0]}, 'dt': 0.01}
STATE_TOPICS = ('/body_states', '/joint_states', '/contact_states', '/odom')


@pytest.fixture(scope='module')
def arrays() -> dict:
    return synthetic_arrays(N, P, dt=0.01, t0=0.005, seed=7)


@pytest.fixture(scope='module')
def bag(tmp_path_factory, arrays) -> Path:
    path = tmp_path_factory.mktemp('bags') / 'run'
    a = dict(arrays)
    masses = a.pop('masses')
    commands = (a['t'][::CMD_EVERY], a['lengths'][::CMD_EVERY] + 0.01)
    writer = record_arrays(path, **a, commands=commands, events=EVENTS, scene=SCENE,
                           masses=masses)
    assert writer.error is None
    return path


def expected_counts() -> dict[str, int]:
    counts = {topic: N for topic in STATE_TOPICS}
    counts.update({'/linkage_cmd': len(range(0, N, CMD_EVERY)), '/events': len(EVENTS),
                   '/crawler_sim/scene': 1})
    return counts


def com(arrays: dict, key: str) -> np.ndarray:
    m = arrays['masses']
    return arrays[key] @ m / m.sum()


# ---------------------------------------------------------------- crawler_sim.bag.load

def test_load_returns_every_field_as_written(bag, arrays):
    run = load(bag)
    assert len(run) == N and run.p == P and not run.truncated
    assert_array_equal(to_ns(run.t), to_ns(arrays['t']))
    for key in ('x', 'v', 'friction', 'lengths', 'rates', 'linkage_force'):
        assert_array_equal(getattr(run, key), arrays[key], err_msg=key)
    assert run.contact.dtype == np.int8
    assert_array_equal(run.contact, arrays['contact'])
    assert run.bodies == ('body_0', 'body_1', 'body_2')
    assert run.linkages == ('linkage_0', 'linkage_1')


def test_load_returns_commands_events_scene_and_topic_counts(bag, arrays):
    run = load(bag)
    assert_array_equal(to_ns(run.commands.t), to_ns(arrays['t'][::CMD_EVERY]))
    assert_array_equal(run.commands.values, arrays['lengths'][::CMD_EVERY] + 0.01)
    assert_array_equal(to_ns(run.events.t), [to_ns(e[0]) for e in EVENTS])
    assert_array_equal(run.events.body, [e[1] for e in EVENTS])
    assert_array_equal(run.events.old, [e[2] for e in EVENTS])
    assert_array_equal(run.events.new, [e[3] for e in EVENTS])
    assert {k: v for k, v in run.scene.items() if k != 'crawler_sim_version'} == SCENE
    assert run.scene['crawler_sim_version']
    assert {topic: s.count for topic, s in run.topics.items()} == expected_counts()
    assert run.topics['/odom'].type == 'nav_msgs/msg/Odometry'


def test_load_accepts_the_bare_mcap_file(bag, arrays):
    run = load(bag / 'run_0.mcap')
    assert_array_equal(run.x, arrays['x'])
    assert len(run.commands.t) == len(range(0, N, CMD_EVERY))


# ---------------------------------------------------------------- mcap_ros2 decoder

def test_mcap_ros2_decoder_reads_every_message_with_the_written_values(bag, arrays):
    counts: Counter[str] = Counter()
    index = {topic: 0 for topic in expected_counts()}
    with open(bag / 'run_0.mcap', 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(log_time_order=False):
            topic = channel.topic
            i = index[topic]
            index[topic] += 1
            counts[topic] += 1
            assert message.publish_time == message.log_time
            if topic in STATE_TOPICS:
                assert message.log_time == to_ns(arrays['t'][i])
            check_decoded(topic, msg, i, arrays)
    assert dict(counts) == expected_counts()


def check_decoded(topic: str, msg, i: int, arrays: dict) -> None:
    """Compare one decoded message (mcap_ros2 or rosbags object) with the written arrays."""
    t_ns = to_ns(arrays['t'][i]) if topic in STATE_TOPICS else None
    if topic in ('/body_states', '/joint_states'):
        keys = ('x', 'v', 'friction') if topic == '/body_states' else (
            'lengths', 'rates', 'linkage_force')
        prefix = 'body' if topic == '/body_states' else 'linkage'
        width = arrays[keys[0]].shape[1]
        assert list(msg.name) == [f'{prefix}_{j}' for j in range(width)]
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == t_ns
        assert msg.header.frame_id == ''
        for field, key in zip(('position', 'velocity', 'effort'), keys):
            assert_array_equal(np.asarray(getattr(msg, field)), arrays[key][i])
    elif topic == '/contact_states':
        assert_array_equal(np.asarray(msg.data, dtype=np.int8), arrays['contact'][i])
    elif topic == '/odom':
        assert msg.header.frame_id == 'odom' and msg.child_frame_id == 'base_link'
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == t_ns
        assert msg.pose.pose.position.x == pytest.approx(com(arrays, 'x')[i], abs=1e-15)
        assert msg.twist.twist.linear.x == pytest.approx(com(arrays, 'v')[i], abs=1e-15)
        assert msg.pose.pose.orientation.w == 1.0
    elif topic == '/linkage_cmd':
        assert_array_equal(np.asarray(msg.data), arrays['lengths'][i * CMD_EVERY] + 0.01)
    elif topic == '/events':
        assert list(msg.data) == list(EVENTS[i][1:])
    elif topic == '/crawler_sim/scene':
        scene = yaml.safe_load(msg.data)
        assert {k: v for k, v in scene.items() if k != 'crawler_sim_version'} == SCENE
    else:
        raise AssertionError(f'unexpected topic {topic}')


# ---------------------------------------------------------------- rosbags AnyReader

@pytest.mark.parametrize('target', ['directory', 'bare_mcap'])
def test_rosbags_anyreader_reads_every_message_with_the_written_values(bag, arrays, target):
    from rosbags.highlevel import AnyReader
    path = bag if target == 'directory' else bag / 'run_0.mcap'
    counts: Counter[str] = Counter()
    with AnyReader([path]) as reader:
        for connection, timestamp, raw in reader.messages():
            topic = connection.topic
            msg = reader.deserialize(raw, connection.msgtype)
            if topic in STATE_TOPICS:
                assert timestamp == to_ns(arrays['t'][counts[topic]])
            check_decoded(topic, msg, counts[topic], arrays)
            counts[topic] += 1
        if target == 'directory':   # digests come from metadata.yaml
            for connection in reader.connections:
                assert connection.digest == bag_schema.type_hash(connection.msgtype)
    assert dict(counts) == expected_counts()


# ---------------------------------------------------------------- metadata.yaml

def test_metadata_yaml_is_rosbag2_version_9_with_counts_files_and_durations(bag, arrays):
    text = (bag / 'metadata.yaml').read_text()
    info = yaml.safe_load(text)['rosbag2_bagfile_information']
    assert list(info) == ['version', 'storage_identifier', 'duration', 'starting_time',
                          'message_count', 'topics_with_message_count', 'compression_format',
                          'compression_mode', 'relative_file_paths', 'files', 'custom_data',
                          'ros_distro']
    start, end = to_ns(arrays['t'][0]), to_ns(arrays['t'][-1])
    total = sum(expected_counts().values())
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['ros_distro'] == 'jazzy'
    assert info['starting_time'] == {'nanoseconds_since_epoch': start}
    assert info['duration'] == {'nanoseconds': end - start}
    assert info['message_count'] == total
    assert info['relative_file_paths'] == ['run_0.mcap']
    assert info['files'] == [{'path': 'run_0.mcap',
                              'starting_time': {'nanoseconds_since_epoch': start},
                              'duration': {'nanoseconds': end - start},
                              'message_count': total}]
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert {name: t['message_count'] for name, t in topics.items()} == expected_counts()
    for name, entry in topics.items():
        meta = entry['topic_metadata']
        assert list(meta) == ['name', 'type', 'serialization_format', 'offered_qos_profiles',
                              'type_description_hash']
        assert meta['serialization_format'] == 'cdr'
        assert meta['type_description_hash'] == bag_schema.type_hash(meta['type'])
        assert meta['type_description_hash'].startswith('RIHS01_')
        (qos,) = meta['offered_qos_profiles']
        assert qos['reliability'] == 'reliable' and qos['history'] == 'unknown'
        assert qos['durability'] == ('transient_local' if name == '/crawler_sim/scene'
                                     else 'volatile')
        assert qos['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
    assert topics['/body_states']['topic_metadata']['type'] == 'sensor_msgs/msg/JointState'


def test_mcap_file_carries_rosbag2_records_channel_metadata_and_zstd_chunks(bag):
    with open(bag / 'run_0.mcap', 'rb') as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        records = list(reader.iter_metadata())
    assert header.profile == 'ros2'
    assert {chunk.compression for chunk in summary.chunk_indexes} == {'zstd'}
    rosbag2 = [yaml.safe_load(r.metadata['serialized_metadata'])
               for r in records if r.name == 'rosbag2']
    assert len(rosbag2) == 2                      # at open and at close, like rosbag2
    assert rosbag2[0]['topics_with_message_count'] == [] and rosbag2[0]['message_count'] == 0
    closing = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert rosbag2[1] == closing
    (scene,) = [r.metadata for r in records if r.name == 'crawler_sim.scene']
    assert {k: json.loads(v) for k, v in scene.items() if k != 'crawler_sim_version'} == SCENE
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == 'cdr' and schema.encoding == 'ros2msg'
        assert schema.name.count('/') == 2                      # pkg/msg/Type
        assert schema.data.decode() == bag_schema.full_text(schema.name)
        assert channel.metadata['topic_type_hash'] == bag_schema.type_hash(schema.name)
        qos = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert isinstance(qos, list) and qos[0]['liveliness'] == 'automatic'


# ---------------------------------------------------------------- schema text

def installed_msg(pkg: str, name: str) -> str:
    # the interface packages here come from the PyPI wheels installed into this interpreter's
    # prefix (share/<pkg> next to lib/); read the file directly, without the code under test
    return (Path(sys.prefix) / 'share' / pkg / 'msg' / f'{name}.msg').read_text()


def test_joint_state_schema_is_root_msg_then_header_then_time_like_rosbag2():
    sep = '=' * 80
    expected = (installed_msg('sensor_msgs', 'JointState')
                + f'\n{sep}\nMSG: std_msgs/Header\n' + installed_msg('std_msgs', 'Header')
                + f'\n{sep}\nMSG: builtin_interfaces/Time\n'
                + installed_msg('builtin_interfaces', 'Time'))
    assert bag_schema.full_text('sensor_msgs/msg/JointState') == expected
    assert expected.startswith('# This is a message that holds data')    # comments kept


def test_multiarray_schema_qualifies_package_relative_dependencies_in_depth_first_order():
    sep = '=' * 80
    expected = (installed_msg('std_msgs', 'Float64MultiArray')
                + f'\n{sep}\nMSG: std_msgs/MultiArrayLayout\n'
                + installed_msg('std_msgs', 'MultiArrayLayout')
                + f'\n{sep}\nMSG: std_msgs/MultiArrayDimension\n'
                + installed_msg('std_msgs', 'MultiArrayDimension'))
    assert bag_schema.full_text('std_msgs/msg/Float64MultiArray') == expected


def test_odometry_schema_lists_each_dependency_once():
    text = bag_schema.full_text('nav_msgs/msg/Odometry')
    names = [line[5:] for line in text.splitlines() if line.startswith('MSG: ')]
    assert names == ['geometry_msgs/PoseWithCovariance', 'geometry_msgs/Pose',
                     'geometry_msgs/Point', 'geometry_msgs/Quaternion',
                     'geometry_msgs/TwistWithCovariance', 'geometry_msgs/Twist',
                     'geometry_msgs/Vector3', 'std_msgs/Header', 'builtin_interfaces/Time']


def test_type_hash_matches_rosbags_rihs01():
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    for type_name in ('sensor_msgs/msg/JointState', 'std_msgs/msg/Float64MultiArray',
                      'nav_msgs/msg/Odometry', 'std_msgs/msg/Int8MultiArray'):
        assert bag_schema.type_hash(type_name) == store.hash_rihs01(type_name)


# ---------------------------------------------------------------- writer details

def test_serialised_bytes_are_stored_verbatim_and_rclpy_objects_round_trip(tmp_path):
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState

    msg = JointState(name=['body_0'], position=[1.5], velocity=[-2.0], effort=[0.25])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 3, 500
    raw = serialize_message(msg)
    with BagWriter(tmp_path / 'b') as w:
        assert w.write('/body_states', 'sensor_msgs/msg/JointState', raw, 3_000_000_500)
        assert w.write('/body_states', 'sensor_msgs/msg/JointState', msg, 3_000_000_501)
    with open(tmp_path / 'b' / 'b_0.mcap', 'rb') as f:
        stored = [m.data for _, _, m in make_reader(f).iter_messages()]
    assert stored[0] == raw
    assert deserialize_message(stored[1], JointState) == msg
    assert len(stored) == 2


def test_bag_builders_match_the_node_message_builders():
    """Offline bags (bag.msgs) and node bags (crawler_sim.ros.messages) hold equal messages.

    So both kinds of bag load the same way.
    """
    messages = pytest.importorskip('crawler_sim.ros.messages')
    from crawler_sim.bag import msgs

    class State:
        x = np.array([0.0, 0.1, 0.25])
        v = np.array([0.5, -0.5, 0.0])
        friction = np.array([-1.0, 2.0, 0.5])
        contact = np.array([1, -1, 0], dtype=np.int8)
        lengths = np.array([0.1, 0.15])
        rates = np.array([0.2, -0.3])
        linkage_force = np.array([3.0, -4.0])

    st, t_ns, masses = State(), 1_234_567_891, np.array([1.0, 2.0, 3.0])
    assert msgs.body_states(t_ns, st.x, st.v, st.friction) == messages.body_states_msg(st, t_ns)
    assert msgs.joint_states(t_ns, st.lengths, st.rates, st.linkage_force) == \
        messages.joint_states_msg(st, t_ns)
    assert msgs.contact_states(st.contact) == messages.contact_states_msg(st)
    assert msgs.odometry(t_ns, st.x, st.v, masses) == messages.odom_msg(st, masses, t_ns)
    assert list(msgs.float64_array_msg([0.1, 0.2]).data) == [0.1, 0.2]


def test_commands_fall_back_to_the_applied_command_topic(tmp_path):
    """Bags that only hold ``~/applied_command`` (JointState) still give the commands."""
    from crawler_sim.bag import msgs
    with BagWriter(tmp_path / 'b') as w:
        for i in range(4):
            t_ns = i * 10_000_000
            w.write('/body_states', 'sensor_msgs/msg/JointState',
                    msgs.body_states(t_ns, [0.0, 0.1], [0.0, 0.0], [0.0, 0.0]), t_ns)
            if i % 2:
                w.write('/crawler_sim/applied_command', 'sensor_msgs/msg/JointState',
                        msgs.joint_state(t_ns, ['linkage_0'], [0.1 * i], [0.0], [0.0]), t_ns)
    with pytest.warns(Warning, match='no joint_states or contact_states'):
        run = load(tmp_path / 'b')
    assert_array_equal(to_ns(run.commands.t), [10_000_000, 30_000_000])
    assert_array_equal(run.commands.values, [[0.1], [0.30000000000000004]])
    assert run.contact.shape == (4, 0) and np.isnan(run.lengths).all()


# ------------------------------------------------------------------ columnar offline recording
# Issue 43: recording an offline run cost about 1,000 times the run. record_arrays now encodes
# whole runs column by column (crawler_sim.bag.cdr.Encoder.rows) and writes the records in
# chunk-sized blocks (McapWriter.add_records): the same file as a loop of Recorder calls.

def _record_by_loop(path: Path, a: dict, commands, events, scene, masses, **options) -> None:
    """What record_arrays did before: one Recorder call per command, event and state."""
    from crawler_sim.bag import Recorder
    cmd_t, cmd_v = commands
    pending = sorted([(tc, 0, i) for i, tc in enumerate(cmd_t)]
                     + [(e[0], 1, e[1:]) for e in events], key=lambda it: (it[0], it[1]))

    def write(item) -> None:
        if item[1] == 0:
            rec.record_command(item[0], cmd_v[item[2]])
        else:
            rec.record_event(item[0], *item[2])
    with Recorder(path, scene=scene, masses=masses, flush_interval=None, **options) as rec:
        k = 0
        for i in range(len(a['t'])):
            while k < len(pending) and pending[k][0] <= a['t'][i]:
                write(pending[k])
                k += 1
            rec.record_state(a['t'][i], a['x'][i], a['v'][i], a['friction'][i],
                             a['contact'][i], a['lengths'][i], a['rates'][i],
                             a['linkage_force'][i])
        for item in pending[k:]:
            write(item)


@pytest.mark.parametrize('batch', [1, 7, 4096])
@pytest.mark.parametrize('chunk_size', [5000, 1 << 20])
def test_columnar_recording_writes_the_file_a_loop_of_recorder_calls_writes(
        tmp_path, arrays, batch, chunk_size, monkeypatch):
    """Byte for byte (.mcap and metadata.yaml), with commands and events before the first
    state, at a state's time, between states and after the last, across chunk boundaries and
    however the steps are batched."""
    from crawler_sim.bag import recorder
    monkeypatch.setattr(recorder, 'BATCH', batch)
    a = dict(arrays)
    masses = a.pop('masses')
    t = a['t']
    commands = (np.array([0.0, t[0], t[3], t[3], 0.5 * (t[9] + t[10]), t[-1] + 1.0]),
                np.arange(6.0 * (P - 1)).reshape(6, P - 1))
    events = [(0.0, 0, 0, 1), (t[3], 1, 0, 1), (t[100] - 1e-9, 2, 1, -1), (t[-1] + 2.0, 0, 1, 0)]
    columnar, loop = tmp_path / 'columnar' / 'run', tmp_path / 'loop' / 'run'
    record_arrays(columnar, **a, commands=commands, events=events, scene=SCENE,
                  masses=masses, chunk_size=chunk_size)
    _record_by_loop(loop, a, commands, events, SCENE, masses, chunk_size=chunk_size)
    data = (columnar / 'run_0.mcap').read_bytes()
    assert len(data) > 50_000 and data == (loop / 'run_0.mcap').read_bytes()
    assert (columnar / 'metadata.yaml').read_text() == (loop / 'metadata.yaml').read_text()
    if chunk_size == 5000:
        with open(columnar / 'run_0.mcap', 'rb') as f:
            assert len(make_reader(f).get_summary().chunk_indexes) > 20


def test_offline_messages_are_the_bytes_the_node_publishes_and_records(bag, arrays):
    """Every state message of an offline bag equals what sim_node's encoder
    (crawler_sim.ros.messages.OutputEncoder) makes of the same state: padding zero, so the
    bytes of serialize_message of a built message (uninitialised padding) are not used."""
    messages = pytest.importorskip('crawler_sim.ros.messages')
    from types import SimpleNamespace
    enc = messages.OutputEncoder()
    a = arrays
    want: dict[str, list[bytes]] = {topic: [] for topic in STATE_TOPICS}
    for i in range(N):
        st = SimpleNamespace(**{k: a[k][i] for k in ('x', 'v', 'friction', 'contact', 'lengths',
                                                     'rates', 'linkage_force')})
        t_ns = to_ns(a['t'][i])
        for topic in STATE_TOPICS:
            want[topic].append(enc.encode(topic[1:], st, t_ns, a['masses']))
    got: dict[str, list[bytes]] = {topic: [] for topic in STATE_TOPICS}
    with open(bag / 'run_0.mcap', 'rb') as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.topic in got:
                got[channel.topic].append(message.data)
    for topic in STATE_TOPICS:
        assert got[topic] == want[topic], topic


def test_a_trajectory_and_its_bag_give_the_same_table_and_a_short_repr(tmp_path):
    """Jupyter (issue 43): ``to_pandas()`` of a Trajectory and of its recorded bag are the
    same frame (one layout, crawler_sim.core.trajectory.sample_frame, also export's); the
    reprs are one short line each instead of every array."""
    pd = pytest.importorskip('pandas')
    from crawler_sim import Crawler, gaits, simulate
    from crawler_sim.bag import record_trajectory
    from crawler_sim.sweep.tables import trajectory_frames

    run = simulate(Crawler([0.5, 1.0], mu=0.3), gaits.Scallop(0.1, 0.02, 2.0, 0.2), 3.0)
    record_trajectory(tmp_path / 'run', run, scene={'crawler': {'masses': [0.5, 1.0]}})
    back = load(tmp_path / 'run')
    frame = run.to_pandas()
    assert list(frame.columns) == ['x_0', 'x_1', 'v_0', 'v_1', 'friction_0', 'friction_1',
                                   'contact_0', 'contact_1', 'length_0', 'rate_0',
                                   'linkage_force_0', 'com']
    assert frame.index.name == 't' and len(frame) == len(run.t)
    pd.testing.assert_frame_equal(frame, trajectory_frames(run)[0])
    loaded = back.to_pandas()
    # the same columns and numbers; the times went through integer ns
    pd.testing.assert_frame_equal(loaded, frame, check_exact=False, rtol=0, atol=1e-9)
    assert_array_equal(loaded.to_numpy(), frame.to_numpy())
    text = repr(run)
    assert text.startswith('Trajectory(p=2, method=\'exact\', t=[0, 3] s, ')
    assert f'{len(run.t)} samples, {len(run.events)} events, mean speed ' in text
    assert len(text) < 150 and '\n' not in text
    text = repr(back)
    assert f'p=2, t=[0, 3] s, {len(run.t)} states, {len(run.events)} events' in text
    assert len(text) < 200 and '\n' not in text
