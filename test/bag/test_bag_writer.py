"""BagWriter and Recorder behaviour: refusals, disk full, flushing, namespaces."""
from __future__ import annotations

import errno
import io
from pathlib import Path
import warnings

from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader
import numpy as np
from numpy.testing import assert_array_equal
import pytest

from crawler_sim.bag import BagError, BagWarning, BagWriter, Recorder, load, record_arrays
from test.support.synthetic import synthetic_arrays

JOINT_STATE = 'sensor_msgs/msg/JointState'


def joint_state(i: int):
    from sensor_msgs.msg import JointState
    return JointState(name=['body_0'], position=[float(i)], velocity=[0.0], effort=[0.0])


def record(path: Path, n: int, **options) -> dict:
    a = synthetic_arrays(n, 3, seed=1)
    masses = a.pop('masses')
    writer = record_arrays(path, **a, masses=masses, **options)
    assert writer.error is None
    return a


def messages(mcap: Path) -> int:
    """Messages of a complete MCAP file (the reader fails on a cut one)."""
    with open(mcap, 'rb') as f:
        return sum(1 for _ in NonSeekingReader(f).iter_messages())


# ---------------------------------------------------------------- never overwrite

def test_recording_into_an_existing_directory_refuses_and_writes_nothing(tmp_path):
    target = tmp_path / 'run'
    target.mkdir()
    (target / 'keep.txt').write_text('data')
    with pytest.raises(BagError, match='exists already'):
        BagWriter(target)
    assert sorted(p.name for p in target.iterdir()) == ['keep.txt']
    assert (target / 'keep.txt').read_text() == 'data'


def test_recording_onto_an_existing_file_refuses_and_leaves_it_unchanged(tmp_path):
    target = tmp_path / 'run'
    target.write_bytes(b'precious')
    with pytest.raises(BagError, match='exists already'):
        record_arrays(target, **{k: v for k, v in synthetic_arrays(3).items()
                                 if k != 'masses'})
    assert target.read_bytes() == b'precious'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['run']


@pytest.mark.parametrize('planted', ['.metadata.yaml.tmp', 'metadata.yaml'])
@pytest.mark.parametrize('how', ['create', 'path'])
def test_a_link_planted_in_the_bag_folder_is_not_written_through_at_close(tmp_path, planted,
                                                                          how):
    """Issue 38: anyone who can write to a shared record folder planted a link at the bag's
    metadata temporary (a fixed name), and the close overwrote what it points to."""
    victim = tmp_path / 'victim.txt'
    victim.write_bytes(b'the user\'s file')
    writer = (BagWriter.create(tmp_path / 'records', 'run', flush_interval=None)
              if how == 'create' else BagWriter(tmp_path / 'run', flush_interval=None))
    (writer.path / planted).symlink_to(victim)
    writer.write('/joint_states', JOINT_STATE, joint_state(1), 10)
    writer.close()
    assert writer.error is None and writer.problems == []
    assert victim.read_bytes() == b'the user\'s file'
    meta = writer.path / 'metadata.yaml'
    assert meta.is_file() and not meta.is_symlink() and 'message_count: 1' in meta.read_text()
    assert messages(writer.mcap_path) == 1


def test_a_link_planted_at_the_recording_file_is_refused_not_followed(tmp_path):
    victim = tmp_path / 'victim.txt'
    victim.write_bytes(b'the user\'s file')

    def planting_opener(path: Path):
        path.symlink_to(victim)                 # planted between mkdir and open
        from crawler_sim.bag.writer import _default_open
        return _default_open(path)

    with pytest.raises(BagError, match='cannot create'):
        BagWriter(tmp_path / 'run', _opener=planting_opener)
    assert victim.read_bytes() == b'the user\'s file'


def test_a_folder_planted_at_the_recording_file_is_refused_in_one_line(tmp_path):
    def planting_opener(path: Path):
        path.mkdir()                            # planted between mkdir and open
        from crawler_sim.bag.writer import _default_open
        return _default_open(path)

    with pytest.raises(BagError, match='cannot create .*run_0.mcap: .*is a directory'):
        BagWriter(tmp_path / 'run', _opener=planting_opener)


def test_a_folder_planted_at_metadata_yaml_is_a_reported_problem_not_an_error(tmp_path):
    writer = BagWriter(tmp_path / 'run', flush_interval=None)
    (writer.path / 'metadata.yaml').mkdir()
    with pytest.warns(RuntimeWarning, match='metadata.yaml could not be written'):
        writer.close()
    assert writer.error is None and len(writer.problems) == 1
    assert messages(writer.mcap_path) == 0                  # the .mcap reads on its own


# ---------------------------------------------------------------- disk full

