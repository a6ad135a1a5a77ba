"""Finding the next intact record after damage in an MCAP file (for :mod:`.mcapfile`).

A damaged record length (a bit flip, a chunk cut in the middle) leaves a reader with no way to
know where the next record starts. :func:`next_record` looks for it the only way the format
allows: byte by byte, for a position where a record *fits* the spec exactly and is followed by
another one that does. Only in-file lengths are ever trusted, so a length of 2^63 costs nothing.

What "fits" means per opcode (the record's fields must add up to its length, exactly):

* Chunk: ``8+8+8+4 + 4+len(compression) + 8+len(records)``, compression one of ``''``, ``zstd``,
  ``lz4``, start time <= end time. This is a strong signature, so a chunk is accepted alone.
* Message index: ``2 + 4 + n`` with ``n`` a multiple of 16.
* Schema, Channel, Metadata: their length-prefixed strings, bytes and maps end exactly at the
  record's end.
* Message: at least its 22 bytes of fields. Data end: 4 bytes. Footer: 20 bytes followed by
  the closing magic at the end of the file.
* Summary records (chunk index, statistics, ...): inside the file.

Every candidate other than a chunk or a footer must be followed by two more records that fit
(or by records up to the end of the file, or up to a chunk), and a message or message index
must name a channel the file declared (when the caller knows them). That makes a false match
negligible, also inside the zero-rich entries of a message index; inside compressed data a
match needs a run of 5 or more zero bytes in the right place, three times. Inside
*uncompressed* chunk data the candidates are the chunk's own records, i.e. real messages.

The search runs over windows of :data:`WINDOW` bytes (copied, so no view of the caller's mmap
outlives the call) with numpy, and stops at the first match: its cost is the distance to the
next record, its memory a few times the window.
"""
from __future__ import annotations

import struct
from typing import Collection

import numpy as np

MAGIC = b'\x89MCAP0\r\n'
RECORD_PREFIX = 9
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x02, 0x03, 0x04, 0x05, 0x06
OP_MESSAGE_INDEX, OP_METADATA, OP_DATA_END = 0x07, 0x0C, 0x0F
SUMMARY_OPS = (0x08, 0x09, 0x0A, 0x0B, 0x0D, 0x0E)   # chunk/attachment/metadata indexes, ...
RESTART_OPS = (OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX,
               OP_METADATA, OP_DATA_END) + SUMMARY_OPS
COMPRESSIONS = (b'', b'zstd', b'lz4')
WINDOW = 256 << 10          # bytes searched per numpy pass
SUCCESSORS = 2              # records that must fit after a candidate (unless it is a chunk)

_U16, _U32, _U64 = struct.Struct('<H'), struct.Struct('<I'), struct.Struct('<Q')
_CHUNK_HEAD = struct.Struct('<QQQII')   # start, end, uncompressed size, crc, compression length


def _skip_str(buf, pos: int, end: int, width: int = 4) -> int | None:
    """Position after a length-prefixed string/bytes field at ``pos``, or None past ``end``."""
    if pos + width > end:
        return None
    n = (_U32 if width == 4 else _U64).unpack_from(buf, pos)[0]
    nxt = pos + width + n
    return nxt if nxt <= end else None


def _skip_map(buf, pos: int, end: int) -> int | None:
    """Position after a map<string, string> (u32 byte length, then key/value strings)."""
    if pos + 4 > end:
        return None
    n = _U32.unpack_from(buf, pos)[0]
    stop = pos + 4 + n
    if stop > end:
        return None
    p = pos + 4
    while p < stop:
        p = _skip_str(buf, p, stop)
        p = None if p is None else _skip_str(buf, p, stop)
        if p is None:
            return None
    return stop


