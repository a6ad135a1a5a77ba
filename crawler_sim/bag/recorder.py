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
from .clock import to_ns
from .topics import (BODY_STATES, CONTACT_STATES, EVENTS, JOINT_STATES, LINKAGE_CMD, ODOM,
                     SCENE, normalize_namespace)
from .writer import BagWriter


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
        body = msgs.body_states(t_ns, x, v, friction)
        joint = msgs.joint_states(t_ns, lengths, rates, linkage_force)
        contact_msg = msgs.contact_states(contact)
        odom = None if self.masses is None else msgs.odometry(t_ns, x, v, self.masses)
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
                                 msgs.float64_array_msg(values), t_ns)

    def record_event(self, t: float, body: int, old: int, new: int) -> bool:
        """Record a contact change of ``body`` from ``old`` to ``new`` at sim time ``t`` [s]."""
        return self.writer.write(self._names[EVENTS], EVENTS.type, msgs.event_msg(body, old, new),
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
        'v': _check('v', v, (n, p)), 'friction': _check('friction', friction, (n, p)),
        'contact': _check('contact', contact, (n, p), np.int8),
        'lengths': _check('lengths', lengths, (n, p - 1)),
        'rates': _check('rates', rates, (n, p - 1)),
        'linkage_force': _check('linkage_force', linkage_force, (n, p - 1)),
    }
    cmd_t, cmd_v = _commands(commands, p)
    pending = sorted([(tc, 0, i) for i, tc in enumerate(cmd_t)]
                     + [(te, 1, payload) for te, payload in _events(events)],
                     key=lambda item: (item[0], item[1]))
    # an offline run is written in one go: no wall-clock flushes, so the bytes are deterministic
    writer_options.setdefault('flush_interval', None)
    rec = Recorder(path, masses=masses, scene=scene, namespace=namespace, **writer_options)
    with rec:
        k = 0
        for i in range(n):
            while k < len(pending) and pending[k][0] <= t_arr[i]:
                _write_pending(rec, pending[k], cmd_v)
                k += 1
            rec.record_state(t_arr[i], x_arr[i], arrays['v'][i], arrays['friction'][i],
                             arrays['contact'][i], arrays['lengths'][i], arrays['rates'][i],
                             arrays['linkage_force'][i])
            if rec.error is not None:
                break
        for item in pending[k:]:
            _write_pending(rec, item, cmd_v)
    return rec.writer


def _commands(commands: tuple[ArrayLike, ArrayLike] | None, p: int
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    if commands is None:
        return np.zeros(0), np.zeros((0, p - 1))
    times, values = commands
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    values = _check('commands values', values, (len(times), p - 1))
    return times, values


def _write_pending(rec: Recorder, item: tuple, cmd_values: NDArray[np.float64]) -> None:
    time, kind, payload = item
    if kind == 0:
        rec.record_command(time, cmd_values[payload])
    else:
        rec.record_event(time, *payload)


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
