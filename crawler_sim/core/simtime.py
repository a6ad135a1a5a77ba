"""Sim time: the one place that turns float seconds into integer nanoseconds and back.

The simulator's clock is an integer number of nanoseconds (the node's ticks, MCAP log times,
``builtin_interfaces/Time``); the solvers work in float seconds. :func:`to_ns` is the one
conversion point (round half to even, for scalars and arrays alike), :func:`to_seconds` its
inverse up to 0.5 ns, and :func:`split_ns` / :func:`from_stamp` go between nanoseconds and a
(sec, nanosec) stamp.
"""
from __future__ import annotations

from typing import overload

import numpy as np
from numpy.typing import NDArray

__all__ = ['NS_PER_S', 'to_ns', 'to_seconds', 'split_ns', 'from_stamp']

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


@overload
def to_seconds(t_ns: int) -> float: ...


@overload
def to_seconds(t_ns: NDArray[np.integer]) -> NDArray[np.float64]: ...


def to_seconds(t_ns):
    """Integer nanoseconds [ns] as float seconds [s]."""
    if isinstance(t_ns, np.ndarray):
        return t_ns.astype(np.float64) / 1e9
    return int(t_ns) / 1e9


def split_ns(t_ns: int) -> tuple[int, int]:
    """``(sec, nanosec)`` of a ``builtin_interfaces/Time`` or ``Duration`` for ``t_ns`` [ns]
    (floor division: a negative duration has a negative ``sec`` and ``nanosec`` in [0, 1e9))."""
    return divmod(int(t_ns), NS_PER_S)


def from_stamp(sec: int | NDArray[np.int64], nanosec: int | NDArray[np.int64]
               ) -> int | NDArray[np.int64]:
    """Nanoseconds [ns] of a (sec, nanosec) stamp (ints, or int64 arrays of them)."""
    return sec * NS_PER_S + nanosec
