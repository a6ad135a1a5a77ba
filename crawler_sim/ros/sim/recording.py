"""sim_node recording glue: one MCAP bag (``crawler_sim.bag.BagWriter``) per run.

Recording never stops the simulation: an error closes the bag, is logged once and is reported
in the diagnostics (``recording_error``). Topics are recorded under their resolved names
(``~/x`` and relative names expanded as ROS does). The bag's folder is confined to
``record_dir`` and unique per process (``BagWriter.create``); the writer flushes itself every
0.5 wall seconds from its own thread, whether or not a message arrives, so a SIGKILL loses at
most that much of the run and the node's loop never waits on the disk.

The writer also watches its file at each of those flushes (``record_dir`` removed, moved or no
longer writable, see :mod:`crawler_sim.bag.writer`) and reports through ``on_error``, from its
flush thread: the problem is logged at ERROR level at once (measured: about 0.5 s after an
``rm -rf record_dir``), without waiting for the loop's next write, and ``path`` follows the bag
when it was restored or moved. At close the node logs where the bag is, only if it exists.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable

from crawler_sim.bag.cdr import LayoutError, set_fields
from crawler_sim.bag.topics import LINKAGE_TRAJECTORY, Topic
from crawler_sim.core.simtime import split_ns

__all__ = ['SessionBag', 'applied_trajectory']


def applied_trajectory(raw: bytes, stamp_ns: int, t_ns: int) -> bytes:
    """A received JointTrajectory (CDR) as recorded: the same bytes, with stamp 0 ("start at
    the tick it is applied") replaced by that tick's sim time ``t_ns`` [ns], so the recorded
    stamp is absolute. ``stamp_ns`` [ns] is the stamp the message arrived with. Bytes that are
    not plain little-endian CDR (the intake checks only the byte order) are recorded as they
    came: this runs in the loop, which must not fail on a message it accepted."""
    if stamp_ns:
        return raw
    sec, nanosec = split_ns(t_ns)
    try:
        return set_fields(raw, LINKAGE_TRAJECTORY.type,
                          {'header.stamp.sec': sec, 'header.stamp.nanosec': nanosec})
    except LayoutError:
        return raw


class SessionBag:
    """The bag of one sim_node session: ``write`` records one message on one of the topics of
    :mod:`crawler_sim.bag.topics`; errors close the bag (the run goes on). Offline runs record
    through :class:`crawler_sim.bag.Recorder` instead."""

    def __init__(self, resolve: Callable[[str], str], log: Any) -> None:
        self._resolve = resolve
        self._log = log
        self._names: dict[Topic, str] = {}
        self.bag = None
        self.path = ''
        self.error = ''

    @property
    def on(self) -> bool:
        return self.bag is not None

    def open(self, record_dir: str, record_name: str, scene: dict[str, Any],
             topics: Iterable[Topic] = ()) -> None:
        """Start recording (with a channel for each of ``topics`` from the first moment); on
        failure set ``error`` and stay off."""
        path = f'{record_dir}/{record_name or "<default name>"}'
        try:
            from crawler_sim.bag import BagWriter
            self.bag = BagWriter.create(record_dir, record_name, scene=scene, topics={
                self._name(t): t.type for t in topics})
            # set after creation (not a create() argument): stand-in writers keep working
            self.bag.on_error = self._bag_problem
            path = self.path = str(self.bag.path)
            self._log.info(f'recording to {path}')
        except Exception as exc:  # recording must never stop the simulation
            self.error = f'{type(exc).__name__}: {exc}'
            self._log.error(f'cannot record to {path}: {self.error}')
            self.bag = None

    def _bag_problem(self, message: str) -> None:
        """The writer's report (a problem it handled, or the error that stopped it): logged at
        ERROR level now; called from the writer's flush thread too."""
        self.error = message
        bag = self.bag
        if bag is not None:
            self.path = str(bag.path)
        self._log.error(f'recording: {message}')

    def _name(self, topic: Topic) -> str:
        name = self._names.get(topic)
        if name is None:
            name = self._names[topic] = self._resolve(topic.node_name)
        return name

    def write(self, topic: Topic, msg: Any, t_ns: int) -> None:
        """Record ``msg`` (a message or its CDR bytes) on ``topic`` at sim time ``t_ns``."""
        bag = self.bag
        if bag is None:
            return
        try:
            bag.write(self._name(topic), topic.type, msg, t_ns)
            error = getattr(bag, 'error', None)
            if error:
                if getattr(bag, 'on_error', None) == self._bag_problem:
                    self.error = error             # logged by _bag_problem already
                    self.close()
                    return
                raise RuntimeError(error)
        except Exception as exc:
            self._fail(exc)

    def _fail(self, exc: Exception) -> None:
        self.error = f'{type(exc).__name__}: {exc}'
        self._log.error(f'recording stopped: {self.error}')
        self.close()

    def close(self) -> None:
        """Close the bag (idempotent) and say where it is, if it is anywhere."""
        bag, self.bag = self.bag, None
        if bag is None:
            return
        try:
            bag.close()
        except Exception as exc:
            self.error = f'{type(exc).__name__}: {exc}'
            self._log.error(f'closing the bag failed: {self.error}')
            return
        mcap_path = getattr(bag, 'mcap_path', None)
        if getattr(bag, 'error', None) is None and mcap_path is not None and mcap_path.exists():
            self.path = str(bag.path)
            self._log.info(f'bag closed: {mcap_path} ({bag.message_count} messages)')
