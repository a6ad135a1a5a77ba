"""Fast, tolerant scanning of one MCAP file into per-channel batches of raw message bytes.

Two strategies, chosen per file:

* **indexed**: the file ends with a valid footer and its summary holds chunk indexes with message
  index offsets (what :class:`mcap.writer.Writer` and rosbag2 write), and the message indexes
  add up to the statistics. Schemas, channels and metadata come from the summary; for each chunk
  only the message indexes of the wanted channels are read, and message positions are gathered
  with numpy (no per-message Python).
* **linear**: no usable footer (e.g. a recording killed with SIGKILL) or summary. Top-level
  records are walked in file order; each chunk's messages come from the message index records
  that follow it, and only the byte ranges of a chunk not covered by messages (schemas, channels)
  are walked record by record. A chunk with no (or damaged) indexes is walked fully.

Damage is skipped, not fatal: a chunk that cannot be read (a corrupted header field, a bad CRC,
data that does not decompress) is recorded as a :class:`Damage` with the messages its indexes
list, and reading goes on with the next chunk. In the indexed strategy the summary says where
that is; in the linear one a damaged record *length* is stepped over by searching for the next
record that fits the spec exactly (:mod:`.resync`), never by trusting a length beyond the file's
end. A message index that does not match its chunk is replaced by a walk of the chunk's records.
The scan ends ``truncated`` only where nothing intact follows (a file cut short).

Message bytes are handed, chunk by chunk, to a *sink* that the caller's ``want(channel)``
returns for the channels it wants: a :class:`Batch` is a decompressed chunk buffer plus the start,
length and log time of each message of one channel in it, in file order. The batches of one
chunk are handed over one after the other, before the next chunk is read. Sinks are expected to
decode what they need right away, so only one decompressed chunk is alive at a time. A sink that
raises ``ValueError`` (undecodable data) makes that batch damage too.

Hostile files: memory is bounded by the file's size. A chunk may not claim (nor decompress to)
more than :func:`chunk_limit` bytes (twice the file size, at least 1.125 MiB: what a writer
with 1 MiB chunks produces), all chunks together not more than :func:`total_limit` (the scan
stops there), messages of one channel in a chunk may not overlap (an index pointing many times
at one big message would be copied many times), and only regular files are opened (a FIFO
named ``*.mcap`` would block forever).

This is the package's one reader of MCAP records: ``load``, ``info``, ``recover`` and the replay
node all go through :func:`scan` (and :func:`check_magic`, its first check on its own). The two
strategies live together with what they share: the record parsing, the damage bookkeeping and
the bounds that keep hostile files harmless; the search for the next record after damage is in
:mod:`.resync`.
"""
from __future__ import annotations

from collections import Counter
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
from .resync import next_record

MAGIC = b'\x89MCAP0\r\n'
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS = 0x06, 0x07, 0x08, 0x0B
OP_METADATA, OP_METADATA_INDEX, OP_DATA_END = 0x0C, 0x0D, 0x0F
# records a linear walk steps over: attachments and the summary's indexes and offsets
_OTHER_OPS = (OP_CHUNK_INDEX, 0x09, 0x0A, OP_STATISTICS, OP_METADATA_INDEX, 0x0E)
RECORD_PREFIX = 9            # opcode (1) + record length (8)
MESSAGE_FIXED = 22           # channel_id 2 + sequence 4 + log_time 8 + publish_time 8
FOOTER_RECORD = RECORD_PREFIX + 20
_U64 = struct.Struct('<Q')
_U16 = struct.Struct('<H')
_CHUNK_HEAD = struct.Struct('<QQQII')   # start, end, uncompressed size, crc, compression length
CHUNK_FLOOR = (1 << 20) + (1 << 17)   # bytes a chunk may always decompress to: 1 MiB chunks
                                      # (mcap's and our writer's default) plus their last message
                                      # (a larger chunk is stored uncompressed: mcapwriter.py)
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


def check_magic(path: Path) -> None:
    """BagError unless ``path`` is a regular file that starts with the MCAP magic bytes (what
    :func:`scan` checks first, without reading further)."""
    fd, _ = open_regular(path)
    try:
        head = os.read(fd, len(MAGIC))
    except OSError as exc:
        raise BagError(f'{path}: cannot read ({exc.strerror or exc})') from None
    finally:
        os.close(fd)
    if head != MAGIC:
        raise BagError(f'{path}: not an MCAP file (bad magic bytes)')


