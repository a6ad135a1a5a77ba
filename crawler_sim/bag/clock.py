"""Time conversion: the only place that turns seconds into integer nanoseconds and back.

MCAP and rosbag2 stamp every message with an unsigned 64-bit count of nanoseconds. The
simulator works in float seconds of *sim time*; :func:`to_ns` is the one conversion point
(round half to even, for scalars and arrays alike), and :func:`to_seconds` is its inverse up to
0.5 ns.
"""
from __future__ import annotations

from typing import overload

import numpy as np
from numpy.typing import NDArray

NS_PER_S = 1_000_000_000


@overload
def to_ns(t: float) -> int: ...


@overload
def to_ns(t: NDArray[np.floating]) -> NDArray[np.int64]: ...


def to_ns(t):
    """Sim time ``t`` [s] as integer nanoseconds [ns], rounded to nearest (ties to even).

    A float (or numpy scalar) gives a Python ``int``; an array gives an ``int64`` array.
    """
    if isinstance(t, np.ndarray):
        return np.rint(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)
    return int(round(float(t) * 1e9))


def to_seconds(t_ns: NDArray[np.integer] | int) -> NDArray[np.float64] | float:
    """Integer nanoseconds [ns] as float seconds [s]."""
    if isinstance(t_ns, np.ndarray):
        return t_ns.astype(np.float64) / 1e9
    return int(t_ns) / 1e9


def rows_at_ns(t: NDArray[np.floating], t_ns: NDArray[np.integer]) -> NDArray[np.int64]:
    """Row of ``t`` [s] (sorted, e.g. a simulation's sample times) recorded as each stamp of
    ``t_ns`` [ns], or -1 where no sample rounds to that stamp.

    A recording stores ``to_ns(t)``; comparing a re-simulation with it must happen in that ns
    base: re-evaluating at ``t_ns / 1e9`` instead moves each sample by up to 0.5 ns, which is
    a velocity difference of ``0.5e-9 * acceleration`` (3.6e-9 m/s at 7 m/s^2), not a bug.
    Samples closer than 1 ns (an event next to a regular sample) share a stamp: the k-th
    recorded occurrence of a stamp is matched with the k-th sample that rounds to it.
    """
    sim_ns = to_ns(np.asarray(t, dtype=np.float64))
    want = np.asarray(t_ns, dtype=np.int64)
    idx = np.searchsorted(sim_ns, want)
    if want.size:   # rank of each stamp among the earlier stamps of equal value
        order = np.argsort(want, kind='stable')
        ws = want[order]
        rank = np.empty(want.size, dtype=np.int64)
        rank[order] = np.arange(want.size) - np.searchsorted(ws, ws)
        idx = idx + rank
    ok = idx < len(sim_ns)
    ok[ok] = sim_ns[idx[ok]] == want[ok]
    return np.where(ok, idx, -1).astype(np.int64)


def stamp(t_ns: int) -> tuple[int, int]:
    """``(sec, nanosec)`` of a ``builtin_interfaces/Time`` for ``t_ns`` [ns] >= 0."""
    return divmod(int(t_ns), NS_PER_S)
