"""Times of a recording: MCAP and rosbag2 stamp every message with an unsigned 64-bit count of
nanoseconds. The conversions live in ``crawler_sim.core.simtime`` (re-exported here); this
module matches a re-simulation's float sample times with recorded stamps (:func:`rows_at_ns`).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from crawler_sim.core.simtime import NS_PER_S, split_ns, to_ns, to_seconds

__all__ = ['NS_PER_S', 'to_ns', 'to_seconds', 'rows_at_ns', 'stamp']

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


#: ``(sec, nanosec)`` of a ``builtin_interfaces/Time`` for ``t_ns`` [ns] >= 0
stamp = split_ns
