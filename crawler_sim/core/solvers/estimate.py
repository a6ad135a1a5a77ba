"""Estimated derivative bounds of a gait that gives none (a ``Custom`` gait without
``jerk_bound``), and its l''' by a difference of its l''.

The exact method's search wants bounds of |l'''| and |l''''| on every interval it proves free of
events. For a gait of user callables they are estimated from a scan of l'':

* a grid of spacing ``T / 1024`` for a periodic gait, ``max_step / 8`` when one is given, else
  1/256 of what is left of the span being integrated (never finer than the grid so far), in
  windows of at most ``WINDOW`` cells;
* refined locally, cell by cell, until the bound of each cell holds inside it by its own
  differences (its first difference plus its |l''''| times its width within ``SAFETY`` times the
  largest first difference of it and its neighbours), so a sharp feature the grid touches is
  resolved where it is and nowhere else;
* per cell, ``SAFETY`` = 4 times the largest first and second differences of l'', each cell
  counted with its two neighbours (its end samples may miss a rise inside it);
* every evaluation of the search checks its l''' against the bound of its cell
  (``_gait._check``); a value above it grows that cell to what it saw, and the search that
  relied on the old bound is redone.

That is not a proof: a feature narrower than the grid, between two grid points, that every
search step also steps over, is not seen. l''' is (l''(t + d) - l''(t)) / d with d = 1e-4 of the
local cell width (t - d near the end of the span), so the user's functions are only called
inside the span being integrated.

l'' that jumps (a contract breach: jumps must be listed in ``breakpoints=``) shows as a cell whose
difference stands out of its neighbours' like a step: it is zoomed into, and a jump that stays a
jump down to a few floats is refused at once with its time, instead of a search that runs out of
steps.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ['BoundEstimate']

PER_PERIOD = 1024      # grid cells per period of a periodic gait
FIRST = 256            # grid cells of a first span without a period or max_step
WINDOW = 4096          # most grid cells scanned at once (before local refinement)
KEEP = 1 << 16         # most cells kept (the oldest go: a long run's memory stays bounded)
ROUNDS = 40            # local refinement rounds (each halves the unresolved cells)
_DIFF = 1e-4           # difference step over the local cell width
_ZOOM = 200            # bisections of an unresolved cell
_JUMP = 1e-3           # a difference of l'' over a few floats above this share of its range


class BoundEstimate:
    """Scan cells of one gait: ``starts`` [s], ``d1`` (|l'''| [m/s^3]) and ``d2`` (|l''''|
    [m/s^4]) per cell and linkage, covering [``lo``, ``hi``]."""

    SAFETY = 4.0

    def __init__(self, accel: Callable[[float], NDArray], n_links: int,
                 period: float | None = None, max_step: float | None = None,
                 breaks: Callable[[float, float], NDArray] | None = None) -> None:
        self._accel = accel
        self._breaks = breaks
        self.nl = n_links
        self.period = period
        self.max_step = max_step
        self.spacing = math.inf    # grid spacing [s], set by the first scan
        self._reset()

    def _reset(self) -> None:
        self.starts = np.empty(0)
        self.d1 = np.zeros((0, self.nl))
        self.d2 = np.zeros((0, self.nl))
        self.lo, self.hi = math.inf, -math.inf

    def diff_step(self, t: float) -> float:
        """The step d [s] of l''' = (l''(t + d) - l''(t)) / d: 1e-4 of the width of the cell of
        t, and at least 64 floats of t (a span of a few floats must not round it to zero)."""
        st = self.starts
        if st.size:
            k = min(max(int(np.searchsorted(st, t, side='right')) - 1, 0), st.size - 1)
            end = st[k + 1] if k + 1 < st.size else self.hi
            w = end - st[k]
        else:
            w = self.spacing if math.isfinite(self.spacing) else 1e-5 * max(1.0, abs(t))
        return max(_DIFF * w, 64.0 * math.ulp(max(abs(t), 1e-300)))

    def ensure(self, a: float, b: float, span_lo: float, span_hi: float) -> None:
        """Scan what of [a, b] is not scanned yet: a window from there, inside
        [span_lo, span_hi] (the callables are only evaluated where the solver integrates)."""
        if self._repeat(a, b):
            return
        # the span from a breakpoint on continues the one that ended at its left limit
        if not (self.starts.size and self.lo <= a <= float(np.nextafter(self.hi, math.inf))):
            self._reset()                    # a fresh span (a restart, a skipped stretch)
            start = a
        else:
            start = self.hi
        cands = [self.period / PER_PERIOD if self.period else None,
                 self.max_step / 8.0 if self.max_step else None]
        cands = [c for c in cands if c]
        if cands:
            self.spacing = min(cands)
        else:
            # 1/FIRST of what is left of the span, never finer than before: the cost of a
            # run stays independent of its length when the same gait object served a shorter
            # run first (a grid set by a 1 s run made a 1e6 s rest cost 3 minutes)
            span = (span_hi if math.isfinite(span_hi) else b) - start
            grid = max(span, 1e-300) / FIRST
            self.spacing = grid if math.isinf(self.spacing) else max(self.spacing, grid)
        end = start + WINDOW * self.spacing
        if self.period:
            # one period is enough: the next ones are its cells shifted (``_repeat``); a
            # window of 4096 cells was four periods of 1024, three of them evaluated for nothing
            end = min(end, start + self.period)
        else:
            end = max(end, b)
        if math.isfinite(span_hi):
            end = min(end, max(span_hi, b))
        self._scan(start, end)
        if self.hi < b and not self._repeat(a, b):
            self._scan(self.hi, b)

    def _repeat(self, a: float, b: float) -> bool:
        """A periodic gait whose scan covers a whole period: the cells of [a, b] are that
        period's, shifted by whole periods (nothing evaluated). False otherwise."""
        T = self.period
        if not T or not self.starts.size or self.hi - self.lo < T:
            return False
        last = self.starts >= self.hi - T
        if a > self.hi + T:
            # far ahead (a skipped stretch): the last period moved there
            k = math.floor((a - self.hi) / T) + 1
            starts = self.starts[last] + k * T
            self.starts, self.d1, self.d2 = (starts, self.d1[last].copy(),
                                             self.d2[last].copy())
            self.lo, self.hi = self.hi - T + k * T, self.hi + k * T
            last = np.ones(starts.size, dtype=bool)
        elif a < self.lo:
            return False
        while self.hi < b:
            tpl = self.starts[last] + T
            self.starts = np.concatenate([self.starts, tpl])
            self.d1 = np.ascontiguousarray(np.concatenate([self.d1, self.d1[last]]))
            self.d2 = np.ascontiguousarray(np.concatenate([self.d2, self.d2[last]]))
            last = np.concatenate([np.zeros(last.size, dtype=bool), np.ones(tpl.size, bool)])
            self.hi += T
            keep = self.starts >= self.hi - 2 * T      # two periods are enough to repeat
            self.starts, self.d1, self.d2 = self.starts[keep], self.d1[keep], self.d2[keep]
            last = last[keep]
            self.lo = float(self.starts[0])
        return True

    def _values(self, t: NDArray) -> NDArray:
        acc = np.array([self._accel(tk) for tk in t.tolist()], dtype=float).reshape(t.size,
                                                                                   self.nl)
        if not np.isfinite(acc).all():
            k = int(np.nonzero(~np.isfinite(acc).all(axis=1))[0][0])
            raise ValueError(f'gait acceleration must be finite, got a non-finite value at '
                             f't = {float(t[k])!r} s')
        return acc

    def _scan(self, a: float, b: float) -> None:
        """Cells over [a, b], piece by piece between the gait's breakpoints (where l'' may
        jump: the cell from a breakpoint's left limit to it carries no difference)."""
        # the breakpoints inside (a, b], b included: the span may end at one (its end value
        # is then read as the left limit)
        cuts = (self._breaks(a, float(np.nextafter(b, math.inf)))
                if self._breaks is not None and b > a else [])
        parts = []
        lo = a
        for bp in [float(x) for x in cuts] + ([b] if not len(cuts) or cuts[-1] < b else []):
            end = float(np.nextafter(bp, -math.inf)) if bp in cuts else bp
            parts.append(self._scan_piece(lo, max(end, lo)))
            if bp < b:
                parts.append((np.array([end]), np.zeros((1, self.nl)), np.zeros((1, self.nl))))
            lo = bp
        starts = np.concatenate([self.starts] + [q[0] for q in parts])
        d1 = np.concatenate([self.d1] + [q[1] for q in parts])
        d2 = np.concatenate([self.d2] + [q[2] for q in parts])
        self.lo, self.hi = min(a, self.lo), max(b, self.hi)
        if starts.size > KEEP:
            starts, d1, d2 = starts[-KEEP:], d1[-KEEP:], d2[-KEEP:]
            self.lo = float(starts[0])
        self.starts, self.d1, self.d2 = (np.ascontiguousarray(starts),
                                         np.ascontiguousarray(d1), np.ascontiguousarray(d2))

    def _scan_piece(self, a: float, b: float) -> tuple[NDArray, NDArray, NDArray]:
        """(cell starts, d1, d2) over [a, b] where l'' is continuous: the grid, refined
        locally (module doc); a cell whose difference stands out of its neighbours' like a
        step is checked for a jump."""
        n = max(1, math.ceil((b - a) / self.spacing)) if b > a else 1
        t = np.linspace(a, b, n + 1) if b > a else np.array([a, a])
        t[-1] = b
        acc = self._values(t)
        for _ in range(ROUNDS):
            d1, d2 = _differences(t, acc)
            bad = _unresolved(t, d1, d2, self.SAFETY)
            if not bad.any():
                break
            mid = 0.5 * (t[:-1][bad] + t[1:][bad])
            keep = (mid > t[:-1][bad]) & (mid < t[1:][bad])
            if not keep.any():
                break
            mid = mid[keep]
            t_new = np.concatenate([t, mid])
            order = np.argsort(t_new, kind='stable')
            t = t_new[order]
            acc = np.concatenate([acc, self._values(mid)])[order]
        d1, d2 = _differences(t, acc)
        for k in _spikes(acc, d1):
            self._refuse_jump(t, acc, k)
        return t[:-1], np.nan_to_num(d1, posinf=1e300), np.nan_to_num(d2, posinf=1e300)

    def _refuse_jump(self, t: NDArray, acc: NDArray, k: int) -> None:
        """Zoom into cell k; a difference of l'' that stays a sizeable share of its range
        down to a few floats is a jump (ValueError)."""
        j = int(np.argmax(np.abs(acc[k + 1] - acc[k])))
        lo, hi = float(t[k]), float(t[k + 1])
        f_lo, f_hi = acc[k, j], acc[k + 1, j]
        scale = float(np.max(np.abs(acc[:, j]))) + 1e-300
        for _ in range(_ZOOM):
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            f_mid = float(np.asarray(self._accel(mid), dtype=float).reshape(self.nl)[j])
            if abs(f_mid - f_lo) >= abs(f_hi - f_mid):
                hi, f_hi = mid, f_mid
            else:
                lo, f_lo = mid, f_mid
            if abs(f_hi - f_lo) <= _JUMP * scale:
                return                       # it shrinks with the interval: continuous
        if abs(f_hi - f_lo) > _JUMP * scale:
            raise ValueError(
                f"gait acceleration (l'') of linkage {j} jumps by {f_hi - f_lo:.6g} m/s^2 at "
                f"t = {hi!r} s: a Custom gait must list the times where l'' jumps in "
                "breakpoints= (l'' must be continuous between breakpoints)")


def _differences(t: NDArray, acc: NDArray) -> tuple[NDArray, NDArray]:
    """Per cell: |first difference| of l'' and the largest |second difference| at its ends."""
    h = np.diff(t)[:, None]
    with np.errstate(divide='ignore', invalid='ignore'):
        slope = np.diff(acc, axis=0) / h
        d1 = np.abs(slope)
        if t.size > 2:
            nodes = 2.0 * np.abs(np.diff(slope, axis=0)) / (t[2:] - t[:-2])[:, None]
            nodes = np.vstack([nodes[:1], nodes, nodes[-1:]])
        else:
            nodes = np.zeros((2, acc.shape[1]))
    d1 = np.where(np.isfinite(d1), d1, 0.0)
    nodes = np.where(np.isfinite(nodes), nodes, 0.0)
    return d1, np.maximum(nodes[:-1], nodes[1:])


def _neighbours(d: NDArray) -> NDArray:
    """Each row the largest of itself and its two neighbours."""
    out = d.copy()
    out[1:] = np.maximum(out[1:], d[:-1])
    out[:-1] = np.maximum(out[:-1], d[1:])
    return out


def _unresolved(t: NDArray, d1: NDArray, d2: NDArray, safety: float) -> NDArray:
    """Cells whose bound, ``safety`` times the largest difference of the cell and its
    neighbours, may not hold inside it: |l'''| there can reach its own difference plus
    |l''''| times its width."""
    w = np.diff(t)[:, None]
    need = d1 + _neighbours(d2) * w
    bad = (need > safety * _neighbours(d1)).any(axis=1)
    return bad & (w[:, 0] > 4.0 * np.spacing(np.maximum(np.abs(t[1:]), 1e-300)))


def _spikes(acc: NDArray, d1: NDArray) -> list[int]:
    """Cells whose difference of l'' is a step out of its neighbours' (more than 4 times
    theirs, and a sizeable share of l'''s range): where l'' may jump."""
    if d1.shape[0] < 3:
        return []
    nb = np.zeros_like(d1)
    nb[1:] = np.maximum(nb[1:], d1[:-1])
    nb[:-1] = np.maximum(nb[:-1], d1[1:])
    step = np.abs(np.diff(acc, axis=0))
    rng = np.ptp(acc, axis=0) + 1e-300
    hit = ((d1 > 4.0 * nb) & (step > _JUMP * rng)).any(axis=1)
    return np.nonzero(hit)[0].tolist()[:8]