class FullDisk(io.BytesIO):
    """A file whose writes fail with ENOSPC once ``capacity`` bytes have been written."""

    def __init__(self, capacity: int) -> None:
        super().__init__()
        self.capacity = capacity

    def write(self, data) -> int:
        if self.tell() + len(data) > self.capacity:
            raise OSError(errno.ENOSPC, 'No space left on device')
        return super().write(data)


def test_disk_full_stops_recording_without_raising_and_later_writes_are_no_ops(tmp_path):
    disk = FullDisk(capacity=20_000)
    writer = BagWriter(tmp_path / 'full', flush_interval=0.0, _opener=lambda path: disk)
    accepted = 0
    with pytest.warns(RuntimeWarning, match='No space left on device'):
        for i in range(2_000):
            if writer.write('/body_states', JOINT_STATE, joint_state(i), i * 1000):
                accepted += 1
    assert writer.error is not None and 'No space left on device' in writer.error
    assert 0 < accepted < 2_000
    assert writer.message_count == accepted
    assert disk.closed                                   # the file was closed
    assert writer.write('/body_states', JOINT_STATE, joint_state(0), 10**9) is False
    writer.flush()                                       # no-ops, no exceptions
    writer.close()
    writer.close()
    assert not (tmp_path / 'full' / 'metadata.yaml').exists()


def test_disk_full_while_opening_keeps_the_writer_usable_as_a_no_op(tmp_path):
    with pytest.warns(RuntimeWarning):
        writer = BagWriter(tmp_path / 'full', scene={'a': 1}, _opener=lambda path: FullDisk(5))
    assert writer.error is not None
    assert writer.write('/body_states', JOINT_STATE, joint_state(0), 0) is False
    writer.close()


def test_recorder_reports_the_writer_error(tmp_path):
    with pytest.warns(RuntimeWarning):
        rec = Recorder(tmp_path / 'r', masses=[1.0, 1.0], flush_interval=0.0,
                       _opener=lambda path: FullDisk(30_000))
        ok = [rec.record_state(0.01 * i, [0.0, 0.1], [0.0, 0.0], [0.0, 0.0], [0, 0], [0.1],
                               [0.0], [0.0]) for i in range(200)]
    assert rec.error is not None and not ok[-1] and ok[0]
    rec.close()


# ---------------------------------------------------------------- argument errors

def test_write_rejects_a_message_of_another_type(tmp_path):
    from std_msgs.msg import String
    with BagWriter(tmp_path / 'b') as w:
        with pytest.raises(ValueError, match='std_msgs/msg/String'):
            w.write('/body_states', JOINT_STATE, String(data='x'), 0)


def test_write_rejects_negative_times_relative_topics_and_retyped_topics(tmp_path):
    from std_msgs.msg import String
    with BagWriter(tmp_path / 'b') as w:
        with pytest.raises(ValueError, match='>= 0'):
            w.write('/body_states', JOINT_STATE, joint_state(0), -1)
        with pytest.raises(ValueError, match='absolute'):
            w.write('body_states', JOINT_STATE, joint_state(0), 0)
        w.write('/x', 'std_msgs/msg/String', String(data='x'), 0)
        with pytest.raises(ValueError, match='recorded as std_msgs/msg/String'):
            w.write('/x', JOINT_STATE, joint_state(0), 0)


def test_unknown_message_type_gives_a_bag_error(tmp_path):
    with BagWriter(tmp_path / 'b') as w:
        with pytest.raises(BagError, match='no_such_msgs'):
            w.write('/x', 'no_such_msgs/msg/Thing', b'\x00\x01\x00\x00', 0)


def test_write_after_close_is_a_runtime_error(tmp_path):
    w = BagWriter(tmp_path / 'b')
    w.close()
    with pytest.raises(RuntimeError, match='after close'):
        w.write('/body_states', JOINT_STATE, joint_state(0), 0)


# ---------------------------------------------------------------- flushing

def count_messages_on_disk(path: Path) -> int:
    """Messages a crash right now would keep (stream read of the unfinished file)."""
    count = 0
    with open(path, 'rb') as f:
        try:
            for _ in NonSeekingReader(f).iter_messages(log_time_order=False):
                count += 1
        except EndOfFile:
            pass
    return count


def test_write_flushes_to_disk_once_per_flush_interval_of_wall_time(tmp_path):
    now = [100.0]
    w = BagWriter(tmp_path / 'b', flush_interval=1.0, _clock=lambda: now[0])
    for i in range(10):
        w.write('/body_states', JOINT_STATE, joint_state(i), i)
    assert count_messages_on_disk(w.mcap_path) == 0           # still in the open chunk
    now[0] += 1.5
    w.write('/body_states', JOINT_STATE, joint_state(10), 10)
    assert count_messages_on_disk(w.mcap_path) == 11
    w.write('/body_states', JOINT_STATE, joint_state(11), 11)
    assert count_messages_on_disk(w.mcap_path) == 11
    w.flush()
    assert count_messages_on_disk(w.mcap_path) == 12
    w.close()


