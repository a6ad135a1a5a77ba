"""A ``Custom`` gait inside the compiled loop: its callables behind one C callback, and the
derivative bounds the event search needs, estimated from the gait's own values.

The compiled search (``kernel._search_ws``) wants l', l'' and l''' at every point it evaluates,
and bounds of |l'''| and |l''''| on the span. A ``Custom`` gait gives l, l' and l'' only, so the
callback adds a difference of the user's l'',

    l'''(t) ~ (l''(t + d) - l''(t)) / d      (t - d near the end of the span),

with d = 1e-4 of the scan spacing h (below): its error, d |l''''| / 2 plus the rounding, is
below 1e-4 of the jerk bound. The user's functions are never called outside the span the solver
integrates. Only the stuck-force rows use this slope; a slope's error moves a Taylor step, and
every step is checked at its end point.

Bounds: 4 times the largest |l'''| and |l''''| that differences of l'' show on an even grid
over the span (the Python search with estimated bounds, ``events``, takes 8 times its observed
second differences), the grid refined until its spacing h is at most the time scale
|l'''| / |l''''| they show (a sinusoid's extremes are then sampled to 8 %). Every evaluation of the
search is checked against the jerk bound; a value above it stops the loop (the callback returns
NaN from then on), and the solver raises the bounds to 4 times what it saw and runs the call
again, keeping nothing of it. This is not a proof: a feature narrower than the grid that every
search step also steps over is not seen. It is the guarantee of the Python search with
estimated bounds, which keeps ``Custom`` gaits given ``jerk_bound`` (a rigorous search) or
breakpoints (l'' jumps, where differences mean nothing).

The callback is a ``ctypes`` function: the cached compiled loop takes any callback of this C
signature (numba types it by signature, not by address), so a new gait compiles nothing. One
call costs about 1 us: the Python transition and three calls of the user's functions.
"""
from __future__ import annotations

import ctypes
import math
import threading
import weakref

import numpy as np
from numpy.typing import NDArray

from ..gaits import Custom, Gait
from ..gaits.base import similar_run
from . import kernel

__all__ = ['CustomBridge', 'bridge']

_SAFETY = 4.0          # factor on the observed |l'''| and |l''''|
_FIRST_GRID = 32       # intervals of the first scan of a span
_RESOLVE = 1.0         # largest scan spacing over the time scale |l'''| / |l''''|
_MAX_GRID = 1 << 16    # most intervals of one scan
_WINDOW = 4096         # most scan cells in one call's block
_DIFF = 1e-4           # difference step d over the scan spacing h (module doc)


def bridge(gait: Gait) -> 'CustomBridge | None':
    """The gait's bridge (made once per gait object), or None when the gait keeps the Python
    path: not a ``Custom`` gait, or one with ``jerk_bound`` or breakpoints (module doc)."""
    if type(gait) is not Custom or gait._jerk is not None or gait._breaks.size:
        return None
    b = _BRIDGES.get(gait)
    if b is None:
        b = _BRIDGES[gait] = CustomBridge(gait)
    return b


