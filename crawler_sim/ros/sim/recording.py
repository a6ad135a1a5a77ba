"""sim_node recording glue: one MCAP bag (``crawler_sim.bag.BagWriter``) per run.

Recording never stops the simulation: an error closes the bag, is logged once and is reported
in the diagnostics (``recording_error``). Topics are recorded under their resolved names
(``~/x`` and relative names expanded as ROS does). The bag is flushed every
:data:`FLUSH_PERIOD` wall seconds by the loop (:meth:`Recorder.maybe_flush`), whether or not
a message arrives, so a SIGKILL loses at most that much of the run.
"""
from __future__ import annotations

import os
import time
from typing import Any, Callable

__all__ = ['Recorder', 'bag_name', 'applied_trajectory', 'FLUSH_PERIOD']

FLUSH_PERIOD = 0.5      # wall s between two flushes of the bag


def bag_name(record_name: str, when: float | None = None) -> str:
    """The bag's directory name: ``record_name``, or ``crawler_sim_<date>-<time>-<pid>``
    (unique per process, so two nodes started in the same second do not collide). A name
    that would leave ``record_dir`` (a path separator, ``..``) raises ValueError."""
    if not record_name:
        stamp = time.strftime('%Y%m%d-%H%M%S', time.localtime(when))
        return f'crawler_sim_{stamp}-{os.getpid()}'
    if (os.sep in record_name or '/' in record_name or record_name in ('.', '..')
            or os.path.isabs(record_name)):
        raise ValueError(f'record_name {record_name!r} must be a plain name inside record_dir '
                         '(no path separators, not . or ..)')
    return record_name


def applied_trajectory(raw: bytes, stamp_ns: int, t_ns: int) -> bytes:
    """A received JointTrajectory (CDR) as recorded: the same bytes, with stamp 0 ("start at
    the tick it is applied") replaced by that tick's sim time ``t_ns``, so the recorded stamp
    is absolute."""
    if stamp_ns:
        return raw
    sec, nanosec = divmod(t_ns, 1_000_000_000)
    return (raw[:4] + sec.to_bytes(4, 'little', signed=True) + nanosec.to_bytes(4, 'little')
            + raw[12:])


class Recorder:
    """The node's bag. ``write`` records one message; errors close the bag."""

    def __init__(self, resolve: Callable[[str], str], log) -> None:
        self._resolve = resolve
        self._log = log
        self._names: dict[str, str] = {}
        self.bag = None
        self.path = ''
        self.error = ''
        self._last_flush = time.monotonic()

    @property
    def on(self) -> bool:
        return self.bag is not None

    def open(self, record_dir: str, record_name: str, scene: dict[str, Any],
             topics: dict[str, str] | None = None) -> None:
        """Start recording; on failure set ``error`` and stay off."""
        path = os.path.join(record_dir, record_name or '?')
        try:
            from crawler_sim.bag import BagWriter
            create = getattr(BagWriter, 'create', None)
            if create is not None:       # confines and uniquifies the name itself
                self.bag = create(record_dir, record_name, scene=scene, topics=topics)
                path = str(getattr(self.bag, 'path', path))
            else:
                path = os.path.join(record_dir, bag_name(record_name))
                if os.path.exists(path):
                    raise FileExistsError(f'{path} exists: choose another record_name')
                os.makedirs(record_dir, exist_ok=True)
                self.bag = BagWriter(path, scene=scene)
            self.path = path
            self._last_flush = time.monotonic()
            self._log.info(f'recording to {path}')
        except Exception as exc:  # recording must never stop the simulation
            self.error = f'{type(exc).__name__}: {exc}'
            self._log.error(f'cannot record to {path}: {self.error}')
            self.bag = None

    def write(self, topic: str, type_name: str, msg: Any, t_ns: int) -> None:
        bag = self.bag
        if bag is None:
            return
        name = self._names.get(topic)
        if name is None:
            name = self._names[topic] = self._resolve(topic)
        try:
            bag.write(name, type_name, msg, t_ns)
            if getattr(bag, 'error', None):
                raise RuntimeError(bag.error)
        except Exception as exc:
            self._fail(exc)

    def maybe_flush(self, now: float) -> None:
        """Flush when FLUSH_PERIOD wall seconds passed since the last flush."""
        if self.bag is None or now - self._last_flush < FLUSH_PERIOD:
            return
        self._last_flush = now
        try:
            self.bag.flush()
        except Exception as exc:
            self._fail(exc)

    def _fail(self, exc: Exception) -> None:
        self.error = f'{type(exc).__name__}: {exc}'
        self._log.error(f'recording stopped: {self.error}')
        self.close()

    def close(self) -> None:
        """Close the bag (idempotent)."""
        bag, self.bag = self.bag, None
        if bag is not None:
            try:
                bag.close()
            except Exception as exc:
                self.error = f'{type(exc).__name__}: {exc}'
                self._log.error(f'closing the bag failed: {self.error}')
