"""What the plant takes as input, and the rules an input must meet before it is applied.

Rules (ros2_control's forward_command_controller and joint_trajectory_controller, plus limits):

- a command (``linkage_cmd``): the size is checked first (a wrong size is rejected even when
  every entry is NaN); then all-NaN means "no command yet" (the caller ignores it); then every
  length must be finite and in [min_length, max_length];
- a trajectory (``linkage_trajectory``, as :class:`TrajectoryArrays`): names known, unique and
  complete; time_from_start >= 0 and strictly increasing; array sizes; finite values;
  positions within limits; zero velocity at the last point; no effort. Stamp 0 means "start at
  the tick it is applied"; a non-zero stamp is absolute sim time and must neither end before
  the current sim time nor start more than ``max_lead`` seconds after it (a wall-clock stamp
  sent to a node on sim time would otherwise be held, silently, for decades). The point times,
  converted to float seconds from the tick they are applied at, must stay strictly increasing
  (two points 1 ns apart at ``stamp.sec = 2e8`` round to the same float: rejected, not a
  crash).

Units: ns, m, m/s, m/s^2.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Sequence

import numpy as np

from ..actuator import TrajectoryReference
from ..simtime import to_seconds

#: the most points one trajectory may hold (1,000,000: 48 MB of positions, velocities and
#: accelerations for one linkage, parsed in a few tens of ms); gait_node and the offline streams
#: keep to it too
MAX_TRAJECTORY_POINTS = 1_000_000

__all__ = ['MAX_TRAJECTORY_POINTS', 'linkage_names', 'check_command', 'TrajectoryArrays',
           'PreparedTrajectory',
           'check_head', 'check_trajectory']


def linkage_names(n: int) -> tuple[str, ...]:
    """``linkage_0`` ... ``linkage_{n-1}``."""
    return tuple(f'linkage_{j}' for j in range(n))


def check_command(data: Sequence[float], n_links: int, lo: float, hi: float) -> str | None:
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
class TrajectoryArrays:
    """One JointTrajectory as arrays (units: ns, m, m/s, m/s^2).

    ``velocities``/``accelerations``/``effort`` are None when every point leaves them empty; a
    trajectory that fills them only for some points has ``mixed`` set (the node rejects it).
    """

    stamp_ns: int
    joint_names: list[str]
    tfs_ns: np.ndarray                 # int64 (N,): time_from_start of each point
    positions: np.ndarray              # (N, n_names) float64, or (N, k) when sizes mismatch
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    effort: np.ndarray | None
    sizes: tuple[int, int, int, int]   # per-point sizes of the four arrays (first point)
    mixed: bool = False                # points of different shapes
    nbytes: int = 0                    # bytes the message uses (0: unknown); rclpy's buffers
    # may carry unused bytes after it, which rosbags refuses ("CDR message size mismatch")

    @property
    def n_points(self) -> int:
        return len(self.tfs_ns)


@dataclass
class PreparedTrajectory:
    """A validated trajectory: arrays in linkage order (units ns, m, m/s, m/s^2)."""

    stamp_ns: int                        # 0: start at the tick it is applied
    tfs_ns: np.ndarray                   # (N,) int64
    positions: np.ndarray                # (N, n_links)
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    raw: bytes | None = None             # the message as received (for the bag)
    #: the reference last built (``reference``) and what it was built from
    _ref: tuple | None = field(default=None, repr=False, compare=False)

    def times(self, t_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """(mask of points not yet past, their times [s] from sim time ``t_ns``)."""
        offset = self.stamp_ns - t_ns if self.stamp_ns else 0
        rel_ns = self.tfs_ns + offset
        keep = rel_ns >= 0
        return keep, to_seconds(rel_ns[keep])

    def reference(self, t_ns: int, state: Sequence[Sequence[float]], lo: float = -math.inf,
                  hi: float = math.inf) -> TrajectoryReference:
        """The actuator reference of this trajectory applied at the tick starting at ``t_ns``
        (points already past are dropped), from the actuator ``state`` (l, l', l'') per
        linkage. Raises ValueError when the times cannot be used (see ``_times_reason``), or
        when the interpolation between the points leaves [``lo``, ``hi``] [m] or is not
        finite (velocities or accelerations too large for the spacing of the points: a
        velocity of 1e3 m/s between in-range points drove a linkage to -0.07 m)."""
        key = (t_ns, tuple(tuple(row) for row in state), lo, hi)
        if self._ref is not None and self._ref[0] == key:
            return self._ref[1]                # checked already for this tick and state
        reason = _times_reason(self, t_ns)
        if reason:
            raise ValueError(reason)
        keep, times = self.times(t_ns)
        vel = self.velocities[keep] if self.velocities is not None else None
        acc = self.accelerations[keep] if self.accelerations is not None else None
        ref = TrajectoryReference.from_arrays(to_seconds(t_ns), state, times, self.positions[keep],
                                              vel, acc)
        out = ref.outside(lo, hi)
        if out is not None:
            k, j, value = out
            starts_at_state = times[0] != 0.0       # segment 0 runs from the actuator's state
            first = int(np.argmax(keep))
            a = 'the current length' if (starts_at_state and k == 0) else (
                f'point #{first + k - starts_at_state}')
            b = f'point #{first + k + 1 - starts_at_state}'
            what = ('is not finite' if math.isnan(value) else
                    f'reaches {value:.6g} m, outside [min_length, max_length] = [{lo}, {hi}]')
            raise ValueError(f'the interpolation of linkage_{j} between {a} and {b} {what} '
                             '(velocities or accelerations too large for the point spacing)')
        self._ref = (key, ref)
        return ref


def check_head(names: Sequence[str], sizes: Sequence[int], n_points: int, n_links: int
               ) -> str | None:
    """The rules a trajectory's head meets (joint names, and the array sizes of its first
    point): the reason it is rejected, or None. Cheap: a parser checks it before reading any
    point (``crawler_sim.bag.trajarrays.parse``), so a wrong message costs microseconds
    whatever its size."""
    if not names:
        return 'empty joint_names'
    if len(set(names)) != len(names):
        shown = list(names[:8]) + (['...'] if len(names) > 8 else [])
        return f'duplicate joint names {shown}'
    known = linkage_names(n_links)
    for name in names:
        if name not in known:
            return f'unknown joint {name[:80]!r} (expected {", ".join(known)})'
    if len(names) != n_links:
        return f'joint_names must list all {n_links} linkages, got {len(names)}'
    if n_points == 0:
        return None
    if sizes[0] != n_links:
        return (f'mismatch between joint_names size ({n_links}) and positions ({sizes[0]}) '
                'at point #0')
    for what, size in (('velocities', sizes[1]), ('accelerations', sizes[2])):
        if size not in (0, n_links):
            return (f'mismatch between joint_names size ({n_links}) and {what} ({size}) '
                    'at point #0')
    if sizes[3]:
        return 'trajectories with effort fields are not supported'
    return None


def check_trajectory(tr: TrajectoryArrays, n_links: int, lo: float, hi: float, t_ns: int,
                     max_lead_s: float) -> tuple[str | None, PreparedTrajectory | None]:
    """(reason, None) when ``tr`` is rejected, else (None, the prepared trajectory)."""
    names = tr.joint_names
    n = tr.n_points
    if n and tr.mixed:
        reason = check_head(names, (n_links, 0, 0, 0), 0, n_links)
        return (reason or 'points differ in which of positions/velocities/accelerations/'
                'effort they fill'), None
    reason = check_head(names, tr.sizes, n, n_links)
    if reason:
        return reason, None
    known = linkage_names(n_links)
    if n == 0:
        empty = np.zeros(0, dtype=np.int64)
        return None, PreparedTrajectory(tr.stamp_ns, empty, np.zeros((0, n_links)), None, None)
    tfs = tr.tfs_ns
    if tfs[0] < 0:
        return f'time_from_start of point #0 is negative ({to_seconds(int(tfs[0]))} s)', None
    steps = np.diff(tfs)
    if n > 1 and not np.all(steps > 0):
        k = int(np.argmin(steps > 0)) + 1
        return (f'time_from_start not strictly increasing at point {k} '
                f'({to_seconds(int(tfs[k - 1]))} -> {to_seconds(int(tfs[k]))} s)'), None
    if tr.stamp_ns:
        lead = tr.stamp_ns - t_ns
        if to_seconds(lead) > max_lead_s:
            return (f'stamp {to_seconds(tr.stamp_ns):.9g} s is {to_seconds(lead):.6g} s ahead of '
                    'the sim time '
                    f'{to_seconds(t_ns):.9g} s (at most max_trajectory_lead = {max_lead_s:g} s; '
                    'a wall-clock stamp on a node running on sim time? stamp 0 = start now)'), None
        end_ns = tr.stamp_ns + int(tfs[-1])
        if end_ns < t_ns:
            return (f'trajectory with start time {to_seconds(tr.stamp_ns)} s ends at '
                    f'{to_seconds(end_ns)}'
                    f' s, before the current sim time {to_seconds(t_ns)} s'), None
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
    for what, arr in (('velocities', tr.velocities), ('accelerations', tr.accelerations)):
        if arr is not None and not np.all(np.isfinite(arr)):
            k = int(np.argwhere(~np.isfinite(arr))[0][0])
            return f'non-finite {what} at point #{k}', None
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