# bridges beside their gaits, not on them: a gait stays picklable (a sweep sends it to its
# workers) and the bridge, which holds no reference to the gait, goes with it
_BRIDGES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class CustomBridge:
    """A ``Custom`` gait's callback (``kind`` is the tuple the kernel takes) and its bound
    estimates (``jerk``, ``snap`` [m/s^3, m/s^4] per linkage)."""

    def __init__(self, gait: Custom) -> None:
        nl = gait.n_links
        self.nl = nl
        self._accel = gait._fns[2]
        # l, l', l'', l''' per linkage, then the times they are of (the kernel's cache)
        self.buf = np.zeros(4 * nl + 2)
        # the callback's state: [stopped, d, last time with a forward difference, time of a
        # value above the bounds, the jerk bound per linkage it checks]
        self._state = [False, 0.0, math.inf, math.nan] + [math.inf] * nl
        self._errors: list[BaseException] = []
        self.lo, self.hi = math.inf, -math.inf      # the span scanned so far [s]
        self.h = math.inf                          # its grid spacing [s]
        self._cells = None      # the scan: cell starts [s], |l'''| and |l''''| per cell
        self.jerk = np.zeros(nl)
        self.snap = np.zeros(nl)
        self.retries = 0          # consecutive runs stopped by a value above the bounds
        self.lock = threading.Lock()    # held by a solver for one call of the loop
        try:
            scalar = nl == 1 and all(isinstance(f(0.0), (float, int)) for f in gait._fns)
        except Exception:         # not defined at 0: the general callback
            scalar = False
        make = _scalar_callback if scalar else _array_callback
        self._callback = kernel.CALLBACK(make(gait._fns, self.buf, self._state, self._errors))
        self.kind = (self._callback, self.buf, 0, 0)
        # what ``kernel.coefficients`` gives for the built-in gaits: (kind, freq, P1, P2)
        self.coefficients = (self.kind, 1.0, np.zeros((1, 1)), np.zeros((1, 1)))

    @property
    def exceeded(self) -> bool:
        """True once a value above the jerk bound stopped the loop (not after an error)."""
        return self._state[0] and not self._errors

    def prepare(self, t0: float, t1: float) -> tuple[float, NDArray, NDArray]:
        """(t_b, jerk, snap) for one call of the compiled loop from t0 towards t1: the end
        t_b <= t1 of the block of similar bounds that starts at t0 (``_block``) and the bounds
        on it. Scans what of [t0, t1] is not scanned yet and arms the callback. Raises
        ValueError for a non-finite acceleration and whatever the user's function raises."""
        if t1 > t0:
            if not self.lo <= t0:
                self._cells = None       # a fresh scan (a run started before the scanned span)
                self._scan(t0, max(t1, self.hi))
            elif t1 > self.hi:
                self._scan(self.hi, t1)
        t_b = t1
        if self._cells is None:          # nothing scanned (an empty span)
            self.jerk, self.snap = np.zeros(self.nl), np.zeros(self.nl)
        else:
            t_b, self.jerk, self.snap = self._block(t0, t1)
        st = self._state
        st[0] = False
        st[1] = d = _DIFF * self.h if math.isfinite(self.h) else 1e-9 * max(1.0, abs(t1))
        st[2] = t1 - d
        st[4:] = self.jerk.tolist()
        self.buf[-2:] = math.nan
        return t_b, self.jerk, self.snap

    def grow(self) -> None:
        """After a value above the jerk bound: the scan cell where it was seen takes it (and
        its |l''''| grows in proportion), so the next bounds there are 4 times it."""
        self.retries += 1
        nl = self.nl
        starts, d1, d2 = self._cells
        j3 = np.abs(self.buf[3 * nl:4 * nl])
        k = min(max(int(np.searchsorted(starts, self._state[3], side='right')) - 1, 0),
                starts.size - 1)
        ratio = np.maximum(j3 / np.maximum(d1[k], 1e-300), 1.0)
        d1[k] = np.maximum(d1[k], j3)
        d2[k] = d2[k] * ratio

    def raise_error(self) -> None:
        """Raise (once) the exception a user function raised inside the loop."""
        if self._errors:
            err = self._errors[-1]
            self._errors.clear()
            self._state[0] = False
            raise err

    def _block(self, t0: float, t1: float) -> tuple[float, NDArray, NDArray]:
        """(t_b, jerk, snap): the cells from t0 towards t1 whose bounds stay within
        ``gaits.base.SIMILAR_BOUNDS`` of each other, and 4 times their largest differences.
        Each cell counts with its two neighbours (its end samples may miss a rise inside it).
        A sharp feature then sets the bounds of its own block only: with one bound per call,
        the slow phase of a sharp gait was searched with the steps of its sharp phase (100x
        the Python search's time on a Scallop of asymmetry 0.006)."""
        starts, d1, d2 = self._cells
        n = starts.size
        k0 = max(int(np.searchsorted(starts, t0, side='right')) - 1, 0)
        k_end = max(min(int(np.searchsorted(starts, t1, side='left')), k0 + _WINDOW), k0 + 1)
        lo, hi = max(k0 - 1, 0), min(k_end + 1, n)
        s1, s2 = _with_neighbours(d1[lo:hi]), _with_neighbours(d2[lo:hi])
        s1, s2 = s1[k0 - lo:k_end - lo], s2[k0 - lo:k_end - lo]
        with np.errstate(divide='ignore', invalid='ignore'):
            v = np.maximum((s1 / s1.max(axis=0)).max(axis=1, initial=0.0),
                           (s2 / s2.max(axis=0)).max(axis=1, initial=0.0))
        e = similar_run(np.maximum(np.nan_to_num(v), 1e-9))
        t_b = float(starts[k0 + e]) if k0 + e < n and starts[k0 + e] < t1 else t1
        return t_b, _SAFETY * s1[:e].max(axis=0), _SAFETY * s2[:e].max(axis=0)

    def _scan(self, a: float, b: float) -> None:
        """Differences of l'' on an even grid over [a, b], fine for the time scale they show
        (module doc), kept per grid cell: |l'''| from the first differences, |l''''| from the
        second differences at the cell's ends."""
        n = _FIRST_GRID if not math.isfinite(self.h) else max(2, math.ceil((b - a) / self.h))
        fa, nl = self._accel, self.nl
        while True:
            t = np.linspace(a, b, n + 1)
            t[-1] = b
            acc = np.array([fa(tk) for tk in t.tolist()], dtype=float).reshape(n + 1, nl)
            if not np.isfinite(acc).all():
                k = int(np.nonzero(~np.isfinite(acc).all(axis=1))[0][0])
                raise ValueError(f'gait acceleration must be finite, got a non-finite value at '
                                 f't = {float(t[k])!r} s')
            h = (b - a) / n
            d1 = np.abs(np.diff(acc, axis=0)) / h
            nodes = np.abs(np.diff(acc, 2, axis=0)) / (h * h)        # interior nodes 1..n-1
            nodes = np.vstack([nodes[:1], nodes, nodes[-1:]]) if n > 1 else np.zeros((2, nl))
            d2 = np.maximum(nodes[:-1], nodes[1:])
            j, s = d1.max(axis=0), d2.max(axis=0)
            with np.errstate(divide='ignore', invalid='ignore'):
                tau = np.where(s > 0.0, j / s, math.inf).min()
            if h <= _RESOLVE * tau or n >= _MAX_GRID:
                break
            n = min(_MAX_GRID, max(2 * n, math.ceil((b - a) / (_RESOLVE * tau))))
        cells = (t[:-1], d1, d2)
        if self._cells is not None:
            cells = tuple(np.concatenate([old, new]) for old, new in zip(self._cells, cells))
        self._cells = cells
        self.h = min(h, self.h)
        self.lo, self.hi = min(a, self.lo), max(b, self.hi)


