"""``recover``: rewrite a damaged or incomplete MCAP file (killed recorder, full disk, flipped
bits) as a valid bag.

The source is read with :func:`crawler_sim.bag.mcapfile.scan` (``verify=True``), which steps over
damage instead of stopping at it: a chunk whose header, data or CRC is damaged is skipped and
the next one read, located through the summary when it survived and otherwise by searching for
the next record that fits the MCAP spec (a length beyond the file's end is never followed).
Every message of every intact chunk, and every Schema, Channel and Metadata record, is copied
into a new bag directory written by :class:`crawler_sim.bag.BagWriter` (fresh ``rosbag2``
metadata records, summary, footer and ``metadata.yaml``). Message bytes, log/publish times and
sequence numbers are kept as they were, and so is the file order of messages. The summary's
schemas and channels are used when the records that declared them were in a damaged part.

mcap's own :class:`~mcap.stream_reader.StreamReader` is not used for this: it stops at the first
damaged record (and skips a chunk whose opcode was damaged without a word).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import re
from typing import Any

from mcap.records import Channel, Schema
import numpy as np

from .errors import BagError
from .files import reading
from .mcapfile import Batch, Scan, check_magic, scan
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
        True when the data section of every source file was read to its end without damage,
        i.e. no message was lost; a cut summary does not matter.
    problems : list of str
        Per damaged source file: each damaged part skipped (which chunk or record, why, the
        messages it cost) and where reading stopped if the file was cut short.
    lost : int
        Messages of the sources known to be lost (exact when the sources' statistics survived
        or every damaged chunk's message indexes did).
    lost_exact : bool
        False when more messages than ``lost`` may be lost (damage whose messages could not be
        counted, or a file cut short).
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
    lost: int = 0
    lost_exact: bool = True


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
        check_magic(file)            # before the destination is made
    # small chunks: the per-chunk state (buffer, message index lists) stays well under the size
    # of even a 1 MB source file; no flush thread (a recovery is written in one go); never
    # the source, nor inside its bag folder (OutputRefused)
    with reading(src_path):
        writer = BagWriter(dst_path, chunk_size=RECOVER_CHUNK, flush_interval=None)
    result = RecoverResult(dst_path, writer.mcap_path)
    try:
        for file in files:
            _copy_file(file, writer, result)
            if writer.error is not None:
                break
    finally:
        writer.close()
    if writer.error is not None:
        raise BagError(writer.error)
    return result


class _WriterStopped(Exception):
    """Internal: the destination cannot be written (its error is in ``writer.error``)."""


class _Copier:
    """Copying one source file: its channels -> writer topics, and the messages of the chunk
    being read, written in file order once the scan moves on to the next chunk."""

    def __init__(self, writer: BagWriter, result: RecoverResult) -> None:
        self.writer = writer
        self.result = result
        self.pending: list[tuple[Any, Batch]] = []

    def want(self, channel: Channel, schema: Schema | None) -> Any:
        entry = self.writer.registered(channel.topic)     # same topic in an earlier file
        if entry is None:
            entry = self.writer.add_channel(
                channel.topic,
                schema_name=schema.name if schema else '',
                schema_encoding=schema.encoding if schema else '',
                schema_data=bytes(schema.data) if schema else b'',
                message_encoding=channel.message_encoding,
                metadata=channel.metadata)
            self.result.channels += 1
        self.result.topics.setdefault(channel.topic, 0)
        return lambda batch: self.add(entry, batch)

    def add(self, entry: Any, batch: Batch) -> None:
        if self.pending and self.pending[0][1].buffer is not batch.buffer:
            self.write_pending()                  # a new chunk: the previous one is complete
        self.pending.append((entry, batch))

    def write_pending(self) -> None:
        """The messages of one chunk, back in their file order across channels."""
        pending, self.pending = self.pending, []
        if not pending:
            return
        owner = np.concatenate([np.full(len(b), k) for k, (_, b) in enumerate(pending)])
        row = np.concatenate([np.arange(len(b)) for _, b in pending])
        order = np.argsort(np.concatenate([b.starts for _, b in pending]), kind='stable')
        fields = [(b.log_times.tolist(), b.publish_times().tolist(), b.sequences().tolist())
                  for _, b in pending]
        for k, i in zip(owner[order].tolist(), row[order].tolist()):
            entry, batch = pending[k]
            log_times, publish_times, sequences = fields[k]
            if not self.writer.write_raw(entry, batch.data(i), log_times[i], publish_times[i],
                                         sequences[i]):
                raise _WriterStopped
            self.result.messages += 1
            self.result.topics[entry.name] += 1


def _copy_file(file: Path, writer: BagWriter, result: RecoverResult) -> None:
    """Copy the readable records of ``file``; note what was damaged or cut."""
    copier = _Copier(writer, result)
    try:
        sc = scan(file, copier.want, verify=True)
        copier.write_pending()
    except _WriterStopped:
        return
    result.schemas += len(sc.schemas)
    for record in sc.metadata:
        if record.name != ROSBAG2_METADATA:        # the writer makes fresh ones
            writer.add_metadata(record.name, record.metadata)
            result.metadata += 1
    _note_damage(file, sc, result)


def _note_damage(file: Path, sc: Scan, result: RecoverResult) -> None:
    cut = sc.truncated and not sc.data_end       # a cut summary alone loses nothing
    if not sc.damage and not cut:
        return
    result.complete = False
    result.problems.append(f'{file}: {sc.problems()}')
    if sc.expected is not None and not cut:
        result.lost += max(sc.expected - sc.message_count, 0)    # the statistics survived
        return
    lost, maybe = sc.lost
    result.lost += lost
    result.lost_exact = result.lost_exact and not (maybe or cut)
