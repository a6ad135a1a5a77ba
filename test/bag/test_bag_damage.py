"""Damage in the middle of a file (issue 25): one corrupted field of one chunk costs that chunk,
never the chunks after it.

A real recording with many chunks is corrupted in one field of one chunk, in several ways, with
its summary kept (the reader can follow the chunk indexes) and cut off (the reader has to find
the next record itself). The messages of each chunk are listed beforehand with the mcap
library (``breakup_chunk`` on the intact file), independently of the code under test; then

* ``recover`` must copy every message of every other chunk, byte for byte, into a bag that
  rosbags and mcap_ros2 read;
* ``load`` must return every state whose messages all lie in other chunks, with their values;
* ``info`` must say DAMAGED, which chunk, and how many messages were lost.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
import struct
import warnings

from mcap.data_stream import ReadDataStream
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk
from mcap_ros2.decoder import DecoderFactory
import numpy as np
from numpy.testing import assert_array_equal
import pytest

from crawler_sim.bag import BagWarning, info, load, record_arrays, recover
from test.support.synthetic import synthetic_arrays

STEPS, P = 1302, 3
STATE_TOPICS = ('/body_states', '/joint_states', '/contact_states')

Key = tuple[str, int, bytes]          # (topic, log time [ns], message bytes)


@dataclass
class Layout:
    """Where the records of the intact file are (MCAP spec: opcode u8, length u64, content)."""

    data: bytes
    chunks: list[int]                 # byte offset of each Chunk record
    indexes: dict[int, list[int]]     # chunk number -> offsets of its MessageIndex records
    data_end: int                     # offset of the DataEnd record
    messages: list[list[Key]]         # per chunk, its messages (from the mcap library)


def read_layout(path: Path) -> Layout:
    data = path.read_bytes()
    with open(path, 'rb') as f:
        topics = {cid: ch.topic for cid, ch in make_reader(f).get_summary().channels.items()}
    pos, chunks, indexes, messages = 8, [], {}, []
    while True:
        opcode = data[pos]
        length = struct.unpack_from('<Q', data, pos + 1)[0]
        if opcode == 0x06:
            chunks.append(pos)
            record = Chunk.read(ReadDataStream(BytesIO(data[pos + 9:pos + 9 + length])))
            messages.append([(topics[r.channel_id], r.log_time, bytes(r.data))
                             for r in breakup_chunk(record, validate_crc=True)
                             if isinstance(r, Message)])
        elif opcode == 0x07:
            indexes.setdefault(len(chunks) - 1, []).append(pos)
        elif opcode == 0x0F:
            return Layout(data, chunks, indexes, pos, messages)
        pos += 9 + length


@pytest.fixture(scope='module')
def original(tmp_path_factory) -> tuple[Path, Layout]:
    """A recording of 1302 states (5 topics per step plus commands) in 16 KB chunks."""
    path = tmp_path_factory.mktemp('damage') / 'run'
    a = synthetic_arrays(STEPS, P, seed=11)
    masses = a.pop('masses')
    record_arrays(path, **a, masses=masses, scene={'p': P},
                  commands=(a['t'][::10], a['lengths'][::10]), chunk_size=16_000)
    layout = read_layout(path / 'run_0.mcap')
    assert len(layout.chunks) >= 20
    return path, layout


def corrupt(layout: Layout, k: int, how: str) -> bytearray:
    """The file with one field of chunk ``k`` (or of its first message index) changed."""
    data = bytearray(layout.data)
    pos = layout.chunks[k]
    content = pos + 9                 # start, end, uncompressed size, crc, compression, records
    clen = struct.unpack_from('<I', data, content + 28)[0]
    length = struct.unpack_from('<Q', data, pos + 1)[0]
    if how == 'uncompressed_size_huge':
        struct.pack_into('<Q', data, content + 16, 1 << 40)
    elif how == 'uncompressed_size_plus_one':
        struct.pack_into('<Q', data, content + 16,
                         struct.unpack_from('<Q', data, content + 16)[0] + 1)
    elif how == 'compression_name':
        data[content + 32:content + 32 + clen] = b'zst!'[:clen]
    elif how == 'records_length_huge':
        struct.pack_into('<Q', data, content + 32 + clen, 1 << 63)
    elif how == 'record_length_huge':
        struct.pack_into('<Q', data, pos + 1, 1 << 63)
    elif how == 'record_length_short':
        struct.pack_into('<Q', data, pos + 1, length - 100)
    elif how == 'opcode':
        data[pos] = 0x55
    elif how == 'compressed_byte':
        data[content + length // 2] ^= 0xFF
    elif how == 'message_index_length':
        struct.pack_into('<Q', data, layout.indexes[k][0] + 1, 1 << 63)
    else:
        raise AssertionError(how)
    return data


WAYS = ['uncompressed_size_huge', 'uncompressed_size_plus_one', 'compression_name',
        'records_length_huge', 'record_length_huge', 'record_length_short', 'opcode',
        'compressed_byte', 'message_index_length']


def rosbags_messages(bag: Path) -> Counter:
    from rosbags.highlevel import AnyReader
    out: Counter = Counter()
    with AnyReader([bag]) as reader:
        for connection, t, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)          # each one decodes
            out[(connection.topic, t, bytes(raw))] += 1
    return out


def mcap_ros2_count(bag: Path) -> int:
    with open(next(bag.glob('*.mcap')), 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return sum(1 for *_, msg in reader.iter_decoded_messages() if msg is not None)


@pytest.mark.parametrize('summary', ['kept', 'cut'])
@pytest.mark.parametrize('how', WAYS)
def test_one_damaged_chunk_costs_only_its_own_messages(original, tmp_path, how, summary):
    path, layout = original
    k = len(layout.chunks) // 3
    data = corrupt(layout, k, how)
    if summary == 'cut':
        data = data[:layout.data_end]        # no DataEnd, no summary, no footer: a linear walk
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(data))
    # only the index is damaged: the chunk itself is intact and every message can be read
    index_only = how == 'message_index_length'
    lost = Counter() if index_only else Counter(layout.messages[k])
    intact = Counter(m for chunk in layout.messages for m in chunk) - lost

    result = recover(bad, tmp_path / 'fixed')
    copied = rosbags_messages(tmp_path / 'fixed')
    assert copied == intact                   # every intact message, byte for byte, nothing else
    assert result.messages == sum(intact.values()) == mcap_ros2_count(tmp_path / 'fixed')
    assert not result.complete and result.problems
    assert result.lost == sum(lost.values())

    with pytest.warns(BagWarning, match='damaged'):
        run = load(bad)
    full = load(path)
    # the states none of whose messages were in the damaged chunk, with their values
    gone = {t for topic, t, _ in lost if topic in STATE_TOPICS}
    keep = ~np.isin(full.t_ns, list(gone))
    assert_array_equal(run.t_ns, full.t_ns[keep])
    for name in ('x', 'v', 'friction', 'contact', 'lengths', 'linkage_force'):
        assert_array_equal(getattr(run, name), getattr(full, name)[keep])
    assert run.truncated == (not index_only or summary == 'cut')   # cut: no footer either

    text = info(bad)
    assert 'DAMAGED' in text and 'status:    complete' not in text
    if summary == 'kept':
        assert f'chunk {k + 1} of {len(layout.chunks)} at byte {layout.chunks[k]}' in text
    n_lost = sum(lost.values())
    assert (f'{n_lost} messages lost' if n_lost else 'no message lost') in text


def test_a_message_index_of_length_2_63_loads_every_state(original, tmp_path):
    # the figure: 45 of 1302 states before the fix
    path, layout = original
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(corrupt(layout, 1, 'message_index_length')))
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', BagWarning)
        assert len(load(bad)) == STEPS


def test_two_damaged_chunks_are_both_reported_and_skipped(original, tmp_path):
    path, layout = original
    first, second = 3, len(layout.chunks) - 4
    data = corrupt(layout, first, 'uncompressed_size_huge')
    pos = layout.chunks[second]
    data[pos + 9 + 100] ^= 0xFF                                   # damage the second's data
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(bytes(data))
    text = info(bad)
    n = len(layout.chunks)
    assert f'chunk {first + 1} of {n}' in text and f'chunk {second + 1} of {n}' in text
    lost = len(layout.messages[first]) + len(layout.messages[second])
    assert f'2 damaged parts skipped, {lost} messages lost' in text
    result = recover(bad, tmp_path / 'fixed')
    assert result.messages == sum(map(len, layout.messages)) - lost


def test_a_file_whose_reading_is_refused_half_way_is_not_called_complete(original, tmp_path,
                                                                         monkeypatch):
    # the bound on decompressed bytes (a chunk bomb's defence), lowered to hit this real file
    from crawler_sim.bag import mcapfile
    path, layout = original
    monkeypatch.setattr(mcapfile, 'TOTAL_FLOOR', 100_000)
    monkeypatch.setattr(mcapfile, 'TOTAL_FACTOR', 0)
    result = recover(path, tmp_path / 'fixed')
    assert not result.complete and 'refusing the rest' in result.problems[0]
    assert 0 < result.messages < sum(map(len, layout.messages))
    assert 'INCOMPLETE' in info(path)