class _Corrupt(Exception):
    """Internal: a record cannot be parsed."""


class _Refused(Exception):
    """Internal: the file asks for more work than any real recording (the scan stops)."""


# Everything a damaged file can raise while being parsed.
_DAMAGE = (_Corrupt, McapError, struct.error, ValueError, IndexError, KeyError, EOFError,
           OverflowError)


@dataclass
class Batch:
    """Messages of one channel inside one buffer (a decompressed chunk), in file order.

    ``starts``/``lengths`` [bytes] locate each message's data (CDR with its 4-byte header) in
    ``buffer``; ``log_times`` [ns] are the MCAP log times. The Message record's fields precede
    each data start in ``buffer`` (see :meth:`publish_times`, :meth:`sequences`).
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

    def publish_times(self) -> NDArray[np.int64]:
        """Publish time [ns] of each message (the 8 bytes before its data)."""
        return self._field(8, '<u8').astype(np.int64)

    def sequences(self) -> NDArray[np.int64]:
        """Sequence number of each message (the u32 20 bytes before its data)."""
        return self._field(20, '<u4').astype(np.int64)

    def _field(self, back: int, dtype: str) -> NDArray:
        width = np.dtype(dtype).itemsize
        rows = self.buffer[(self.starts - back)[:, None] + np.arange(width)]
        return np.ascontiguousarray(rows).view(dtype)[:, 0]


@dataclass
class Damage:
    """A damaged part of a file that reading stepped over.

    Attributes
    ----------
    offset, end : int
        Bytes ``[offset, end)`` skipped (``end``: where reading went on).
    what : str
        What was there (``'chunk 3 of 28'``, ``'message index of chunk 3 of 28'``, ...).
    reason : str
        Why it could not be read.
    lost : int
        Messages known to be lost there.
    at_least : bool
        True when more may be lost (skipped bytes whose messages could not be counted).
    """

    offset: int
    end: int
    what: str
    reason: str
    lost: int = 0
    at_least: bool = False

    def __str__(self) -> str:
        if self.at_least:
            cost = (f'at least {self.lost} messages lost' if self.lost
                    else 'an unknown number of messages lost')
        else:
            cost = f'{self.lost} messages lost' if self.lost else 'no message lost'
        return f'{self.what} at byte {self.offset} skipped ({self.reason}): {cost}'


@dataclass
class Scan:
    """What :func:`scan` found in one MCAP file."""

    path: Path
    profile: str = ''
    library: str = ''
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)      # messages read per channel id
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: list[Metadata] = field(default_factory=list)
    indexed: bool = False          # read through the summary
    inflated: int = 0              # bytes of chunks decompressed so far
    truncated: bool = False        # no valid end of file, or nothing intact after some damage
    stop_reason: str = ''
    damage: list[Damage] = field(default_factory=list)       # damaged parts stepped over
    chunks: int = 0                # chunks in the file (seen so far, in a linear walk)
    data_end: bool = False         # a linear walk reached the end of the data section
    expected: int | None = None    # messages the file's Statistics record claims (if readable)

    @property
    def message_count(self) -> int:
        """Total number of messages read (or, for channels no sink asked for in an indexed
        scan, listed by the summary) in the file."""
        return sum(self.counts.values())

    @property
    def lost(self) -> tuple[int, bool]:
        """``(messages known lost to damage, whether more may be lost)``."""
        return (sum(d.lost for d in self.damage),
                self.truncated or any(d.at_least for d in self.damage))

    @property
    def incomplete(self) -> bool:
        """True when messages may be missing: cut short, or damage that cost messages."""
        lost, maybe = self.lost
        return lost > 0 or maybe

    def problems(self) -> str:
        """The damage and truncation, one line ('' for an intact file)."""
        parts = [str(d) for d in self.damage]
        if self.truncated or (self.stop_reason and not self.damage):
            parts.append(self.stop_reason)
        return '; '.join(p for p in parts if p)

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


def scan(path: Path | str, want: Want | None = None, *, verify: bool = False) -> Scan:
    """Read the file structure of ``path``; pass messages to the sinks ``want`` returns.

    ``want(channel, schema)`` is called once per channel (again if the file has to be re-read
    linearly after a damaged summary, before any message was handed over) and returns a
    callable that receives that channel's :class:`Batch` objects in file order, or None to skip
    the channel. ``verify=True`` reads (decompresses and checks) every chunk and every message
    index even when no sink asks for it, so that ``counts`` and ``damage`` describe the whole
    file (what ``info`` reports).

    Raises :class:`BagError` for a missing, empty or non-MCAP file. A damaged file gives a
    :class:`Scan` holding every intact part, with ``damage`` saying what was skipped; a file cut
    short has ``truncated=True``.
    """
    path = Path(path)
    want = want or (lambda channel, schema: None)
    fd, size = open_regular(path)
    try:
        if size == 0:
            raise BagError(f'{path}: empty file, not an MCAP bag')
        with mmap.mmap(fd, 0, access=mmap.ACCESS_READ) as mm:
            return _scan_mapped(path, mm, size, want, verify)
    except PermissionError:
        raise
    except (OSError, ValueError) as exc:
        raise BagError(f'{path}: cannot read ({exc})') from None
    finally:
        os.close(fd)


def _scan_mapped(path: Path, mm: mmap.mmap, size: int, want: Want, verify: bool) -> Scan:
    if size < len(MAGIC) or mm[:len(MAGIC)] != MAGIC:
        raise BagError(f'{path}: not an MCAP file (bad magic bytes)')
    result = Scan(path=path)
    if _has_footer(mm, size):
        try:
            if _scan_indexed(result, mm, size, want, verify):
                return result
            result = Scan(path=path)          # what the summary held is read again below
        except _Refused as exc:
            result.truncated = True
            result.stop_reason = str(exc)
            return result
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

    The CRC is checked when the writer stored one. A chunk that claims more than
    :func:`chunk_limit` is damage (_Corrupt) and is not counted; all chunks of a file together
    may not decompress to more than :func:`total_limit` bytes (the CPU and time a scan may
    take): beyond that the scan stops (_Refused).
    """
    _, _, usize, crc, clen = _CHUNK_HEAD.unpack_from(mm, content_start)
    limit = chunk_limit(len(mm))
    if usize > limit:
        raise _Corrupt(f'chunk claims {usize} bytes uncompressed, more than the {limit} '
                       'allowed for a file of this size')
    result.inflated += usize
    if result.inflated > total_limit(len(mm)):
        raise _Refused(f'chunks decompress to more than {total_limit(len(mm))} bytes '
                       f'({TOTAL_FACTOR}x the file size); refusing the rest (crafted file?)')
    pos = content_start + _CHUNK_HEAD.size
    if pos + clen + 8 > content_end:
        raise _Corrupt(f'chunk compression name of {clen} bytes runs past its record')
    compression = bytes(mm[pos:pos + clen]).decode()
    pos += clen
    dlen = _U64.unpack_from(mm, pos)[0]
    pos += 8
    if pos + dlen > content_end:
        raise _Corrupt('chunk data runs past its record')
    try:
        raw = _decompress(compression, mm[pos:pos + dlen], usize, limit)
    except _Corrupt:
        raise
    except Exception as exc:          # zstd/lz4 raise their own error types
        raise _Corrupt(f'chunk does not decompress ({exc})') from None
    if len(raw) != usize:
        raise _Corrupt(f'chunk decompressed to {len(raw)} bytes, its record claims {usize}')
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


