"""Compiled event search for the trigonometric and cubic gaits: ``events`` in numba.

Same rows, bounds and rules as ``events`` (see its docstring), one point at a time instead of
chunks, with the gait l' and l'' evaluated inside the kernel: from the Fourier coefficients,

    l_j(t) = mean_j + sum_k a_jk cos(k th) + b_jk sin(k th),  th = 2 pi (f t mod 1),

or from the Scallop's closed form (``gaits.smooth.Scallop``). The bounds are those of the whole
segment (a Scallop's local ones from its bins), so steps are smaller than the Python search's
in a slow phase, and cost about 0.1 us each.

numba with ``cache=True`` (compiled once per machine into __pycache__, then loaded in about a
tenth of a second): it needs no build step in colcon or setup.py, numba is already a dependency
of the implicit kernels, and the kernel stays plain Python for reading and testing. ``exact``
imports this module only when a trigonometric gait is run, so ``import crawler_sim`` and ROS
nodes that never run one do not import numba.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

_MAX_STEPS = 10_000_000   # grid and narrowing steps of one search (about 1 s): a safety net

if True:  # (one block, indented)
    @njit(cache=True, inline='always')
    def rates(t, kind, freq, cosc, sinc, ld, ldd, ld3):
        """l', l'' and l''' of the kernel's gaits at t (into ld, ldd, ld3)."""
        if kind == 2:
            # constant-jerk pieces (gaits.cubic): sinc rows (start, t0), cosc rows
            # (l0, v0, a0, jerk) per linkage; the expressions of cubic_values
            k = 0
            while k + 1 < sinc.shape[0] and sinc[k + 1, 0] <= t:
                k += 1
            d = t - sinc[k, 1]
            for j in range(ld.size):
                a0 = cosc[k, 4 * j + 2]
                jk = cosc[k, 4 * j + 3]
                ld[j] = cosc[k, 4 * j + 1] + d * (a0 + 0.5 * d * jk)
                ldd[j] = a0 + d * jk
                ld3[j] = jk
            return
        ft = freq * t
        th = 2.0 * math.pi * (ft - math.floor(ft))     # phase in cycles first (large t)
        w = 2.0 * math.pi * freq
        if kind == 1:
            # Scallop (gaits.smooth): cosc rows hold (amplitude, phase - pi r, c, s);
            # phi''' = -s c (cos x / D^2 - 2 c sin^2 x / D^3), and
            # l''' = amp w^3 (cos phi (phi''' - phi'^3) - 3 sin phi phi' phi'')
            for j in range(cosc.shape[0]):
                amp, off, c, s = cosc[j, 0], cosc[j, 1], cosc[j, 2], cosc[j, 3]
                x = th + off
                cx = math.cos(x)
                sx = math.sin(x)
                inv_d = 1.0 / (1.0 - c * cx)
                sin_phi = s * sx * inv_d
                cos_phi = (cx - c) * inv_d
                dphi = s * inv_d
                ddphi = -s * c * sx * inv_d ** 2
                dddphi = -s * c * (cx * inv_d ** 2 - 2.0 * c * sx * sx * inv_d ** 3)
                ld[j] = amp * w * cos_phi * dphi
                ldd[j] = amp * w ** 2 * (cos_phi * ddphi - sin_phi * dphi ** 2)
                ld3[j] = amp * w ** 3 * (cos_phi * (dddphi - dphi ** 3)
                                         - 3.0 * sin_phi * dphi * ddphi)
            return
        # harmonics k by the angle-addition recurrence from cos th, sin th: two
        # trigonometric calls per time instead of two per harmonic (rounding ~k eps)
        nl, nk = cosc.shape
        c_1 = math.cos(th)
        s_1 = math.sin(th)
        for j in range(nl):
            ld[j] = 0.0
            ldd[j] = 0.0
            ld3[j] = 0.0
        c = c_1
        s = s_1
        for k in range(nk):
            wk = w * (k + 1)
            wk2 = wk * wk
            wk3 = wk2 * wk
            for j in range(nl):
                a_ = cosc[j, k]
                b_ = sinc[j, k]
                ld[j] += wk * (b_ * c - a_ * s)
                ldd[j] -= wk2 * (a_ * c + b_ * s)
                ld3[j] += wk3 * (a_ * s - b_ * c)
            c, s = c * c_1 - s * s_1, s * c_1 + c * s_1

    @njit(cache=True, inline='always')
    def values(t, t0, c0, c1, A1, A2, kind, freq, cosc, sinc, ld, ldd, ld3, g, dg):
        """The rows g (see ``events.Rows``) and their time derivatives dg at t."""
        rates(t, kind, freq, cosc, sinc, ld, ldd, ld3)
        K, nl = A1.shape
        for r in range(K):
            v = c0[r] + c1[r] * (t - t0)
            dv = c1[r]
            for j in range(nl):
                v += A1[r, j] * ld[j] + A2[r, j] * ldd[j]
                dv += A1[r, j] * ldd[j] + A2[r, j] * ld3[j]
            g[r] = v
            dg[r] = dv

    @njit(cache=True, inline='always')
    def _finite2(x, y):
        # a loop, not np.isfinite: that allocates a temporary array at every evaluation
        for r in range(x.size):
            if not (math.isfinite(x[r]) and math.isfinite(y[r])):
                return False
        return True

    @njit(cache=True, inline='always')
    def bad_any(g, watch, noise):
        for r in range(g.size):
            if (watch[r] and g[r] < -noise[r]) or (not watch[r] and g[r] <= 0.0):
                return True
        return False

    @njit(cache=True, inline='always')
    def proven(h, ga, gb, da, db, watch, B2, B1):
        """True if every unwatched row is proven > 0 on an interval of length h with end
        values ga, gb and end slopes da, db: the best of four lower bounds, each rigorous
        where |g''| <= B2 (chord: min - B2 h^2 / 8; Taylor from either end:
        g(a) + g'(a) tau - B2 tau^2 / 2, concave, so its minimum is at an end) or
        |g'| <= B1 (mean of the ends - B1 h / 2)."""
        for r in range(ga.size):
            if watch[r]:
                continue
            q = B2[r] * (h * h)
            lo = max(min(ga[r], gb[r]) - q / 8.0, 0.5 * (ga[r] + gb[r]) - B1[r] * (h / 2.0))
            lo = max(lo, min(ga[r], ga[r] + da[r] * h - q / 2.0))
            lo = max(lo, min(gb[r], gb[r] - db[r] * h - q / 2.0))
            if lo <= 0.0:
                return False
        return True

    @njit(cache=True, inline='always')
    def step(ga, da, watch, B2, B1, tol, cap):
        """A step from a that ``proven`` accepts from a's value and slope alone (just inside
        the first zero of each row's Taylor lower bound, or of g(a) - B1 tau): near a simple
        root this is a Newton step from the left, so the approach converges fast."""
        h = math.inf
        for r in range(ga.size):
            if watch[r]:
                continue
            g = max(ga[r], 0.0)
            d = da[r]
            b2 = B2[r]
            if b2 == 0.0:
                ht = g / (-d) if d < 0.0 else math.inf
            elif b2 < math.inf:
                ht = (d + math.sqrt(d * d + 2.0 * b2 * g)) / b2
            else:
                ht = 0.0
            h1 = g / B1[r] if B1[r] > 0 else math.inf
            h = min(h, 0.9999 * max(ht, h1))
        return min(max(h, 64.0 * tol), cap)

    @njit(cache=True)
    def _search(t0, end, c0, c1, A1, A2, kind, freq, cosc, sinc, B2, B1, tol, cap):
        """First event in (t0, end]: (t, hit rows, number of evaluations), or (inf, empty, n)
        when there is none."""
        K, nl = A1.shape
        work = np.empty((14, max(K, nl)))
        watch = np.empty(K, dtype=np.bool_)
        hits = np.zeros(K, dtype=np.bool_)
        t, n_eval = _search_ws(t0, end, c0, c1, A1, A2, kind, freq, cosc, sinc, B2, B1, tol,
                               cap, work, watch, hits)
        if t >= 0.0 and math.isfinite(t):
            return t, hits, n_eval
        return t, hits[:0], n_eval

    @njit(cache=True)
    def _search_ws(t0, end, c0, c1, A1, A2, kind, freq, cosc, sinc, B2, B1, tol, cap, work,
                   watch, hits):
        """``_search`` with its work arrays given (the compiled loop calls it once per
        segment: allocations cost as much as the evaluations): ``work`` of shape
        (14, >= max(K, n_links)), ``watch`` and ``hits`` (K,) bool. Returns (t, number of
        evaluations), t = inf when there is no event, -1 for a non-finite gait value, -2 when
        out of steps; the rows hit at t are set in ``hits``."""
        K, nl = A1.shape
        ld = work[0, :nl]
        ldd = work[1, :nl]
        ld3 = work[2, :nl]
        ga = work[3, :K]
        da = work[4, :K]
        values(t0, t0, c0, c1, A1, A2, kind, freq, cosc, sinc, ld, ldd, ld3, ga, da)
        noise = work[5, :K]
        for r in range(K):
            sc = abs(c0[r]) + abs(c1[r]) * (end - t0)
            for j in range(nl):
                sc += abs(A1[r, j] * ld[j]) + abs(A2[r, j] * ldd[j])
            noise[r] = 1e-13 * sc + 1e-300
            # a row at zero to within its rounding noise (a rigid pair, a body at rest)
            # is watched: a row of +1e-16 stuck there would otherwise need ~1e-9 s steps
            watch[r] = ga[r] <= noise[r]
        a = t0
        n_eval = 1
        h = step(ga, da, watch, B2, B1, tol, cap)
        for r in range(K):
            if watch[r]:
                h = min(h, max(1e3 * tol, 1e-9 * (end - a)))
        gm = work[6, :K]
        dm = work[7, :K]
        gb = work[8, :K]
        db = work[9, :K]
        gs = work[10, :K]
        ds = work[11, :K]
        fa = work[12, :K]
        fb = work[13, :K]
        have_b = False       # a point b > a where some row is bad (the bracket)
        b = math.inf
        saved = False        # a bracket put aside while [a, m] is scanned
        sb = math.inf
        lim = end            # scanning limit while a bracket is put aside
        side = 0
        w_hist0 = math.inf
        w_hist1 = math.inf
        w_hist2 = math.inf
        for _ in range(_MAX_STEPS):
            if have_b:
                m = 0.5 * (a + b)
                if not (a < m < b):
                    break
                w = b - a
                if w < 0.5 * w_hist0:
                    f = 1.0
                    for r in range(K):
                        bad = (watch[r] and gb[r] < -noise[r]) or (
                            not watch[r] and gb[r] <= 0.0)
                        den = fa[r] - fb[r]
                        if bad and den != 0.0:
                            fr = fa[r] / den
                            if fr < f:
                                f = fr
                    if 0.0 < f < 1.0:
                        # a secant point within one float of an end: the adjacent float
                        # (else the bracket shrinks only by bisection, ~40 halvings)
                        ms = a + f * w
                        if ms <= a:
                            ms = np.nextafter(a, math.inf)
                        elif ms >= b:
                            ms = np.nextafter(b, -math.inf)
                        if a < ms < b:
                            m = ms
                w_hist0, w_hist1, w_hist2 = w_hist1, w_hist2, w
            else:
                if a >= lim:
                    if saved:        # the put-aside part is proven: back to its bracket
                        have_b = True
                        saved = False
                        b = sb
                        gb[:] = gs
                        db[:] = ds
                        for r in range(K):
                            lvl = -noise[r] if watch[r] else 0.0
                            fa[r] = ga[r] - lvl
                            fb[r] = gb[r] - lvl
                        lim = end
                        side = 0
                        continue
                    return math.inf, n_eval
                m = min(a + h, lim)
            values(m, t0, c0, c1, A1, A2, kind, freq, cosc, sinc, ld, ldd, ld3, gm, dm)
            n_eval += 1
            if not _finite2(gm, dm):
                return -1.0, n_eval   # non-finite gait: the caller raises
            if bad_any(gm, watch, noise):
                saved = False
                lim = end
                have_b = True
                b = m
                gb[:] = gm
                db[:] = dm
                for r in range(K):
                    lvl = -noise[r] if watch[r] else 0.0
                    fb[r] = gm[r] - lvl
                    fa[r] = (ga[r] - lvl) * (0.5 if side == -1 else 1.0)
                side = -1
                continue
            if m - a > tol and not proven(m - a, ga, gm, da, dm, watch, B2, B1):
                if have_b:           # scan [a, m] first, the bracket put aside
                    saved = True
                    sb = b
                    gs[:] = gb
                    ds[:] = db
                    have_b = False
                    lim = m
                h = max(0.25 * (m - a), 0.5 * tol)
                continue
            for r in range(K):
                if watch[r] and gm[r] > noise[r]:
                    watch[r] = False
            a = m
            ga[:] = gm
            da[:] = dm
            if have_b:
                for r in range(K):
                    lvl = -noise[r] if watch[r] else 0.0
                    fa[r] = ga[r] - lvl
                    if side == 1:
                        fb[r] *= 0.5
                side = 1
            else:
                h = step(ga, da, watch, B2, B1, tol, cap)
        if not have_b:
            return -2.0, n_eval   # out of steps: the caller raises
        for r in range(K):
            hits[r] = (watch[r] and gb[r] < -noise[r]) or (not watch[r] and gb[r] <= 0.0)
        return b, n_eval


