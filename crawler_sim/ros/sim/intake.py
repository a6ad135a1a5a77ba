"""Command and trajectory intake of sim_node: validation, queueing, cheap rejection.

Rules (ros2_control's forward_command_controller and joint_trajectory_controller, plus limits):

- ``linkage_cmd`` (Float64MultiArray): the size is checked first (a wrong size is rejected even
  when every entry is NaN); then all-NaN means "no command yet" (counted, ignored); then every
  length must be finite and in [min_length, max_length].
- ``linkage_trajectory`` (JointTrajectory, taken raw and parsed by :mod:`.trajarrays`): names
  known, unique and complete; time_from_start >= 0 and strictly increasing; array sizes; finite
  values; positions within limits; zero velocity at the last point; no effort; at most
  :data:`~.trajarrays.MAX_TRAJECTORY_POINTS` points. Stamp 0 means "start at the tick it is
  applied"; a non-zero stamp is absolute sim time and must neither end before the current sim
  time nor start more than ``max_trajectory_lead`` seconds after it (a wall-clock stamp sent to a
  node on sim time would otherwise be held, silently, for decades). The point times, converted
  to float seconds from the tick they are applied at, must stay strictly increasing (two points
  1 ns apart at ``stamp.sec = 2e8`` round to the same float: rejected, not a crash).

A rejection is counted and costs microseconds: it is logged at most once per
:data:`LOG_PERIOD` per input with the count since the last message, and the logger is not called
at all in between (rclpy's logger inspects its caller on every call, about 540 us, even when a
throttle then drops the message).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import time
from typing import Any, Callable, Sequence

import numpy as np

from crawler_sim.core.actuator import TrajectoryReference
from . import trajarrays
from .trajarrays import TrajectoryArrays, TrajectoryFormatError

__all__ = ['validate_command', 'check_trajectory', 'RejectionLog', 'PreparedTrajectory',
           'prepare', 'reference', 'LOG_PERIOD', 'linkage_names']

LOG_PERIOD = 1.0     # wall s between two log lines about rejected input of one kind


def linkage_names(n: int) -> tuple[str, ...]:
    """``linkage_0`` ... ``linkage_{n-1}``."""
    return tuple(f'linkage_{j}' for j in range(n))


def validate_command(data: Sequence[float], n_links: int, lo: float, hi: float) -> str | None:
    """forward_command_controller rules for ``linkage_cmd``: the reason it is rejected, or None.

    The size is checked first; an all-NaN message of the right size ("no command yet") is not
    an error here (the caller ignores it).
    """
    if len(data) != n_links:
        return f'expected {n_links} lengths (linkage_0..linkage_{n_links - 1}), got {len(data)}'
    if all(math.isnan(x) for x in data):
        return None
    for j, x in enumerate(data):
        if not math.isfinite(x):
            return f'linkage_{j} length is not finite ({x})'
        if not lo <= x <= hi:
            return f'linkage_{j} length {x} outside [min_length, max_length] = [{lo}, {hi}]'
    return None


@dataclass
class PreparedTrajectory:
    """A validated trajectory: arrays in linkage order (units ns, m, m/s, m/s^2)."""

    stamp_ns: int                        # 0: start at the tick it is applied
    tfs_ns: np.ndarray                   # (N,) int64
    positions: np.ndarray                # (N, n_links)
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    raw: bytes | None = None             # the message as received (for the bag)

    def times(self, t_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """(mask of points not yet past, their times [s] from sim time ``t_ns``)."""
        offset = self.stamp_ns - t_ns if self.stamp_ns else 0
        rel_ns = self.tfs_ns + offset
        keep = rel_ns >= 0
        return keep, rel_ns[keep] / 1e9


def check_trajectory(tr: TrajectoryArrays, n_links: int, lo: float, hi: float, t_ns: int,
                     max_lead_s: float) -> tuple[str | None, PreparedTrajectory | None]:
    """(reason, None) when ``tr`` is rejected, else (None, the prepared trajectory)."""
    names = tr.joint_names
    if not names:
        return 'empty joint_names', None
    if len(set(names)) != len(names):
        return f'duplicate joint names {names}', None
    known = linkage_names(n_links)
    for name in names:
        if name not in known:
            return f'unknown joint {name!r} (expected {", ".join(known)})', None
    if len(names) != n_links:
        return f'joint_names must list all {n_links} linkages, got {len(names)}', None
    n = tr.n_points
    if n == 0:
        empty = np.zeros(0, dtype=np.int64)
        return None, PreparedTrajectory(tr.stamp_ns, empty, np.zeros((0, n_links)), None, None)
    if tr.mixed:
        return ('points differ in which of positions/velocities/accelerations/effort they '
                'fill'), None
    sizes = tr.sizes
    if sizes[0] != n_links:
        return (f'mismatch between joint_names size ({n_links}) and positions ({sizes[0]}) '
                'at point #0'), None
    for field, size in (('velocities', sizes[1]), ('accelerations', sizes[2])):
        if size not in (0, n_links):
            return (f'mismatch between joint_names size ({n_links}) and {field} ({size}) '
                    'at point #0'), None
    if sizes[3]:
        return 'trajectories with effort fields are not supported', None
    tfs = tr.tfs_ns
    if tfs[0] < 0:
        return f'time_from_start of point #0 is negative ({tfs[0] / 1e9} s)', None
    steps = np.diff(tfs)
    if n > 1 and not np.all(steps > 0):
        k = int(np.argmin(steps > 0)) + 1
        return (f'time_from_start not strictly increasing at point {k} '
                f'({tfs[k - 1] / 1e9} -> {tfs[k] / 1e9} s)'), None
    if tr.stamp_ns:
        lead = tr.stamp_ns - t_ns
        if lead > max_lead_s * 1e9:
            return (f'stamp {tr.stamp_ns / 1e9:.9g} s is {lead / 1e9:.6g} s ahead of the sim time '
                    f'{t_ns / 1e9:.9g} s (at most max_trajectory_lead = {max_lead_s:g} s; '
                    'a wall-clock stamp on a node running on sim time? stamp 0 = start now)'), None
        end_ns = tr.stamp_ns + int(tfs[-1])
        if end_ns < t_ns:
            return (f'trajectory with start time {tr.stamp_ns / 1e9} s ends at {end_ns / 1e9}'
                    f' s, before the current sim time {t_ns / 1e9} s'), None
    order = [names.index(name) for name in known]
    pos = tr.positions[:, order]
    bad = ~(np.isfinite(pos) & (pos >= lo) & (pos <= hi))
    if bad.any():
        k, j = (int(i) for i in np.argwhere(bad)[0])
        return (f'position {pos[k, j]} of {known[j]} at point #{k} outside [min_length, '
                f'max_length] = [{lo}, {hi}]'), None
    vel = tr.velocities[:, order] if tr.velocities is not None else None
    acc = tr.accelerations[:, order] if (tr.accelerations is not None and vel is not None) \
        else None
    for field, arr in (('velocities', tr.velocities), ('accelerations', tr.accelerations)):
        if arr is not None and not np.all(np.isfinite(arr)):
            k = int(np.argwhere(~np.isfinite(arr))[0][0])
            return f'non-finite {field} at point #{k}', None
    if vel is not None and np.any(vel[-1] != 0.0):
        return 'velocity of the last trajectory point is not zero', None
    prepared = PreparedTrajectory(tr.stamp_ns, tfs, pos, vel, acc)
    reason = _times_reason(prepared, t_ns)
    return (reason, None) if reason else (None, prepared)


def _times_reason(tr: PreparedTrajectory, t_ns: int) -> str | None:
    """Why the point times cannot be used from sim time ``t_ns`` (float rounding), or None."""
    keep, times = tr.times(t_ns)
    if not len(times):
        return 'trajectory ended before it could be applied'
    if len(times) > 1 and not np.all(np.diff(times) > 0):
        return ('points too close together for their distance from the sim time: two point '
                'times round to the same float second')
    return None


def prepare(data: bytes, n_links: int, lo: float, hi: float, t_ns: int, max_lead_s: float
            ) -> tuple[str | None, PreparedTrajectory | None]:
    """Parse and check a raw ``linkage_trajectory`` message (see :func:`check_trajectory`)."""
    try:
        tr = trajarrays.parse(data)
    except TrajectoryFormatError as exc:
        return str(exc), None
    reason, prepared = check_trajectory(tr, n_links, lo, hi, t_ns, max_lead_s)
    if prepared is not None:
        prepared.raw = data[:tr.nbytes] if tr.nbytes else data
    return reason, prepared


def reference(tr: PreparedTrajectory, t_ns: int, state: Sequence[Sequence[float]]
              ) -> TrajectoryReference | None:
    """The actuator reference of ``tr`` applied at the tick starting at ``t_ns`` (points already
    past are dropped); None when nothing is left. Raises ValueError when the times cannot be
    used (see :func:`_times_reason`)."""
    reason = _times_reason(tr, t_ns)
    if reason:
        raise ValueError(reason)
    keep, times = tr.times(t_ns)
    vel = tr.velocities[keep] if tr.velocities is not None else None
    acc = tr.accelerations[keep] if tr.accelerations is not None else None
    return TrajectoryReference.from_arrays(t_ns / 1e9, state, times, tr.positions[keep], vel,
                                           acc)


class RejectionLog:
    """Counts rejected inputs and logs at most once per ``period`` wall seconds per kind.

    ``note`` costs a dict update and one ``time.monotonic()`` call; the logger (about 540 us
    per call in rclpy) is called only when a line is due.
    """

    def __init__(self, counters: dict[str, int], warn: Callable[[str], Any],
                 period: float = LOG_PERIOD, clock: Callable[[], float] = time.monotonic) -> None:
        self.counters = counters
        self._warn = warn
        self._period = period
        self._clock = clock
        self._next: dict[str, float] = {}
        self._since: dict[str, int] = {}
        self.last = ''
        self.lines = 0            # log lines written

    def note(self, kind: str, topic: str, reason: str) -> None:
        key = kind + '_rejected'
        self.counters[key] = self.counters.get(key, 0) + 1
        self.last = f'{kind}: {reason}'
        self._since[kind] = self._since.get(kind, 0) + 1
        now = self._clock()
        if now >= self._next.get(kind, 0.0):
            n, self._since[kind] = self._since[kind], 0
            self._next[kind] = now + self._period
            self.lines += 1
            self._warn(f'{topic} rejected: {reason} ({n} rejected since the last message, '
                       f'{self.counters[key]} in all)')