def _fields_fit(buf, opcode: int, a: int, b: int) -> bool:
    """Whether the content ``buf[a:b]`` of a record of ``opcode`` has exactly its fields."""
    n = b - a
    if opcode == OP_CHUNK:
        if n < _CHUNK_HEAD.size + 8:
            return False
        start, end, _, _, clen = _CHUNK_HEAD.unpack_from(buf, a)
        pos = a + _CHUNK_HEAD.size
        if clen > 8 or pos + clen + 8 > b or bytes(buf[pos:pos + clen]) not in COMPRESSIONS:
            return False
        return start <= end and pos + clen + 8 + _U64.unpack_from(buf, pos + clen)[0] == b
    if opcode == OP_MESSAGE_INDEX:
        return n >= 6 and _U32.unpack_from(buf, a + 2)[0] == n - 6 and (n - 6) % 16 == 0
    if opcode == OP_MESSAGE:
        return n >= 22
    if opcode == OP_DATA_END:
        return n == 4
    if opcode == OP_FOOTER:
        return n == 20
    if opcode == OP_SCHEMA:          # id u16, name, encoding, data (u32 length)
        pos = _skip_str(buf, a + 2, b)
        pos = None if pos is None else _skip_str(buf, pos, b)
        return pos is not None and _skip_str(buf, pos, b) == b
    if opcode == OP_CHANNEL:         # id u16, schema id u16, topic, encoding, metadata map
        pos = _skip_str(buf, a + 4, b)
        pos = None if pos is None else _skip_str(buf, pos, b)
        return pos is not None and _skip_map(buf, pos, b) == b
    if opcode == OP_METADATA:        # name, map
        pos = _skip_str(buf, a, b)
        return pos is not None and _skip_map(buf, pos, b) == b
    return opcode in SUMMARY_OPS


def record_end(buf: bytes | bytearray | memoryview, pos: int, size: int,
               channels: Collection[int] = ()) -> int | None:
    """End of the record at ``pos`` if it lies inside ``size`` bytes and fits the spec (a
    message or message index of a channel in ``channels``, unless that is empty)."""
    if pos + RECORD_PREFIX > size:
        return None
    opcode = buf[pos]
    if opcode not in RESTART_OPS:
        return None
    if (channels and opcode in (OP_MESSAGE, OP_MESSAGE_INDEX) and pos + RECORD_PREFIX + 2 <= size
            and _U16.unpack_from(buf, pos + RECORD_PREFIX)[0] not in channels):
        return None
    end = pos + RECORD_PREFIX + _U64.unpack_from(buf, pos + 1)[0]
    if end > size:
        return None
    try:
        return end if _fields_fit(buf, opcode, pos + RECORD_PREFIX, end) else None
    except (struct.error, ValueError, IndexError):
        return None


def _is_footer(buf, pos: int, end: int, size: int) -> bool:
    return (buf[pos] == OP_FOOTER and end + len(MAGIC) == size
            and bytes(buf[end:size]) == MAGIC)


def _restart_at(buf, pos: int, size: int, channels: Collection[int]) -> bool:
    end = record_end(buf, pos, size, channels)
    if end is None:
        return False
    if buf[pos] == OP_FOOTER:
        return _is_footer(buf, pos, end, size)
    if buf[pos] == OP_CHUNK or end == size:
        return True
    for _ in range(SUCCESSORS):
        if buf[end] == OP_CHUNK and record_end(buf, end, size) is not None:
            return True
        nxt = record_end(buf, end, size, channels)
        if nxt is None:
            return False
        if nxt == size or _is_footer(buf, end, nxt, size):
            return True
        end = nxt
    return True


def next_record(buf: bytes | bytearray | memoryview, start: int, size: int,
                channels: Collection[int] = ()) -> int | None:
    """First position ``>= start`` where an intact record (see the module doc) begins, or None.

    ``buf`` is the whole file (bytes or mmap) of ``size`` bytes; ``channels`` the channel ids
    the file declared so far (a message or index of another channel is not a restart).
    """
    ops = np.array(RESTART_OPS, dtype=np.uint8)
    pos = max(start, 0)
    while pos + RECORD_PREFIX <= size:
        stop = min(pos + WINDOW, size - RECORD_PREFIX + 1)     # candidate starts in [pos, stop)
        window = np.frombuffer(bytes(buf[pos:stop + RECORD_PREFIX - 1]), dtype=np.uint8)
        cand = np.flatnonzero(np.isin(window[:stop - pos], ops))
        if len(cand):
            # record lengths of every candidate at once; most are far beyond the file's end
            lengths = window[cand[:, None] + 1 + np.arange(8)].copy().view('<u8')[:, 0]
            fits = lengths <= np.uint64(size - RECORD_PREFIX) - (cand + pos).astype(np.uint64)
            for c in cand[fits]:
                if _restart_at(buf, pos + int(c), size, channels):
                    return pos + int(c)
        pos = stop
    return None


__all__ = ['next_record', 'record_end']