def _index_length(buf, pos: int, limit: int) -> int:
    """Number of entries of the MessageIndex record at ``pos`` (its header only)."""
    opcode, a, b = _record_at(buf, pos, limit)
    if opcode != OP_MESSAGE_INDEX or b - a < 6:
        raise _Corrupt('no message index where the summary puts one')
    nbytes = struct.unpack_from('<I', buf, a + 2)[0]
    if a + 6 + nbytes > b or nbytes % 16:
        raise _Corrupt('malformed message index')
    return nbytes // 16


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


def _records_in(chunk: NDArray[np.uint8], start: int, end: int, *, messages: bool
                ) -> tuple[list[Schema | Channel], dict[int, Batch]]:
    """Definitions (parsed) and, if ``messages``, the messages per channel of
    ``chunk[start:end]``, walked record by record (slow path). _Corrupt at the first record that
    does not fit; nothing is handed on before the whole range has been read."""
    buf = chunk.data
    definitions: list[Schema | Channel] = []
    found: dict[int, tuple[list[int], list[int], list[int]]] = {}
    pos = start
    while pos < end:
        opcode, a, b = _record_at(buf, pos, end)
        if opcode == OP_SCHEMA:
            definitions.append(Schema.read(_stream(bytes(buf[a:b]))))
        elif opcode == OP_CHANNEL:
            definitions.append(Channel.read(_stream(bytes(buf[a:b]))))
        elif opcode == OP_MESSAGE and messages:
            if b - a < MESSAGE_FIXED:
                raise _Corrupt(f'message record of {b - a} bytes (fewer than its fields)')
            cid = _U16.unpack_from(buf, a)[0]
            starts, lengths, times = found.setdefault(cid, ([], [], []))
            starts.append(a + MESSAGE_FIXED)
            lengths.append(b - a - MESSAGE_FIXED)
            times.append(_U64.unpack_from(buf, a + 6)[0])
        pos = b
    batches = {cid: Batch(chunk, np.array(s, np.int64), np.array(n, np.int64),
                          np.array(t, dtype=np.uint64).astype(np.int64))
               for cid, (s, n, t) in found.items()}
    return definitions, batches