def coefficients(gait):
    """(kind, freq, P1, P2) of a Fourier / Sinusoid (kind 0: cos and sin coefficients, shape
    (n_links, K)), Scallop (kind 1: rows amplitude, phase - pi r, c, s) or Cubic /
    PiecewiseCubic gait (kind 2: rows of (l0, v0, a0, jerk) per linkage, and of (start, t0)
    per piece), or None."""
    from ..gaits import Cubic, Fourier, PiecewiseCubic, Scallop, Sinusoid
    cached = getattr(gait, '_kernel_coefficients', None)
    if cached is not None:
        return cached
    if type(gait) is Fourier:
        out = (0, gait.frequency, np.ascontiguousarray(gait.cos), np.ascontiguousarray(gait.sin))
    elif type(gait) is Sinusoid:
        # A sin(w t + phi) = A sin(phi) cos(w t) + A cos(phi) sin(w t)
        a = gait.amplitude
        out = (0, gait.frequency, (a * np.sin(gait.phase))[:, None].copy(),
               (a * np.cos(gait.phase))[:, None].copy())
    elif type(gait) is Scallop:
        n = gait.n_links
        rows = np.column_stack([gait.amplitude, gait.phase - math.pi * gait.asymmetry,
                                np.full(n, gait._c), np.full(n, gait._s)])
        out = (1, gait.frequency, np.ascontiguousarray(rows), np.zeros((n, 1)))
    elif type(gait) in (Cubic, PiecewiseCubic):
        pieces = [gait] if type(gait) is Cubic else gait.pieces
        starts = [gait.t0] if type(gait) is Cubic else gait._starts
        coef = np.array([[x for row in pc._rows for x in row] for pc in pieces])
        out = (2, 1.0, coef, np.array([[st, pc.t0] for st, pc in zip(starts, pieces)]))
    else:
        return None
    gait._kernel_coefficients = out
    return out


def search(t0: float, end: float, rows, coef, B2, B1, tol: float, cap: float):
    """Run the compiled search; returns (t, hit rows as a bool array, number of evaluations)
    or (inf, empty, n)."""
    kind, freq, p1, p2 = coef
    return _search(float(t0), float(end), rows.c0, rows.c1, np.ascontiguousarray(rows.A1),
                   np.ascontiguousarray(rows.A2), int(kind), float(freq), p1, p2,
                   np.ascontiguousarray(B2, dtype=float), np.ascontiguousarray(B1, dtype=float),
                   float(tol), float(cap))


_WARM = False


def warm() -> None:
    """Load (or compile) the kernel now with one tiny search, so the first real search of a
    real-time loop does not pay for it (about 0.1-1 s per process with a warm disk cache)."""
    global _WARM
    if _WARM:
        return
    one = np.ones(1)
    z = np.zeros((1, 1))
    _search(0.0, 1.0, one, one * 0.0, np.ones((1, 1)), z, 0, 1.0, z, z, one, one, 1e-13, 1.0)
    _WARM = True
