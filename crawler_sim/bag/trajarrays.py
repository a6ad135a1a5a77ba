"""``linkage_trajectory`` as numpy arrays: CDR parsed without building rclpy messages.

rclpy turns a JointTrajectory into one Python object per point (a 100k-point message takes
about 1.5 s to deserialise, all of it in the simulation loop). The node takes the message raw
instead and :func:`parse` reads it with numpy: the header and the names in Python, then the
points, which all have the same shape in any real trajectory, as strided views of the buffer.
A message whose points differ in shape is rejected (the node would reject it anyway) without
handing it to rclpy's per-point parse.

Limits: at most :data:`MAX_TRAJECTORY_POINTS` points (1,000,000: 48 MB of positions for one
linkage, parsed in a few tens of ms); larger messages are rejected from their point count
before anything else is read.

CDR layout (XCDR1, plain, little-endian; offsets from the end of the 4-byte encapsulation
header): Header (int32 sec, uint32 nanosec, string frame_id), string[] joint_names,
JointTrajectoryPoint[] points; a point is float64[] positions, velocities, accelerations, effort
(uint32 count, then 8-aligned doubles when count > 0) and Duration (int32 sec, uint32 nanosec).
"""
from __future__ import annotations

import struct
from typing import Any

import numpy as np

from crawler_sim.core.plant.inputs import MAX_TRAJECTORY_POINTS, TrajectoryArrays, check_head
from crawler_sim.core.simtime import from_stamp

__all__ = ['TrajectoryArrays', 'parse', 'from_message', 'MAX_TRAJECTORY_POINTS',
           'TrajectoryFormatError']

_U32 = struct.Struct('<I')


class TrajectoryFormatError(ValueError):
    """The bytes are not a JointTrajectory this parser (or rclpy) can read."""


def _align(off: int, n: int) -> int:
    return (off + n - 1) // n * n


def _string(buf: memoryview, off: int) -> tuple[str, int]:
    off = _align(off, 4)
    (n,) = _U32.unpack_from(buf, off)
    off += 4
    if n == 0 or off + n > len(buf):
        raise TrajectoryFormatError('string runs past the end of the message')
    return bytes(buf[off:off + n - 1]).decode('utf-8', 'replace'), off + n


def _point_layout(start: int, sizes: tuple[int, ...]) -> tuple[list[int], int]:
    """Offsets of the four count fields and the data starts for a point at ``start`` (data
    offsets), and the offset after the point."""
    off = start
    fields = []
    for n in sizes:
        off = _align(off, 4)
        count_at = off
        off += 4
        if n:
            off = _align(off, 8)
        fields += [count_at, off]
        off += 8 * n
    off = _align(off, 4)
    fields.append(off)                 # Duration
    return fields, off + 8