def _feed(result: Scan, sinks: dict[int, Sink | None], batches: dict[int, Batch], where: str,
          offset: int, end: int) -> None:
    """Hand ``batches`` of one chunk to their sinks and count them; a sink that finds the data
    undecodable (or a channel never declared) makes that batch damage."""
    for cid, batch in batches.items():
        if not len(batch):
            continue
        if cid not in result.channels:
            result.damage.append(Damage(offset, end, where, f'{len(batch)} messages on '
                                        f'channel {cid}, which the file never declares',
                                        len(batch)))
            continue
        sink = sinks.get(cid)
        if sink is not None:
            try:
                sink(batch)
            except _DAMAGE as exc:
                topic = result.channels[cid].topic
                result.damage.append(Damage(offset, end, where,
                                            f'{topic} messages undecodable ({exc})', len(batch)))
                continue
        result._saw(cid, batch.log_times)


# ---------------------------------------------------------------- indexed strategy

def _scan_indexed(result: Scan, mm, size: int, want: Want, verify: bool) -> bool:
    """Fill ``result`` from the summary; False (nothing handed to a sink yet) when the summary
    is missing, lacks indexes or disagrees with them. A damaged chunk is skipped."""
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
    chunk_indexes.sort(key=lambda c: c.chunk_start_offset)
    listed = _listed(mm, footer_pos, chunk_indexes)
    claimed = Counter({cid: n for cid, n in stats.channel_message_counts.items() if n})
    known = Counter()
    for per_channel in listed:
        known.update({cid: n for cid, n in per_channel.items() if n is not None})
    unreadable = {cid for per_channel in listed for cid, n in per_channel.items() if n is None}
    if any(known[cid] != claimed[cid] for cid in set(claimed) | set(known)
           if cid not in unreadable):
        return False              # indexes and statistics disagree: trust neither, walk the file
    _read_header(result, mm)
    result.indexed = True
    result.expected = stats.message_count
    for index in metadata_indexes:
        opcode, a, b = _record_at(mm, index.offset, footer_pos)
        if opcode == OP_METADATA:
            result.metadata.append(Metadata.read(_stream(mm[a:b])))
    sinks = {cid: sink for cid, ch in result.channels.items()
             if (sink := want(ch, result.schemas.get(ch.schema_id))) is not None}
    lost_unread = Counter()        # messages of damaged chunks on channels no sink reads
    for number, (ci, per_channel) in enumerate(zip(chunk_indexes, listed), 1):
        cids = sorted(ci.message_index_offsets if verify
                      else set(sinks) & set(ci.message_index_offsets))
        if not cids:
            continue
        where = f'chunk {number} of {len(chunk_indexes)}'
        end = ci.chunk_start_offset + ci.chunk_length
        batches = _indexed_chunk(result, mm, footer_pos, ci, cids, per_channel, where)
        if batches is None:
            lost_unread.update({cid: n for cid, n in per_channel.items()
                                if n and cid not in cids})
            continue
        _feed(result, sinks, batches, where, ci.chunk_start_offset, end)
    read = set(sinks) | (set(claimed) if verify else set())
    for cid, n in claimed.items():            # channels not read: as the summary lists them
        if cid not in read and n - lost_unread[cid] > 0:
            result.counts[cid] = n - lost_unread[cid]
    if not verify and any(cid not in read for cid in claimed) and stats.message_count:
        lo, hi = stats.message_start_time, stats.message_end_time
        result.start_ns = lo if result.start_ns is None else min(lo, result.start_ns)
        result.end_ns = hi if result.end_ns is None else max(hi, result.end_ns)
    return True