def test_an_unclosed_flushed_bag_loads_partially_with_a_warning(tmp_path):
    a = synthetic_arrays(40, 3, seed=3)
    rec = Recorder(tmp_path / 'open', masses=a['masses'])
    for i in range(40):
        rec.record_state(a['t'][i], a['x'][i], a['v'][i], a['friction'][i], a['contact'][i],
                         a['lengths'][i], a['rates'][i], a['linkage_force'][i])
    rec.flush()
    with pytest.warns(BagWarning, match='no MCAP footer'):
        run = load(tmp_path / 'open')
    assert run.truncated and len(run) == 40
    assert_array_equal(run.x, a['x'])
    rec.close()
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        assert not load(tmp_path / 'open').truncated


# ---------------------------------------------------------------- namespaces and QoS

def test_namespaced_topics_are_matched_by_suffix(tmp_path):
    a = record(tmp_path / 'ns', 20, namespace='crawler1', scene={'p': 3})
    run = load(tmp_path / 'ns')
    assert run.scene['p'] == 3
    assert run.namespace == '/crawler1'
    assert '/crawler1/body_states' in run.topics and '/crawler1/crawler_sim/scene' in run.topics
    assert_array_equal(run.x, a['x'])


def test_several_namespaces_need_an_explicit_choice(tmp_path):
    path = tmp_path / 'two'
    first = synthetic_arrays(5, 2, seed=1)
    second = synthetic_arrays(5, 2, seed=2)
    w = BagWriter(path)
    for ns, a in (('/a', first), ('/b', second)):
        rec = Recorder(writer=w, namespace=ns)
        for i in range(5):
            rec.record_state(a['t'][i], a['x'][i], a['v'][i], a['friction'][i],
                             a['contact'][i], a['lengths'][i], a['rates'][i],
                             a['linkage_force'][i])
        rec.close()                                   # does not close the shared writer
    w.close()
    with pytest.raises(BagError, match=r'several crawler_sim namespaces \(/a, /b\)'):
        load(path)
    assert_array_equal(load(path, namespace='b').x, second['x'])
    assert_array_equal(load(path, namespace='/a').v, first['v'])
    with pytest.raises(BagError, match='no /c/body_states'):
        load(path, namespace='c')


def test_qos_overrides_are_recorded_per_topic(tmp_path):
    import yaml
    record(tmp_path / 'q', 3, qos={'odom': {'reliability': 'best_effort', 'depth': 5,
                                            'history': 'keep_last'}})
    meta = yaml.safe_load((tmp_path / 'q' / 'metadata.yaml').read_text())
    topics = {t['topic_metadata']['name']: t['topic_metadata']['offered_qos_profiles'][0]
              for t in meta['rosbag2_bagfile_information']['topics_with_message_count']}
    assert topics['/odom']['reliability'] == 'best_effort' and topics['/odom']['depth'] == 5
    assert topics['/body_states']['reliability'] == 'reliable'


def test_scene_with_numpy_values_is_stored_as_plain_data(tmp_path):
    record(tmp_path / 's', 3, scene={'masses': np.array([1.0, 2.0, 3.0]), 'p': np.int64(3),
                                     'path': tmp_path, 'pair': (1, 2)})
    scene = load(tmp_path / 's').scene
    assert scene['masses'] == [1.0, 2.0, 3.0] and scene['p'] == 3
    assert scene['path'] == str(tmp_path) and scene['pair'] == [1, 2]


def test_empty_bag_closes_to_a_valid_file_with_the_scene(tmp_path):
    with BagWriter(tmp_path / 'e', scene={'p': 2}) as w:
        pass
    assert w.topics == {'/crawler_sim/scene': ('std_msgs/msg/String', 1)}
    # a recording stopped before its first state is an empty run, not an error (issue 11.7)
    with pytest.warns(BagWarning, match='no states recorded'):
        run = load(tmp_path / 'e')
    assert len(run) == 0 and run.scene['p'] == 2


# --------------------------------------------------------------------------- the MCAP writer

def _mcap_bytes(make) -> bytes:
    """The same calls on a writer ``make(stream)``: definitions, metadata, 200 messages in
    several chunks with log times out of order, a flush in the middle."""
    out = io.BytesIO()
    w = make(out)
    w.start(profile='ros2', library='test')
    sid = w.register_schema('a/msg/B', 'ros2msg', b'float64 x')
    channels = [w.register_channel(f'/t{k}', 'cdr', sid, {'k': str(k)}) for k in range(3)]
    w.add_metadata('m', {'a': 'b'})
    rng = np.random.default_rng(1)
    for i in range(200):                  # several chunks, log times not monotonic
        t = int(rng.integers(0, 10**12)) if i % 17 == 0 else 10**9 + i * 10**6
        w.add_message(channels[i % 3], t, bytes(rng.integers(0, 256, size=i % 50, dtype=np.uint8)),
                      t + 5, sequence=i % 7)
        if i == 120:
            w.flush()
    w.finish()
    return out.getvalue()


