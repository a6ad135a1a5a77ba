"""Constant-jerk pieces: `cubic_values`, `Cubic` and `PiecewiseCubic` (the node's actuator output)."""
from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import (Gait, Triple, _per_link)


def cubic_values(l0, v0, a0, jerk, d):
    """(l, l', l'') of a constant-jerk piece d [s] after its start, for floats or arrays.

    The one expression used by ``Cubic``, ``PiecewiseCubic`` and the node's actuator, so that a
    piece evaluated at its end gives bit-identically the next piece's start."""
    return (l0 + d * (v0 + d * (0.5 * a0 + d * jerk / 6.0)), v0 + d * (a0 + 0.5 * d * jerk),
            a0 + d * jerk)


class Cubic(Gait):
    """One cubic piece per linkage: constant jerk from (l0, v0, a0) at time t0.

    l(t) = l0 + v0 d + a0 d^2 / 2 + jerk d^3 / 6 with d = t - t0. The node's actuator model
    hands the solver one of these per integration tick, so l is C2 across ticks.
    """

    def __init__(self, t0: float, l0: ArrayLike, v0: ArrayLike, a0: ArrayLike,
                 jerk: ArrayLike) -> None:
        l0 = _per_link('l0', l0, None)
        self.n_links = l0.size
        self.t0 = float(t0)
        self._arrays = (l0, _per_link('v0', v0, self.n_links), _per_link('a0', a0, self.n_links),
                        _per_link('jerk', jerk, self.n_links))
        self._constant = not any(np.any(x) for x in self._arrays[1:])
        self._rows = list(zip(*(x.tolist() for x in self._arrays)))

    # the coefficients as arrays [m, m/s, m/s^2, m/s^3], shape (n_links,); a trusted piece
    # (one per node tick) makes them only if asked
    l0 = property(lambda self: self._coefficients()[0])
    v0 = property(lambda self: self._coefficients()[1])
    a0 = property(lambda self: self._coefficients()[2])
    jerk = property(lambda self: self._coefficients()[3])

    def _coefficients(self) -> tuple[NDArray[np.float64], ...]:
        if self._arrays is None:
            self._arrays = tuple(np.array(x) for x in zip(*self._rows))
        return self._arrays

    @classmethod
    def trusted(cls, t0: float, l0: list[float], v0: list[float], a0: list[float],
                jerk: list[float]) -> Cubic:
        """Build from lists of finite floats of equal length without validation (the
        actuator's hot path, one piece per tick; it produces only finite values)."""
        self = cls.__new__(cls)
        self.t0 = float(t0)
        self.n_links = len(l0)
        self._arrays = None
        self._constant = not (any(v0) or any(a0) or any(jerk))
        self._rows = list(zip(l0, v0, a0, jerk))
        return self

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            return self.at(float(t))
        return super().__call__(t)

    def at(self, t: float) -> Triple:
        # cubic_values in Python floats (IEEE, same operation order: the array path's bits)
        d = t - self.t0
        l, v, a = zip(*(cubic_values(*row, d) for row in self._rows))
        return np.array(l), np.array(v), np.array(a)

    def at1(self, t: float) -> tuple[float, float, float]:
        return cubic_values(*self._rows[0], t - self.t0)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        return cubic_values(*self._coefficients(), (t - self.t0)[:, None])

    def is_constant(self, t0: float, t1: float) -> bool:
        return self._constant

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.array([abs(r[3]) for r in self._rows])

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.zeros(self.n_links)


