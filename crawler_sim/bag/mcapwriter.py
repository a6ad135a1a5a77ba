"""``McapWriter``: the bag's MCAP file writer (chunked, zstd, indexed, with a summary).

It writes what :class:`mcap.writer.Writer` writes (header, zstd chunks with CRCs, message
indexes after each chunk, a data-end record, a summary repeating schemas and channels with
statistics, chunk and metadata indexes and summary offsets, a footer with the summary CRC),
with three differences the recording needs:

* Schema and Channel records go outside chunks, so they reach the disk with the next flush
  (the library puts them in the open chunk, which it writes only once a message joined it):
  a file cut anywhere still declares them.
* A chunk that grew past :data:`crawler_sim.bag.mcapfile.CHUNK_FLOOR` (it holds a message
  larger than a chunk, e.g. a preloaded trajectory of minutes) is written uncompressed:
  readers bound a chunk's claimed size by the file's size (a zip bomb is refused), and a
  well-compressing large message would otherwise claim more than its file holds. The library
  compresses every chunk alike.
* The per-message work is ours: a Message record is one ``struct.pack`` appended to the chunk
  buffer, and a chunk's message indexes are packed from flat ``array('Q')`` lists of (log time,
  offset) at once. Every other record (header, schema, channel, chunk, chunk index, metadata,
  statistics, summary offsets, data end, footer) is made by the record classes of
  :mod:`mcap.records`, written through :class:`mcap.data_stream.RecordBuilder` (public API).

Why this is our code rather than :class:`mcap.writer.Writer`: the first two points cannot be had
through the library's public API (its writer keeps chunking and compression in name-mangled
attributes; subclassing it to reach them was how this module started), and the third is
measured with ``python -m benchmarks.bag --writer`` (200,000 messages of 150 bytes on 5
channels, 1 MiB zstd chunks, into memory, one process): ``Writer.add_message`` 3.7-4.1 us per
message (a ``Message`` dataclass, eight small writes, two more ``struct.pack`` calls for its
index entry), this writer 0.8-0.9 us. In the node (about 500 recorded messages per second) that
is 0.15 % of a core; offline, ``record_arrays`` of an hour at 100 Hz (1.4 million messages)
spends about 1.2 s in this writer instead of 5.5 s, and ``recover`` as much per message.

No private attribute or private module of mcap is used.
"""
from __future__ import annotations

from array import array
import struct
import sys
from typing import Any, BinaryIO, Mapping
import zlib

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, McapRecord,
                          Metadata, MetadataIndex, Schema, Statistics, SummaryOffset)
import numpy as np
from numpy.typing import NDArray
import zstandard

from .mcapfile import CHUNK_FLOOR, MAGIC, MESSAGE_FIXED

#: a Message record up to its data: opcode, record length, channel id, sequence, log time [ns],
#: publish time [ns] (the MCAP spec's field order)
_MESSAGE_HEAD = struct.Struct('<BQHIQQ')
#: a MessageIndex record up to its entries: opcode, record length, channel id, entries' bytes
_INDEX_HEAD = struct.Struct('<BQHI')
_FOOTER_HEAD = struct.Struct('<BQQQ')     # opcode, length, summary start, summary offset start
_FOOTER_FIELDS = 20
_COMPRESSIONS = ('zstd', '')