def parse(data: bytes, n_links: int | None = None) -> TrajectoryArrays:
    """A JointTrajectory from its serialised CDR bytes (see module doc); raise
    TrajectoryFormatError when the bytes cannot be read or exceed the limits. With ``n_links``
    (the node's), the head rules (``core.plant.inputs.check_head``: joint names, the sizes of
    the first point) are checked before any point is read: a message that breaks them costs
    microseconds whatever its size."""
    if len(data) < 16 or data[1] != 1:        # encapsulation: plain CDR, little-endian
        raise TrajectoryFormatError('not a little-endian CDR JointTrajectory')
    buf = memoryview(data)[4:]
    try:
        sec, nanosec = struct.unpack_from('<iI', buf, 0)
        _, off = _string(buf, 8)                                  # frame_id
        off = _align(off, 4)
        (n_names,) = _U32.unpack_from(buf, off)
        off += 4
        if n_names > 1000:
            raise TrajectoryFormatError(f'{n_names} joint names (at most 1000)')
        names = []
        for _ in range(n_names):
            name, off = _string(buf, off)
            names.append(name)
        off = _align(off, 4)
        (n_pts,) = _U32.unpack_from(buf, off)
        off += 4
    except struct.error as exc:
        raise TrajectoryFormatError(f'truncated message ({exc})') from None
    if n_pts > MAX_TRAJECTORY_POINTS:
        raise TrajectoryFormatError(f'{n_pts} points: at most {MAX_TRAJECTORY_POINTS} per '
                                    'trajectory (split it, or send it again as it runs)')
    stamp_ns = from_stamp(sec, nanosec)
    if n_links is not None:
        reason = check_head(names, _first_sizes(buf, off) if n_pts else (0, 0, 0, 0), n_pts,
                            n_links)
        if reason:
            raise TrajectoryFormatError(reason)
    if n_pts == 0:
        empty = np.zeros(0, dtype=np.int64)
        return TrajectoryArrays(stamp_ns, names, empty, np.zeros((0, n_names)), None, None,
                                None, (n_names, 0, 0, 0), nbytes=4 + off)
    regular = _regular_points(buf, off, n_pts)
    if regular is None:
        # the node rejects such a message anyway: it is not handed to rclpy's per-point parse
        # (about 1.5 s for 80 MB, in the simulation loop)
        raise TrajectoryFormatError('points differ in which of positions/velocities/'
                                    'accelerations/effort they fill, or in their sizes')
    tfs, arrays, sizes, end = regular
    return TrajectoryArrays(stamp_ns, names, tfs, arrays[0],
                            arrays[1] if sizes[1] else None, arrays[2] if sizes[2] else None,
                            arrays[3] if sizes[3] else None, sizes, nbytes=4 + end)


def _first_sizes(buf: memoryview, off: int) -> tuple[int, int, int, int]:
    """The four array counts of the point at ``off``."""
    sizes = []
    try:
        for _ in range(4):
            off = _align(off, 4)
            (n,) = _U32.unpack_from(buf, off)
            sizes.append(n)
            off += 4 + (8 * n + (_align(off + 4, 8) - (off + 4) if n else 0))
    except struct.error:
        raise TrajectoryFormatError('truncated trajectory point') from None
    return sizes[0], sizes[1], sizes[2], sizes[3]


