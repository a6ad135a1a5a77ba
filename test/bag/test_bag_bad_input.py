"""Bad input never ends in a traceback: BagError with a one-line message, or a BagWarning."""
from __future__ import annotations

from pathlib import Path

from mcap_ros2.writer import Writer as Ros2Writer
import numpy as np
from numpy.testing import assert_array_equal
import pytest

from crawler_sim.bag import (BagError, BagWarning, BagWriter, info, load, plot, record_arrays,
                             recover)
from crawler_sim.bag import schema as bag_schema
from test.support.synthetic import synthetic_arrays


def one_line_error(func, *args, match: str) -> BagError:
    with pytest.raises(BagError, match=match) as excinfo:
        func(*args)
    assert '\n' not in str(excinfo.value)
    return excinfo.value


@pytest.fixture(scope='module')
def good_bag(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('good') / 'run'
    a = synthetic_arrays(600, 3, seed=4)
    masses = a.pop('masses')
    record_arrays(path, **a, masses=masses, scene={'p': 3}, chunk_size=16_384)
    return path


@pytest.fixture(scope='module')
def foreign_mcap(tmp_path_factory) -> Path:
    """An MCAP written by another program (plain mcap_ros2 Writer) with unrelated topics."""
    from std_msgs.msg import String
    path = tmp_path_factory.mktemp('foreign') / 'chatter.mcap'
    with open(path, 'wb') as f:
        writer = Ros2Writer(f)
        schema = writer.register_msgdef('std_msgs/msg/String',
                                        bag_schema.full_text('std_msgs/msg/String'))
        for i in range(5):
            writer.write_message('/chatter', schema, String(data=f'hello {i}'),
                                 log_time=i * 1000, publish_time=i * 1000)
        writer.finish()
    return path


@pytest.mark.parametrize('func', [load, info, recover], ids=['load', 'info', 'recover'])
def test_a_missing_path_is_a_bag_error(tmp_path, func):
    one_line_error(func, tmp_path / 'nope', match='no such file')


def test_plot_of_a_missing_path_is_a_bag_error(tmp_path):
    one_line_error(plot, tmp_path / 'nope', tmp_path / 'x.png', match='no such file')


@pytest.mark.parametrize('func', [load, info], ids=['load', 'info'])
def test_an_empty_file_is_a_bag_error(tmp_path, func):
    (tmp_path / 'empty.mcap').touch()
    one_line_error(func, tmp_path / 'empty.mcap', match='empty file')


@pytest.mark.parametrize('func', [load, info], ids=['load', 'info'])
def test_random_bytes_are_a_bag_error(tmp_path, func):
    path = tmp_path / 'noise.mcap'
    path.write_bytes(np.random.default_rng(1).bytes(4096))
    one_line_error(func, path, match='not an MCAP file')


def test_a_directory_without_mcap_files_is_a_bag_error(tmp_path):
    (tmp_path / 'd').mkdir()
    one_line_error(load, tmp_path / 'd', match='no .mcap file')


def test_magic_bytes_alone_load_as_a_bag_without_crawler_topics(tmp_path):
    path = tmp_path / 'magic.mcap'
    path.write_bytes(b'\x89MCAP0\r\n')
    with pytest.warns(BagWarning):
        one_line_error(load, path, match='no crawler_sim topics')


def test_an_mcap_from_another_program_without_crawler_topics_is_a_bag_error(foreign_mcap):
    error = one_line_error(load, foreign_mcap, match='no crawler_sim topics')
    assert '/chatter' in str(error)


def test_info_still_describes_an_mcap_from_another_program(foreign_mcap):
    text = info(foreign_mcap)
    assert '/chatter' in text and 'std_msgs/msg/String' in text
    assert 'status:    complete' in text
    assert 'messages:  5' in text


def test_a_truncated_file_loads_its_first_part_with_a_warning(good_bag, tmp_path):
    data = (good_bag / 'run_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) * 2 // 3])
    with pytest.warns(BagWarning, match='no MCAP footer'):
        run = load(cut)
    full = load(good_bag)
    assert run.truncated and 0 < len(run) < len(full)
    assert_array_equal(run.x, full.x[:len(run)])
    assert_array_equal(run.contact, full.contact[:len(run)])


def test_a_directory_with_a_bad_metadata_yaml_falls_back_to_its_mcap_files(good_bag, tmp_path):
    import shutil
    copy = tmp_path / 'run'
    shutil.copytree(good_bag, copy)
    (copy / 'metadata.yaml').write_text(': not yaml [')
    assert len(load(copy)) == 600


def chunk_middle(data: bytes, fraction: float) -> int:
    """A byte in the middle of the first Chunk record (opcode 0x06) at or after ``fraction`` of
    the file, found by walking the top-level records (MCAP spec: opcode u8, length u64)."""
    pos, chunks = 8, []
    while pos + 9 <= len(data):
        length = int.from_bytes(data[pos + 1:pos + 9], 'little')
        if data[pos] == 0x06:
            chunks.append((pos, length))
        if data[pos] == 0x0F:                 # DataEnd
            break
        pos += 9 + length
    pos, length = next(c for c in chunks if c[0] >= fraction * len(data))
    return pos + 9 + length // 2


@pytest.mark.parametrize('offset', [0.3, 0.6])
def test_corrupted_chunk_bytes_give_a_partial_load_or_bag_error(good_bag, tmp_path, offset):
    data = bytearray((good_bag / 'run_0.mcap').read_bytes())
    start = chunk_middle(data, offset)
    data[start:start + 64] = bytes(64)                # zeros inside a compressed chunk
    path = tmp_path / 'corrupt.mcap'
    path.write_bytes(bytes(data))
    with pytest.warns(BagWarning, match='damaged: chunk'):
        run = load(path)
    full = load(good_bag)
    assert len(run) < len(full)
    # the states of the damaged chunk are missing, those of every chunk after it are not
    kept = np.isin(full.t_ns, run.t_ns)
    assert kept[-1] and not kept.all()
    assert_array_equal(run.x, full.x[kept])
    assert_array_equal(run.contact, full.contact[kept])


def test_joint_states_with_empty_effort_load_with_nan_friction(tmp_path):
    """Other publishers may leave effort empty (the rosbags trap): NaN friction, no error.

    The loader falls back to rclpy for such layouts and marks the missing values NaN.
    """
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Int8MultiArray
    with BagWriter(tmp_path / 'b') as w:
        for i in range(20):
            body = JointState(name=['body_0', 'body_1'], position=[i, i + 0.5],
                              velocity=[1.0, 2.0], effort=[])
            body.header.stamp.sec = i
            joint = JointState(name=['linkage_0'], position=[0.5], velocity=[], effort=[])
            joint.header.stamp.sec = i
            w.write('/body_states', 'sensor_msgs/msg/JointState', body, i * 10**9)
            w.write('/joint_states', 'sensor_msgs/msg/JointState', joint, i * 10**9)
            w.write('/contact_states', 'std_msgs/msg/Int8MultiArray',
                    Int8MultiArray(data=[0, 1]), i * 10**9)
    run = load(tmp_path / 'b')
    assert_array_equal(run.t, np.arange(20.0))
    assert_array_equal(run.x[:, 1], np.arange(20) + 0.5)
    assert_array_equal(run.v, np.tile([1.0, 2.0], (20, 1)))
    assert np.isnan(run.friction).all() and run.friction.shape == (20, 2)
    assert_array_equal(run.lengths, np.full((20, 1), 0.5))
    assert np.isnan(run.rates).all()


def test_topics_of_unexpected_types_are_not_mistaken_for_crawler_topics(tmp_path):
    from std_msgs.msg import String
    with BagWriter(tmp_path / 'b') as w:
        w.write('/body_states', 'std_msgs/msg/String', String(data='x'), 0)
    one_line_error(load, tmp_path / 'b', match='no crawler_sim topics')


def test_plot_of_a_bag_without_states_is_a_bag_error(tmp_path):
    from sensor_msgs.msg import JointState
    with BagWriter(tmp_path / 'b') as w:
        w.write('/body_states', 'sensor_msgs/msg/JointState', JointState(), 0)
    data = (tmp_path / 'b' / 'b_0.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:200])
    with pytest.warns(BagWarning):
        one_line_error(plot, tmp_path / 'cut.mcap', tmp_path / 'x.png', match='cut.mcap')