class McapWriter:
    """Write one MCAP file to ``stream`` (a binary file object; not closed here).

    Parameters
    ----------
    stream : binary file object
        A new, empty file, written with ``write`` and ``flush`` only (file offsets are
        counted here, not asked of the stream).
    chunk_size : int
        Uncompressed chunk size [bytes] before a chunk is compressed and written.
    compression : str
        ``'zstd'`` (default) or ``''`` (no compression).

    Methods are those of :class:`mcap.writer.Writer` that a recording uses, with the same
    arguments: :meth:`start`, :meth:`register_schema`, :meth:`register_channel`,
    :meth:`add_message`, :meth:`add_metadata`, :meth:`flush`, :meth:`finish`.
    """

    def __init__(self, stream: BinaryIO, *, chunk_size: int = 1 << 20,
                 compression: str = 'zstd') -> None:
        if compression not in _COMPRESSIONS:
            raise ValueError(f'compression must be one of {_COMPRESSIONS}, got {compression!r}')
        self._stream = stream
        # a chunk past CHUNK_FLOOR is written at once, uncompressed (see the module doc)
        self._limit = min(int(chunk_size), CHUNK_FLOOR)
        self._compression = compression
        self._offset = 0                         # bytes written to the stream so far
        self._records = RecordBuilder()          # top-level records not yet written
        self._chunk = bytearray()                # Message records of the open chunk
        self._indexes: dict[int, array] = {}     # channel id -> flat (log time, offset) pairs
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}        # messages per channel id, in written chunks
        self._start_ns: int | None = None        # log time range [ns] of the written chunks
        self._end_ns = 0
        self._metadata_count = 0

    # ---------------------------------------------------------------- the mcap.Writer methods

    def start(self, profile: str = '', library: str = '') -> None:
        """Write the magic and the Header record (``profile``, ``library``)."""
        self._write(MAGIC)
        self._record(Header(profile=profile, library=library))
        self._write_records()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """A Schema record (outside chunks, written at the next flush); its id (1, 2, ...)."""
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._record(schema)
        return schema.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: Mapping[str, str] | None = None) -> int:
        """A Channel record (outside chunks, written at the next flush); its id (1, 2, ...)."""
        channel = Channel(id=len(self._channels) + 1, topic=topic,
                          message_encoding=message_encoding, schema_id=schema_id,
                          metadata=dict(metadata or {}))
        self._channels.append(channel)
        self._record(channel)
        return channel.id

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        """Append a Message record to the open chunk (times in ns); write the chunk when it
        is full."""
        chunk = self._chunk
        index = self._indexes.get(channel_id)
        if index is None:
            index = self._indexes[channel_id] = array('Q')
        index.append(log_time)
        index.append(len(chunk))
        chunk += _MESSAGE_HEAD.pack(Opcode.MESSAGE, MESSAGE_FIXED + len(data), channel_id,
                                    sequence, log_time, publish_time)
        chunk += data
        if len(chunk) > self._limit:
            self._write_chunk()

    def add_records(self, records: Any, channel_ids: NDArray[np.integer],
                    log_times: NDArray[np.integer], sizes: NDArray[np.integer]) -> None:
        """Append many Message records at once (see :func:`message_records`): ``records`` holds
        them back to back (bytes-like), message ``k`` on channel ``channel_ids[k]`` at
        ``log_times[k]`` [ns], ``sizes[k]`` bytes long. The file is byte for byte what
        :meth:`add_message` of each in turn writes: the same chunks (cut after the message
        that takes a chunk past its size) and the same indexes. A chunk's worth of records
        is copied at once and its index entries are made with numpy, so a message costs no
        Python call of its own."""
        view = memoryview(records).cast('B')
        sizes = np.asarray(sizes, dtype=np.int64)
        ends = np.cumsum(sizes)
        starts = ends - sizes
        channel_ids = np.asarray(channel_ids, dtype=np.int64)
        log_times = np.asarray(log_times, dtype=np.uint64)
        total = len(sizes)
        if total and int(ends[-1]) != len(view):
            raise ValueError(f'the records hold {len(view)} bytes, their sizes add up to '
                             f'{int(ends[-1])}')
        first = 0
        while first < total:
            base = int(starts[first])
            # the chunk is written after the first message that takes it past the limit
            room = self._limit - len(self._chunk)
            last = min(int(np.searchsorted(ends, base + room, side='right')), total - 1)
            offset = len(self._chunk) - base
            self._chunk += view[base:int(ends[last])]
            part = slice(first, last + 1)
            channels = channel_ids[part]
            ids, first_seen = np.unique(channels, return_index=True)
            for channel_id in ids[np.argsort(first_seen)].tolist():  # dict order as one by one
                mine = channels == channel_id
                pairs = np.empty((int(mine.sum()), 2), dtype='<u8')
                pairs[:, 0] = log_times[part][mine]
                pairs[:, 1] = starts[part][mine] + offset
                index = self._indexes.get(channel_id)
                if index is None:
                    index = self._indexes[channel_id] = array('Q')
                index.frombytes(pairs.astype(np.uint64).tobytes())
            first = last + 1
            if len(self._chunk) > self._limit:
                self._write_chunk()

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """A Metadata record ``name`` (string keys and values), written at once."""
        self._write_records()
        record = Metadata(name=name, metadata=dict(data))
        self._record(record)
        self._metadata_indexes.append(MetadataIndex(offset=self._offset,
                                                    length=self._records.count, name=name))
        self._metadata_count += 1
        self._write_records()

    def flush(self) -> None:
        """Write the open chunk (if it holds messages) and every pending record; flush the
        stream (no fsync)."""
        self._write_chunk()
        self._write_records()
        self._stream.flush()

    def finish(self) -> None:
        """Write the open chunk, the data end, the summary, the footer and the closing magic;
        flush the stream (it stays open)."""
        self._write_chunk()
        self._record(DataEnd(data_section_crc=0))
        self._write_records()
        summary_start = self._offset
        summary = RecordBuilder()
        offsets: list[SummaryOffset] = []
        stats = Statistics(
            message_count=sum(self._counts.values()), schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=0,
            metadata_count=self._metadata_count, chunk_count=len(self._chunk_indexes),
            message_start_time=self._start_ns or 0, message_end_time=self._end_ns,
            channel_message_counts=dict(self._counts))
        for opcode, group in ((Opcode.SCHEMA, self._schemas), (Opcode.CHANNEL, self._channels),
                              (Opcode.STATISTICS, [stats]),
                              (Opcode.CHUNK_INDEX, self._chunk_indexes),
                              (Opcode.ATTACHMENT_INDEX, []),      # as the library: none
                              (Opcode.METADATA_INDEX, self._metadata_indexes)):
            start = summary.count
            for record in group:
                record.write(summary)
            offsets.append(SummaryOffset(group_opcode=opcode,
                                         group_start=summary_start + start,
                                         group_length=summary.count - start))
        offset_start = summary_start + summary.count
        for record in offsets:
            record.write(summary)
        data = summary.end()
        crc = zlib.crc32(_FOOTER_HEAD.pack(Opcode.FOOTER, _FOOTER_FIELDS, summary_start,
                                           offset_start), zlib.crc32(data))
        self._write(data)
        self._record(Footer(summary_start=summary_start, summary_offset_start=offset_start,
                            summary_crc=crc))
        self._write_records()
        self._write(MAGIC)
        self._stream.flush()

    # ---------------------------------------------------------------- internals

    def _write(self, data: bytes) -> None:
        self._stream.write(data)
        self._offset += len(data)

    def _record(self, record: McapRecord) -> None:
        record.write(self._records)

    def _write_records(self) -> None:
        if self._records.count:
            self._write(self._records.end())

    def _write_chunk(self) -> None:
        """The open chunk as a Chunk record, its MessageIndex records after it, and its
        ChunkIndex kept for the summary (nothing if it holds no message)."""
        if not self._indexes:
            return
        raw = bytes(self._chunk)
        indexes = self._indexes
        self._chunk = bytearray()
        self._indexes = {}
        start = min(min(index[0::2]) for index in indexes.values())
        end = max(max(index[0::2]) for index in indexes.values())
        # a chunk past the floor holds a message larger than a chunk: stored as it is
        compression = self._compression if len(raw) <= CHUNK_FLOOR else ''
        data = zstandard.compress(raw) if compression == 'zstd' else raw
        self._write_records()                   # definitions before the chunk that uses them
        chunk_start = self._offset
        self._record(Chunk(compression=compression, data=data, message_start_time=start,
                           message_end_time=end, uncompressed_crc=zlib.crc32(raw),
                           uncompressed_size=len(raw)))
        chunk_length = self._records.count
        self._write_records()
        index_start = self._offset
        offsets: dict[int, int] = {}
        parts = []
        for channel_id, entries in indexes.items():
            offsets[channel_id] = index_start + sum(len(p) for p in parts)
            parts.append(_message_index(channel_id, entries))
            self._counts[channel_id] = self._counts.get(channel_id, 0) + len(entries) // 2
        block = b''.join(parts)
        self._write(block)
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=chunk_start,
            chunk_length=chunk_length, message_index_offsets=offsets,
            message_index_length=len(block), compression=compression,
            compressed_size=len(data), uncompressed_size=len(raw)))
        self._start_ns = start if self._start_ns is None else min(self._start_ns, start)
        self._end_ns = max(self._end_ns, end)


