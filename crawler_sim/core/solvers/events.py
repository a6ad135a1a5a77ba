"""Event search of the exact method: the first zero of a set of event rows, never a later one.

Between events every event function of MODEL.md section 2 is an affine combination of the gait
and its derivatives (``Rows``):

    g_k(t) = c0_k + c1_k (t - t0) + A1_k . l'(t) + A2_k . l''(t)

(a sliding body's velocity V + e_i': c1 = the centre-of-mass acceleration, A1 = its offset
row; a stuck group's force slack to a bound: A2 = -+ M e_r'' rows; a relative velocity while a
body sticks: A1 = C_i - C_r). Each is positive while the segment's mode is valid. So

    |g_k''| <= |A1_k| . max|l'''| + |A2_k| . max|l''''|,     |g_k'| <= |A2_k| . max|l'''|

(the second for the force rows, whose second derivative needs l'''' and is unknown where the
gait's jerk jumps). On an interval [a, b], h = b - a, these bounds give rigorous lower bounds
of g_k from its end values (a function with |g''| <= B2 lies above its chord minus B2 h^2 / 8;
one with |g'| <= B1 above the mean of its end values minus B1 h / 2). An interval whose lower
bounds are all positive is proven free of events; otherwise it is split, down to ``tol``
seconds. The first interval with a row <= 0 at its right end brackets the first event, which
is narrowed by safeguarded secant steps, each left part again proven free of events, to
``tol``; the event is reported on the crossed side (g <= 0 there).

Where the gait gives no bound (a ``Custom`` gait without ``jerk_bound``) the search uses 8
times the largest second difference of the row values observed on the segment, and the caller
redoes the segment with the larger estimate when a later observation exceeds the one an
accepted interval relied on (``Search.estimate_grew``). That is not a proof; the docstring of
``ExactSolver`` says so.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..gaits import Gait

__all__ = ['Rows', 'Search']

_N = 8                  # grid points per chunk (one vectorised gait call)
_SAFETY = 8.0           # factor on an estimated second-derivative bound
_EPS = np.finfo(float).eps


def check_finite_gait(vals, t) -> None:
    """Raise ValueError naming the quantity and time if a gait value (l, l', l'') is not finite."""
    if all(np.isfinite(v).all() for v in vals):
        return
    for name, arr in zip(('length', 'velocity', 'acceleration'), vals):
        if not np.all(np.isfinite(arr)):
            bad = np.atleast_1d(t)[np.nonzero(~np.isfinite(np.reshape(
                arr, (np.size(t), -1))).any(axis=1))[0][0]]
            raise ValueError(f'gait {name} must be finite, got a non-finite value at t = '
                             f'{float(bad)!r} s')


@dataclass(slots=True)
class Rows:
    """Event rows g = c0 + c1 (t - t0) + l' A1^T + l'' A2^T, shape (K,) each (A: (K, n_links)).

    Rows that start at or below their noise level, 1e-13 of their scale (a body leaving rest,
    a rigid pair), are *watched*: they become ordinary rows once above that level, and trigger
    an event only when they go below minus that level; the mode declared such a row zero, so
    its start value is rounding too and the level is at least 4 times its magnitude.
    """

    t0: float
    c0: NDArray[np.float64]
    c1: NDArray[np.float64]
    A1: NDArray[np.float64]
    A2: NDArray[np.float64]

    def values(self, ld: NDArray, ldd: NDArray, tau: NDArray) -> NDArray[np.float64]:
        return self.c0 + np.multiply.outer(tau - self.t0, self.c1) + ld @ self.A1.T \
            + ldd @ self.A2.T

    def bounds(self, gait: Gait, a: float, b: float) -> tuple[NDArray, NDArray]:
        """(B2, B1): bounds of |g''| and |g'| on [a, b] (inf where the gait gives none)."""
        k = self.c0.size
        j = gait.jerk_bound(a, b)
        if j is None:
            inf = np.full(k, math.inf)
            return inf, inf
        s = gait.snap_bound(a, b)
        a1, a2 = np.abs(self.A1), np.abs(self.A2)
        has2 = a2.any(axis=1)
        b1 = np.where(has2 & (self.c1 == 0) & ~a1.any(axis=1), a2 @ j, math.inf)
        if s is None:
            b2 = np.where(has2, math.inf, a1 @ j)
        else:
            b2 = a1 @ j + a2 @ s
        return b2, b1


class Search:
    """The first event of one segment's rows on [t0, t_stop] (see the module docstring).

    ``left_limit``: t_stop is a gait breakpoint; the rows are evaluated just before it.
    ``h0``: first grid step; ``cap``: largest grid step (both only set the cost, not what is
    found, except where bounds are estimated).
    """

    def __init__(self, gait: Gait, rows: Rows, tol: float, cap: float) -> None:
        self.gait, self.rows, self.tol, self.cap = gait, rows, tol, cap
        self.known = gait.jerk_bound(rows.t0, rows.t0) is not None
        self.est = np.zeros(rows.c0.size)        # estimated |g''| (unknown bounds)
        self.used = np.zeros(rows.c0.size)       # largest estimate accepted intervals used
        self.n_eval = 0

    # ------------------------------------------------------------------ helpers
    def _eval(self, tau: NDArray) -> NDArray:
        _, ld, ldd = self.gait._eval(tau)
        check_finite_gait((ld, ld, ldd), tau)
        self.n_eval += tau.size
        return self.rows.values(ld, ldd, tau)

    def _observe(self, tau: NDArray, G: NDArray) -> None:
        """Second divided differences of consecutive samples: the estimate of |g''|."""
        if self.known or tau.size < 3:
            return
        # only spacings well above rounding: near a grazing zero the steps become tiny and
        # second differences there are rounding noise, not curvature
        wide = (tau[2:] - tau[:-2]) >= 1e-4 * self.cap
        if not wide.any():
            return
        d1 = np.diff(G, axis=0) / np.diff(tau)[:, None]
        d2 = 2.0 * np.abs(np.diff(d1, axis=0)) / (tau[2:] - tau[:-2])[:, None]
        self.est = np.maximum(self.est, _SAFETY * d2[wide].max(axis=0))

    def estimate_grew(self) -> bool:
        """True if an accepted interval relied on an estimate that later observations exceed."""
        return not self.known and bool(np.any(self.est > _SAFETY * self.used * (1 + 1e-9)))

    def _bounds(self, a: float, b: float) -> tuple[NDArray, NDArray]:
        """(B2, B1) on [a, b]: the gait's bounds, or the current estimate (module doc)."""
        if self.known:
            return self.rows.bounds(self.gait, a, b)
        self.used = np.maximum(self.used, self.est)
        return self.est, np.full(self.est.size, math.inf)

    @staticmethod
    def _lower(h: float, ga: NDArray, gb: NDArray, b2: NDArray, b1: NDArray) -> NDArray:
        """Lower bounds of the rows on an interval of length h with end values ga, gb."""
        # h > 0 and the values are finite, so an infinite bound gives -inf, never NaN
        return np.maximum(np.minimum(ga, gb) - b2 * (h * h / 8.0), 0.5 * (ga + gb) - b1 * (h / 2.0))

    def _step(self, ga: NDArray, active: NDArray, b2: NDArray, b1: NDArray) -> float:
        """A step from a that the bounds are likely to accept (sets the cost only)."""
        g = np.where(active, np.maximum(ga, 0.0), math.inf)
        with np.errstate(divide='ignore', invalid='ignore'):
            # bounds that leave half of g(a): the next point passes unless g drops by half
            h = np.fmax(np.sqrt(4.0 * g / b2), g / b1)     # NaN: inf / inf
        h = float(np.where(np.isnan(h), math.inf, h).min(initial=math.inf))
        return min(max(h, 64.0 * self.tol), self.cap)

    # --------------------------------------------------------------------- search
    def run(self, t_stop: float, left_limit: bool, h0: float | None = None):
        """Returns (t_event, rows hit) or (t_stop, None) when no event occurs before t_stop."""
        t0 = self.rows.t0
        end = float(np.nextafter(t_stop, -math.inf)) if left_limit else t_stop
        _, ld, ldd = self.gait._eval(np.array([t0]))
        r = self.rows
        ga = r.values(ld, ldd, np.array([t0]))[0]
        scale = (np.abs(r.c0) + np.abs(r.c1) * (t_stop - t0) + np.abs(ld) @ np.abs(r.A1).T
                 + np.abs(ldd) @ np.abs(r.A2).T)[0]
        self._noise = 1e-13 * scale + 1e-300    # below it a watched row counts as zero
        watch = ga <= self._noise      # zero to rounding: watched (see Rows)
        # declared zero by the mode at t0: its value there is rounding, so at least that
        # much is noise (kernel._search_ws, the same rule)
        self._noise = np.where(watch, np.maximum(self._noise, 4.0 * np.abs(ga)), self._noise)
        if end <= t0:
            return t_stop, None
        return self._scan(t0, end, ga, watch, h0, t_stop)

    def _bad(self, g: NDArray, watch: NDArray) -> NDArray:
        return np.where(watch, g < -self._noise, g <= 0.0)

    def _scan(self, a: float, end: float, ga: NDArray, watch: NDArray, h0, t_stop):
        """Scan [a, end] from a (proven up to a). Returns (t, hits) or (t_stop, None).

        Each chunk is checked at once: interval i runs from point i - 1 to point i (point 0 is
        a); a watched row becomes ordinary after its first point above the noise level.
        """
        noise = self._noise
        b2, b1 = self._bounds(a, min(a + self.cap, end))
        h = self._step(ga, ~watch, b2, b1) if h0 is None else min(h0, self.cap)
        if watch.any():
            h = min(h, max(1e3 * self.tol, 1e-9 * (end - a)))   # leave rest carefully
        while a < end:
            tau = a + h * np.arange(1, _N + 1)
            if tau[-1] >= end:
                tau = np.append(tau[tau < end], end)
            G = self._eval(tau)
            ta = np.concatenate(([a], tau))
            Ga = np.vstack([ga, G])
            self._observe(ta, Ga)
            b2, b1 = self._bounds(a, float(tau[-1]))
            # watch state on each interval: not yet above the noise at its start point
            w = watch & ~np.logical_or.accumulate(Ga[:-1] > noise, axis=0)
            bad = np.where(w, G < -noise, G <= 0.0).any(axis=1)
            hs = np.diff(ta)[:, None]
            lo = np.maximum(np.minimum(Ga[:-1], G) - b2 * (hs * hs / 8.0),
                            0.5 * (Ga[:-1] + G) - b1 * (hs / 2.0))
            fail = ~((lo > 0.0) | w).all(axis=1) & (hs[:, 0] > self.tol)
            k_bad = int(np.argmax(bad)) if bad.any() else tau.size
            k_fail = int(np.argmax(fail)) if fail.any() else tau.size
            if k_bad < tau.size and k_bad <= k_fail:
                return self._refine(float(ta[k_bad]), float(tau[k_bad]), Ga[k_bad], G[k_bad],
                                    w[k_bad], t_stop, end)
            k = min(k_fail, tau.size)          # intervals 0 .. k-1 are proven
            if k > 0:
                watch = w[k - 1] & ~(G[k - 1] > noise)
                a, ga = float(tau[k - 1]), G[k - 1]
            if k < tau.size:
                h = max(0.25 * float(hs[k, 0]), 0.5 * self.tol)
            else:
                rule = self._step(ga, ~watch, b2, b1)
                # estimated bounds: grow at most 2x per chunk, so the estimate sees the gait
                h = rule if self.known else min(rule, 2.0 * h)
        return t_stop, None

    def _refine(self, a: float, b: float, ga: NDArray, gb: NDArray, watch: NDArray,
                t_stop: float | None, end: float):
        """First event in [a, b]: every row proven > 0 up to a, some row bad at b.

        Illinois steps (regula falsi that halves the value kept twice) on the row that crosses
        first, a bisection whenever three steps did not halve the bracket; every left part is
        proven free of events (or scanned) before it is dropped. Ends when a and b are adjacent
        floats: the root to machine precision, reported on the crossed side b.
        """
        noise = self._noise
        b2, b1 = self._bounds(a, b)
        lvl = np.where(watch, -noise, 0.0)
        fa, fb = ga - lvl, gb - lvl
        side, widths = 0, [math.inf] * 3
        for _ in range(300):
            w = b - a
            m = 0.5 * (a + b)
            if not a < m < b:
                break
            if w < 0.5 * widths[0]:
                with np.errstate(divide='ignore', invalid='ignore'):
                    frac = fa / (fa - fb)
                frac = np.where(self._bad(gb, watch) & np.isfinite(frac), frac, 1.0)
                f = float(frac.min())
                if 0.0 < f < 1.0 and a < a + f * w < b:
                    m = a + f * w
            widths = widths[1:] + [w]
            gm = self._eval(np.array([m]))[0]
            if self._bad(gm, watch).any():
                b, gb, fb = m, gm, gm - lvl
                if side == -1:
                    fa = 0.5 * fa
                side = -1
                continue
            ok = (self._lower(m - a, ga, gm, b2, b1) > 0.0) | watch
            if not ok.all() and m - a > self.tol:
                found = self._scan(a, m, ga, watch, 0.125 * (m - a), None)
                if found[1] is not None:
                    return found
            watch = watch & ~(gm > noise)
            lvl = np.where(watch, -noise, 0.0)
            a, ga, fa = m, gm, gm - lvl
            if side == 1:
                fb = 0.5 * fb
            side = 1
        if t_stop is not None and b >= end and end < t_stop:
            b = t_stop       # the left limit at a breakpoint: the event is at the breakpoint
        return b, np.nonzero(self._bad(gb, watch))[0]