def _records(data: bytes) -> tuple:
    """What mcap's own reader finds in a file: schemas, channels, messages (file order),
    metadata, and the statistics but for the chunk count."""
    from dataclasses import replace
    from mcap.reader import make_reader
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    schemas = sorted((s.id, s.name, s.encoding, s.data) for s in summary.schemas.values())
    channels = sorted((c.id, c.topic, c.schema_id, tuple(sorted(c.metadata.items())))
                      for c in summary.channels.values())
    messages = [(m.channel_id, m.log_time, m.publish_time, m.sequence, m.data)
                for _, _, m in reader.iter_messages(log_time_order=False)]
    metadata = [(m.name, m.metadata) for m in reader.iter_metadata()]
    return (schemas, channels, messages, metadata,
            replace(summary.statistics, chunk_count=0))


def test_our_mcap_writer_holds_what_the_library_writer_holds_with_definitions_outside_chunks():
    from mcap.records import Channel, Chunk, Schema
    from mcap.stream_reader import StreamReader
    from mcap.writer import CompressionType, Writer
    from crawler_sim.bag.mcapwriter import McapWriter
    ours = _mcap_bytes(lambda out: McapWriter(out, chunk_size=700))
    library = _mcap_bytes(lambda out: Writer(out, chunk_size=700,
                                             compression=CompressionType.ZSTD))
    assert _records(ours) == _records(library)
    # CRCs (chunks, summary) check out; schemas and channels are top-level records, on disk
    # before any chunk is complete
    top = [type(r) for r in StreamReader(io.BytesIO(ours), emit_chunks=True,
                                         validate_crcs=True).records]
    assert top.index(Schema) < top.index(Channel) < top.index(Chunk)
    assert top.count(Chunk) > 5


def test_our_mcap_writer_puts_definitions_on_disk_at_a_flush_before_any_message():
    """The library writes a chunk only once a message joined it: its definitions stay in
    memory until then. Ours are on disk at the first flush, readable from a file cut there."""
    from crawler_sim.bag.mcapwriter import McapWriter
    out = io.BytesIO()
    w = McapWriter(out)
    w.start(profile='ros2', library='test')
    w.register_channel('/a', 'cdr', w.register_schema('a/msg/B', 'ros2msg', b'float64 x'))
    w.flush()
    cut = out.getvalue()
    from mcap.records import Channel, Schema
    from mcap.stream_reader import StreamReader
    found = []
    with pytest.raises(EndOfFile):                 # no footer: the recording goes on
        for record in StreamReader(io.BytesIO(cut)).records:
            found.append(type(record))
    assert Schema in found and Channel in found


def test_the_mcap_writer_refuses_an_unknown_compression():
    from crawler_sim.bag.mcapwriter import McapWriter
    with pytest.raises(ValueError, match='compression'):
        McapWriter(io.BytesIO(), compression='lz4')


def test_a_message_larger_than_a_chunk_that_compresses_well_reads_back_intact(tmp_path):
    """A preloaded trajectory of 10 minutes at 100 Hz (about 3.4 MB, compressing ~2x): its chunk
    holds more than the reader lets a chunk claim for a file of that size when compressed (a
    zip-bomb guard), so the writer stores it uncompressed; before, the reader skipped it as
    damage and the run could not be replayed (issue 24)."""
    from rclpy.serialization import serialize_message
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    from crawler_sim.bag.inputs import load_inputs
    from crawler_sim.bag.mcapfile import scan
    t = np.arange(60_000) / 100.0
    msg = JointTrajectory(joint_names=['linkage_0'])
    for k, tk in enumerate(t):
        pt = JointTrajectoryPoint(positions=[0.1 + 0.02 * np.sin(tk)], velocities=[0.0],
                                  accelerations=[0.0])
        pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(k * 10_000_000,
                                                                    1_000_000_000)
        msg.points.append(pt)
    data = serialize_message(msg)
    assert len(data) > 3_000_000
    w = BagWriter(tmp_path / 'big')
    w.write('/linkage_trajectory', 'trajectory_msgs/msg/JointTrajectory', data, 5)
    w.write('/body_states', JOINT_STATE, joint_state(0), 10)
    w.close()
    files = list((tmp_path / 'big').glob('*.mcap'))
    result = scan(files[0], verify=True)
    assert not result.damage and not result.truncated
    rec = load_inputs(tmp_path / 'big')
    (item,) = rec.inputs
    assert item.kind == 'trajectory' and item.t_ns == 5
    np.testing.assert_array_equal(item.payload.positions[:, 0], 0.1 + 0.02 * np.sin(t))
