"""``BagWriter``: rosbag2-compatible (Jazzy, MCAP storage) recording from Python.

A bag is a directory ``NAME/`` holding ``NAME_0.mcap`` and, once closed, ``metadata.yaml``
(version 9), laid out as ``ros2 bag record -o NAME`` lays it out:

* MCAP header profile ``ros2``; zstd chunks of about 1 MiB; summary with statistics and indexes.
* one ``ros2msg`` schema per type, named ``pkg/msg/Type``, holding the concatenated definitions
  (:func:`crawler_sim.bag.schema.full_text`);
* one ``cdr`` channel per topic with metadata ``offered_qos_profiles`` (version-9 YAML) and
  ``topic_type_hash`` (``RIHS01_...``);
* message data from ``rclpy.serialization.serialize_message``; ``log_time = publish_time`` = sim
  time in integer ns; ``sequence = 0``;
* a Metadata record ``rosbag2`` / ``serialized_metadata`` written at open (no topics) and at close.

The scene (simulation parameters plus ``crawler_sim_version``) goes in twice: as the MCAP Metadata
record ``crawler_sim.scene`` (one JSON string per top-level key) and as one latched
(transient local) ``std_msgs/msg/String`` message of YAML on ``/crawler_sim/scene``, stamped with
the time of the first message, for ``ros2 bag play`` users.

Crash safety: the header, the ``rosbag2`` record and every schema and channel known at
creation (``topics=``) are written outside chunks and flushed the moment the writer is created,
so the file is a recoverable MCAP from the first millisecond. A background thread flushes the
open chunk every ``flush_interval`` (0.5 s) of wall time whether or not messages arrive, so a
SIGKILL loses at most about that much of the run; the ``fsync`` runs outside the writer's lock.

Failure policy: an ``OSError`` while writing (disk full, I/O error) stops the recording. The
writer sets :attr:`BagWriter.error` (saying how many messages actually reached the disk),
closes the file and turns later calls into no-ops, so a simulation that records keeps running.
The partial ``.mcap`` can be repaired with :func:`crawler_sim.bag.recover`.

The bag's place is watched too (at every flush-thread pass, every ``flush_interval``, and at
close), because writing into a file that was removed fails nowhere: the writes succeed and
the data vanishes with the descriptor. So:

* the file was removed (``rm -rf record_dir``; its link count is 0): its bytes are still there
  behind the open descriptor, so the bag directory is created again (``record_dir`` too), the
  file is copied back from the descriptor and the writer carries on in the copy (``dup2`` onto
  the same descriptor number, at the same offset). Nothing is lost; the event is reported. If
  the directory cannot be made again, recording stops with an error that says the messages
  are lost (never that a removed file holds them);
* the file was moved (``mv record_dir ...``; the path no longer leads to it, but it still
  exists): recording goes on into it, and :attr:`BagWriter.path` follows it (``metadata.yaml``
  is written next to it);
* the bag directory is not writable any more: reported (``metadata.yaml`` cannot be written at
  close; the ``.mcap`` itself is unaffected and reads on its own).

Each such event is a line in :attr:`BagWriter.problems` and a call of
:attr:`BagWriter.on_error` (outside the writer's lock, possibly from the flush thread), which a
node uses to log it at ERROR level, or a ``RuntimeWarning`` when there is no callback; so is
the error that stops a recording.

The MCAP records themselves are written by :class:`crawler_sim.bag.mcapwriter.McapWriter`;
this module holds the bag around them: one class owns the file's whole life (open, crash-safe
flushing, failure policy, where the file is, metadata.yaml).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, is_dataclass
import errno
import io
import json
import os
from pathlib import Path
import threading
import time
from typing import Any, BinaryIO, Callable, Mapping
import warnings

import numpy as np
import yaml

from . import schema as schemas
from .cdr import Trimmer
from .errors import BagError
from .files import OPEN_NEW, OutputRefused, check_new_folder, open_new, write_text
from .mcapwriter import McapWriter
from .naming import claim_directory
from .rosmsg import ros_class, serialize
from .topics import SCENE, SCENE_METADATA

ROS_DISTRO = 'jazzy'
METADATA_VERSION = 9
ROSBAG2_METADATA = 'rosbag2'
ROSBAG2_METADATA_KEY = 'serialized_metadata'
CHUNK_SIZE = 1 << 20          # bytes of uncompressed chunk data before a chunk is written
FLUSH_INTERVAL = 0.5          # s of wall time between automatic flushes (SIGKILL loses <= this)
_EMPTY_START = 2**63 - 1      # rosbag2's starting_time of a bag without messages

Opener = Callable[[Path], BinaryIO]


def package_version() -> str:
    """Version of the installed crawler_sim package ('unknown' if it cannot be found)."""
    try:
        from crawler_sim import __version__
        return str(__version__)
    except ImportError:
        pass
    try:
        from importlib.metadata import version
        return version('crawler_sim')
    except Exception:  # noqa: BLE001 - any failure means "unknown"
        return 'unknown'


def plain(value: Any) -> Any:
    """``value`` turned into YAML/JSON-safe builtins (numpy arrays and scalars, tuples, paths)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if is_dataclass(value) and not isinstance(value, type):
        return plain(asdict(value))
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple, set, frozenset)):
        return [plain(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def scene_record(scene: Mapping[str, Any]) -> dict[str, str]:
    """The ``crawler_sim.scene`` Metadata record: each top-level key maps to a JSON string."""
    return {key: json.dumps(value) for key, value in plain(scene).items()}


def _ns_span(start: int | None, end: int | None) -> tuple[int, int]:
    if start is None or end is None:
        return _EMPTY_START, 0
    return start, end - start


@dataclass
class _Topic:
    """One recorded topic: its channel and what metadata.yaml needs to know about it."""

    name: str
    type: str
    channel_id: int
    qos: list[dict[str, Any]]
    type_hash: str
    cls: type | None
    serialization_format: str = 'cdr'
    count: int = 0
    trimmer: Trimmer | None = None

    def metadata(self) -> dict[str, Any]:
        """``topics_with_message_count`` entry (version 9)."""
        return {
            'topic_metadata': {
                'name': self.name,
                'type': self.type,
                'serialization_format': self.serialization_format,
                'offered_qos_profiles': self.qos,
                'type_description_hash': self.type_hash,
            },
            'message_count': self.count,
        }


@dataclass
class _Stats:
    count: int = 0
    start: int | None = None
    end: int | None = None

    def add(self, t_ns: int) -> None:
        self.count += 1
        if self.start is None or t_ns < self.start:
            self.start = t_ns
        if self.end is None or t_ns > self.end:
            self.end = t_ns


def _default_open(path: Path) -> BinaryIO:
    """A new file (never overwriting one), opened read-write: if it is removed while recording,
    its bytes can still be read back from this descriptor (see :meth:`BagWriter._restore`)."""
    return open_new(path, readable=True)      # never an existing file, never through a link


@dataclass
class _Schema:
    id: int
    name: str


class BagWriter:
    """Write one rosbag2 bag directory (MCAP storage) with sim-time stamps.

    Parameters
    ----------
    path : path-like
        Bag directory to create; it must not exist (nothing is overwritten or written then).
        The MCAP file is ``path/<name>_0.mcap``.
    scene : dict, optional
        Simulation parameters, recorded as Metadata ``crawler_sim.scene`` and on ``scene_topic``.
        ``crawler_sim_version`` is added.
    qos : dict, optional
        Offered QoS per topic, keyed by absolute topic name or by suffix (``'odom'``): either a
        dict of :func:`crawler_sim.bag.schema.qos_profile` arguments or a full list of profiles.
        Default: reliable/volatile; the scene topic is transient local (latched).
    custom_data : dict of str, optional
        ``custom_data`` of metadata.yaml.
    scene_topic : str
        Topic of the scene message (default ``/crawler_sim/scene``).
    chunk_size : int
        Uncompressed chunk size [bytes] before a chunk is compressed and written.
    flush_interval : float or None
        Wall time [s] between automatic flushes of the open chunk, by a background thread
        (by :meth:`write` instead when a test clock ``_clock`` is injected). ``0`` flushes at
        every write; None never flushes on its own. Writes grouped in :meth:`atomic` reach
        the disk together.
    topics : mapping, optional
        ``{absolute topic: type name}`` registered (schema and channel) and flushed to disk at
        creation, before any message.
    on_error : callable, optional
        ``on_error(message)`` for every problem (see :attr:`problems`) and for the error that
        stops the recording; called outside the writer's lock, possibly from its flush thread,
        so it must not block. Also settable as an attribute after creation (messages from before
        are delivered then, at the next flush).

    Attributes
    ----------
    error : str or None
        Why recording stopped (disk full...), or None while all is well.
    problems : list of str
        Events the writer handled while recording went on (the bag directory removed and
        restored, moved, or no longer writable), one line each, naming the paths.
    path, mcap_path : Path
        Where the bag is now (they change when it had to be restored or was moved).
    """

    def __init__(self, path: os.PathLike | str, *, scene: Mapping[str, Any] | None = None,
                 qos: Mapping[str, Any] | None = None,
                 custom_data: Mapping[str, str] | None = None,
                 scene_topic: str = SCENE.name(),
                 chunk_size: int = CHUNK_SIZE, flush_interval: float | None = FLUSH_INTERVAL,
                 topics: Mapping[str, str] | None = None,
                 on_error: Callable[[str], None] | None = None,
                 _opener: Opener | None = None,
                 _clock: Callable[[], float] = time.monotonic,
                 _claimed: bool = False) -> None:
        self.path = Path(path)
        self.name = self.path.name
        self.file_name = f'{self.name}_0.mcap'
        self.mcap_path = self.path / self.file_name
        self.error: str | None = None
        self.problems: list[str] = []
        self.on_error = on_error
        self._notices: list[str] = []        # problems and errors not yet handed to on_error
        self._place_lost = False             # the file is somewhere this writer cannot name
        self._unwritable_reported = False
        self._qos = dict(qos or {})
        self._custom = {str(k): str(v) for k, v in (custom_data or {}).items()} or None
        self._flush_interval = None if flush_interval is None else float(flush_interval)
        self._clock = _clock
        self._lock = threading.RLock()       # write/flush/close vs. the flush thread
        self._flushed_count = 0              # messages on disk at the last successful flush
        self._dirty = False                  # records added since the last flush
        self._stop = threading.Event()
        self._sync_wanted = threading.Event()
        self._thread: threading.Thread | None = None
        self._sync_thread: threading.Thread | None = None
        self._topics: dict[str, _Topic] = {}
        self._schemas: dict[str, _Schema] = {}
        self._stats = _Stats()
        self._closed = False
        self._scene: dict[str, Any] | None = None
        self._scene_pending = False           # the scene message waits for the first time stamp
        self._scene_topic = scene_topic
        if not _claimed:
            self._make_directory()
        try:
            self._stream = (_opener or _default_open)(self.mcap_path)
        except (OSError, BagError) as exc:    # BagError: e.g. a folder planted in its place
            _remove_empty(self.path)         # left as it is if something was put in it
            reason = getattr(exc, 'strerror', None) or exc
            raise BagError(f'cannot create {self.mcap_path}: {reason}') from None
        self._fileno = _fileno(self._stream)
        self._writer = McapWriter(self._stream, chunk_size=chunk_size, compression='zstd')
        self._last_flush = self._last_check = self._clock()
        self._guard(self._start)
        if scene is not None:
            self._scene = plain(dict(scene))
            self._scene.setdefault('crawler_sim_version', package_version())
            self._scene_pending = True
            self._guard(self._writer.add_metadata, SCENE_METADATA, scene_record(self._scene))
        for topic, type_name in (topics or {}).items():
            if self.error is None:
                self._topic(topic, type_name)
        if self._scene is not None and self.error is None:
            self._topic(self._scene_topic, SCENE.type)
        self.flush()             # header, schemas and channels on disk before any message
        if self._flush_interval and _clock is time.monotonic and self.error is None:
            self._thread = threading.Thread(target=self._flush_loop, daemon=True,
                                            name=f'bag flush {self.name}')
            self._sync_thread = threading.Thread(target=self._sync_loop, daemon=True,
                                                 name=f'bag fsync {self.name}')
            self._thread.start()
            self._sync_thread.start()

    @classmethod
    def create(cls, record_dir: os.PathLike | str, record_name: str | None = None, *,
               scene: Mapping[str, Any] | None = None, topics: Mapping[str, str] | None = None,
               **options: Any) -> BagWriter:
        """A new bag in a new folder directly inside ``record_dir``.

        ``record_name`` must be 1-200 characters of ``[A-Za-z0-9._-]`` (no separators, no
        ``..``: :func:`crawler_sim.bag.naming.check_record_name`, ``ValueError`` naming
        ``record_name`` otherwise); '' or None gives ``crawler_sim_<date-time>_<pid>``. An
        existing folder of that name gets ``_2``, ``_3``... appended, so two writers never share
        a folder. ``scene``, ``topics`` and ``options`` are those of :class:`BagWriter`.
        """
        folder = claim_directory(record_dir, record_name)
        try:
            return cls(folder, scene=scene, topics=topics, _claimed=True, **options)
        except BaseException:
            _remove_empty(folder)
            raise

    # ------------------------------------------------------------ public API

    @property
    def message_count(self) -> int:
        """Messages written so far (those for which :meth:`write` returned True)."""
        return self._stats.count

    @property
    def topics(self) -> dict[str, tuple[str, int]]:
        """``{topic: (type, message count)}`` of the topics written so far."""
        return {name: (t.type, t.count) for name, t in self._topics.items()}

    def write(self, topic: str, type_name: str, msg: Any, t_ns: int) -> bool:
        """Record ``msg`` on ``topic`` at sim time ``t_ns`` [ns] (log and publish time).

        ``msg`` is an rclpy message of ``type_name`` (``'sensor_msgs/msg/JointState'``) or its
        CDR serialisation (bytes). Returns False, without raising, once recording has stopped
        (see :attr:`error`). Raises ``ValueError`` for a negative time or a message whose type
        differs from ``type_name``, :class:`BagError` if ``type_name`` is not installed, and
        ``RuntimeError`` after :meth:`close`.
        """
        if self._closed:
            raise RuntimeError(f'{self.path}: write() after close()')
        if self.error is not None:
            return False
        with self._lock:
            if self._closed or self.error is not None:      # closed by another thread meanwhile
                return False
            written = self._write(topic, type_name, msg, t_ns)
        if self._notices:
            self._notify()
        return written

    def _write(self, topic: str, type_name: str, msg: Any, t_ns: int) -> bool:
        t_ns = int(t_ns)
        if t_ns < 0:
            raise ValueError(f'`t_ns` must be >= 0 (MCAP times are unsigned), got {t_ns}')
        entry = self._topics.get(topic)
        if entry is None or entry.type != type_name:
            entry = self._topic(topic, type_name)
            if self.error is not None:
                return False
        data = self._serialize(entry, msg)
        if self._scene_pending:
            self._write_scene(t_ns)
        return self._add(entry, data, t_ns)

    def flush(self) -> None:
        """Write the open chunk and everything buffered to disk (``fsync``); check that the
        file is still where it was (see the module doc)."""
        with self._lock:
            if self._closed or self.error is not None:
                return
            self._guard(self._flush)
            self._check_place()
            fileno = self._fileno if self.error is None else None
        self._notify()
        _fsync(fileno)

    def atomic(self) -> threading.RLock:
        """``with writer.atomic(): ...`` - the writes inside are not split by the flush thread
        (one time step's topics reach the disk together)."""
        return self._lock

    def flush_if_due(self, *, sync: bool = True) -> bool:
        """Flush if records are pending and ``flush_interval`` has passed since the last flush
        (what the background thread does); True if it flushed. Every ``flush_interval``, with
        or without records, also check that the file is still where it was (see the module
        doc). ``sync=False`` leaves the ``fsync`` to the caller (the data is with the OS
        already: a SIGKILL keeps it)."""
        with self._lock:
            if self._closed or self.error is not None or self._flush_interval is None:
                return False
            now = self._clock()
            flushed = self._dirty and now - self._last_flush >= self._flush_interval
            if flushed:
                self._guard(self._flush)
            if now - self._last_check >= self._flush_interval:
                self._check_place()
            fileno = self._fileno if flushed and self.error is None else None
        self._notify()
        if sync:
            _fsync(fileno)
        return fileno is not None

    def _flush_loop(self) -> None:
        """Flush thread: the open chunk to the OS every interval; fsync in the sync thread, so
        a slow disk never delays the next flush."""
        interval = self._flush_interval or FLUSH_INTERVAL
        while not self._stop.wait(interval / 4):
            try:
                if self.flush_if_due(sync=False):
                    self._sync_wanted.set()
            except Exception as exc:  # noqa: BLE001 - the thread must not die silently
                with self._lock:
                    if self.error is None:
                        self.error = f'recording to {self.mcap_path} stopped: flush failed ({exc})'
                return

    def _sync_loop(self) -> None:
        while True:
            self._sync_wanted.wait()
            self._sync_wanted.clear()
            if self._stop.is_set():
                return
            with self._lock:
                fileno = None if self._closed or self.error is not None else self._fileno
            _fsync(fileno)        # close() joins this thread before it closes the file

    def close(self) -> None:
        """Finish the MCAP file (summary, footer) and write metadata.yaml. Idempotent.

        After a write error only the file handle is closed: no summary and no metadata.yaml,
        as for a killed ``ros2 bag record``; :func:`crawler_sim.bag.recover` repairs the file.
        """
        self._stop.set()
        self._sync_wanted.set()
        for thread in (self._thread, self._sync_thread):
            if thread is not None and thread is not threading.current_thread():
                thread.join()
        with self._lock:
            if self._closed:
                return
            if self.error is None:
                self._check_place()          # removed or moved since the last check
            if self.error is None and self._scene_pending:
                self._write_scene(0)
            if self.error is None:
                self._guard(self._finish)
            if self.error is None:
                self._close_metadata()
            self._closed = True
            self._close_stream()
        self._notify()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    # ------------------------------------------------------------ raw API (used by recover)

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Add an MCAP Metadata record ``name`` with string keys and values."""
        with self._lock:
            if self.error is None and not self._closed:
                self._guard(self._writer.add_metadata, name, dict(data))

    def add_channel(self, topic: str, *, schema_name: str, schema_encoding: str,
                    schema_data: bytes, message_encoding: str,
                    metadata: Mapping[str, str]) -> _Topic:
        """Register ``topic`` with an explicit schema and channel metadata (no lookups)."""
        if topic in self._topics:
            raise BagError(f'{self.path}: topic {topic} registered twice')
        key = f'{schema_name}\0{schema_encoding}\0{schema_data!r}'
        if key not in self._schemas:
            sid = self._guard(self._writer.register_schema, schema_name, schema_encoding,
                              schema_data)
            self._schemas[key] = _Schema(_id(sid), schema_name)
        cid = self._guard(self._writer.register_channel, topic, message_encoding,
                          self._schemas[key].id, dict(metadata))
        entry = _Topic(topic, schema_name, _id(cid),
                       schemas.parse_qos_yaml(metadata.get('offered_qos_profiles', '')),
                       metadata.get('topic_type_hash', ''), None, message_encoding)
        self._topics[topic] = entry
        return entry

    def registered(self, topic: str) -> _Topic | None:
        """The entry of ``topic`` if it has been registered (for :meth:`write_raw`)."""
        return self._topics.get(topic)

    def write_raw(self, entry: _Topic, data: bytes, log_time: int, publish_time: int,
                  sequence: int = 0) -> bool:
        """Write already-serialised ``data`` on a topic from :meth:`add_channel`."""
        if self._closed or self.error is not None:
            return False
        with self._lock:
            return self._add(entry, data, log_time, publish_time, sequence)

    # ------------------------------------------------------------ columnar API (offline runs)

    def channel(self, topic: str, type_name: str) -> tuple[int, Trimmer | None]:
        """Register ``topic`` (schema and channel, as :meth:`write` does) if new; its MCAP
        channel id and the trimmer its messages go through, for :meth:`write_records`."""
        with self._lock:
            entry = self._topic(topic, schemas.canonical_type(type_name))
            return entry.channel_id, entry.trimmer

    def write_records(self, records: Any, channel_ids: Any, log_times: Any, sizes: Any) -> bool:
        """Write many Message records already laid out (:func:`crawler_sim.bag.mcapwriter.
        message_records`, on channels from :meth:`channel`), in file order: the bytes
        :meth:`write` of each message in turn writes (scene message included). False once
        recording has stopped."""
        if self._closed:
            raise RuntimeError(f'{self.path}: write_records() after close()')
        channel_ids = np.asarray(channel_ids, dtype=np.int64)
        log_times = np.asarray(log_times, dtype=np.int64)
        if len(log_times) and log_times.min() < 0:
            raise ValueError(f'log times must be >= 0 (MCAP times are unsigned), got '
                             f'{int(log_times.min())}')
        with self._lock:
            if self.error is not None or not len(channel_ids):
                return self.error is None
            if self._scene_pending:
                self._write_scene(int(log_times[0]))
            if self._guard(self._writer.add_records, records, channel_ids, log_times,
                           sizes) is _FAILED:
                return False
            self._dirty = True
            counts = np.bincount(channel_ids)
            for entry in self._unique_topics():
                if entry.channel_id < len(counts):
                    entry.count += int(counts[entry.channel_id])
            stats = self._stats
            stats.count += len(log_times)
            low, high = int(log_times.min()), int(log_times.max())
            stats.start = low if stats.start is None else min(stats.start, low)
            stats.end = high if stats.end is None else max(stats.end, high)
        return True

    # ------------------------------------------------------------ internals

    def _make_directory(self) -> None:
        check_new_folder(self.path)      # not an input, nothing there (OutputRefused)
        try:
            self.path.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            raise OutputRefused(f'{self.path} exists already, not overwriting') from None
        except OSError as exc:
            raise BagError(f'cannot create bag directory {self.path}: {exc.strerror}') from None

    def _start(self) -> None:
        self._writer.start(profile='ros2', library=f'crawler_sim {package_version()}')
        self._writer.add_metadata(ROSBAG2_METADATA, self._rosbag2_record())

    def _topic(self, topic: str, type_name: str) -> _Topic:
        canonical = schemas.canonical_type(type_name)
        entry = self._topics.get(topic)
        if entry is not None:
            if entry.type != canonical:
                raise ValueError(f'topic {topic} is recorded as {entry.type}, not {canonical}')
            return entry
        if not topic.startswith('/'):
            raise ValueError(f'topic {topic!r} must be absolute (start with /)')
        if canonical not in self._schemas:
            text = schemas.full_text(canonical).encode()
            sid = self._guard(self._writer.register_schema, canonical, 'ros2msg', text)
            self._schemas[canonical] = _Schema(_id(sid), canonical)
        qos = self._qos_for(topic)
        try:
            type_hash = schemas.type_hash(canonical)
        except BagError:                # no .json type description: rosbag2 leaves it empty
            type_hash = ''
        cid = self._guard(self._writer.register_channel, topic, 'cdr',
                          self._schemas[canonical].id,
                          {'offered_qos_profiles': schemas.qos_yaml(qos),
                           'topic_type_hash': type_hash})
        entry = _Topic(topic, canonical, _id(cid), qos, type_hash,
                       ros_class(canonical), trimmer=Trimmer(canonical))
        self._topics[topic] = entry
        return entry

    def _qos_for(self, topic: str) -> list[dict[str, Any]]:
        latched = topic == self._scene_topic
        spec = None
        for key in (topic, topic.lstrip('/'), topic.rsplit('/', 1)[-1]):
            if key in self._qos:
                spec = self._qos[key]
                break
        if isinstance(spec, list):
            return [dict(p) for p in spec]
        options = {'durability': 'transient_local'} if latched else {}
        options.update(spec or {})
        return [schemas.qos_profile(**options)]

    @staticmethod
    def _serialize(entry: _Topic, msg: Any) -> bytes:
        """CDR bytes of ``msg``, cut to their content (rclpy's surplus tail would make rosbags
        refuse the message, see :class:`crawler_sim.bag.cdr.Trimmer`)."""
        if isinstance(msg, (bytes, bytearray, memoryview)):
            data = bytes(msg)
            if len(data) < 4:
                raise ValueError(f'{entry.name}: {len(data)} bytes is not a CDR message')
        else:
            if entry.cls is not None and type(msg) is not entry.cls:
                raise ValueError(f'{entry.name}: message of type {schemas.type_of(msg)}, '
                                 f'expected {entry.type}')
            data = serialize(msg, entry.type)       # rclpy's, or rosbags' without ROS
        return data if entry.trimmer is None else entry.trimmer.trim(data)

    def _write_scene(self, t_ns: int) -> None:
        from . import msgs
        self._scene_pending = False
        entry = self._topic(self._scene_topic, SCENE.type)
        self._add(entry, self._serialize(entry, msgs.scene_string(self._scene)), t_ns)

    def _add(self, entry: _Topic, data: bytes, log_time: int, publish_time: int | None = None,
             sequence: int = 0) -> bool:
        publish_time = log_time if publish_time is None else publish_time
        if self._guard(self._writer.add_message, entry.channel_id, log_time, data,
                       publish_time, sequence) is _FAILED:
            return False
        self._dirty = True
        # with the flush thread running, flushes happen there (between atomic() blocks only)
        if (self._flush_interval is not None and (self._thread is None or not self._flush_interval)
                and self._clock() - self._last_flush >= self._flush_interval):
            self._guard(self._flush)
            if self.error is not None:
                return False           # this message went down with the chunk being written
            if self._clock() - self._last_check >= max(self._flush_interval, FLUSH_INTERVAL):
                self._check_place()    # no flush thread: the writes watch the file
        entry.count += 1
        self._stats.add(log_time)
        return True

    def _flush(self) -> None:
        """Open chunk and buffers to the OS (survives SIGKILL); the caller fsyncs."""
        count = self._stats.count
        self._writer.flush()
        self._flushed_count = count
        self._dirty = False
        self._last_flush = self._clock()

    def _finish(self) -> None:
        self._writer.add_metadata(ROSBAG2_METADATA, self._rosbag2_record())
        self._writer.finish()
        self._stream.flush()
        if self._fileno is not None:
            os.fsync(self._fileno)

    def _guard(self, func: Callable[..., Any], *args: Any) -> Any:
        """Call ``func``; on OSError stop recording (set :attr:`error`) and return _FAILED."""
        if self.error is not None:
            return _FAILED
        try:
            return func(*args)
        except OSError as exc:
            self._fail(exc)
            return _FAILED

    def _fail(self, exc: OSError) -> None:
        reason = exc.strerror or str(exc) or type(exc).__name__
        on_disk = self._flushed_count
        if self._removed():
            kept = (f'the file had been removed, so the {self._stats.count} messages '
                    'recorded are lost')
        elif on_disk:
            kept = (f'the file holds the first {on_disk} of {self._stats.count} messages '
                    '(crawler_sim.bag.recover makes a complete bag of them)')
        else:
            kept = f'none of the {self._stats.count} messages reached the disk'
        self._stopped(f'recording to {self.mcap_path} stopped: {reason}; {kept}')

    def _stopped(self, error: str) -> None:
        """Stop recording for good: set :attr:`error`, report it and close the file."""
        self.error = error
        self._stop.set()
        self._sync_wanted.set()
        self._notices.append(error)
        if self.on_error is None:           # else the callback is the channel (a node's log)
            warnings.warn(error, RuntimeWarning, stacklevel=4)
        self._close_stream()

    # ------------------------------------------------------------ the bag's place on disk

    def _report(self, message: str) -> None:
        """A problem handled while recording goes on (see :attr:`problems`)."""
        self.problems.append(message)
        self._notices.append(message)
        if self.on_error is None:           # else the callback is the channel (a node's log)
            warnings.warn(message, RuntimeWarning, stacklevel=4)

    def _notify(self) -> None:
        """Hand pending problems and errors to :attr:`on_error` (outside the lock)."""
        callback = self.on_error
        if not self._notices or callback is None:
            return
        with self._lock:
            notices, self._notices = self._notices, []
        for message in notices:
            try:
                callback(message)
            except Exception:  # noqa: BLE001 - a failing logger must not stop the recording
                pass

    def _removed(self) -> bool:
        """True when the open file has no name left on disk (link count 0)."""
        try:
            return self._fileno is not None and os.fstat(self._fileno).st_nlink == 0
        except OSError:
            return False

    def _check_place(self) -> None:
        """Under the lock: is the open file still at :attr:`mcap_path`? Restore it if it was
        removed, follow it if it was moved, report a directory that is no longer writable.

        Two ``stat`` calls (about 2 us), every ``flush_interval`` and at close.
        """
        self._last_check = self._clock()
        fileno = self._fileno
        if fileno is None or self._stream is None or self._place_lost:
            return
        try:
            opened = os.fstat(fileno)
        except OSError:
            return
        try:
            here = os.stat(self.mcap_path)
            same = (here.st_dev, here.st_ino) == (opened.st_dev, opened.st_ino)
        except OSError:
            same = False
        if same:
            self._check_writable()
        elif opened.st_nlink == 0:
            self._restore()
        else:
            self._follow(fileno)

    def _check_writable(self) -> None:
        if self._unwritable_reported or os.access(self.path, os.W_OK):
            return
        self._unwritable_reported = True
        self._report(f'bag directory {self.path} is no longer writable: recording goes on into '
                     f'{self.mcap_path}, but metadata.yaml cannot be written there at close '
                     '(the .mcap file reads on its own)')

    def _restore(self) -> None:
        """The file was removed (``rm -rf record_dir``): copy it back from the open descriptor
        into a new bag directory and carry on there; stop (reporting the loss) if impossible."""
        old = self.mcap_path
        fileno = self._fileno
        count = self._stats.count
        record_dir = self.path.parent
        what = (f'record_dir {record_dir} was removed' if not record_dir.exists() else
                f'bag directory {self.path} was removed' if not self.path.exists() else
                'the file was removed')
        try:
            self._stream.flush()              # the buffered tail into the (removed) file first
            size = os.fstat(fileno).st_size
            directory, target = _reclaim(self.path, self.file_name)
            fd = os.open(target, os.O_RDWR | OPEN_NEW, 0o666)
        except OSError as exc:
            self._stopped(f'recording stopped: {old} is gone ({what} during the recording) '
                          f'and cannot be written again ({exc.strerror or exc}); the {count} '
                          'messages recorded are lost')
            return
        try:
            _copy_back(fileno, fd, size)
            os.fsync(fd)
            # the writer's stream now writes into the copy, at the same offset as before
            os.dup2(fd, fileno, inheritable=False)
        except OSError as exc:
            self._stopped(f'recording stopped: {old} is gone ({what}); copying '
                          f'it back to {target} failed ({exc.strerror or exc}), so the {count} '
                          'messages recorded are lost (what reached the copy may be salvaged '
                          'with crawler_sim.bag.recover)')
            return
        finally:
            os.close(fd)
        self.path, self.file_name, self.mcap_path = directory, target.name, target
        self._report(f'{old} is gone ({what} during the recording); the {count} messages '
                     f'recorded so far were copied back from the still-open file into {target}, '
                     'and recording goes on there')

    def _follow(self, fileno: int) -> None:
        """The file still exists but not at :attr:`mcap_path` (its directory was moved)."""
        old = self.mcap_path
        where = _path_of(fileno)
        if where is None:
            self._place_lost = True
            self._report(f'{old} was moved or renamed during the recording and its new place '
                         'is unknown: recording goes on into the open file; no metadata.yaml '
                         'will be written')
            return
        self.path, self.file_name, self.mcap_path = where.parent, where.name, where
        self._report(f'{old} was moved during the recording: it is now {where}, and recording '
                     'goes on there')

    def _close_metadata(self) -> None:
        """metadata.yaml next to the finished file; a failure is reported, not an error: the
        .mcap is complete and reads on its own."""
        if self._place_lost:
            return
        try:
            self._write_metadata_yaml()
        except (OSError, BagError) as exc:      # BagError: e.g. a folder planted in its place
            where = (f'{self.mcap_path} is complete and reads on its own (crawler_sim.bag.load, '
                     'rosbags, ros2 bag play FILE.mcap)' if self.mcap_path.exists()
                     else f'{self.mcap_path} no longer exists either')
            reason = getattr(exc, 'strerror', None) or exc
            self._report(f'metadata.yaml could not be written in {self.path} '
                         f'({reason}); {where}')

    def _close_stream(self) -> None:
        stream, self._stream = getattr(self, '_stream', None), None
        if stream is not None:
            try:
                stream.close()
            except OSError:
                pass   # the buffered tail cannot be written either; the error is recorded

    def _bag_metadata(self) -> dict[str, Any]:
        """The version-9 BagMetadata map, fields in rosbag2's order."""
        start, duration = _ns_span(self._stats.start, self._stats.end)
        return {
            'version': METADATA_VERSION,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': self._stats.count,
            'topics_with_message_count': [t.metadata() for t in self._unique_topics()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.file_name],
            'files': [{
                'path': self.file_name,
                'starting_time': {'nanoseconds_since_epoch': start},
                'duration': {'nanoseconds': duration},
                'message_count': self._stats.count,
            }],
            'custom_data': self._custom,
            'ros_distro': ROS_DISTRO,
        }

    def _unique_topics(self) -> list[_Topic]:
        seen: dict[int, _Topic] = {}
        for entry in self._topics.values():
            seen.setdefault(id(entry), entry)
        return list(seen.values())

    def _rosbag2_record(self) -> dict[str, str]:
        return {ROSBAG2_METADATA_KEY: _yaml(self._bag_metadata())}

    def _write_metadata_yaml(self) -> None:
        # atomically, never through a link planted in the bag folder (crawler_sim.bag.files)
        write_text(self.path / 'metadata.yaml',
                   _yaml({'rosbag2_bagfile_information': self._bag_metadata()}))


_FAILED = object()

def _id(value: Any) -> int:
    """A schema/channel id returned through :meth:`BagWriter._guard` (0 after a failure)."""
    return value if isinstance(value, int) else 0


def _yaml(data: Any) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=False)


def _fsync(fileno: int | None) -> None:
    """fsync outside the writer's lock (it may take milliseconds on a busy disk); a file closed
    meanwhile (EBADF) has been synced by its close."""
    if fileno is None:
        return
    try:
        os.fsync(fileno)
    except OSError:
        pass


def _reclaim(directory: Path, file_name: str) -> tuple[Path, Path]:
    """``(bag directory, file path)`` where a removed bag can be written again: ``directory``
    itself (made again, with its parents) unless someone else's file is there now, else a new
    ``<name>_2``, ``<name>_3``... beside it. Never overwrites anything."""
    directory.parent.mkdir(parents=True, exist_ok=True)
    try:
        directory.mkdir()
    except FileExistsError:
        pass
    if directory.is_dir() and not os.path.lexists(directory / file_name):
        return directory, directory / file_name
    for k in range(2, 1000):
        candidate = directory.parent / f'{directory.name}_{k}'
        try:
            candidate.mkdir()
        except FileExistsError:
            continue
        return candidate, candidate / f'{candidate.name}_0.mcap'
    raise FileExistsError(errno.EEXIST, f'no free name beside {directory}')


def _copy_back(src: int, dst: int, size: int) -> None:
    """Copy the first ``size`` bytes of descriptor ``src`` to ``dst`` (1 MiB at a time)."""
    try:
        os.pread(src, 0, 0)
        read = lambda n, offset: os.pread(src, n, offset)       # noqa: E731
        handle = None
    except OSError:
        # a write-only descriptor (a custom opener): read the file through /proc (Linux)
        handle = open(f'/proc/self/fd/{src}', 'rb')

        def read(n: int, offset: int) -> bytes:
            handle.seek(offset)
            return handle.read(n)
    try:
        offset = 0
        while offset < size:
            block = read(min(1 << 20, size - offset), offset)
            if not block:
                raise OSError(errno.EIO, f'the removed file ended after {offset} of {size} bytes')
            view = memoryview(block)
            while view:
                view = view[os.write(dst, view):]
            offset += len(block)
    finally:
        if handle is not None:
            handle.close()


def _path_of(fileno: int) -> Path | None:
    """The current path of an open file (Linux: /proc/self/fd), if it still has one."""
    try:
        where = Path(os.readlink(f'/proc/self/fd/{fileno}'))
        opened, here = os.fstat(fileno), os.stat(where)
    except OSError:
        return None
    return where if (opened.st_dev, opened.st_ino) == (here.st_dev, here.st_ino) else None


def _remove_empty(folder: Path) -> None:
    try:
        folder.rmdir()
    except OSError:
        pass


def _fileno(stream: Any) -> int | None:
    try:
        return stream.fileno()
    except (AttributeError, io.UnsupportedOperation, ValueError):
        return None


__all__ = ['BagWriter', 'package_version', 'plain', 'scene_record']
