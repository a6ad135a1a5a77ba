"""Constant-jerk pieces: `cubic_values`, `Cubic` and `PiecewiseCubic` (the node's actuator
output)."""
from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import BuiltinGait, _per_link

_EPS = float(np.finfo(float).eps)


#: tables of up to this many (piece, linkage) pairs are classified in Python floats, larger ones
#: with numpy (its per-call overhead, some 10 us for the expression, outweighs a loop of
#: 0.2 us a pair below it; the engine's syncs hand over 10 pieces of one linkage)
_LOOP_MAX = 48


def table_jumps(starts: NDArray[np.float64], anchors: NDArray[np.float64],
                coef: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(n,) bool: where l'' jumps at the start of piece k of a table that is not periodic,
    bit for bit what the compiled ``table`` decides when not given ``jumps`` (the same
    expressions on the same floats, element by element), for ``table(..., jumps=)``.

    Why: ``table``'s own classification (four ``np.roll`` of the whole table and a mask for a
    first piece from -inf) was half of building a table, and the engine builds one per sync
    (issues 41 and 42). A small table is a loop over Python floats (IEEE doubles as numpy's,
    the same operations in the same order), a large one slices of the neighbouring pieces;
    piece 0 never jumps (no join before it), so a one-piece table needs no arithmetic.
    ``starts`` and ``anchors`` (n,) [s], ``coef`` (n, n_links, 4)."""
    n, nl = coef.shape[0], coef.shape[1]
    if n < 2:
        return np.zeros(n, dtype=bool)
    if n * nl <= _LOOP_MAX:
        return np.array(_jumps_loop(starts.tolist(), anchors.tolist(),
                                    coef[:, :, 2:].tolist()), dtype=bool)
    jumps = np.zeros(n, dtype=bool)
    prev_a, prev_j = coef[:-1, :, 2], coef[:-1, :, 3]
    before = anchors[:-1]
    d = starts[1:] - before
    end_acc = prev_a + d[:, None] * prev_j
    # the rounding of that expression and of d (see ``table``); a size that is not finite
    # counts as 0 there, as the first piece's from -inf does
    size = np.abs(starts[1:]) + np.abs(before)
    size[~np.isfinite(size)] = 0.0
    noise = 4.0 * _EPS * (np.abs(prev_a) + np.abs(d[:, None] * prev_j)
                          + size[:, None] * np.abs(prev_j))
    jumps[1:] = np.any(np.abs(end_acc - coef[1:, :, 2]) > noise, axis=1)
    return jumps


def _jumps_loop(starts: list[float], anchors: list[float],
                acc_jerk: list[list[list[float]]]) -> list[bool]:
    """``table_jumps`` of a small table: ``acc_jerk`` [k][j] = (a0, jerk) of piece k, linkage j.
    Each comparison is ``table``'s: |end_acc - a0| > noise, False for NaN as there."""
    out = [False] * len(starts)
    scale = 4.0 * _EPS
    for k in range(1, len(starts)):
        before = anchors[k - 1]
        d = starts[k] - before
        size = abs(starts[k]) + abs(before)
        if not math.isfinite(size):
            size = 0.0
        for (a, j), (a0, _) in zip(acc_jerk[k - 1], acc_jerk[k]):
            dj = d * j
            if abs((a + dj) - a0) > scale * ((abs(a) + abs(dj)) + size * abs(j)):
                out[k] = True
                break
    return out


def cubic_values(l0: ArrayLike, v0: ArrayLike, a0: ArrayLike, jerk: ArrayLike, d: ArrayLike
                 ) -> tuple:
    """(l, l', l'') of a constant-jerk piece d [s] after its start, for floats or arrays.

    The expression of the compiled TABLE kind (``solvers._gait``) written for the actuator,
    which builds its pieces in Python floats: a piece evaluated at its end gives
    bit-identically the next piece's start."""
    return (l0 + d * (v0 + d * (0.5 * a0 + d * jerk / 6.0)), v0 + d * (a0 + 0.5 * d * jerk),
            a0 + d * jerk)


