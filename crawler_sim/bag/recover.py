"""``recover``: rewrite an incomplete MCAP file (killed recorder, full disk) as a valid bag.

The source is streamed with :class:`mcap.stream_reader.StreamReader`; every complete Schema,
Channel, Message and Metadata record before the damage is copied into a new bag directory written
by :class:`crawler_sim.bag.BagWriter` (fresh ``rosbag2`` metadata records, summary, footer and
``metadata.yaml``). Message bytes, log/publish times and sequence numbers are kept as they were.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from io import BytesIO
import os
from pathlib import Path
import re
from typing import Any, Iterator
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from .errors import BagError
from .mcapfile import chunk_limit, decompress, open_regular, total_limit
from .reader import bag_files
from .writer import ROSBAG2_METADATA, BagWriter

_FILE_NUMBER = re.compile(r'_(\d+)$')
RECOVER_CHUNK = 256 << 10        # bytes of uncompressed chunk in the recovered bag


@dataclass
class RecoverResult:
    """What :func:`recover` salvaged.

    Attributes
    ----------
    bag : Path
        The new bag directory; ``mcap_path`` is its .mcap file.
    messages, schemas, channels, metadata : int
        Records copied.
    topics : dict
        ``{topic: messages copied}``.
    complete : bool
        True when the data section of every source file was read to its end (its DataEnd
        record) without damage, i.e. no message was lost; a cut summary does not matter.
    problems : list of str
        Where and why reading stopped, per damaged source file.
    """

    bag: Path
    mcap_path: Path
    messages: int = 0
    schemas: int = 0
    channels: int = 0
    metadata: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    complete: bool = True
    problems: list[str] = field(default_factory=list)


def default_destination(src: Path) -> Path:
    """``run`` -> ``run_recovered`` (next to the bag directory, also for ``run/run_0.mcap``)."""
    if src.is_dir():
        return src.parent / f'{src.name}_recovered'
    stem = src.stem
    match = _FILE_NUMBER.search(stem)
    if match and stem[:match.start()] == src.parent.name:
        return src.parent.parent / f'{src.parent.name}_recovered'
    return src.parent / f'{stem}_recovered'


def recover(src: os.PathLike | str, dst: os.PathLike | str | None = None) -> RecoverResult:
    """Salvage the readable records of ``src`` into the new bag directory ``dst``.

    Parameters
    ----------
    src : path-like
        A ``.mcap`` file or a bag directory (all its .mcap files, in order).
    dst : path-like, optional
        Bag directory to create (must not exist); default ``<src>_recovered`` next to ``src``.

    The output reads with :func:`crawler_sim.bag.load`, ``mcap_ros2`` and rosbags. Raises
    :class:`BagError` if ``src`` is missing or not MCAP, or ``dst`` exists.
    """
    src_path = Path(src)
    files = bag_files(src_path)
    dst_path = Path(dst) if dst is not None else default_destination(src_path)
    for file in files:
        _check_magic(file)
    # small chunks: the per-chunk state (buffer, message index lists) stays well under the size
    # of even a 1 MB source file; no flush thread (a recovery is written in one go)
    writer = BagWriter(dst_path, chunk_size=RECOVER_CHUNK, flush_interval=None)
    result = RecoverResult(dst_path, writer.mcap_path)
    try:
        for file in files:
            _copy_file(file, writer, result)
    finally:
        writer.close()
    if writer.error is not None:
        raise BagError(writer.error)
    return result


def _check_magic(file: Path) -> None:
    fd, _ = open_regular(file)          # BagError for FIFOs and other special files
    try:
        head = os.read(fd, 8)
    except OSError as exc:
        raise BagError(f'{file}: cannot read ({exc.strerror})') from None
    finally:
        os.close(fd)
    if head != b'\x89MCAP0\r\n':
        raise BagError(f'{file}: not an MCAP file (bad magic bytes)')


class _Copier:
    """State of copying one source file: its schema and channel ids -> writer topics."""

    def __init__(self, writer: BagWriter, result: RecoverResult) -> None:
        self.writer = writer
        self.result = result
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Any] = {}

    def schema(self, record: Schema) -> None:
        if record.id not in self.schemas:
            self.schemas[record.id] = record
            self.result.schemas += 1

    def channel(self, record: Channel) -> None:
        if record.id in self.channels:
            return
        topic_entry = self.writer.registered(record.topic)     # same topic in an earlier file
        if topic_entry is None:
            schema = self.schemas.get(record.schema_id)
            topic_entry = self.writer.add_channel(
                record.topic,
                schema_name=schema.name if schema else '',
                schema_encoding=schema.encoding if schema else '',
                schema_data=bytes(schema.data) if schema else b'',
                message_encoding=record.message_encoding,
                metadata=record.metadata)
            self.result.channels += 1
        self.channels[record.id] = topic_entry
        self.result.topics.setdefault(record.topic, 0)

    def message(self, record: Message) -> None:
        entry = self.channels.get(record.channel_id)
        if entry is None:
            raise McapError(f'message on unknown channel {record.channel_id}')
        if self.writer.write_raw(entry, bytes(record.data), record.log_time,
                                 record.publish_time, record.sequence):
            self.result.messages += 1
            self.result.topics[entry.name] += 1

    def metadata(self, record: Metadata) -> None:
        if record.name != ROSBAG2_METADATA:        # the writer makes fresh ones
            self.writer.add_metadata(record.name, record.metadata)
            self.result.metadata += 1


def _records(f: Any, size: int) -> Iterator[Any]:
    """Top-level records of an open MCAP file, chunks opened with bounded decompression (a chunk
    may not claim more than :func:`crawler_sim.bag.mcapfile.chunk_limit` bytes)."""
    inflated = 0
    for record in StreamReader(f, skip_magic=False, emit_chunks=True,
                               record_size_limit=size).records:
        if isinstance(record, Chunk):
            inflated += record.uncompressed_size
            if inflated > total_limit(size):
                raise McapError(f'chunks decompress to more than {total_limit(size)} bytes '
                                '(64x the file size); the rest is not copied (crafted file?)')
            raw = decompress(record.compression, record.data, record.uncompressed_size,
                             chunk_limit(size))
            if record.uncompressed_crc and zlib.crc32(raw) != record.uncompressed_crc:
                raise McapError('chunk CRC mismatch (damaged data)')
            yield from _chunk_records(raw)
        else:
            yield record


def _chunk_records(raw: bytes) -> Iterator[Any]:
    """Schema, Channel and Message records of a decompressed chunk (others skipped)."""
    stream = ReadDataStream(BytesIO(raw))
    while stream.count < len(raw):
        opcode = stream.read1()
        length = stream.read8()
        if stream.count + length > len(raw):
            raise McapError('record runs past the end of its chunk')
        if opcode == Opcode.SCHEMA:
            yield Schema.read(stream)
        elif opcode == Opcode.CHANNEL:
            yield Channel.read(stream)
        elif opcode == Opcode.MESSAGE:
            yield Message.read(stream, length)
        else:
            stream.read(length)


def _copy_file(file: Path, writer: BagWriter, result: RecoverResult) -> None:
    """Copy the readable records of ``file``; note where and why reading stopped."""
    copier = _Copier(writer, result)
    handlers = {Schema: copier.schema, Channel: copier.channel, Message: copier.message,
                Metadata: copier.metadata}
    fd, size = open_regular(file)
    with os.fdopen(fd, 'rb') as f:
        records = _records(f, size)
        while writer.error is None:
            try:
                record = next(records)
                handler = handlers.get(type(record))
                if handler is not None:
                    handler(record)
                elif _is_end(record):
                    return
            except StopIteration:
                return
            except Exception as exc:  # noqa: BLE001 - damaged input raises zstd, struct, ...
                result.complete = False
                result.problems.append(f'{file}: reading stopped near byte {f.tell()}: '
                                       f'{type(exc).__name__}: {exc}')
                return


def _is_end(record: Any) -> bool:
    """True for the records after the data section (the summary repeats what was copied)."""
    return type(record).__name__ in ('DataEnd', 'Footer')
