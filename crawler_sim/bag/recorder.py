"""``Recorder`` (one crawler's topics on top of :class:`BagWriter`) and ``record_arrays``.

An offline run records the node's state topics, commands, events and scene with the same
types (the node records more; see
:mod:`crawler_sim.bag.topics`), so :func:`crawler_sim.bag.load` reads either kind of bag.
"""
from __future__ import annotations

import os
from typing import Any, Iterable, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import msgs
from .cdr import Encoder
from .clock import NS_PER_S, split_ns, to_ns
from .mcapwriter import message_records
from .topics import (BODY_STATES, CONTACT_STATES, EVENTS, JOINT_STATES, LINKAGE_CMD, ODOM,
                     SCENE, Topic, normalize_namespace)
from .writer import BagWriter

#: steps of an offline run encoded at once by :func:`record_arrays` (about 1 KB each)
BATCH = 4096
#: the encoder's field groups of each recorded topic (:mod:`crawler_sim.bag.msgs`)
_GROUPS = {BODY_STATES: msgs.JOINT_GROUPS, JOINT_STATES: msgs.JOINT_GROUPS,
           CONTACT_STATES: msgs.DATA_GROUPS, ODOM: msgs.ODOM_GROUPS,
           LINKAGE_CMD: msgs.DATA_GROUPS, EVENTS: msgs.DATA_GROUPS}


class Encoders:
    """One :class:`crawler_sim.bag.cdr.Encoder` per recorded topic and message shape (its
    number of values), made from the first message of that shape with the builders of
    :mod:`crawler_sim.bag.msgs`, as the node's ``OutputEncoder`` makes its own: so a recorded
    message is byte for byte what the node records for the same numbers (padding zero), with
    ROS or without it."""

    def __init__(self) -> None:
        self._cache: dict[tuple[Topic, int], Encoder] = {}

    def get(self, topic: Topic, width: int, build: Any) -> Encoder:
        """The encoder of ``topic`` messages of ``width`` values; ``build()`` makes the
        prototype the first time."""
        key = (topic, width)
        encoder = self._cache.get(key)
        if encoder is None:
            encoder = self._cache[key] = Encoder(build(), topic.type, _GROUPS[topic])
        return encoder