def _regular_points(buf: memoryview, off: int, n_pts: int):
    """Points as strided arrays when they all have the first point's shape, else None."""
    try:
        sizes = []
        o = off
        for _ in range(4):
            o = _align(o, 4)
            (n,) = _U32.unpack_from(buf, o)
            if n > 1000:
                return None
            sizes.append(n)
            o += 4 + (8 * n + (_align(o + 4, 8) - (o + 4) if n else 0))
    except struct.error:
        raise TrajectoryFormatError('truncated trajectory point') from None
    sizes_t = tuple(sizes)
    # a point's layout depends only on its start offset mod 8, which is 0 or 4: the starts
    # either settle (from point 1 on, one stride) or alternate (period 2 from point 0)
    f0, end0 = _point_layout(off, sizes_t)
    f1, end1 = _point_layout(end0, sizes_t)
    if (end1 - end0) % 8 == 0:          # point 0, then blocks of one point from end0
        block = end1 - end0
        head = [_one_point(buf, f0, sizes_t)]
        blocks = (end0, n_pts - 1, block, [[x - end0 for x in f1]])
        tail = []
        total_end = end0 + (n_pts - 1) * block
    else:                                # blocks of two points from off
        block = end1 - off
        head = []
        blocks = (off, n_pts // 2, block, [[x - off for x in f0], [x - off for x in f1]])
        last = off + (n_pts // 2) * block
        total_end = last + (end0 - off if n_pts % 2 else 0)
        tail = [_one_point(buf, [x - off + last for x in f0], sizes_t)] if n_pts % 2 else []
    if total_end > len(buf):       # (rclpy's buffers may carry unused bytes at the end)
        return None
    slots = _read_blocks(buf, *blocks, sizes_t)
    if slots is None or any(p is None for p in head + tail):
        return None
    # points in order: head, then the slots of each block interleaved, then tail
    parts = []
    for j in range(5):              # tfs, positions, velocities, accelerations, effort
        if j > 0 and sizes_t[j - 1] == 0:
            parts.append(None)
            continue
        mid = [sl[j] for sl in slots]
        if len(mid) == 2:
            inter = np.empty((len(mid[0]) + len(mid[1]),) + mid[0].shape[1:], mid[0].dtype)
            inter[0::2], inter[1::2] = mid[0], mid[1]
        else:
            inter = mid[0]
        pieces = [np.asarray(h[j])[None] for h in head] + [inter] \
            + [np.asarray(t[j])[None] for t in tail]
        parts.append(np.concatenate(pieces) if len(pieces) > 1 else inter)
    return parts[0], parts[1:], sizes_t, total_end


def _one_point(buf: memoryview, fields: list[int], sizes: tuple[int, ...]):
    """(tfs_ns, positions, velocities, accelerations, effort) of the point whose field offsets
    are ``fields`` (see :func:`_point_layout`), or None when its counts differ from ``sizes``."""
    out: list = []
    try:
        for j in range(4):
            (n,) = _U32.unpack_from(buf, fields[2 * j])
            if n != sizes[j]:
                return None
            out.append(np.array(struct.unpack_from(f'<{n}d', buf, fields[2 * j + 1])) if n
                       else None)
        sec, nsec = struct.unpack_from('<iI', buf, fields[8])
    except struct.error:          # runs past the end of the message
        return None
    return [from_stamp(sec, nsec)] + out


def _read_blocks(buf: memoryview, start: int, n_blocks: int, block: int,
                 slots: list[list[int]], sizes: tuple[int, ...]):
    """Per slot (point position within a block): [tfs_ns, positions, velocities,
    accelerations, effort] of every block, read from 2-D views of the buffer (no copy but the
    results); None when a count differs from ``sizes``. Blocks are ``block`` bytes (a multiple
    of 8) from ``start``; slot field offsets are relative to the block start."""
    u32 = np.frombuffer(buf, '<u4', count=n_blocks * block // 4,
                        offset=start).reshape(n_blocks, block // 4)
    base8 = start - start % 8         # doubles are 8-aligned in the buffer
    f64 = np.frombuffer(buf, '<f8', count=n_blocks * block // 8,
                        offset=base8).reshape(n_blocks, block // 8)
    out = []
    for rel in slots:
        got: list = []
        for j in range(4):
            if not np.all(u32[:, rel[2 * j] // 4] == sizes[j]):
                return None
            n = sizes[j]
            col = (start + rel[2 * j + 1] - base8) // 8
            got.append(f64[:, col:col + n].copy() if n else None)
        dur = rel[8] // 4
        tfs = from_stamp(u32[:, dur].view('<i4').astype(np.int64),
                         u32[:, dur + 1].astype(np.int64))
        out.append([tfs] + got)
    return out


def from_message(msg: Any) -> TrajectoryArrays:
    """A JointTrajectory message object as :class:`TrajectoryArrays` (the slow path; tests)."""
    pts = list(msg.points)
    stamp_ns = from_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
    names = list(msg.joint_names)
    tfs = np.array([from_stamp(pt.time_from_start.sec, pt.time_from_start.nanosec)
                    for pt in pts], dtype=np.int64)
    first = pts[0] if pts else None
    sizes = tuple(len(getattr(first, f)) if first is not None else 0
                  for f in ('positions', 'velocities', 'accelerations', 'effort'))
    mixed = any(tuple(len(getattr(pt, f)) for f in ('positions', 'velocities',
                                                    'accelerations', 'effort')) != sizes
                for pt in pts)
    if mixed:
        return TrajectoryArrays(stamp_ns, names, tfs, np.zeros((len(pts), 0)), None, None, None,
                                sizes, mixed=True)

    def arr(field: str, n: int):
        if n == 0:
            return None
        return np.array([list(getattr(pt, field)) for pt in pts], dtype=float).reshape(-1, n)

    pos = arr('positions', sizes[0])
    if pos is None:
        pos = np.zeros((len(pts), 0 if pts else len(names)))
    return TrajectoryArrays(stamp_ns, names, tfs, pos, arr('velocities', sizes[1]),
                            arr('accelerations', sizes[2]), arr('effort', sizes[3]), sizes)