def _listed(mm, limit: int, chunk_indexes: list[ChunkIndex]) -> list[dict[int, int | None]]:
    """Per chunk, the messages its index records list per channel (None: unreadable index)."""
    out = []
    for ci in chunk_indexes:
        per_channel: dict[int, int | None] = {}
        for cid, offset in ci.message_index_offsets.items():
            try:
                per_channel[cid] = _index_length(mm, offset, limit)
            except _DAMAGE:
                per_channel[cid] = None
        out.append(per_channel)
    return out


def _indexed_chunk(result: Scan, mm, limit: int, ci: ChunkIndex, cids: list[int],
                   per_channel: dict[int, int | None], where: str) -> dict[int, Batch] | None:
    """Batches of channels ``cids`` of one chunk, or None (damage recorded) if it is unreadable.

    A message index that does not match the chunk is replaced by a walk of its records."""
    offset = ci.chunk_start_offset
    try:
        opcode, a, b = _record_at(mm, offset, limit)
        if opcode != OP_CHUNK:
            raise _Corrupt(f'opcode 0x{opcode:02x} where the summary puts a chunk')
        chunk = _read_chunk(result, mm, a, b)
    except _DAMAGE as exc:
        counted = [n for n in per_channel.values() if n is not None]
        result.damage.append(Damage(offset, offset + ci.chunk_length, where, str(exc),
                                    sum(counted), len(counted) < len(per_channel)))
        return None
    try:
        batches = {}
        for cid in cids:
            opcode, ia, ib = _record_at(mm, ci.message_index_offsets[cid], limit)
            if opcode != OP_MESSAGE_INDEX:
                raise _Corrupt(f'opcode 0x{opcode:02x} where the summary puts a message index')
            index_cid, entries = _message_index(mm, ia, ib)
            if index_cid != cid:
                raise _Corrupt(f'message index of channel {index_cid}, expected {cid}')
            batches[cid] = _batch(chunk, cid, entries)
        return batches
    except _DAMAGE as exc:
        index_damage = str(exc)
    try:          # the chunk is intact, an index of it is not: read the chunk's own records
        _, walked = _records_in(chunk, 0, len(chunk), messages=True)
    except _DAMAGE as exc:
        counted = [n for n in per_channel.values() if n is not None]
        result.damage.append(Damage(offset, offset + ci.chunk_length, where,
                                    f'{index_damage}; and its records: {exc}', sum(counted),
                                    len(counted) < len(per_channel)))
        return None
    result.damage.append(Damage(offset, offset + ci.chunk_length, f'message index of {where}',
                                f'{index_damage}; its messages were read from the chunk '
                                'records instead'))
    return {cid: walked[cid] for cid in cids if cid in walked}


def _read_header(result: Scan, mm) -> None:
    opcode, a, b = _record_at(mm, len(MAGIC), len(mm))
    if opcode == OP_HEADER:
        header = Header.read(_stream(mm[a:b]))
        result.profile, result.library = header.profile, header.library


# ---------------------------------------------------------------- linear strategy