class Recorder:
    """Record one crawler's state stream, commands and events into a new bag.

    Parameters
    ----------
    path : path-like, optional
        Bag directory to create (must not exist). Not needed when ``writer`` is given.
    writer : BagWriter, optional
        Record into this open writer instead (several robots, one per namespace, in one bag);
        it is not closed by :meth:`close`.
    masses : array_like, shape (p,), optional
        Body masses [kg]; needed for ``odom`` (centre of mass). Without them (and without
        ``scene['masses']``) no ``odom`` is recorded.
    scene : dict, optional
        Simulation parameters (see :class:`BagWriter`).
    namespace : str
        Robot namespace: topics are ``/<namespace>/body_states`` etc.
    **writer_options
        Passed to :class:`BagWriter` (``qos``, ``custom_data``, ``flush_interval``, ...).
    """

    def __init__(self, path: os.PathLike | str | None = None, *,
                 writer: BagWriter | None = None, masses: ArrayLike | None = None,
                 scene: Mapping[str, Any] | None = None, namespace: str = '',
                 **writer_options: Any) -> None:
        ns = normalize_namespace(namespace)
        if masses is None and scene is not None and scene.get('masses') is not None:
            masses = scene['masses']
        self.masses = None if masses is None else np.asarray(masses, dtype=np.float64)
        if self.masses is not None and not np.all(self.masses > 0):
            raise ValueError('`masses` must be positive')
        self._names = {t: t.name(ns) for t in (BODY_STATES, JOINT_STATES, CONTACT_STATES, ODOM,
                                              LINKAGE_CMD, EVENTS)}
        if (writer is None) == (path is None):
            raise ValueError('give either `path` or `writer`')
        self._owns_writer = writer is None
        self.writer = writer if writer is not None else BagWriter(
            path, scene=scene, scene_topic=SCENE.name(ns), **writer_options)
        self.encoders = Encoders()

    @classmethod
    def create(cls, record_dir: os.PathLike | str, record_name: str | None = None, *,
               masses: ArrayLike | None = None, scene: Mapping[str, Any] | None = None,
               namespace: str = '', **writer_options: Any) -> Recorder:
        """A recorder writing a new bag inside ``record_dir`` (see :meth:`BagWriter.create`:
        the name is checked, unique, and the robot's topics are on disk at once)."""
        ns = normalize_namespace(namespace)
        topics = {t.name(ns): t.type for t in (BODY_STATES, JOINT_STATES, CONTACT_STATES,
                                               LINKAGE_CMD, EVENTS)}
        if masses is not None or (scene is not None and scene.get('masses') is not None):
            topics[ODOM.name(ns)] = ODOM.type
        writer = BagWriter.create(record_dir, record_name, scene=scene, topics=topics,
                                  scene_topic=SCENE.name(ns), **writer_options)
        try:
            rec = cls(writer=writer, masses=masses, scene=scene, namespace=namespace)
        except BaseException:
            writer.close()
            raise
        rec._owns_writer = True
        return rec

    @property
    def error(self) -> str | None:
        """Why recording stopped, or None (see :attr:`BagWriter.error`)."""
        return self.writer.error

    def record_state(self, t: float, x: ArrayLike, v: ArrayLike, friction: ArrayLike,
                     contact: ArrayLike, lengths: ArrayLike, rates: ArrayLike,
                     linkage_force: ArrayLike) -> bool:
        """Record the state at sim time ``t`` [s]; False once recording has stopped.

        Writes ``body_states``, ``joint_states``, ``contact_states`` and ``odom``; the arrays
        are those of ``Stepper.state`` (units m, m/s, N).
        """
        t_ns = to_ns(t)
        w = self.writer
        enc = self.encoders.get
        stamp = split_ns(t_ns)
        x, v, friction = (np.asarray(a, dtype=np.float64) for a in (x, v, friction))
        lengths, rates, linkage_force = (np.asarray(a, dtype=np.float64)
                                         for a in (lengths, rates, linkage_force))
        contact = np.asarray(contact, dtype=np.int8)
        body = enc(BODY_STATES, len(x), lambda: msgs.body_states(t_ns, x, v, friction)).encode(
            stamp, x.tolist(), v.tolist(), friction.tolist())
        joint = enc(JOINT_STATES, len(lengths), lambda: msgs.joint_states(
            t_ns, lengths, rates, linkage_force)).encode(
            stamp, lengths.tolist(), rates.tolist(), linkage_force.tolist())
        contact_msg = enc(CONTACT_STATES, len(contact),
                          lambda: msgs.contact_states(contact)).encode(contact.tolist())
        odom = None
        if self.masses is not None:
            com = msgs.centre_of_mass(x, v, self.masses)
            odom = enc(ODOM, 1, lambda: msgs.odometry(t_ns, x, v, self.masses)).encode(
                stamp, com[:1], com[1:])
        with w.atomic():            # a flush never splits one time step
            w.write(self._names[BODY_STATES], BODY_STATES.type, body, t_ns)
            w.write(self._names[JOINT_STATES], JOINT_STATES.type, joint, t_ns)
            w.write(self._names[CONTACT_STATES], CONTACT_STATES.type, contact_msg, t_ns)
            if odom is not None:
                w.write(self._names[ODOM], ODOM.type, odom, t_ns)
        return w.error is None

    def record(self, state: Any) -> bool:
        """Record a core ``State`` (``t, x, v, friction, contact, lengths, rates, ...``)."""
        return self.record_state(state.t, state.x, state.v, state.friction, state.contact,
                                 state.lengths, state.rates, state.linkage_force)

    def record_command(self, t: float, values: ArrayLike) -> bool:
        """Record a command (``linkage_cmd``, p-1 values) applied at sim time ``t`` [s]."""
        t_ns = to_ns(t)
        return self.writer.write(self._names[LINKAGE_CMD], LINKAGE_CMD.type,
                                 self._command(values), t_ns)

    def _command(self, values: ArrayLike) -> bytes:
        data = np.atleast_1d(np.asarray(values, dtype=np.float64))
        return self.encoders.get(LINKAGE_CMD, len(data),
                                 lambda: msgs.float64_array_msg(data)).encode(data.tolist())

    def _event(self, body: int, old: int, new: int) -> bytes:
        data = [int(body), int(old), int(new)]
        return self.encoders.get(EVENTS, 3, lambda: msgs.event_msg(*data)).encode(data)

    def record_event(self, t: float, body: int, old: int, new: int) -> bool:
        """Record a contact change of ``body`` from ``old`` to ``new`` at sim time ``t`` [s]."""
        return self.writer.write(self._names[EVENTS], EVENTS.type, self._event(body, old, new),
                                 to_ns(t))

    def flush(self) -> None:
        """See :meth:`BagWriter.flush`."""
        self.writer.flush()

    def close(self) -> None:
        """Close the bag (see :meth:`BagWriter.close`) unless the writer was passed in."""
        if self._owns_writer:
            self.writer.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()


