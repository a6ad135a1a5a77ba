"""``LeanWriter``: ``mcap.writer.Writer`` with a faster message path and definitions outside
chunks.

Split from :mod:`crawler_sim.bag.writer` (which uses it) to keep modules short.
"""
from __future__ import annotations

import struct
from typing import Any, Callable

from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import CompressionType, Writer

from .mcapfile import CHUNK_FLOOR

#: MCAP Message record up to its data: opcode, record length, channel id, sequence, log time,
#: publish time (the MCAP spec's field order; 22 bytes of fields before the data)
_MESSAGE_HEAD = struct.Struct('<BQHIQQ')
_MESSAGE_FIELDS = 22


class LeanWriter(Writer):
    """``mcap.writer.Writer`` whose :meth:`add_message` appends the Message record with one
    ``struct.pack`` (the library makes a dataclass and eight small writes: ~4 us of the ~5 us a
    recorded message costs). Same bookkeeping, same bytes; a file written through it is
    byte-identical to one written by the base class (tested). It reaches into the base class's
    private state, so it checks that state once and otherwise falls back to the base method.

    A chunk that grew past ``mcapfile.CHUNK_FLOOR`` (it holds a message larger than a chunk,
    e.g. a preloaded trajectory of minutes) is written uncompressed: readers bound a chunk's
    claimed size by the file's size (a zip bomb is refused), and a well-compressing large message
    would otherwise claim more than its file holds.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        builder = getattr(self, '_Writer__chunk_builder', None)
        lean = (builder is not None and hasattr(self, '_Writer__statistics')
                and hasattr(self, '_Writer__maybe_finalize_chunk')
                and hasattr(getattr(builder, 'record_writer', None), '_buffer')
                and all(hasattr(builder, a) for a in (
                    'message_indices', 'num_messages', 'message_start_time',
                    'message_end_time')))
        self._lean = builder if lean else None

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        """As the base class, but the Schema record goes outside chunks (flushed at once by
        the caller), so a file cut anywhere still declares it."""
        return self._unchunked(super().register_schema, name, encoding, data)

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        """As the base class, but the Channel record goes outside chunks (see above)."""
        return self._unchunked(super().register_channel, topic, message_encoding, schema_id,
                               metadata or {})

    def _unchunked(self, register: Callable[..., int], *args: Any) -> int:
        builder = getattr(self, '_Writer__chunk_builder', None)
        if builder is None:
            return register(*args)
        self._Writer__chunk_builder = None        # the base writes to the record builder then
        try:
            return register(*args)
        finally:
            self._Writer__chunk_builder = builder

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        builder = self._lean
        if builder is None:
            super().add_message(channel_id, log_time, data, publish_time, sequence)
            return
        stats = self._Writer__statistics
        if stats.message_count == 0 or log_time < stats.message_start_time:
            stats.message_start_time = log_time
        if log_time > stats.message_end_time:
            stats.message_end_time = log_time
        stats.channel_message_counts[channel_id] += 1
        stats.message_count += 1
        if builder.num_messages == 0 or log_time < builder.message_start_time:
            builder.message_start_time = log_time
        if log_time > builder.message_end_time:
            builder.message_end_time = log_time
        index = builder.message_indices.get(channel_id)
        if index is None:
            index = builder.message_indices[channel_id] = MessageIndex(channel_id=channel_id,
                                                                       records=[])
        buffer = builder.record_writer._buffer
        index.records.append((log_time, buffer.tell()))
        builder.num_messages += 1
        buffer.write(_MESSAGE_HEAD.pack(Opcode.MESSAGE, _MESSAGE_FIELDS + len(data), channel_id,
                                        sequence, log_time, publish_time))
        buffer.write(data)
        if buffer.tell() > CHUNK_FLOOR and hasattr(self, '_Writer__compression'):
            saved = self._Writer__compression
            self._Writer__compression = CompressionType.NONE
            try:
                self._Writer__maybe_finalize_chunk()
            finally:
                self._Writer__compression = saved
            return
        self._Writer__maybe_finalize_chunk()

__all__ = ['LeanWriter']