def _scan_linear(result: Scan, mm, size: int, want: Want) -> None:
    """Walk top-level records from the start, stepping over damage (see the module doc)."""
    wanted: dict[int, Sink | None] = {}
    _summary_definitions(result, mm, size, want, wanted)
    pos = len(MAGIC)
    skipped: Damage | None = None      # the last damage, if only message indexes followed it
    while pos < size:
        try:
            opcode, a, b = _record_at(mm, pos, size)
            if opcode == OP_MESSAGE_INDEX:
                if skipped is not None:   # the index of a chunk skipped with the damage
                    skipped.lost += len(_message_index(mm, a, b)[1])
            elif opcode == OP_CHUNK:
                skipped = None
                b = _linear_chunk(result, mm, size, pos, a, b, want, wanted)
            elif opcode in (OP_DATA_END, OP_FOOTER):
                result.data_end = True    # the summary repeats what was seen already
                return
            elif opcode not in _OTHER_OPS:
                skipped = None
                _top_level(result, opcode, mm, pos, a, b, want, wanted)
            pos = b
        except _Refused as exc:
            result.truncated = True
            result.stop_reason = _joined(result.stop_reason, f'stopped at byte {pos}: {exc}')
            return
        except _DAMAGE as exc:
            restart = next_record(mm, pos + 1, size, result.channels.keys())
            if restart is None:           # nothing intact follows: the file was cut here
                result.truncated = True
                result.stop_reason = _joined(result.stop_reason,
                                             f'stopped at byte {pos} of {size}: {exc}')
                return
            damaged = 'record'
            if pos < size:
                damaged = _RECORD_NAMES.get(mm[pos], f'record (opcode 0x{mm[pos]:02x})')
            skipped = Damage(pos, restart, damaged, str(exc), 0, at_least=True)
            result.damage.append(skipped)
            # message indexes found right after a damaged chunk list what it held; after a
            # damaged index they belong to a chunk that was read
            if mm[pos] == OP_MESSAGE_INDEX:
                skipped.at_least = False
                skipped = None
            pos = restart


_RECORD_NAMES = {OP_CHUNK: 'chunk record', OP_MESSAGE_INDEX: 'message index record',
                 OP_MESSAGE: 'message record', OP_SCHEMA: 'schema record',
                 OP_CHANNEL: 'channel record', OP_METADATA: 'metadata record'}


def _joined(first: str, second: str) -> str:
    return f'{first}; {second}' if first else second


def _top_level(result: Scan, opcode: int, mm, pos: int, a: int, b: int, want: Want,
               wanted: dict[int, Sink | None]) -> None:
    """A record outside chunks (header, definitions, metadata, unchunked messages)."""
    if opcode == OP_HEADER:
        header = Header.read(_stream(mm[a:b]))
        result.profile, result.library = header.profile, header.library
    elif opcode == OP_SCHEMA:
        _add_definition(result, Schema.read(_stream(mm[a:b])), want, wanted)
    elif opcode == OP_CHANNEL:
        _add_definition(result, Channel.read(_stream(mm[a:b])), want, wanted)
    elif opcode == OP_MESSAGE:
        _add_loose_message(result, mm, pos, a, b, wanted)
    elif opcode == OP_METADATA:
        result.metadata.append(Metadata.read(_stream(mm[a:b])))
    elif opcode < 0x80:
        # not a record of MCAP version 0 (0x80-0xFF are private records, skipped by the spec)
        raise _Corrupt(f'unknown opcode 0x{opcode:02x}')


def _summary_definitions(result: Scan, mm, size: int, want: Want,
                         wanted: dict[int, Sink | None]) -> None:
    """Schemas and channels (and the statistics' count) of a readable summary, so that messages
    whose definitions were in a damaged part can still be read. Nothing if there is none."""
    if not _has_footer(mm, size):
        return
    footer_pos = size - len(MAGIC) - FOOTER_RECORD
    try:
        footer = Footer.read(_stream(mm[footer_pos + RECORD_PREFIX:size - len(MAGIC)]))
        start = footer.summary_start
        if not len(MAGIC) <= start <= footer_pos:
            return
        found: list[Schema | Channel] = []
        pos = start
        while pos < footer_pos:
            opcode, a, b = _record_at(mm, pos, footer_pos)
            if opcode == OP_SCHEMA:
                found.append(Schema.read(_stream(mm[a:b])))
            elif opcode == OP_CHANNEL:
                found.append(Channel.read(_stream(mm[a:b])))
            elif opcode == OP_STATISTICS:
                result.expected = Statistics.read(_stream(mm[a:b])).message_count
            pos = b
    except _DAMAGE:
        return                                 # what the data section holds is all there is
    for record in found:
        _add_definition(result, record, want, wanted)