def _check(name: str, value: ArrayLike, shape: tuple[int, ...], dtype: Any = np.float64
           ) -> NDArray:
    arr = np.asarray(value, dtype=dtype)
    if arr.shape != shape:
        raise ValueError(f'`{name}` must have shape {shape}, got {arr.shape}')
    return arr


def _events(items: Iterable[Any] | None) -> list[tuple[float, tuple[int, int, int]]]:
    """[(time [s], (body, old, new))] from Event-like objects or 4-tuples."""
    out = []
    for item in items or ():
        time, body, old, new = (item.time, item.body, item.old, item.new) \
            if hasattr(item, 'time') else item
        out.append((float(time), (int(body), int(old), int(new))))
    return out


def record_arrays(path: os.PathLike | str, *, t: ArrayLike, x: ArrayLike, v: ArrayLike,
                  friction: ArrayLike, contact: ArrayLike, lengths: ArrayLike, rates: ArrayLike,
                  linkage_force: ArrayLike,
                  commands: tuple[ArrayLike, ArrayLike] | None = None,
                  events: Iterable[Any] | None = None,
                  scene: Mapping[str, Any] | None = None,
                  masses: ArrayLike | None = None, namespace: str = '',
                  **writer_options: Any) -> BagWriter:
    """Write an offline run as a bag with the node's topics and types.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sim times [s].
    x, v, friction : array_like, shape (N, p)
        Positions [m], velocities [m/s], ground friction on each body [N].
    contact : array_like, shape (N, p)
        Contact states (+1, 0, -1).
    lengths, rates, linkage_force : array_like, shape (N, p-1)
        Linkage lengths [m], rates [m/s], forces [N].
    commands : (times (K,), values (K, p-1)), optional
        Commands and the sim times [s] at which they took effect (``linkage_cmd``).
    events : iterable, optional
        ``Event(time, body, old, new)`` objects or tuples (``events``).
    scene : dict, optional
        Parameters of the run; ``scene['masses']`` is used when ``masses`` is not given.
    masses : array_like, shape (p,), optional
        Body masses [kg] for ``odom``.

    Messages are written in time order; a command or event at time ``tc`` is written just before
    the first state with ``t >= tc``. Returns the closed :class:`BagWriter` (``error``,
    ``topics``, ``mcap_path``).
    """
    t_arr = np.asarray(t, dtype=np.float64)
    if t_arr.ndim != 1:
        raise ValueError(f'`t` must be one-dimensional, got shape {t_arr.shape}')
    n = len(t_arr)
    x_arr = np.asarray(x, dtype=np.float64)
    if x_arr.ndim != 2 or len(x_arr) != n:
        raise ValueError(f'`x` must have shape ({n}, p), got {x_arr.shape}')
    p = x_arr.shape[1]
    arrays = {
        'x': x_arr,
        'v': _check('v', v, (n, p)), 'friction': _check('friction', friction, (n, p)),
        'contact': _check('contact', contact, (n, p), np.int8),
        'lengths': _check('lengths', lengths, (n, p - 1)),
        'rates': _check('rates', rates, (n, p - 1)),
        'linkage_force': _check('linkage_force', linkage_force, (n, p - 1)),
    }
    if n and not (np.all(np.isfinite(t_arr)) and t_arr.min() >= 0):
        raise ValueError('`t` must hold finite times >= 0 [s] (MCAP times are unsigned)')
    cmd_t, cmd_v = _commands(commands, p)
    event_list = _events(events)
    for name, times in (('commands', cmd_t), ('events', [e[0] for e in event_list])):
        if len(times) and not (np.all(np.isfinite(times)) and np.min(times) >= 0):
            raise ValueError(f'`{name}` times must be finite and >= 0 [s] (MCAP times are '
                             'unsigned)')
    pending = sorted([(tc, 0, i) for i, tc in enumerate(cmd_t)]
                     + [(te, 1, payload) for te, payload in event_list],
                     key=lambda item: (item[0], item[1]))
    # an offline run is written in one go: no wall-clock flushes, so the bytes are deterministic
    writer_options.setdefault('flush_interval', None)
    rec = Recorder(path, masses=masses, scene=scene, namespace=namespace, **writer_options)
    with rec:
        _write_columns(rec, to_ns(t_arr), arrays, pending, cmd_v,
                       np.maximum.accumulate(t_arr) if n else t_arr)
    return rec.writer


