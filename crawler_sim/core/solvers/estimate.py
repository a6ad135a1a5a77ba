"""Estimated derivative bounds of a gait that gives none (a ``Custom`` gait without
``jerk_bound``), and its l''' by a difference of its l''.

The exact method's search wants bounds of |l'''| and |l''''| on every interval it proves free of
events. For a gait of user callables they are estimated from a scan of l'':

* a grid of spacing ``T / 1024`` for a periodic gait, ``max_step / 8`` when one is given, else
  1/256 of the first span scanned, in windows of at most ``WINDOW`` cells;
* refined locally, cell by cell, until each cell is at most the time scale |l'''| / |l''''| its
  differences (with its neighbours') show, so a sharp feature the grid touches is resolved where
  it is and nowhere else;
* per cell, ``SAFETY`` = 4 times the largest first and second differences of l'', each cell
  counted with its two neighbours (its end samples may miss a rise inside it);
* every evaluation of the search checks its l''' against the bound of its cell
  (``_gait._check``); a value above it grows that cell to what it saw, and the search that
  relied on the old bound is redone.

That is not a proof: a feature narrower than the grid, between two grid points, that every
search step also steps over, is not seen. l''' is (l''(t + d) - l''(t)) / d with d = 1e-4 of the
local cell width (t - d near the end of the span), so the user's functions are only called
inside the span being integrated.

l'' that jumps (a contract breach: jumps must be listed in ``breakpoints=``) shows as a cell that
never resolves: it is zoomed into, and a jump that stays a jump down to a few floats is refused
at once with its time, instead of a search that runs out of steps.
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
_RESOLVE = 0.5         # largest cell width over the local time scale |l'''| / |l''''|
_FLOOR = 1e-3          # |l'''| below this share of the scan's largest counts as this share
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
        if math.isinf(self.spacing):
            span = (span_hi if math.isfinite(span_hi) else b) - start
            cands = [self.period / PER_PERIOD if self.period else None,
                     self.max_step / 8.0 if self.max_step else None]
            cands = [c for c in cands if c]
            self.spacing = min(cands) if cands else max(span, 1e-300) / FIRST
        end = start + WINDOW * self.spacing
        end = max(end, b)
        if math.isfinite(span_hi):
            end = min(end, max(span_hi, b))
        self._scan(start, end)

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
        cuts = self._breaks(a, b) if self._breaks is not None and b > a else []
        parts = []
        lo = a
        for bp in list(cuts) + [b]:
            bp = float(bp)
            end = float(np.nextafter(bp, -math.inf)) if bp < b else bp
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
        locally (module doc)."""
        n = max(1, math.ceil((b - a) / self.spacing)) if b > a else 1
        t = np.linspace(a, b, n + 1) if b > a else np.array([a, a])
        t[-1] = b
        acc = self._values(t)
        for _ in range(ROUNDS):
            d1, d2 = _differences(t, acc)
            bad = _unresolved(t, d1, d2)
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
        bad = _unresolved(t, d1, d2)
        if bad.any():
            self._refuse_jump(t, acc, d1, bad)
        return t[:-1], np.nan_to_num(d1, posinf=1e300), np.nan_to_num(d2, posinf=1e300)

    def _refuse_jump(self, t: NDArray, acc: NDArray, d1: NDArray, bad: NDArray) -> None:
        """Cells that did not resolve: zoom into the steepest; a difference of l'' that stays a
        sizeable share of its range down to a few floats is a jump (ValueError)."""
        k = int(np.argmax(np.where(bad[:, None], d1, -1.0).max(axis=1)))
        j = int(np.argmax(d1[k]))
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


def _unresolved(t: NDArray, d1: NDArray, d2: NDArray) -> NDArray:
    """Cells wider than half the time scale |l'''| / |l''''| of themselves and their
    neighbours (|l'''| floored at ``_FLOOR`` of its largest value: where l''' is nearly still,
    as where it crosses zero, its own scale is not the gait's). A jump of l''' never resolves:
    its cell's scale is its width."""
    def nb(d):
        out = d.copy()
        out[1:] = np.maximum(out[1:], d[:-1])
        out[:-1] = np.maximum(out[:-1], d[1:])
        return out
    j, s = nb(d1), nb(d2)
    j = np.maximum(j, _FLOOR * d1.max(axis=0, initial=0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        tau = np.where(s > 0.0, j / s, math.inf).min(axis=1)
    w = np.diff(t)
    return (w > _RESOLVE * tau) & (w > 4.0 * np.spacing(np.maximum(np.abs(t[1:]), 1e-300)))