def _add_definition(result: Scan, record: Schema | Channel, want: Want,
                    wanted: dict[int, Sink | None]) -> None:
    if isinstance(record, Schema):
        result.schemas.setdefault(record.id, record)
    elif record.id not in result.channels:
        result.channels[record.id] = record
        wanted[record.id] = want(record, result.schemas.get(record.schema_id))


def _add_loose_message(result: Scan, buf, pos: int, a: int, b: int,
                       wanted: dict[int, Sink | None]) -> None:
    """A Message record outside any chunk (unchunked files)."""
    if b - a < MESSAGE_FIXED:
        raise _Corrupt(f'message record of {b - a} bytes (fewer than its fields)')
    cid = _U16.unpack_from(buf, a)[0]
    if cid not in result.channels:
        raise _Corrupt(f'message on unknown channel {cid}')
    # the whole record, so that the batch can give publish times and sequence numbers too
    record = np.frombuffer(bytes(buf[pos:b]), dtype=np.uint8)
    head = RECORD_PREFIX + MESSAGE_FIXED
    batch = Batch(record, np.array([head], np.int64), np.array([b - pos - head], np.int64),
                  np.array([_U64.unpack_from(buf, a + 6)[0]], dtype=np.uint64).astype(np.int64))
    _feed(result, wanted, {cid: batch}, 'message record', pos, b)


def _linear_chunk(result: Scan, mm, size: int, pos: int, a: int, b: int, want: Want,
                  wanted: dict[int, Sink | None]) -> int:
    """Read one chunk and the message indexes after it; return the position after them.

    An unreadable chunk is damage (the messages its indexes list are lost); indexes that do
    not match the chunk are replaced by a walk of its records."""
    result.chunks += 1
    where = f'chunk {result.chunks}'
    indexes, end, complete = _following_indexes(mm, b, size)
    try:
        chunk = _read_chunk(result, mm, a, b)
        definitions, batches = _chunk_content(chunk, indexes if complete else None)
    except _DAMAGE as exc:
        result.damage.append(Damage(pos, end, where, str(exc),
                                    sum(len(e) for e in indexes.values()), not complete))
        return end
    for record in definitions:
        _add_definition(result, record, want, wanted)
    _feed(result, wanted, batches, where, pos, end)
    return end


def _following_indexes(mm, pos: int, size: int
                       ) -> tuple[dict[int, NDArray[np.uint64]], int, bool]:
    """The MessageIndex records from ``pos`` on: ``(entries per channel, position after them,
    complete)``; not complete when one is damaged or cut off (the walk stops there)."""
    indexes: dict[int, NDArray[np.uint64]] = {}
    while pos < size:
        try:
            opcode, a, b = _record_at(mm, pos, size)
            if opcode != OP_MESSAGE_INDEX:
                return indexes, pos, True
            cid, entries = _message_index(mm, a, b)
        except _DAMAGE:
            return indexes, pos, False
        if cid in indexes:                 # two indexes of one channel: not what a writer does
            return indexes, pos, False
        indexes[cid] = entries
        pos = b
    return indexes, pos, True


def _chunk_content(chunk: NDArray[np.uint8], indexes: dict[int, NDArray[np.uint64]] | None
                   ) -> tuple[list[Schema | Channel], dict[int, Batch]]:
    """Definitions and message batches of a chunk: from its ``indexes`` when they match it,
    else by walking its records."""
    if indexes:
        try:
            batches = {cid: _batch(chunk, cid, entries) for cid, entries in indexes.items()
                       if len(entries)}
            # only the bytes not covered by messages are walked: definitions live there
            definitions: list[Schema | Channel] = []
            for start, end in _gaps(batches.values(), len(chunk)):
                definitions += _records_in(chunk, start, end, messages=False)[0]
            return definitions, batches
        except _DAMAGE:
            pass                           # indexes that do not match: walk the records
    return _records_in(chunk, 0, len(chunk), messages=True)


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