def message_records(channel_id: int, log_times: NDArray[np.integer],
                    data: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Message records of ``len(log_times)`` messages of equal length on one channel, one per
    row: ``data`` (n, L) holds their CDR bytes; sequence 0 and publish time = log time [ns],
    as :class:`crawler_sim.bag.writer.BagWriter` records. Row ``k`` is the bytes
    :meth:`McapWriter.add_message` appends for message ``k``."""
    n, length = data.shape
    head = np.zeros((n,), dtype=np.dtype([('opcode', 'u1'), ('length', '<u8'),
                                          ('channel', '<u2'), ('sequence', '<u4'),
                                          ('log', '<u8'), ('publish', '<u8')]))
    head['opcode'] = Opcode.MESSAGE
    head['length'] = MESSAGE_FIXED + length
    head['channel'] = channel_id
    head['log'] = head['publish'] = np.asarray(log_times, dtype=np.uint64)
    out = np.empty((n, _MESSAGE_HEAD.size + length), dtype=np.uint8)
    out[:, :_MESSAGE_HEAD.size] = head.view(np.uint8).reshape(n, _MESSAGE_HEAD.size)
    out[:, _MESSAGE_HEAD.size:] = data
    return out


def _message_index(channel_id: int, entries: array) -> bytes:
    """A MessageIndex record of ``entries`` (flat log time [ns], chunk offset pairs)."""
    if sys.byteorder != 'little':
        entries = array('Q', entries)
        entries.byteswap()
    nbytes = 8 * len(entries)
    return (_INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + nbytes, channel_id, nbytes)
            + entries.tobytes())


__all__ = ['McapWriter', 'message_records']
