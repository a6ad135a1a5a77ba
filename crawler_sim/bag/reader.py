"""``load``: a crawler_sim bag (directory or bare .mcap) as numpy arrays.

Topics are matched by suffix (``/body_states``, ``/crawler1/body_states``...), see
:mod:`crawler_sim.bag.topics`. The hot topics are decoded by :class:`crawler_sim.bag.cdr.Decoder`
(vectorized, checked against rclpy, or rosbags without ROS), chunk by chunk while the file is
scanned.

Module size: about 520 lines, over the ~400 guide: the chunk scan, the per-topic decoders and
the memory budget all read one scan state (splitting them would pass it around in pieces).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import re
from typing import Any, Callable, NamedTuple
import warnings

from mcap.records import Channel, Schema
import numpy as np
from numpy.typing import NDArray
import yaml

from crawler_sim.core.trajectory import sample_frame

from .cdr import Decoder
from .clock import NS_PER_S, to_seconds
from .errors import BagError
from .mcapfile import Batch, Scan, scan
from .rosmsg import deserialize
from .topics import (APPLIED_COMMAND, BODY_STATES, CONTACT_STATES, EVENTS, JOINT_STATES,
                     LINKAGE_CMD, SCENE, SCENE_METADATA, normalize_namespace, split_topic)

_JOINT_FIELDS = ('header.stamp.sec', 'header.stamp.nanosec', 'position', 'velocity', 'effort')
_APPLIED = APPLIED_COMMAND.leaf     # <node>/applied_command, whatever the node's name
_FILE_NUMBER = re.compile(r'_(\d+)\.mcap$')
_MAX_METADATA = 16 << 20       # bytes; rosbag2 writes a few KiB
#: ``Run.contact`` of a body that did not exist at that state (a bag whose number of bodies
#: changed during the run): distinct from +1, 0 (stuck) and -1, and far from them
NO_BODY = -128


class BagWarning(UserWarning):
    """A bag was read only in part (truncated file, dropped incomplete steps)."""


class TopicSummary(NamedTuple):
    """Type and message count of one topic."""

    type: str
    count: int


class Commands(NamedTuple):
    """Commands as applied: ``t`` (K,) [s] and ``values`` (K, p-1)."""

    t: NDArray[np.float64]
    values: NDArray[np.float64]


class Events(NamedTuple):
    """Contact changes: ``t`` (K,) [s], ``body`` (K,), ``old`` and ``new`` states (K,) int8."""

    t: NDArray[np.float64]
    body: NDArray[np.int64]
    old: NDArray[np.int8]
    new: NDArray[np.int8]


@dataclass(frozen=True, eq=False)
class Run:
    """A recorded run.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Sim time [s] of each state (``body_states`` header stamps).
    x, v, friction : ndarray, shape (N, p)
        Body positions [m], velocities [m/s], friction force of the ground on each body [N].
    contact : ndarray, shape (N, p), int8
        +1 sliding forward, 0 stuck, -1 sliding backward; :data:`NO_BODY` (-128) where the
        body did not exist (see ``present``).
    lengths, rates, linkage_force : ndarray, shape (N, p-1)
        Linkage lengths [m], rates [m/s] and forces [N] (``joint_states``); NaN for a linkage
        that did not exist.
    commands : Commands
        Applied commands (``linkage_cmd``, else ``applied_command``): (K,) and (K, p-1).
    events : Events
        Recorded contact changes (empty if none were recorded).
    scene : dict
        Simulation parameters (from the scene topic, else the ``crawler_sim.scene`` record).
    topics : dict
        ``{topic: TopicSummary(type, count)}`` for every topic of the bag.
    namespace : str
        Robot namespace that was read ('' for the root namespace).
    bodies, linkages : tuple of str
        Joint names of ``body_states`` and ``joint_states``.
    truncated : bool
        True when the file was incomplete and only its readable part was loaded.
    t_ns : ndarray, shape (N,), int64
        The same stamps as recorded, in integer nanoseconds: compare times in this base (``t``
        is ``to_seconds(t_ns)`` and may differ from the simulated float time by up to 0.5 ns, see
        :func:`crawler_sim.bag.clock.rows_at_ns`).
    present : ndarray, shape (N, p), bool
        True where body j existed at state i. All True unless the number of bodies changed
        during the run (sim_node resets on a new ``p`` and records on): then ``p`` is the
        largest number of bodies, and a body that did not exist at a state has NaN ``x``,
        ``v`` and ``friction``, contact :data:`NO_BODY`, and NaN for the linkages beyond it.
    """

    path: Path
    t: NDArray[np.float64]
    x: NDArray[np.float64]
    v: NDArray[np.float64]
    friction: NDArray[np.float64]
    contact: NDArray[np.int8]
    lengths: NDArray[np.float64]
    rates: NDArray[np.float64]
    linkage_force: NDArray[np.float64]
    commands: Commands
    events: Events
    scene: dict[str, Any]
    topics: dict[str, TopicSummary]
    namespace: str = ''
    bodies: tuple[str, ...] = ()
    linkages: tuple[str, ...] = ()
    truncated: bool = False
    t_ns: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    present: NDArray[np.bool_] = field(default_factory=lambda: np.zeros((0, 0), bool))

    @property
    def p(self) -> int:
        """Number of bodies."""
        return self.x.shape[1]

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s] (0 for fewer than two states)."""
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def incumbent(self) -> NDArray[np.bool_]:
        """(N, p) bool: the bodies of the cluster stuck just before each state (the
        incumbent of a crawler with stiction, ``State.incumbent``). A recorded state is the
        one on the interval ending at its time, and at most one cluster is stuck on an
        interval, so these are its bodies with contact 0: the bag holds the incumbent without
        a field of its own (False where a body did not exist)."""
        return self.contact == 0

    @property
    def masses(self) -> NDArray[np.float64] | None:
        """The body masses [kg] of the recorded scene, when it gives one per body."""
        crawler = self.scene.get('crawler') if isinstance(self.scene, dict) else None
        masses = crawler.get('masses') if isinstance(crawler, dict) else None
        if masses is None and isinstance(self.scene, dict):
            masses = self.scene.get('masses')
        try:
            m = np.asarray(masses, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            return None
        return m if masses is not None and m.size == self.p else None

    def to_pandas(self) -> 'pandas.DataFrame':  # noqa: F821 - pandas is optional
        """The states as a pandas DataFrame, the layout of ``Trajectory.to_pandas``
        (:func:`crawler_sim.core.trajectory.sample_frame`; ``com`` when the scene gives the
        masses). Needs pandas (``pip install pandas``)."""
        return sample_frame(self.t, self.x, self.v, self.friction, self.contact, self.lengths,
                            self.rates, self.linkage_force, self.masses)

    def __repr__(self) -> str:
        """One line: where from, bodies, span, states, events (not every array in full)."""
        span = f't=[{self.t[0]:g}, {self.t[-1]:g}] s, ' if len(self.t) else ''
        return (f'Run({str(self.path)!r}, p={self.p}, {span}{len(self.t)} states, '
                f'{len(self.events.t)} events{", truncated" if self.truncated else ""})')


# ---------------------------------------------------------------- files of a bag

def bag_files(path: os.PathLike | str) -> list[Path]:
    """The .mcap files of a bag directory (from metadata.yaml if present) or ``[path]``.

    Only regular files count (a FIFO or device named ``*.mcap`` is refused, not opened); a
    metadata.yaml that lists a file twice is refused (the data would be read twice).
    """
    path = Path(path)
    if path.is_dir():
        return _directory_files(path)
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    if not path.is_file():
        raise BagError(f'{path}: not a regular file or directory (FIFO, device or socket)')
    return [path]


def _directory_files(path: Path) -> list[Path]:
    meta = path / 'metadata.yaml'
    files: list[Path] = []
    if meta.is_file():
        try:
            if meta.stat().st_size > _MAX_METADATA:
                raise ValueError('metadata.yaml too large')
            info = yaml.safe_load(meta.read_text(encoding='utf-8'))['rosbag2_bagfile_information']
            # only plain strings: str() of nested YAML aliases could grow exponentially
            names = [Path(rel).name for rel in info['relative_file_paths']
                     if isinstance(rel, str)]
        except (yaml.YAMLError, KeyError, TypeError, ValueError, OSError, RecursionError):
            names = []
        repeated = sorted(n for n, k in Counter(names).items() if k > 1)
        if repeated:
            raise BagError(f'{meta}: relative_file_paths lists {", ".join(repeated[:3])} more '
                           'than once; refusing to read the same data twice')
        files = [f for f in (path / n for n in names) if f.is_file()]
    if not files:
        files = sorted((f for f in path.glob('*.mcap') if f.is_file()), key=_file_order)
    if not files:
        raise BagError(f'{path}: no .mcap file (regular file) in this directory')
    return files


def _file_order(path: Path) -> tuple[int, str]:
    match = _FILE_NUMBER.search(path.name)
    return (int(match.group(1)) if match else -1, path.name)


# ---------------------------------------------------------------- collecting messages

class _Budget:
    """Bytes of decoded data one file may give: :data:`DECODE_FACTOR` times its size (at least
    :data:`DECODE_FLOOR`). A real recording decodes to a fraction of its uncompressed size (names,
    headers and untouched topics are dropped), so only a crafted file (a chunk bomb) reaches it."""

    def __init__(self, path: Path, file_size: int) -> None:
        self.path = path
        self.limit = max(DECODE_FLOOR, DECODE_FACTOR * file_size)
        self.used = 0

    def take(self, nbytes: int) -> None:
        self.used += nbytes
        if self.used > self.limit:
            raise BagError(f'{self.path}: decodes to more than {self.limit} bytes '
                           f'({DECODE_FACTOR}x the file size); refusing a file that expands '
                           'like this (crafted or corrupt)')


DECODE_FACTOR = 2
DECODE_FLOOR = 1 << 20


@dataclass
class _TopicData:
    """Messages of one topic collected from one file."""

    type: str
    decoder: Decoder | None
    budget: _Budget
    log_times: list[NDArray[np.int64]] = field(default_factory=list)
    first: bytes | None = None

    def sink(self, batch: Batch) -> None:
        before = self.decoder.nbytes if self.decoder is not None else 0
        if self.decoder is not None:          # first: it raises on damaged data
            self.decoder.add(batch.buffer, batch.starts, batch.lengths)
        if self.first is None and len(batch):
            self.first = batch.data(0)
        self.log_times.append(batch.log_times)
        after = self.decoder.nbytes if self.decoder is not None else 0
        self.budget.take(after - before + batch.log_times.nbytes)

    def times(self) -> NDArray[np.int64]:
        return np.concatenate(self.log_times) if self.log_times else np.zeros(0, np.int64)


#: fields read from each type of the topics :func:`load` reads
_FIELDS = {
    BODY_STATES.type: _JOINT_FIELDS,         # and joint_states, applied_command
    CONTACT_STATES.type: ('data',),
    LINKAGE_CMD.type: ('data',),
    EVENTS.type: ('data',),
}


_LOADED = (BODY_STATES, JOINT_STATES, CONTACT_STATES, LINKAGE_CMD, EVENTS, SCENE)


def _interesting(topic: str) -> bool:
    """Whether :func:`load` reads ``topic`` (in any namespace)."""
    return (any(split_topic(topic, t.suffix) is not None for t in _LOADED)
            or topic.endswith('/' + _APPLIED))


def _scan_file(path: Path) -> tuple[Scan, dict[str, _TopicData]]:
    """Scan one file, decoding the crawler_sim topics on the way."""
    store: dict[str, _TopicData] = {}
    try:
        size = path.stat().st_size
    except OSError:
        size = 0                          # scan() reports the reason
    budget = _Budget(path, size)

    def want(channel: Channel, schema: Schema | None) -> Callable[[Batch], None] | None:
        if not _interesting(channel.topic):
            return None
        type_name = schema.name if schema is not None else ''
        fields = _FIELDS.get(type_name)
        data = _TopicData(type_name, Decoder(type_name, fields) if fields else None, budget)
        store[channel.topic] = data          # a re-scan of the file replaces the first attempt
        return data.sink

    return scan(path, want), store


@dataclass
class _Series:
    """One topic merged over all files: log times [ns], decoded columns, first message."""

    type: str
    log_times: NDArray[np.int64]
    columns: dict[str, NDArray]
    first: bytes | None
    widths: dict[str, NDArray[np.int64]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.log_times)

    def column(self, path: str, width: int, dtype: Any = np.float64, fill: Any = 0) -> NDArray:
        """Column ``path`` as shape (N, width); entries a message did not hold are NaN for
        floats and ``fill`` for integers (never a NaN cast to an integer)."""
        values = self.columns.get(path, np.zeros((len(self), 0)))
        integer = np.dtype(dtype).kind in 'iu'
        if integer and values.dtype.kind == 'f':
            # ragged integer columns were NaN-padded as floats: the NaN are absent entries
            values = np.where(np.isnan(values), fill, values)
        if values.shape[1] == width:
            return values.astype(dtype, copy=False)
        out = np.full((len(self), width), fill if integer else np.nan, dtype=dtype)
        w = min(width, values.shape[1])
        out[:, :w] = values[:, :w]
        return out


_WIDTHS = ('position',)         # columns whose per-message length load needs (Run.present)


def _merged(stores: list[dict[str, _TopicData]], topic: str) -> _Series | None:
    parts = [store[topic] for store in stores if topic in store]
    if not parts:
        return None
    columns: dict[str, NDArray] = {}
    decoded = [p.decoder.columns() for p in parts if p.decoder is not None]
    for key in (decoded[0] if decoded else {}):
        arrays = [d[key] for d in decoded]
        width = max(a.shape[1] for a in arrays)
        if any(a.shape[1] != width for a in arrays):
            arrays = [np.pad(a.astype(np.float64), ((0, 0), (0, width - a.shape[1])),
                             constant_values=np.nan) for a in arrays]
        columns[key] = np.concatenate(arrays) if len(arrays) > 1 else arrays[0]
    first = next((p.first for p in parts if p.first is not None), None)
    times = [p.times() for p in parts]
    # entries each message held, where a ragged width means something: bodies per state
    widths = {key: np.concatenate([p.decoder.widths(key) for p in parts
                                   if p.decoder is not None])
              for key in _WIDTHS if key in columns}
    return _Series(parts[0].type, np.concatenate(times) if len(times) > 1 else times[0],
                   columns, first, widths)


def _topic_summary(scans: list[Scan]) -> dict[str, TopicSummary]:
    out: dict[str, TopicSummary] = {}
    for sc in scans:
        for cid, channel in sorted(sc.channels.items()):
            schema = sc.schemas.get(channel.schema_id)
            old = out.get(channel.topic, TopicSummary(schema.name if schema else '', 0))
            out[channel.topic] = TopicSummary(old.type, old.count + sc.counts.get(cid, 0))
    return out


def _namespace(path: Path, topics: dict[str, TopicSummary], namespace: str | None) -> str:
    found = sorted(ns for topic, info in topics.items()
                   if (ns := split_topic(topic, BODY_STATES.suffix)) is not None
                   and info.type == BODY_STATES.type)
    shown = ', '.join(n or '/' for n in found)
    if namespace is not None:
        ns = normalize_namespace(namespace)
        if ns not in found:
            raise BagError(f'{path}: no {BODY_STATES.name(ns)} topic; crawler_sim namespaces '
                           f'in this bag: {shown or "none"}')
        return ns
    scenes = sorted(ns for topic in topics if (ns := split_topic(topic, SCENE.suffix)) is not None)
    if not found and len(scenes) == 1:
        return scenes[0]            # stopped before its first state: an empty run
    if not found:
        names = sorted(topics)
        listed = ', '.join(names[:8]) + (' ...' if len(names) > 8 else '')
        raise BagError(f'{path}: no crawler_sim topics (…/{BODY_STATES.suffix} of type '
                       f'{BODY_STATES.type}); topics: {listed or "none"}')
    if len(found) > 1:
        raise BagError(f'{path}: several crawler_sim namespaces ({shown}); '
                       'choose one with namespace=')
    return found[0]


Rows = 'slice | NDArray[np.int64]'


def _align(series: list[_Series | None], stacklevel: int, by_time: bool = False
           ) -> list[Rows | None]:
    """Rows of each present topic that put them on common time steps.

    Topics with equal message counts are taken row by row (also when recorded live, where log
    times differ between topics) unless ``by_time`` (messages were lost in the middle of the
    file: equal counts no longer mean equal steps); otherwise only the log times present in
    all are kept (the k-th message at a log time pairs with the k-th of the others).
    """
    present = [s for s in series if s is not None]
    if len({len(s) for s in present}) <= 1 and not by_time:
        return [slice(None) if s is not None else None for s in series]
    keys = _occurrence_keys([s.log_times for s in present])
    common = keys[0]
    for k in keys[1:]:
        common = np.intersect1d(common, k)
    rows = iter([np.flatnonzero(np.isin(k, common)) for k in keys])
    out = [None if s is None else next(rows) for s in series]
    dropped = max(len(s) for s in present) - len(common)
    if dropped:
        warnings.warn(f'{dropped} time steps without all of body, joint and contact states '
                      'were dropped', BagWarning, stacklevel=stacklevel)
    return out


def _occurrence_keys(times: list[NDArray[np.int64]]) -> list[NDArray[np.int64]]:
    """One integer per message, equal across the lists for the k-th message at the same log
    time (a reset publishes twice at one sim time), unique within each list."""
    if not times or not sum(len(t) for t in times):
        return [np.zeros(0, np.int64) for _ in times]
    _, inverse = np.unique(np.concatenate(times), return_inverse=True)
    ids = np.split(inverse.reshape(-1).astype(np.int64), np.cumsum([len(t) for t in times])[:-1])
    ranks = []
    for t_ids in ids:
        order = np.argsort(t_ids, kind='stable')
        ordered = t_ids[order]
        rank = np.empty_like(t_ids)
        rank[order] = np.arange(len(t_ids)) - np.searchsorted(ordered, ordered, side='left')
        ranks.append(rank)
    width = 1 + max((int(r.max()) for r in ranks if len(r)), default=0)
    return [i * width + r for i, r in zip(ids, ranks)]


def _stamps_ns(series: _Series) -> NDArray[np.int64]:
    sec = series.column('header.stamp.sec', 1, np.int64)[:, 0]
    nanosec = series.column('header.stamp.nanosec', 1, np.int64)[:, 0]
    return sec * NS_PER_S + nanosec


def _names(series: _Series | None) -> tuple[str, ...]:
    if series is None or series.first is None:
        return ()
    try:
        return tuple(deserialize(series.first, series.type).name)
    except Exception:  # noqa: BLE001 - names are informative only
        return ()


def _scene(stores: list[dict[str, _TopicData]], scans: list[Scan], ns: str) -> dict[str, Any]:
    series = _merged(stores, SCENE.name(ns))
    if series is not None and series.first is not None and series.type == SCENE.type:
        try:
            text = deserialize(series.first, SCENE.type).data
            value = yaml.safe_load(text)
            if isinstance(value, dict):
                return value
        except Exception:  # noqa: BLE001 - fall back to the metadata record
            pass
    for sc in scans:
        for record in sc.metadata:
            if record.name == SCENE_METADATA:
                return {key: _json_or_text(text) for key, text in record.metadata.items()}
    return {}


def _json_or_text(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text


def _commands(stores: list[dict[str, _TopicData]], topics: dict[str, TopicSummary], ns: str,
              width: int) -> Commands:
    series = _merged(stores, LINKAGE_CMD.name(ns))
    if series is not None and series.type == LINKAGE_CMD.type:
        return Commands(to_seconds(series.log_times), series.column('data', width))
    for topic in sorted(topics):
        if topic.startswith(ns + '/') and topic.endswith('/' + _APPLIED):
            series = _merged(stores, topic)
            if series is not None and series.type == JOINT_STATES.type:
                return Commands(to_seconds(_stamps_ns(series)), series.column('position', width))
    return Commands(np.zeros(0), np.zeros((0, width)))


def _events(stores: list[dict[str, _TopicData]], ns: str) -> Events:
    series = _merged(stores, EVENTS.name(ns))
    if series is None or series.type != EVENTS.type:
        return Events(np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int8),
                      np.zeros(0, np.int8))
    data = series.column('data', 3, np.int64)
    return Events(to_seconds(series.log_times), data[:, 0], data[:, 1].astype(np.int8),
                  data[:, 2].astype(np.int8))


def load(path: os.PathLike | str, *, namespace: str | None = None) -> Run:
    """Load a crawler_sim recording.

    Parameters
    ----------
    path : path-like
        A bag directory (``metadata.yaml`` optional) or a bare ``.mcap`` file.
    namespace : str, optional
        Robot namespace to read when the bag holds several (``'crawler1'``).

    Raises :class:`BagError` (one-line message) for a missing, empty or non-MCAP file and for a
    bag without crawler_sim topics. A truncated file loads up to where it was cut, a damaged
    one every intact chunk, with a :class:`BagWarning` that says what was lost.
    """
    files = bag_files(path)
    scans: list[Scan] = []
    stores: list[dict[str, _TopicData]] = []
    for file in files:
        result, store = _scan_file(file)
        if result.damage:
            warnings.warn(f'{file}: damaged: {"; ".join(str(d) for d in result.damage)}; '
                          'loaded the messages of every intact part (crawler_sim.bag.recover '
                          'copies them into a new bag)', BagWarning, stacklevel=2)
        if result.truncated:
            warnings.warn(f'{file}: {result.stop_reason}; loaded the {result.message_count} '
                          'messages before that point (crawler_sim.bag.recover repairs the file)',
                          BagWarning, stacklevel=2)
        scans.append(result)
        stores.append(store)
    topics = _topic_summary(scans)
    ns = _namespace(Path(path), topics, namespace)
    return _build_run(Path(path), ns, scans, stores, topics)


def _bodies_of(scene: dict[str, Any], names: tuple[str, ...]) -> int:
    """Number of bodies of a bag without states: from the scene's masses, else 0."""
    for masses in (scene.get('masses'), (scene.get('crawler') or {}).get('masses')
                   if isinstance(scene.get('crawler'), dict) else None):
        if isinstance(masses, list) and masses:
            return len(masses)
    return len(names)


def _build_run(path: Path, ns: str, scans: list[Scan], stores: list[dict[str, _TopicData]],
               topics: dict[str, TopicSummary]) -> Run:
    body = _merged(stores, BODY_STATES.name(ns))
    joint = _merged(stores, JOINT_STATES.name(ns))
    contact = _merged(stores, CONTACT_STATES.name(ns))
    joint = joint if joint is not None and joint.type == JOINT_STATES.type else None
    contact = contact if contact is not None and contact.type == CONTACT_STATES.type else None
    if body is None and BODY_STATES.name(ns) in topics:   # a channel without readable data
        raise BagError(f'{path}: {BODY_STATES.name(ns)} could not be read')
    stateless = body is None
    if stateless:                  # only the scene: the recording stopped before any state
        warnings.warn(f'{path}: no states recorded (only the scene)', BagWarning, stacklevel=3)
        body = _Series(BODY_STATES.type, np.zeros(0, np.int64), {}, None)
    scene = _scene(stores, scans, ns)
    p = body.columns['position'].shape[1] if len(body) else _bodies_of(scene, _names(body))
    # a damaged middle loses a run of messages: steps are matched by time, not by count
    ib, ij, ic = _align([body, joint, contact], stacklevel=4,
                        by_time=any(sc.damage for sc in scans))
    missing = [t.suffix for t, s in ((JOINT_STATES, joint), (CONTACT_STATES, contact))
               if s is None]
    if missing and not stateless:
        warnings.warn(f'{path}: no {" or ".join(missing)} topic in namespace {ns or "/"}',
                      BagWarning, stacklevel=3)
    n_links = max(p - 1, 0)

    t_ns = _stamps_ns(body)[ib]
    n = len(t_ns)
    # bodies each state held (p changes when sim_node is reconfigured during a recording)
    held = body.widths.get('position', np.full(len(body), p, np.int64))[ib]
    present = np.arange(p) < held[:, None]

    def rows(series: _Series | None, idx: Rows | None, field_path: str, width: int,
             dtype: Any = np.float64) -> NDArray:
        if series is None:        # missing topic: NaN floats, no contact columns
            return (np.full((n, width), np.nan) if np.dtype(dtype).kind == 'f'
                    else np.zeros((n, 0), dtype))
        return series.column(field_path, width, dtype, fill=NO_BODY)[idx]

    return Run(
        path=path,
        t=to_seconds(t_ns),
        x=rows(body, ib, 'position', p), v=rows(body, ib, 'velocity', p),
        friction=rows(body, ib, 'effort', p),
        contact=rows(contact, ic, 'data', p, np.int8),
        lengths=rows(joint, ij, 'position', n_links), rates=rows(joint, ij, 'velocity', n_links),
        linkage_force=rows(joint, ij, 'effort', n_links),
        commands=_commands(stores, topics, ns, n_links),
        events=_events(stores, ns),
        scene=scene,
        topics=topics,
        namespace=ns,
        bodies=_names(body),
        linkages=_names(joint),
        truncated=any(sc.incomplete for sc in scans),
        t_ns=t_ns,
        present=present,
    )
