"""Fast, tolerant scanning of one MCAP file into per-channel batches of raw message bytes.

Two strategies, chosen per file:

* **indexed**: the file ends with a valid footer and its summary holds chunk indexes with message
  index offsets (what :class:`mcap.writer.Writer` and rosbag2 write). Schemas, channels, counts
  and metadata come from the summary; for each chunk only the message indexes of the wanted
  channels are read, and message positions are gathered with numpy (no per-message Python).
* **linear**: no usable footer (e.g. a recording killed with SIGKILL) or no indexes. Top-level
  records are walked in file order; each chunk's messages come from the message index records
  that follow it, and only the byte ranges of a chunk not covered by messages (schemas, channels)
  are walked record by record. A chunk with no indexes is walked fully. The walk stops at the
  first incomplete or corrupt record and marks the scan ``truncated``.

Message bytes are handed, chunk by chunk, to a *sink* that the caller's ``want(channel)``
returns for the channels it wants: a :class:`Batch` is a decompressed chunk buffer plus the start,
length and log time of each message of one channel in it, in file order. Sinks are expected to
decode what they need right away, so only one decompressed chunk is alive at a time.

Hostile files: memory is bounded by the file's size. A chunk may not claim (nor decompress to)
more than :func:`chunk_limit` bytes (twice the file size, at least 1.125 MiB: what a writer
with 1 MiB chunks produces), messages of one channel in a chunk may not
overlap (an index pointing many times at one big message would be copied many times), and only
regular files are opened (a FIFO named ``*.mcap`` would block forever).

Length: over 400 lines because the two strategies share the record parsing and the bounds
that keep hostile files harmless; splitting them would spread those checks over modules.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from io import BytesIO
import mmap
import os
from pathlib import Path
import stat
import struct
from typing import Callable
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import (
    Channel, ChunkIndex, Footer, Header, Metadata, MetadataIndex, Schema, Statistics)
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from .errors import BagError

MAGIC = b'\x89MCAP0\r\n'
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS = 0x06, 0x07, 0x08, 0x0B
OP_METADATA, OP_METADATA_INDEX, OP_DATA_END = 0x0C, 0x0D, 0x0F
RECORD_PREFIX = 9            # opcode (1) + record length (8)
MESSAGE_FIXED = 22           # channel_id 2 + sequence 4 + log_time 8 + publish_time 8
FOOTER_RECORD = RECORD_PREFIX + 20
_U64 = struct.Struct('<Q')
_U16 = struct.Struct('<H')
_CHUNK_HEAD = struct.Struct('<QQQII')   # start, end, uncompressed size, crc, compression length
CHUNK_FLOOR = (1 << 20) + (1 << 17)   # bytes a chunk may always decompress to: 1 MiB chunks
                                      # (mcap's and our writer's default) plus their last message
CHUNK_FACTOR = 2             # ... or this many times the file size


TOTAL_FACTOR = 64           # all chunks of a file: this many times its size (or TOTAL_FLOOR)
TOTAL_FLOOR = 64 << 20


def total_limit(file_size: int) -> int:
    """Largest sum of uncompressed chunk sizes [bytes] read from a file of ``file_size``."""
    return max(TOTAL_FLOOR, TOTAL_FACTOR * int(file_size))


def chunk_limit(file_size: int) -> int:
    """Largest uncompressed chunk [bytes] accepted in a file of ``file_size`` bytes."""
    return max(CHUNK_FLOOR, CHUNK_FACTOR * int(file_size))


def open_regular(path: Path) -> tuple[int, int]:
    """``(fd, size)`` of ``path`` opened read-only; BagError unless it is a regular file.

    Opened with O_NONBLOCK so that a FIFO or device does not block the open; the caller owns
    the descriptor.
    """
    flags = os.O_RDONLY | getattr(os, 'O_NONBLOCK', 0) | getattr(os, 'O_CLOEXEC', 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise BagError(f'{path}: no such file') from None
    except IsADirectoryError:
        raise BagError(f'{path}: is a directory, expected an .mcap file') from None
    except PermissionError:
        raise
    except OSError as exc:
        raise BagError(f'{path}: cannot open ({exc.strerror or exc})') from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        kind = ('a directory' if stat.S_ISDIR(info.st_mode) else 'a FIFO'
                if stat.S_ISFIFO(info.st_mode) else 'not a regular file')
        raise BagError(f'{path}: is {kind}, expected an .mcap file')
    return fd, info.st_size


class _Corrupt(Exception):
    """Internal: a record cannot be parsed; the scan stops there."""


# Everything a damaged file can raise while being parsed.
_DAMAGE = (_Corrupt, McapError, struct.error, ValueError, IndexError, KeyError, EOFError,
           OverflowError)


@dataclass
class Batch:
    """Messages of one channel inside one buffer (a decompressed chunk), in file order.

    ``starts``/``lengths`` [bytes] locate each message's data (CDR with its 4-byte header) in
    ``buffer``; ``log_times`` [ns] are the MCAP log times.
    """

    buffer: NDArray[np.uint8]
    starts: NDArray[np.int64]
    lengths: NDArray[np.int64]
    log_times: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.starts)

    def data(self, i: int) -> bytes:
        """Bytes of message ``i``."""
        a = int(self.starts[i])
        return self.buffer[a:a + int(self.lengths[i])].tobytes()


@dataclass
class Scan:
    """What :func:`scan` found in one MCAP file."""

    path: Path
    profile: str = ''
    library: str = ''
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)      # messages per channel id
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: list[Metadata] = field(default_factory=list)
    indexed: bool = False          # read through the summary
    inflated: int = 0              # bytes of chunks decompressed so far
    truncated: bool = False        # no valid end of file, or stopped at a corrupt record
    stop_reason: str = ''

    @property
    def message_count(self) -> int:
        """Total number of messages in the file."""
        return sum(self.counts.values())

    def schema_of(self, channel: Channel) -> Schema | None:
        """Schema of ``channel`` (None for schemaless channels)."""
        return self.schemas.get(channel.schema_id)

    def _saw(self, cid: int, log_times: NDArray[np.int64]) -> None:
        if len(log_times) == 0:
            return
        self.counts[cid] = self.counts.get(cid, 0) + len(log_times)
        lo, hi = int(log_times.min()), int(log_times.max())
        self.start_ns = lo if self.start_ns is None else min(self.start_ns, lo)
        self.end_ns = hi if self.end_ns is None else max(self.end_ns, hi)


Sink = Callable[[Batch], None]
Want = Callable[[Channel, 'Schema | None'], 'Sink | None']


def scan(path: Path | str, want: Want | None = None) -> Scan:
    """Read the file structure of ``path``; pass messages to the sinks ``want`` returns.

    ``want(channel, schema)`` is called once per channel (again if the file has to be re-read
    linearly after a damaged summary) and returns a callable that receives that channel's
    :class:`Batch` objects in file order, or None to skip the channel.

    Raises :class:`BagError` for a missing, empty or non-MCAP file. A truncated or partly corrupt
    file gives a :class:`Scan` with ``truncated=True`` holding everything before the damage.
    """
    path = Path(path)
    want = want or (lambda channel, schema: None)
    fd, size = open_regular(path)
    try:
        if size == 0:
            raise BagError(f'{path}: empty file, not an MCAP bag')
        with mmap.mmap(fd, 0, access=mmap.ACCESS_READ) as mm:
            return _scan_mapped(path, mm, size, want)
    except PermissionError:
        raise
    except (OSError, ValueError) as exc:
        raise BagError(f'{path}: cannot read ({exc})') from None
    finally:
        os.close(fd)


def _scan_mapped(path: Path, mm: mmap.mmap, size: int, want: Want) -> Scan:
    if size < len(MAGIC) or mm[:len(MAGIC)] != MAGIC:
        raise BagError(f'{path}: not an MCAP file (bad magic bytes)')
    result = Scan(path=path)
    if _has_footer(mm, size):
        try:
            if _scan_indexed(result, mm, size, want):
                return result
            result = Scan(path=path)          # what the summary held is read again below
        except _DAMAGE as exc:
            result = Scan(path=path, stop_reason=f'unreadable summary ({exc}); scanned linearly')
    else:
        result.truncated = True
        result.stop_reason = 'no MCAP footer (file not closed properly)'
    _scan_linear(result, mm, size, want)
    return result


# ---------------------------------------------------------------- low-level record parsing

def _has_footer(mm: mmap.mmap, size: int) -> bool:
    start = size - len(MAGIC) - FOOTER_RECORD
    return (start >= len(MAGIC) and mm[size - len(MAGIC):size] == MAGIC
            and mm[start] == OP_FOOTER and _U64.unpack_from(mm, start + 1)[0] == 20)


def _stream(content: bytes) -> ReadDataStream:
    return ReadDataStream(BytesIO(content))


def _record_at(buf, pos: int, limit: int) -> tuple[int, int, int]:
    """(opcode, content start, content end) of the record at ``pos``; _Corrupt if it overruns."""
    if pos + RECORD_PREFIX > limit:
        raise _Corrupt(f'incomplete record header at byte {pos}')
    opcode = buf[pos]
    length = _U64.unpack_from(buf, pos + 1)[0]
    end = pos + RECORD_PREFIX + length
    if end > limit:
        raise _Corrupt(f'record (opcode 0x{opcode:02x}) at byte {pos} runs past the end')
    return opcode, pos + RECORD_PREFIX, end


def decompress(compression: str, data: bytes, size: int, limit: int) -> bytes:
    """Chunk ``data`` decompressed to the ``size`` bytes its record claims, never allocating
    more than ``limit`` bytes (ValueError otherwise: a claim or a stream larger than that)."""
    if size > limit:
        raise ValueError(f'chunk claims {size} bytes uncompressed, more than the {limit} '
                         'allowed for a file of this size')
    if compression == '':
        return bytes(data)
    if compression == 'zstd':
        import zstandard
        # stream mode: the frame's own content-size field is not trusted for the allocation
        return _zstd_bounded(zstandard, data, size)
    if compression == 'lz4':
        import lz4.frame
        out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        if len(out) > size:
            raise ValueError('lz4 chunk decompresses to more than it claims')
        return out
    raise ValueError(f'unsupported chunk compression {compression!r}')


def _zstd_bounded(zstandard, data, size: int) -> bytes:
    reader = zstandard.ZstdDecompressor().stream_reader(bytes(data))
    out = reader.read(size + 1)          # at most size + 1 bytes are ever held
    while len(out) <= size:
        more = reader.read(size + 1 - len(out))
        if not more:
            break
        out += more
    if len(out) > size:
        raise ValueError('zstd chunk decompresses to more than it claims')
    return out


def _decompress(compression: str, data: bytes, size: int, limit: int) -> bytes:
    try:
        return decompress(compression, data, size, limit)
    except ValueError as exc:
        raise _Corrupt(str(exc)) from None


def _read_chunk(result: Scan, mm, content_start: int, content_end: int) -> NDArray[np.uint8]:
    """Decompressed records of the Chunk record whose content spans the given bytes.

    The CRC is checked when the writer stored one. All chunks of a file together may not
    decompress to more than :func:`total_limit` bytes (the CPU and time a scan may take).
    """
    _, _, usize, crc, clen = _CHUNK_HEAD.unpack_from(mm, content_start)
    result.inflated += usize
    if result.inflated > total_limit(len(mm)):
        raise _Corrupt(f'chunks decompress to more than {total_limit(len(mm))} bytes '
                       f'({TOTAL_FACTOR}x the file size); refusing the rest (crafted file?)')
    pos = content_start + _CHUNK_HEAD.size
    compression = bytes(mm[pos:pos + clen]).decode()
    pos += clen
    dlen = _U64.unpack_from(mm, pos)[0]
    pos += 8
    if pos + dlen > content_end:
        raise _Corrupt('chunk data runs past its record')
    try:
        raw = _decompress(compression, mm[pos:pos + dlen], usize, chunk_limit(len(mm)))
    except _Corrupt:
        raise
    except Exception as exc:          # zstd/lz4 raise their own error types
        raise _Corrupt(f'chunk does not decompress ({exc})') from None
    if len(raw) != usize:
        raise _Corrupt('chunk decompressed to the wrong size')
    if crc and zlib.crc32(raw) != crc:
        raise _Corrupt('chunk CRC mismatch (damaged data)')
    return np.frombuffer(raw, dtype=np.uint8)


def _message_index(buf, content_start: int, content_end: int) -> tuple[int, NDArray[np.uint64]]:
    """(channel id, (n, 2) array of [log_time, offset]) of a MessageIndex record's content."""
    channel_id = _U16.unpack_from(buf, content_start)[0]
    nbytes = struct.unpack_from('<I', buf, content_start + 2)[0]
    first = content_start + 6
    if first + nbytes > content_end or nbytes % 16:
        raise _Corrupt('malformed message index')
    entries = np.frombuffer(buf, dtype='<u8', count=nbytes // 8, offset=first).copy()
    return channel_id, entries.reshape(-1, 2)


# Opcode, record length and the fixed fields of a Message record, as laid out in the file.
_MESSAGE_HEAD = np.dtype({'names': ['opcode', 'length', 'channel_id', 'log_time'],
                          'formats': ['u1', '<u8', '<u2', '<u8'],
                          'offsets': [0, 1, 9, 15], 'itemsize': RECORD_PREFIX + MESSAGE_FIXED})


def _message_heads(chunk: NDArray[np.uint8], offsets: NDArray[np.int64]) -> np.ndarray:
    """Structured array of the Message record headers at ``offsets`` of ``chunk``."""
    rows = sliding_window_view(chunk, _MESSAGE_HEAD.itemsize)[offsets]     # (n, 31) copy
    return rows.view(_MESSAGE_HEAD).reshape(-1)


def _batch(chunk: NDArray[np.uint8], channel_id: int, entries: NDArray[np.uint64]) -> Batch:
    """Batch of one channel's messages from its message index ``entries`` (log_time, offset)."""
    offsets = entries[:, 1].astype(np.int64)
    log_times = entries[:, 0].astype(np.int64)
    if np.any(offsets[1:] < offsets[:-1]):          # indexes sorted by time: back to file order
        order = np.argsort(offsets, kind='stable')
        offsets, log_times = offsets[order], log_times[order]
    if len(offsets) and offsets[0] < 0:
        raise _Corrupt('message index points outside its chunk')
    if len(offsets) == 0:
        return Batch(chunk, offsets, offsets, log_times)
    if offsets[-1] + _MESSAGE_HEAD.itemsize > len(chunk):
        raise _Corrupt('message index points outside its chunk')
    heads = _message_heads(chunk, offsets)
    # each record must end before the next one starts (no message counted twice)
    ends = offsets + RECORD_PREFIX + heads['length'].astype(np.int64)
    if np.any(ends[:-1] > offsets[1:]) or np.any(heads['length'] > len(chunk)):
        raise _Corrupt('message index entries overlap (the same bytes counted twice)')
    if np.any(heads['opcode'] != OP_MESSAGE) or np.any(heads['channel_id'] != channel_id):
        raise _Corrupt('message index does not point at messages of its channel')
    if np.any(heads['log_time'].astype(np.int64) != log_times):
        raise _Corrupt('message index log times differ from the messages')
    lengths = heads['length'].astype(np.int64) - MESSAGE_FIXED
    starts = offsets + _MESSAGE_HEAD.itemsize
    if np.any(lengths < 0) or np.any(starts + lengths > len(chunk)):
        raise _Corrupt('message record runs past its chunk')
    return Batch(chunk, starts, lengths, log_times)


# ---------------------------------------------------------------- indexed strategy

def _scan_indexed(result: Scan, mm, size: int, want: Want) -> bool:
    """Fill ``result`` from the summary; False when the summary is missing or lacks indexes."""
    footer = Footer.read(_stream(mm[size - len(MAGIC) - 20:size - len(MAGIC)]))
    footer_pos = size - len(MAGIC) - FOOTER_RECORD
    if footer.summary_start == 0 or not len(MAGIC) <= footer.summary_start <= footer_pos:
        return False
    chunk_indexes: list[ChunkIndex] = []
    metadata_indexes: list[MetadataIndex] = []
    stats: Statistics | None = None
    pos = footer.summary_start
    while pos < footer_pos:
        opcode, a, b = _record_at(mm, pos, footer_pos)
        if opcode == OP_SCHEMA:
            schema = Schema.read(_stream(mm[a:b]))
            result.schemas[schema.id] = schema
        elif opcode == OP_CHANNEL:
            channel = Channel.read(_stream(mm[a:b]))
            result.channels[channel.id] = channel
        elif opcode == OP_CHUNK_INDEX:
            chunk_indexes.append(ChunkIndex.read(_stream(mm[a:b])))
        elif opcode == OP_METADATA_INDEX:
            metadata_indexes.append(MetadataIndex.read(_stream(mm[a:b])))
        elif opcode == OP_STATISTICS:
            stats = Statistics.read(_stream(mm[a:b]))
        pos = b
    if (stats is None or not chunk_indexes
            or any(not ci.message_index_offsets for ci in chunk_indexes)
            or any(cid not in result.channels for cid in stats.channel_message_counts)):
        return False
    _read_header(result, mm)
    result.indexed = True
    result.counts = {cid: n for cid, n in stats.channel_message_counts.items() if n}
    if stats.message_count:
        result.start_ns, result.end_ns = stats.message_start_time, stats.message_end_time
    for index in metadata_indexes:
        opcode, a, b = _record_at(mm, index.offset, footer_pos)
        if opcode == OP_METADATA:
            result.metadata.append(Metadata.read(_stream(mm[a:b])))
    sinks = {cid: sink for cid, ch in result.channels.items()
             if (sink := want(ch, result.schemas.get(ch.schema_id))) is not None}
    fed: dict[int, int] = {}
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        present = sorted(set(sinks) & set(ci.message_index_offsets))
        if not present:
            continue
        opcode, a, b = _record_at(mm, ci.chunk_start_offset, footer_pos)
        if opcode != OP_CHUNK:
            raise _Corrupt('chunk index does not point at a chunk')
        chunk = _read_chunk(result, mm, a, b)
        for cid in present:
            opcode, ia, ib = _record_at(mm, ci.message_index_offsets[cid], footer_pos)
            if opcode != OP_MESSAGE_INDEX:
                raise _Corrupt('message index offset does not point at a message index')
            index_cid, entries = _message_index(mm, ia, ib)
            if index_cid != cid:
                raise _Corrupt('message index of the wrong channel')
            if len(entries):
                sinks[cid](_batch(chunk, cid, entries))
                fed[cid] = fed.get(cid, 0) + len(entries)
    if any(fed.get(cid, 0) != result.counts.get(cid, 0) for cid in sinks):
        raise _Corrupt('message indexes disagree with the statistics')
    return True


def _read_header(result: Scan, mm) -> None:
    opcode, a, b = _record_at(mm, len(MAGIC), len(mm))
    if opcode == OP_HEADER:
        header = Header.read(_stream(mm[a:b]))
        result.profile, result.library = header.profile, header.library


# ---------------------------------------------------------------- linear strategy

def _scan_linear(result: Scan, mm, size: int, want: Want) -> None:
    """Walk top-level records from the start; stop (truncated) at the first damaged record."""
    wanted: dict[int, Sink | None] = {}
    pos = len(MAGIC)
    try:
        while pos < size:
            opcode, a, b = _record_at(mm, pos, size)
            if opcode == OP_HEADER:
                header = Header.read(_stream(mm[a:b]))
                result.profile, result.library = header.profile, header.library
            elif opcode in (OP_SCHEMA, OP_CHANNEL):
                _add_definition(result, opcode, mm[a:b], want, wanted)
            elif opcode == OP_MESSAGE:
                _add_loose_message(result, mm, a, b, wanted)
            elif opcode == OP_METADATA:
                result.metadata.append(Metadata.read(_stream(mm[a:b])))
            elif opcode == OP_CHUNK:
                b = _linear_chunk(result, mm, size, a, b, want, wanted)
            elif opcode in (OP_DATA_END, OP_FOOTER):
                return                      # the summary repeats what was seen already
            pos = b
    except _DAMAGE as exc:
        result.truncated = True
        reason = f'stopped at byte {pos} of {size}: {exc}'
        result.stop_reason = f'{result.stop_reason}; {reason}' if result.stop_reason else reason


def _add_definition(result: Scan, opcode: int, content: bytes, want: Want,
                    wanted: dict[int, Sink | None]) -> None:
    if opcode == OP_SCHEMA:
        schema = Schema.read(_stream(content))
        result.schemas.setdefault(schema.id, schema)
    else:
        channel = Channel.read(_stream(content))
        if channel.id not in result.channels:
            result.channels[channel.id] = channel
            wanted[channel.id] = want(channel, result.schemas.get(channel.schema_id))


def _add_loose_message(result: Scan, buf, a: int, b: int,
                       wanted: dict[int, Sink | None]) -> None:
    """A Message record outside any chunk (unchunked files)."""
    cid = _U16.unpack_from(buf, a)[0]
    log_time = np.array([_U64.unpack_from(buf, a + 6)[0]], dtype=np.int64)
    if cid not in result.channels:
        raise _Corrupt(f'message on unknown channel {cid}')
    result._saw(cid, log_time)
    sink = wanted.get(cid)
    if sink is not None:
        data = np.frombuffer(bytes(buf[a + MESSAGE_FIXED:b]), dtype=np.uint8)
        sink(Batch(data, np.zeros(1, np.int64), np.array([len(data)], np.int64), log_time))


def _linear_chunk(result: Scan, mm, size: int, a: int, b: int, want: Want,
                  wanted: dict[int, Sink | None]) -> int:
    """Process one chunk and the message indexes after it; return the position after them."""
    chunk = _read_chunk(result, mm, a, b)
    indexes: dict[int, NDArray[np.uint64]] = {}
    pos = b
    complete_indexes = False
    while pos < size:
        try:
            opcode, ia, ib = _record_at(mm, pos, size)
        except _Corrupt:
            break                           # indexes cut off: walk the chunk instead
        if opcode != OP_MESSAGE_INDEX:
            complete_indexes = True
            break
        cid, entries = _message_index(mm, ia, ib)
        indexes[cid] = entries
        pos = ib
    else:
        complete_indexes = True
    if complete_indexes and indexes:
        _chunk_from_indexes(result, chunk, indexes, want, wanted)
    else:
        _walk(result, chunk, 0, len(chunk), want, wanted, collect_messages=True)
    return pos


def _chunk_from_indexes(result: Scan, chunk: NDArray[np.uint8],
                        indexes: dict[int, NDArray[np.uint64]], want: Want,
                        wanted: dict[int, Sink | None]) -> None:
    batches = {cid: _batch(chunk, cid, entries) for cid, entries in indexes.items()
               if len(entries)}
    # Walk only the bytes not covered by messages: schema and channel records live there.
    for start, end in _gaps(batches.values(), len(chunk)):
        _walk(result, chunk, start, end, want, wanted, collect_messages=False)
    for cid, batch in batches.items():
        if cid not in result.channels:
            raise _Corrupt(f'messages on unknown channel {cid}')
        result._saw(cid, batch.log_times)
        if (sink := wanted.get(cid)) is not None:
            sink(batch)


def _gaps(batches, size: int) -> list[tuple[int, int]]:
    """Byte ranges of a chunk of ``size`` bytes that no message record of ``batches`` covers."""
    head = RECORD_PREFIX + MESSAGE_FIXED
    starts = np.concatenate([b.starts - head for b in batches] or [np.zeros(0, np.int64)])
    ends = np.concatenate([b.starts + b.lengths for b in batches] or [np.zeros(0, np.int64)])
    if len(starts) == 0:
        return [(0, size)] if size else []
    order = np.argsort(starts, kind='stable')
    starts, reach = starts[order], np.maximum.accumulate(ends[order])
    gaps = [(0, int(starts[0]))] if starts[0] > 0 else []
    holes = np.flatnonzero(starts[1:] > reach[:-1])
    gaps += [(int(reach[i]), int(starts[i + 1])) for i in holes]
    if reach[-1] < size:
        gaps.append((int(reach[-1]), size))
    return gaps


def _walk(result: Scan, chunk: NDArray[np.uint8], start: int, end: int, want: Want,
          wanted: dict[int, Sink | None], *, collect_messages: bool) -> None:
    """Walk the records of ``chunk[start:end]`` one by one (slow path, few records)."""
    buf = chunk.data
    found: dict[int, tuple[list[int], list[int], list[int]]] = {}
    pos = start
    while pos < end:
        opcode, a, b = _record_at(buf, pos, end)
        if opcode in (OP_SCHEMA, OP_CHANNEL):
            _add_definition(result, opcode, bytes(buf[a:b]), want, wanted)
        elif opcode == OP_MESSAGE and collect_messages:
            cid = _U16.unpack_from(buf, a)[0]
            starts, lengths, times = found.setdefault(cid, ([], [], []))
            starts.append(a + MESSAGE_FIXED)
            lengths.append(b - a - MESSAGE_FIXED)
            times.append(_U64.unpack_from(buf, a + 6)[0])
        pos = b
    for cid, (starts, lengths, times) in found.items():
        if cid not in result.channels:
            raise _Corrupt(f'messages on unknown channel {cid}')
        batch = Batch(chunk, np.array(starts, np.int64), np.array(lengths, np.int64),
                      np.array(times, dtype=np.uint64).astype(np.int64))
        result._saw(cid, batch.log_times)
        if (sink := wanted.get(cid)) is not None:
            sink(batch)