def _write_columns(rec: Recorder, t_ns: NDArray[np.int64], arrays: dict[str, NDArray],
                   pending: list[tuple], cmd_values: NDArray[np.float64],
                   t_max: NDArray[np.float64]) -> None:
    """The columnar form of :meth:`Recorder.record_state` for every row, with the commands
    and events of ``pending`` each written just before the first state at or after its time:
    the file a loop of ``record_command``/``record_event``/``record_state`` calls writes, byte
    for byte (each channel registered just before its first message, as :meth:`BagWriter.write`
    does). States are encoded :data:`BATCH` steps at a time
    (:meth:`crawler_sim.bag.cdr.Encoder.rows`, :func:`crawler_sim.bag.mcapwriter.
    message_records`) and written with :meth:`BagWriter.write_records`."""
    w = rec.writer
    n = len(t_ns)
    out = _Records(w)
    known: dict[Topic, tuple[int, Any]] = {}

    def channel(topic: Topic) -> tuple[int, Any]:
        if topic not in known:
            out.flush()              # the records before it go to the chunks they would
            known[topic] = w.channel(rec._names[topic], topic.type)
        return known[topic]

    steps: list | None = None
    cursor = 0

    def states(upto: int) -> None:
        nonlocal steps, cursor
        while cursor < upto and w.error is None:
            if steps is None:
                steps = _step_topics(rec, t_ns, arrays, channel)
            stop = min(upto, cursor + BATCH)
            block, cids, sizes = _step_block(steps, t_ns, cursor, stop)
            count = stop - cursor
            out.add(block.reshape(-1), np.tile(cids, count),
                    np.repeat(t_ns[cursor:stop], len(cids)), np.tile(sizes, count))
            cursor = stop

    times = np.array([item[0] for item in pending], dtype=np.float64)
    positions = np.searchsorted(t_max, times, side='left') if n else np.zeros(len(times), int)
    for (time, kind, payload), position in zip(pending, positions.tolist()):
        states(position)
        topic = LINKAGE_CMD if kind == 0 else EVENTS
        data = rec._command(cmd_values[payload]) if kind == 0 else rec._event(*payload)
        cid, trimmer = channel(topic)
        data = data if trimmer is None else trimmer.trim(data)
        item_ns = to_ns(time)
        record = message_records(cid, np.array([item_ns]),
                                 np.frombuffer(data, np.uint8)[None, :]).reshape(-1)
        out.add(record, np.array([cid]), np.array([item_ns]), np.array([len(record)]))
    states(n)
    out.flush()


class _Records:
    """Message records gathered for one :meth:`BagWriter.write_records` call."""

    def __init__(self, writer: BagWriter) -> None:
        self.writer = writer
        self.parts: list[tuple[NDArray, NDArray, NDArray, NDArray]] = []
        self.nbytes = 0

    def add(self, records: NDArray[np.uint8], channels: NDArray, times: NDArray,
            sizes: NDArray) -> None:
        self.parts.append((records, channels, times, sizes))
        self.nbytes += len(records)
        if self.nbytes >= 4 << 20:       # a few chunks at a time: memory stays small
            self.flush()

    def flush(self) -> None:
        if not self.parts:
            return
        records, channels, times, sizes = (np.concatenate(c) for c in zip(*self.parts))
        self.parts, self.nbytes = [], 0
        self.writer.write_records(records, channels, times, sizes)