def _with_neighbours(d: NDArray) -> NDArray:
    """Each row the largest of itself and its two neighbours."""
    out = d.copy()
    out[1:] = np.maximum(out[1:], d[:-1])
    out[:-1] = np.maximum(out[:-1], d[1:])
    return out


def _scalar_callback(fns, buf: NDArray, st: list, errors: list):
    """The callback of a one-linkage gait whose functions return floats (module doc)."""
    fl, fv, fa = fns
    out = (ctypes.c_double * buf.size).from_buffer(buf)

    def callback(t: float, with_length: int) -> None:
        if st[0]:
            out[0] = out[1] = out[2] = math.nan
            return
        s = t + st[1] if t <= st[2] else t - st[1]
        try:
            a = fa(t)
            j3 = (fa(s) - a) / (s - t)
            out[1] = fv(t)
            out[2] = a
            out[3] = j3
            if with_length:
                out[0] = fl(t)
        except BaseException as exc:      # raised again by the solver after the loop returns
            errors.append(exc)
            st[0] = True
            out[0] = out[1] = out[2] = math.nan
            return
        if abs(j3) > st[4]:
            st[0] = True                  # stop the loop: the solver grows the bounds
            st[3] = t
            out[1] = math.nan
    return callback


def _array_callback(fns, buf: NDArray, st: list, errors: list):
    """The callback of any other Custom gait (functions returning arrays of n_links)."""
    nl = (buf.size - 2) // 4
    fl, fv, fa = fns

    def callback(t: float, with_length: int) -> None:
        if st[0]:
            buf[:3 * nl] = math.nan
            return
        s = t + st[1] if t <= st[2] else t - st[1]
        try:
            a = _row(fa(t), nl)
            j3 = (_row(fa(s), nl) - a) / (s - t)
            buf[nl:2 * nl] = _row(fv(t), nl)
            if with_length:
                buf[:nl] = _row(fl(t), nl)
        except BaseException as exc:
            errors.append(exc)
            st[0] = True
            buf[:3 * nl] = math.nan
            return
        buf[2 * nl:3 * nl] = a
        buf[3 * nl:4 * nl] = j3
        if np.any(np.abs(j3) > st[4:]):
            st[0] = True
            st[3] = t
            buf[nl] = math.nan
    return callback


def _row(v, nl: int) -> NDArray:
    return np.asarray(v, dtype=float).reshape(nl)