class PiecewiseCubic(Gait):
    """Consecutive ``Cubic`` pieces, piece k valid on [starts[k], starts[k+1]) (the last one
    from its start on), as the node's actuator hands them out tick by tick.

    The node integrates many ticks in one exact solve with this gait. Joins where l'' does not
    continue exactly (a cubic's end value differs from the next piece's a0) are reported as
    breakpoints, so the exact solver places events there precisely.
    """

    def __init__(self, starts: ArrayLike, pieces: list[Cubic]) -> None:
        # built once per publish tick by the node: checks and joins in plain Python floats
        starts = np.asarray(starts, dtype=float)
        if starts.ndim != 1 or starts.size != len(pieces) or starts.size == 0:
            raise ValueError('starts must list one start time [s] per piece')
        sl = starts.tolist()
        if any(b <= a for a, b in zip(sl, sl[1:])) or not all(map(math.isfinite, sl)):
            raise ValueError('starts must be finite and strictly increasing')
        self.n_links = pieces[0].n_links
        if any(pc.n_links != self.n_links for pc in pieces):
            raise ValueError('every piece must have the same number of linkages')
        self._join(starts, sl, list(pieces))

    @classmethod
    def trusted(cls, starts: list[float], pieces: list[Cubic]) -> PiecewiseCubic:
        """Build from a list of finite, strictly increasing floats and as many pieces of equal
        n_links without the checks (the node's engine, once per publish tick)."""
        self = cls.__new__(cls)
        self.n_links = pieces[0].n_links
        self._join(np.array(starts), starts, pieces)
        return self

    def _join(self, starts: NDArray[np.float64], sl: list[float], pieces: list[Cubic]) -> None:
        self.starts = starts
        self._starts = sl
        self.pieces = pieces
        self._arrays = None       # stacked coefficients for array evaluation, made on demand
        # l'' at the end of piece k (the Cubic's own expression a0 + d j) against a0 of k+1
        jumps = []
        prev = pieces[0]
        for k in range(1, len(pieces)):
            nxt = pieces[k]
            d = sl[k] - prev.t0
            for r, n in zip(prev._rows, nxt._rows):
                if r[2] + d * r[3] != n[2]:
                    jumps.append(sl[k])
                    break
            prev = nxt
        self._jumps = np.array(jumps)
        self._constant = [pc._constant for pc in pieces]

    def _index(self, t: float) -> int:
        return max(bisect_right(self._starts, t) - 1, 0)

    def at(self, t: float) -> Triple:
        return self.pieces[self._index(t)].at(t)

    def at1(self, t: float) -> tuple[float, float, float]:
        return self.pieces[self._index(t)].at1(t)

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            return self.at(float(t))
        return super().__call__(t)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        if t.size * self.n_links <= 64:
            return self._eval_small(t)
        if self._arrays is None:
            rows = np.array([pc._rows for pc in self.pieces])     # (K, n_links, 4)
            self._arrays = (np.array([pc.t0 for pc in self.pieces]),
                            [rows[:, :, i] for i in range(4)])
        t0s, c = self._arrays
        k = np.clip(np.searchsorted(self.starts, t, side='right') - 1, 0, len(self.pieces) - 1)
        return cubic_values(*(x[k] for x in c), (t - t0s[k])[:, None])

    def _eval_small(self, t: NDArray[np.float64]) -> Triple:
        # The node's event grid (a few points per publish window): Python floats beat numpy's
        # per-call overhead here; same expressions, so the same bits as the array path.
        starts, pieces = self._starts, self.pieces
        rows = []
        for tt in t.tolist():
            pc = pieces[max(bisect_right(starts, tt) - 1, 0)]
            rows.append([cubic_values(*row, tt - pc.t0) for row in pc._rows])
        out = np.array(rows)                      # (N, n_links, 3)
        return out[:, :, 0], out[:, :, 1], out[:, :, 2]

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        b = self._jumps
        return b[(b > t0) & (b < t1)] if b.size else b

    def is_constant(self, t0: float, t1: float) -> bool:
        k0, k1 = self._index(t0), self._index(t1)
        return all(self._constant[k0:k1 + 1])

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        k0, k1 = self._index(t0), self._index(t1)
        return np.array([max(abs(pc._rows[i][3]) for pc in self.pieces[k0:k1 + 1])
                         for i in range(self.n_links)])

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64] | None:
        # the jerk is constant on a piece and jumps at the joins: no bound across a join
        k0 = self._index(t0)
        if k0 + 1 < len(self._starts) and self._starts[k0 + 1] < t1:
            return None
        return np.zeros(self.n_links)
