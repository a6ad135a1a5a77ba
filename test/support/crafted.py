"""Hostile MCAP files, built byte by byte from the MCAP spec, for tests and the bag benchmark.

Each builder writes one file that a careless reader turns into a huge allocation, a hang or
duplicated data (issue 11, point 6), and returns its path. Records are packed here by hand (not
with the mcap library, whose writer refuses to produce such files): opcode u8, content length
u64, then the fields in spec order; strings and byte arrays carry a u32 length.

:func:`node_bag` is the other kind: a well-formed sim_node bag (the package's own writer) whose
``~/plant_inputs`` journal holds whatever entries a test gives it (issue 38 item 6).
"""
from __future__ import annotations

import os
from pathlib import Path
import struct
from typing import Callable

import yaml

MAGIC = b'\x89MCAP0\r\n'
JOINT_STATE = 'sensor_msgs/msg/JointState'


def _str(text: str | bytes) -> bytes:
    data = text.encode() if isinstance(text, str) else text
    return struct.pack('<I', len(data)) + data


def _record(opcode: int, content: bytes) -> bytes:
    return struct.pack('<BQ', opcode, len(content)) + content


def header() -> bytes:
    """Magic and a Header record of profile ros2."""
    return MAGIC + _record(0x01, _str('ros2') + _str('crafted'))


def schema_and_channel(topic: str = '/body_states', type_name: str = JOINT_STATE) -> bytes:
    """Schema 1 (ros2msg, a one-line definition) and Channel 1 on ``topic`` (cdr)."""
    schema = _record(0x03, struct.pack('<H', 1) + _str(type_name) + _str('ros2msg')
                     + _str(b'float64[] position'))
    channel = _record(0x04, struct.pack('<HH', 1, 1) + _str(topic) + _str('cdr')
                      + struct.pack('<I', 0))
    return schema + channel


def message(data: bytes, t_ns: int, channel_id: int = 1) -> bytes:
    """A Message record."""
    return _record(0x05, struct.pack('<HIQQ', channel_id, 0, t_ns, t_ns) + data)


def chunk(records: bytes, *, compression: str = 'zstd', claim: int | None = None,
          payload: bytes | None = None) -> bytes:
    """A Chunk record of ``records``; ``claim`` overrides the uncompressed size it states and
    ``payload`` the compressed bytes it holds."""
    if payload is None:
        if compression == 'zstd':
            import zstandard
            payload = zstandard.ZstdCompressor(level=19).compress(records)
        else:
            payload = records
    size = len(records) if claim is None else claim
    content = (struct.pack('<QQQI', 0, 0, size, 0) + _str(compression)
               + struct.pack('<Q', len(payload)) + payload)
    return _record(0x06, content)


def message_index(entries: list[tuple[int, int]], channel_id: int = 1) -> bytes:
    """A MessageIndex record of (log_time, offset) pairs."""
    body = b''.join(struct.pack('<QQ', t, off) for t, off in entries)
    return _record(0x07, struct.pack('<HI', channel_id, len(body)) + body)


def joint_state_cdr(t_ns: int, position: float = 0.0) -> bytes:
    """CDR of a JointState with one joint 'body_0' (little endian, header included)."""
    sec, nsec = divmod(t_ns, 1_000_000_000)
    out = b'\x00\x01\x00\x00' + struct.pack('<iI', sec, nsec) + _str(b'\x00')   # stamp, frame ''
    out += b'\x00' * (-(len(out) - 4) % 4) + struct.pack('<I', 1) + _str(b'body_0\x00')
    out += b'\x00' * (-(len(out) - 4) % 4)
    for value in (position, 0.0, 0.0):
        out += struct.pack('<I', 1)
        out += b'\x00' * (-(len(out) - 4) % 8) + struct.pack('<d', value)
    return out


def _pad_to(path: Path, parts: list[bytes], size: int) -> Path:
    """Write ``parts`` and pad with a harmless unknown record (opcode 0x80) to ``size`` bytes."""
    data = b''.join(parts)
    room = size - len(data) - 9
    if room > 0:
        data += _record(0x80, bytes(room))
    path.write_bytes(data)
    return path


def zstd_bomb(path: Path, size: int = 1 << 20) -> Path:
    """Chunks of 64 MiB of zeros, each ~2 KiB compressed, stating their true size."""
    import zstandard
    bomb = zstandard.ZstdCompressor(level=19).compress(bytes(64 << 20))
    parts = [header(), schema_and_channel()]
    while sum(map(len, parts)) + len(bomb) + 64 < size - 64:
        parts.append(chunk(b'', claim=64 << 20, payload=bomb))
    return _pad_to(path, parts, size)


def zstd_liar(path: Path, size: int = 1 << 20) -> Path:
    """A chunk that claims 1 KiB but decompresses to 256 MiB (frame without content size)."""
    import zstandard
    compressor = zstandard.ZstdCompressor(level=19, write_content_size=False)
    bomb = compressor.compress(bytes(256 << 20))
    return _pad_to(path, [header(), schema_and_channel(), chunk(b'', claim=1024, payload=bomb)],
                   size)