def _step_topics(rec: Recorder, t_ns: NDArray[np.int64], arrays: dict[str, NDArray],
                 channel: Any) -> list[tuple[int, Any, dict[str, NDArray], int]]:
    """Per topic of a state: (channel id, encoder, columns, bytes per message), in the order
    :meth:`Recorder.record_state` writes them."""
    x, v, friction = arrays['x'], arrays['v'], arrays['friction']
    contact = arrays['contact']
    lengths, rates, force = arrays['lengths'], arrays['rates'], arrays['linkage_force']
    sec, nanosec = np.divmod(t_ns, NS_PER_S)
    stamp = {'header.stamp.sec': sec, 'header.stamp.nanosec': nanosec}
    t0 = int(t_ns[0]) if len(t_ns) else 0
    row = 0 if len(t_ns) else None
    p = x.shape[1]

    def first(a: NDArray, width: int) -> NDArray:
        return a[row] if row is not None else np.zeros(width, a.dtype)

    specs: list[tuple[Topic, int, Any, dict[str, NDArray]]] = [
        (BODY_STATES, p, lambda: msgs.body_states(t0, first(x, p), first(v, p),
                                                  first(friction, p)),
         {**stamp, 'position': x, 'velocity': v, 'effort': friction}),
        (JOINT_STATES, p - 1, lambda: msgs.joint_states(
            t0, first(lengths, p - 1), first(rates, p - 1), first(force, p - 1)),
         {**stamp, 'position': lengths, 'velocity': rates, 'effort': force}),
        (CONTACT_STATES, p, lambda: msgs.contact_states(first(contact, p)), {'data': contact}),
    ]
    if rec.masses is not None:
        com_x, com_v = msgs.centre_of_mass_rows(x, v, rec.masses)
        specs.append((ODOM, 1, lambda: msgs.odometry(t0, first(x, p), first(v, p), rec.masses),
                      {**stamp, 'pose.pose.position.x': com_x, 'twist.twist.linear.x': com_v}))
    out = []
    for topic, width, build, columns in specs:
        encoder = rec.encoders.get(topic, width, build)
        cid, trimmer = channel(topic)
        template = encoder.template
        size = len(template if trimmer is None else trimmer.trim(template))
        out.append((cid, encoder, columns, size))
    return out


def _step_block(steps: list[tuple[int, Any, dict[str, NDArray], int]], t_ns: NDArray[np.int64],
                start: int, stop: int
                ) -> tuple[NDArray[np.uint8], NDArray[np.int64], NDArray[np.int64]]:
    """The Message records of steps ``start:stop``, one step per row, and the channel id and
    record size of each topic of a step."""
    records = [message_records(cid, t_ns[start:stop], encoder.rows(
        {k: c[start:stop] for k, c in columns.items()}, stop - start)[:, :size])
        for cid, encoder, columns, size in steps]
    block = np.hstack(records)
    cids = np.array([cid for cid, _, _, _ in steps], dtype=np.int64)
    sizes = np.array([r.shape[1] for r in records], dtype=np.int64)
    return block, cids, sizes


def _commands(commands: tuple[ArrayLike, ArrayLike] | None, p: int
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if commands is None:
        return np.zeros(0), np.zeros((0, p - 1))
    times, values = commands
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    values = _check('commands values', values, (len(times), p - 1))
    return times, values


def record_trajectory(path: os.PathLike | str, trajectory: Any, *,
                      commands: tuple[ArrayLike, ArrayLike] | None = None,
                      scene: Mapping[str, Any] | None = None, **options: Any) -> BagWriter:
    """Write a ``crawler_sim.Trajectory`` with :func:`record_arrays`.

    Contact comes from ``trajectory.contact``, events from ``trajectory.events`` and masses from
    ``trajectory.crawler``.
    """
    masses = getattr(getattr(trajectory, 'crawler', None), 'masses', None)
    return record_arrays(
        path, t=trajectory.t, x=trajectory.x, v=trajectory.v, friction=trajectory.friction,
        contact=trajectory.contact, lengths=trajectory.lengths, rates=trajectory.rates,
        linkage_force=trajectory.linkage_force, commands=commands,
        events=getattr(trajectory, 'events', None), scene=scene,
        masses=options.pop('masses', masses), **options)