class Cubic(BuiltinGait):
    """One cubic piece per linkage: constant jerk from (l0, v0, a0) at time t0.

    l(t) = l0 + v0 d + a0 d^2 / 2 + jerk d^3 / 6 with d = t - t0, at every t. The node's
    actuator model hands the solver one of these per integration tick, so l is C2 across ticks.
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

    @classmethod
    def from_rows(cls, t0: float, rows: list[tuple[float, float, float, float]],
                  constant: bool) -> Cubic:
        """``trusted`` from what it computes: the rows (l0, v0, a0, jerk) per linkage, tuples
        of finite floats, and ``constant`` (v0, a0 and jerk all zero). The compiled actuator's
        path (``core/_actuator.pyx``, one piece per tick), which has both at hand."""
        self = cls.__new__(cls)
        self.t0 = t0
        self.n_links = len(rows)
        self._arrays = None
        self._constant = constant
        self._rows = rows
        return self

    def _kind(self):
        from ..solvers._gait import table
        # one piece: no join, so no jump (what ``table`` would find, without its search)
        return table(np.array([self._rows], dtype=float), starts=np.array([-math.inf]),
                     anchors=np.array([self.t0]), jumps=np.zeros(1, dtype=bool))

    def is_constant(self, t0: float, t1: float) -> bool:
        return self._constant


#: ``solvers._gait.table_of_run``, imported on first use (not at import: the solvers import
#: the gaits), then read as a global: an import statement per table build cost ~0.5 us (issue 41)
_TABLE_OF_RUN = None


def _import_table_of_run():
    global _TABLE_OF_RUN
    from ..solvers._gait import table_of_run
    _TABLE_OF_RUN = table_of_run
    return table_of_run


class PiecewiseCubic(BuiltinGait):
    """Consecutive ``Cubic`` pieces, piece k valid on [starts[k], starts[k+1]) (the last one
    from its start on, the first one also before its start), as the node's actuator hands them
    out tick by tick.

    The node integrates many ticks in one exact solve with this gait. Joins where l'' does not
    continue (a cubic's end value differs from the next piece's a0 by more than the rounding
    of evaluating it there, a few ulps) are breakpoints, so the exact solver places events
    there precisely; l''' may jump at every join.
    """

    def __init__(self, starts: ArrayLike, pieces: list[Cubic]) -> None:
        starts = np.asarray(starts, dtype=float)
        if starts.ndim != 1 or starts.size != len(pieces) or starts.size == 0:
            raise ValueError('starts must list one start time [s] per piece')
        sl = starts.tolist()
        if any(b <= a for a, b in zip(sl, sl[1:])) or not all(map(math.isfinite, sl)):
            raise ValueError('starts must be finite and strictly increasing')
        self.n_links = pieces[0].n_links
        if any(pc.n_links != self.n_links for pc in pieces):
            raise ValueError('every piece must have the same number of linkages')
        self._starts = sl
        self._pieces = list(pieces)
        self._arrays = None

    @classmethod
    def trusted(cls, starts: list[float], pieces: list[Cubic]) -> PiecewiseCubic:
        """Build from a list of finite, strictly increasing floats and as many pieces of equal
        n_links without the checks (the node's engine, once per publish tick)."""
        self = cls.__new__(cls)
        self.n_links = pieces[0].n_links
        self._starts = starts
        self._pieces = pieces
        self._arrays = None
        return self

    @classmethod
    def from_arrays(cls, starts: NDArray[np.float64], anchors: NDArray[np.float64],
                    coef: NDArray[np.float64]) -> PiecewiseCubic:
        """The gait of ``trusted(starts, pieces)`` with piece k = ``Cubic(anchors[k],
        *coef[k].T)``, from arrays and without one Cubic object per piece (the actuator's runs
        of ticks, ``actuator.Pieces``): ``starts`` (n,) [s] finite and strictly increasing,
        ``anchors`` (n,) each piece's time origin [s], ``coef`` (n, n_links, 4) float64 =
        (l0 [m], v0 [m/s], a0 [m/s^2], jerk [m/s^3]) per piece and linkage, all finite.
        Not checked; the arrays are used as they are (not copied)."""
        self = cls.__new__(cls)
        self.n_links = coef.shape[1]
        self._starts = starts
        self._pieces = None
        self._arrays = (starts, anchors, coef)
        return self

    @property
    def pieces(self) -> list[Cubic]:
        """The pieces as ``Cubic`` objects (made on first use when built from arrays)."""
        if self._pieces is None:
            self._pieces = [self._piece(k) for k in range(len(self._starts))]
        return self._pieces

    def _piece(self, k: int) -> Cubic:
        """Piece k as a Cubic (one object when built from arrays, without making the others)."""
        if self._pieces is not None:
            return self._pieces[k]
        _, anchors, coef = self._arrays
        return Cubic.trusted(float(anchors[k]), *coef[k].T.tolist())

    @property
    def starts(self) -> NDArray[np.float64]:
        """Start time of each piece [s]."""
        return np.array(self._starts)

    def as_arrays(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The pieces as arrays, what ``from_arrays`` takes: (starts (n,) [s], anchors (n,)
        each piece's time origin [s], coef (n, n_links, 4) = (l0 [m], v0 [m/s], a0 [m/s^2],
        jerk [m/s^3]) per piece and linkage). A gait built from arrays returns them as they
        are (not copied: do not modify them), one built from pieces new arrays."""
        if self._arrays is not None:
            return self._arrays
        pcs = self.pieces
        return (np.array(self._starts, dtype=float), np.array([pc.t0 for pc in pcs], dtype=float),
                np.array([pc._rows for pc in pcs], dtype=float).reshape(len(pcs), self.n_links, 4))

    def _index(self, t: float) -> int:
        if self._arrays is not None:        # bisect_right on the array
            return max(int(np.searchsorted(self._starts, t, side='right')) - 1, 0)
        return max(bisect_right(self._starts, t) - 1, 0)

    def _kind(self):
        table_of_run = _TABLE_OF_RUN or _import_table_of_run()
        if self._arrays is not None:
            try:     # float64 and contiguous, as ``from_arrays`` asks: read as they are
                return table_of_run(*self._arrays)
            except (TypeError, ValueError):     # not so after all: converted below
                pass
        starts, anchors, coef = (np.ascontiguousarray(x, dtype=np.float64)
                                 for x in self.as_arrays())
        # ``table`` with ``table_jumps``' breakpoints, bit for bit, in one compiled pass (the
        # engine builds one per sync: issue 41)
        return table_of_run(starts, anchors, coef)