def overlapping_index(path: Path, size: int = 1 << 20) -> Path:
    """One chunk holding one 256 KiB message and an index listing it 30,000 times: a reader that
    copies each indexed message allocates 30,000 x 256 KiB = 7.3 GiB."""
    body = joint_state_cdr(0) + bytes(256 << 10)
    records = message(body, 0)
    parts = [header(), schema_and_channel(), chunk(records)]
    parts.append(message_index([(0, 0)] * 30_000))
    return _pad_to(path, parts, size)


def message_flood(path: Path, size: int = 1 << 20) -> Path:
    """Many chunks of 1 MiB (within the per-chunk limit) of tiny, identical, valid JointState
    messages: each compresses ~1000:1, so the file decodes to far more than its size."""
    one = message(joint_state_cdr(0, 1.0), 0)
    records = one * ((1 << 20) // len(one) - 1)
    block = chunk(records)
    parts = [header(), schema_and_channel()]
    while sum(map(len, parts)) + len(block) < size - 64:
        parts.append(block)
    return _pad_to(path, parts, size)


def huge_lengths(path: Path, size: int = 1 << 20) -> Path:
    """Records whose length fields claim 2**63 bytes, inside and outside a chunk."""
    inner = struct.pack('<BQ', 0x05, 1 << 63) + bytes(32)
    parts = [header(), schema_and_channel(), chunk(inner, compression=''),
             struct.pack('<BQ', 0x03, 1 << 63)]
    return _pad_to(path, parts, size)


def fifo(path: Path) -> Path:
    """A FIFO named ``*.mcap`` (opening it for reading blocks until a writer appears)."""
    os.mkfifo(path)
    return path


def fifo_in_bag(path: Path) -> Path:
    """A bag directory whose only ``*.mcap`` is a FIFO."""
    path.mkdir()
    fifo(path / f'{path.name}_0.mcap')
    return path


def repeated_metadata(path: Path, good_mcap: Path, repeats: int = 200) -> Path:
    """A bag directory whose metadata.yaml lists its one (valid) .mcap ``repeats`` times."""
    path.mkdir()
    name = f'{path.name}_0.mcap'
    (path / name).write_bytes(good_mcap.read_bytes())
    info = {'rosbag2_bagfile_information': {
        'version': 9, 'storage_identifier': 'mcap', 'relative_file_paths': [name] * repeats}}
    (path / 'metadata.yaml').write_text(yaml.safe_dump(info))
    return path


#: name -> builder(path) of the single-file attacks (1 MB each)
FILES: dict[str, Callable[[Path], Path]] = {
    'zstd_bomb': zstd_bomb, 'zstd_liar': zstd_liar, 'overlapping_index': overlapping_index,
    'message_flood': message_flood, 'huge_lengths': huge_lengths,
}



def string_cdr(text: str | bytes) -> bytes:
    """CDR of a ``std_msgs/msg/String`` holding ``text`` (bytes: as they are, even if they are
    not UTF-8)."""
    data = text.encode() if isinstance(text, str) else text
    return b'\x00\x01\x00\x00' + struct.pack('<I', len(data) + 1) + data + b'\x00'


#: the journal of :func:`node_bag`'s run: one command at t = 0, as sim_node writes it
GOOD_JOURNAL: list[tuple[int, str | bytes]] = [
    (0, '{"seq": 1, "kind": "command", "lengths": [0.12]}')]


def node_bag(path: Path, journal: list[tuple[int, str | bytes]] | None = None,
             until_ns: int = 200_000_000) -> Path:
    """A sim_node bag of the default plant (the node's parameters as its scene) driven by
    one command of 0.12 m at t = 0 for ``until_ns`` [ns]: the states the plant's engine gives
    (``core.plant.replay``, what the node publishes), recorded with the node's topics by the
    package's writer, and on ``/crawler_sim/plant_inputs`` the ``journal`` entries (sim time
    [ns], JSON text or raw bytes) instead of :data:`GOOD_JOURNAL`."""
    from crawler_sim.bag import Recorder
    from crawler_sim.bag.topics import PLANT_INPUTS
    from crawler_sim.core.plant.config import PlantConfig
    from crawler_sim.core.plant.replay import Input, replay

    values = dict(PlantConfig.defaults().values)
    snaps = replay(values, [Input(0, 'command', [0.12])], until_ns)
    with Recorder(path, scene=values, flush_interval=None) as rec:
        for t_ns, entry in GOOD_JOURNAL if journal is None else journal:
            rec.writer.write(PLANT_INPUTS.name(''), PLANT_INPUTS.type, string_cdr(entry), t_ns)
        for t_ns, x, v in zip(snaps.t_ns, snaps.x, snaps.v):
            zeros = [0.0] * len(x)
            rec.record_state(t_ns / 1e9, x, v, zeros, [0] * len(x), zeros[1:], zeros[1:],
                             zeros[1:])
    return path


__all__ = ['FILES', 'GOOD_JOURNAL', 'fifo', 'fifo_in_bag', 'joint_state_cdr', 'node_bag',
           'repeated_metadata', 'string_cdr']
