"""Compiled event search for the trigonometric and cubic gaits: ``events`` in numba.

Same rows and rules as ``events`` (see its docstring), one point at a time instead of chunks,
with the gait's l', l'' and l''' evaluated inside the kernel: from the Fourier coefficients,

    l_j(t) = mean_j + sum_k a_jk cos(k th) + b_jk sin(k th),  th = 2 pi (f t mod 1),

from the Scallop's closed form (``gaits.smooth.Scallop``) or from the constant-jerk pieces. So
each row's slope is known at every point too, and an interval is also proven free of events by
the Taylor lower bound from either end, g(a) + g'(a) tau - B2 tau^2 / 2 (rigorous where
|g''| <= B2); steps go just inside its first zero, which near a simple root is a Newton step from
the left: about ten evaluations per segment instead of fifty. The bounds are those of the
whole span of one call; the solver makes a call per stretch of similar bounds
(``Gait.block_end``: a Scallop's from its bins). A ``Custom`` gait reaches the kernel as a C
callback (``CALLBACK``, built by ``callback``), its l''' a difference of its l'' and its bounds
estimated from a scan.

numba with ``cache=True`` (compiled once per machine into __pycache__, then loaded in about a
tenth of a second): it needs no build step in colcon or setup.py, numba is already a dependency
of the implicit kernels, and the kernel stays plain Python for reading and testing. ``exact``
imports this module only when a trigonometric gait is run, so ``import crawler_sim`` and ROS
nodes that never run one do not import numba.

The exact method's segment loop (``drive``) is compiled here too, for the same gaits.
``ExactSolver._segment`` in Python costs about 0.2 ms per segment (numpy calls on arrays of p
entries), twenty times the event search itself; ``drive`` runs the same loop for the common
segments and hands the rest back to Python, so the two paths share every rule: mode choice
with at most one body at zero velocity (``ExactSolver._solve_mode_one``, ties decided by the
same look-ahead), event rows ``vel`` and ``force`` (``ExactSolver._rows``), their bounds
(``Rows.bounds``, for the whole span of one call), the search, the closed-form end of a segment
(``ExactSolver._close``) and the periodic check (``ExactSolver._period_boundary``). It returns
to Python (status ``NEED_PYTHON``) before a segment that needs more: two or more bodies at zero
velocity (groups, rigid links), a contact sign contradicted by the velocity (after a jump of
l'), a non-finite gait value. One module for the search and the loop because numba's disk
cache is keyed on the file that defines a function: a loop cached in another file would keep
running an old search after this file changes.
"""
from __future__ import annotations

import ctypes
import math

import numpy as np
from numba import njit
from numba.extending import overload

_MAX_STEPS = 10_000_000   # grid and narrowing steps of one search (about 1 s): a safety net

# the compiled segment loop (``drive``): its return statuses and ExactSolver's constants
REACHED, NEED_PYTHON, FULL, STALLED, NONFINITE, NO_STEPS, PERIODIC = 0, 1, 2, 3, 4, 5, 6
_EPS = 2.220446049250313e-16
_STALL_ULPS = 64
_STALL_SEGMENTS = 256
_AMBIGUOUS = 1e-10

# The gait's kind travels through the compiled functions as a tuple of kind + 1 zeros: its
# length is a compile-time constant, so numba compiles one specialisation per kind (on first
# use, each cached) and the dispatch on it folds away. With the kind as a run-time integer the
# code of the other two kinds in the same functions made the Fourier path twice as slow
# (``drive`` on the bench's scene 1: 195 us -> 87 us for the same 548 evaluations).
FOURIER, SCALLOP, CUBIC = (0,), (0, 0), (0, 0, 0)
# A Custom gait's kind is (callback, buffer, 0, 0) (``callback.CustomBridge``). The callback
# fills the buffer with l, l', l'' and l''' per linkage at time t; its second argument is 1
# when l is wanted too (the search needs no l: a user call saved is a quarter of the
# callback's cost). The kernel keeps the times of the values in the buffer's last two entries
# (the loop asks for one time several times).
CALLBACK = ctypes.CFUNCTYPE(None, ctypes.c_double, ctypes.c_int64)


def _custom_rates(kind, t, ld, ldd, ld3):
    """A Custom kind's l', l'' and l''' at t (compiled only; nothing for the other kinds)."""


def _custom_lengths(kind, t, l):
    """A Custom kind's l at t (compiled only; nothing for the other kinds)."""


# Overloads, not branches written in ``rates``: numba types both branches of ``if len(kind)
# == 4`` before it drops the dead one, and ``rates`` is inlined at a dozen places of
# ``drive``; a no-op per other kind keeps their compilation as it was (the code written in
# the branch made the Cubic kind's first compilation 3.4 s longer, 16.1 -> 19.5 s).
@overload(_custom_rates)
def _custom_rates_impl(kind, t, ld, ldd, ld3):
    if len(kind) != 4:
        return lambda kind, t, ld, ldd, ld3: None

    def impl(kind, t, ld, ldd, ld3):
        buf = kind[1]
        n = buf.size
        if buf[n - 1] != t:
            kind[0](t, 0)
            buf[n - 1] = t
        nl = ld.size
        for j in range(nl):
            ld[j] = buf[nl + j]
            ldd[j] = buf[2 * nl + j]
            ld3[j] = buf[3 * nl + j]
    return impl


@overload(_custom_lengths)
def _custom_lengths_impl(kind, t, l):
    if len(kind) != 4:
        return lambda kind, t, l: None

    def impl(kind, t, l):
        buf = kind[1]
        n = buf.size
        if buf[n - 2] != t:
            kind[0](t, 1)
            buf[n - 2] = t
            buf[n - 1] = t
        for j in range(l.size):
            l[j] = buf[j]
    return impl


if True:  # (one block, indented)
    @njit(cache=True, inline='always')
    def rates(t, kind, freq, cosc, sinc, ld, ldd, ld3):
        """l', l'' and l''' of the kernel's gaits at t (into ld, ldd, ld3)."""
        if len(kind) == 4:
            _custom_rates(kind, t, ld, ldd, ld3)
            return
        if len(kind) == 3:
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
        if len(kind) == 2:
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
        watched = False
        for r in range(ga.size):
            if watch[r]:
                watched = True
                continue
            g = max(ga[r], 0.0)
            d = da[r]
            b2 = B2[r]
            if b2 == math.inf:
                ht = 0.0
            else:
                # the positive root of g + d h - b2 h^2 / 2, in the form without cancellation
                # (d < 0 with b2 g << d^2: a tiny jerk bound, a nearly linear row)
                q = math.sqrt(d * d + 2.0 * b2 * g)
                if d <= 0.0:
                    if q - d > 0.0:
                        ht = 2.0 * g / (q - d)
                    else:          # d = 0 and b2 g = 0: a constant row is never crossed
                        ht = math.inf if g > 0.0 else 0.0
                else:
                    ht = (d + q) / b2 if b2 > 0.0 else math.inf
            h1 = g / B1[r] if B1[r] > 0 else math.inf
            h = min(h, 0.9999 * max(ht, h1))
        # ``cap`` (a cost setting) only while a row is watched: a watched row is checked at the
        # search points alone, so they stay dense; the others are proven whatever the step
        return min(max(h, 64.0 * tol), cap) if watched else max(h, 64.0 * tol)

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
        for r in range(K):
            hits[r] = False
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
            if watch[r]:
                # the mode declared this row zero at t0 (a body at rest, a rigid link): its
                # value there is rounding, so at least that much is noise (a rigid pair whose
                # link rates cancel to -5e-16 m/s, not to 0, would split again every float)
                noise[r] = max(noise[r], 4.0 * abs(ga[r]))
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
                settled = False
                for r in range(K):
                    # a row come down to its rounding noise with no slope to cross zero in
                    # the shortest step is zero as far as floats tell: an event here, and the
                    # mode is decided again (a velocity settling onto zero with the command,
                    # whose Taylor steps would shrink to ~sqrt(noise / B2) for ever; a
                    # velocity touching zero, where the body sticks)
                    if (not watch[r] and ga[r] <= noise[r]
                            and abs(da[r]) * (64.0 * tol) <= noise[r]):
                        hits[r] = True
                        settled = True
                if settled:
                    return a, n_eval
                h = step(ga, da, watch, B2, B1, tol, cap)
        if not have_b:
            return -2.0, n_eval   # out of steps: the caller raises
        for r in range(K):
            hits[r] = (watch[r] and gb[r] < -noise[r]) or (not watch[r] and gb[r] <= 0.0)
        return b, n_eval


if True:  # the segment loop (one block, indented)
    @njit(cache=True)
    def lengths(t, kind, freq, mean, cosc, sinc, l):
        """l(t) of the kernel's gaits (the expressions of the gaits' ``_eval``)."""
        if len(kind) == 4:
            _custom_lengths(kind, t, l)
            return
        if len(kind) == 3:
            k = 0
            while k + 1 < sinc.shape[0] and sinc[k + 1, 0] <= t:
                k += 1
            d = t - sinc[k, 1]
            for j in range(l.size):
                l0 = cosc[k, 4 * j]
                v0 = cosc[k, 4 * j + 1]
                a0 = cosc[k, 4 * j + 2]
                jk = cosc[k, 4 * j + 3]
                l[j] = l0 + d * (v0 + d * (0.5 * a0 + d * jk / 6.0))
            return
        th = 2.0 * math.pi * ((freq * t) % 1.0)
        if len(kind) == 2:
            for j in range(cosc.shape[0]):
                amp, off, c, s = cosc[j, 0], cosc[j, 1], cosc[j, 2], cosc[j, 3]
                x = th + off
                l[j] = mean[j] + amp * (s * math.sin(x) / (1.0 - c * math.cos(x)))
            return
        nl, nk = cosc.shape
        for j in range(nl):
            v = 0.0
            for k in range(nk):
                v += cosc[j, k] * math.cos((k + 1) * th) + sinc[j, k] * math.sin((k + 1) * th)
            l[j] = mean[j] + v

    @njit(cache=True)
    def _dot(W, i, x):
        acc = 0.0
        for j in range(x.size):
            acc += W[i, j] * x[j]
        return acc

    @njit(cache=True)
    def _mode_one(j, force, epp, fp, fm, f_total, M, slack):
        """``ExactSolver._solve_mode_one``: (a, contact of j, ambiguous) when body j alone is at
        rest and the others push with ``force`` [N]."""
        e2 = epp[j]
        need = -M * e2 - force                 # ground force on j if it sticks
        acc_scale = (f_total + abs(force)) / M
        for i in range(epp.size):
            acc_scale = max(acc_scale, abs(epp[i]))
        acc_scale = max(acc_scale, 1e-300)
        if need < -fp[j]:
            a = (force - fp[j]) / M
            return a, 1, abs(a + e2) <= slack * acc_scale
        if need > fm[j]:
            a = (force + fm[j]) / M
            return a, -1, abs(a + e2) <= slack * acc_scale
        f_scale = max(max(f_total, abs(force)), max(M * acc_scale, 1e-300))
        return -e2, 0, fp[j] + fm[j] > 0 and min(need + fp[j], fm[j] - need) <= slack * f_scale

    @njit(cache=True)
    def drive(t, t_stop, left_limit, t_end, T, tscale, tol, cap,
              X, V, K, contact, zero, ref, x_ref, cache_ok, cache_a,
              W, C, fp, fm, free, fext, M, f_total, v_acc,
              kind, freq, mean, cosc, sinc, jerk, snap, has_snap,
              ck_f, ck_K, ck_contact, ck_zero,
              seg_f, seg_ref, seg_contact, seg_R, seg_K0, ev_t, ev_i, state):
        """Integrate from ``t`` towards ``t_stop`` (a gait breakpoint when ``left_limit``, or
        the end of the caller's advance ``t_end``) segment by segment (see the module doc).

        ``tscale``: the look-ahead time scale of ``ExactSolver._timescale``. ``T`` > 0: the
        period; segments end at its multiples and the state there is compared
        with the checkpoint of the previous one (``ExactSolver._period_boundary``):
        ``ck_f`` = (k, X, V, x_ref, ref, segment index, event index, written here), with
        ``ck_K``, ``ck_contact``, ``ck_zero`` (k = -1: none). On a repeat the call returns
        ``PERIODIC`` at that multiple, the checkpoint left at the previous one.

        State in/out: ``K`` (p,), ``contact`` (p,) int8, ``zero`` (p,) bool are updated in
        place; the floats come back in ``state`` = [t, X, V, x_ref, ref, -, n_segments,
        cache_ok, cache_a, n_evals, n_events, k]. Segment k is ``seg_f[k]`` = (t0, t1, X0,
        V0, a, x_ref), ``seg_ref[k]``, ``seg_contact[k]``, ``seg_R[k]``, ``seg_K0[k]``; event
        k (a contact change) is at ``ev_t[k]`` for body ``ev_i[k, 0]`` from ``ev_i[k, 1]`` to
        ``ev_i[k, 2]``. Returns a status.
        """
        p, nl = W.shape
        l = np.empty(nl)
        ld = np.empty(nl)
        ldd = np.empty(nl)
        ld3 = np.empty(nl)
        ld2 = np.empty(nl)
        ldd2 = np.empty(nl)
        epp2 = np.empty(p)
        e = np.empty(p)
        ep = np.empty(p)
        epp = np.empty(p)
        R = np.empty(p)
        n_max = seg_f.shape[0]
        # event rows: at most p velocity rows and 2 force rows
        c0 = np.empty(p + 2)
        c1 = np.empty(p + 2)
        A1 = np.zeros((p + 2, nl))
        A2 = np.zeros((p + 2, nl))
        lab_kind = np.empty(p + 2, np.int64)
        lab_body = np.empty(p + 2, np.int64)
        B2 = np.empty(p + 2)
        B1 = np.empty(p + 2)
        work = np.empty((14, max(p + 2, nl)))
        watch = np.empty(p + 2, np.bool_)
        hit = np.empty(p + 2, np.bool_)
        hits = np.zeros(p, np.bool_)
        n = 0
        n_ev = 0
        n_eval = 0
        k_at = -1
        guard = 0
        status = REACHED
        while t < t_stop:
            if n == n_max:
                status = FULL
                break
            # this segment's span: to t_stop or the next multiple of the period
            ts = t_stop
            left = left_limit
            k_next = -1
            if T > 0.0:
                k_next = math.floor(t / T * (1 + 4 * _EPS) + 4 * _EPS) + 1
                if k_next * T < t_stop:
                    ts = k_next * T
                    left = False
                elif k_next * T == t_stop:
                    left = False
            end = np.nextafter(ts, -math.inf) if left else ts
            lengths(t, kind, freq, mean, cosc, sinc, l)
            rates(t, kind, freq, cosc, sinc, ld, ldd, ld3)
            finite = True
            for j in range(nl):
                if not (math.isfinite(l[j]) and math.isfinite(ld[j]) and math.isfinite(ldd[j])):
                    finite = False
            if not finite:
                status = NEED_PYTHON
                break
            for i in range(p):
                e[i] = _dot(W, i, l)
                ep[i] = _dot(W, i, ld)
                epp[i] = _dot(W, i, ldd)
            X_s, V_s = X, V
            if ref >= 0:
                V = -ep[ref]
                X = x_ref - e[ref]
            stale = False
            n_zero = 0
            j0 = -1
            for i in range(p):
                if zero[i]:
                    n_zero += 1
                    j0 = i
                elif not free[i] and contact[i] * (V + ep[i]) <= 0.0:
                    stale = True
            if stale or n_zero > 1:
                X, V = X_s, V_s
                status = NEED_PYTHON
                break
            # ---- mode
            new_ref = -1
            if cache_ok:
                a = cache_a
                new_ref = ref
                cache_ok = False
            elif n_zero == 0:
                tot = 0.0
                for i in range(p):
                    tot += -fp[i] if contact[i] > 0 else (fm[i] if contact[i] < 0 else 0.0)
                a = (fext + tot) / M
            else:
                j = j0
                total = 0.0
                for i in range(p):
                    if i != j:
                        total += -fp[i] if contact[i] > 0 else fm[i]
                force = fext + total
                a, cj, ambiguous = _mode_one(j, force, epp, fp, fm, f_total, M, _AMBIGUOUS)
                if ambiguous:
                    # a tie (at the bound just after a force event, say): decided by the
                    # inclusion a little later, as ExactSolver._mode does
                    span = max(ts - t, 0.0)
                    for rel in (1e-9, 1e-7, 1e-5):
                        dt = min(rel * max(span, tscale), 0.5 * span) if span > 0 else 0.0
                        if dt <= 0.0:
                            break
                        rates(t + dt, kind, freq, cosc, sinc, ld2, ldd2, ld3)
                        for i in range(p):
                            epp2[i] = _dot(W, i, ldd2)
                        a, cj, ambiguous = _mode_one(j, force, epp2, fp, fm, f_total, M, 1e-14)
                        if not ambiguous:
                            break
                if cj == 0:
                    new_ref = j
                    a = -epp[j]
                if cj == 0 and p == 1:
                    X, V = X_s, V_s
                    status = NEED_PYTHON
                    break
                if contact[j] != cj:
                    ev_t[n_ev] = t
                    ev_i[n_ev, 0] = j
                    ev_i[n_ev, 1] = contact[j]
                    ev_i[n_ev, 2] = cj
                    n_ev += 1
                contact[j] = cj
            if new_ref >= 0:
                if new_ref != ref:
                    x_ref = X + e[new_ref]
            else:
                x_ref = 0.0
                for i in range(p):
                    if zero[i] and contact[i] != 0:
                        V = -ep[i]
                        break
            ref = new_ref
            for i in range(p):
                R[i] = -fp[i] if contact[i] > 0 else (fm[i] if contact[i] < 0 else 0.0)
            V0 = -ep[ref] if ref >= 0 else V
            t0 = t
            seg_f[n, 0] = t0
            seg_f[n, 2] = X
            seg_f[n, 3] = V0
            seg_f[n, 4] = a
            seg_f[n, 5] = x_ref
            seg_ref[n] = ref
            for i in range(p):
                seg_contact[n, i] = contact[i]
                seg_R[n, i] = R[i]
                seg_K0[n, i] = K[i]
            # ---- rows (ExactSolver._rows)
            nr = 0
            for i in range(p):
                if free[i] or i == ref:
                    continue
                sg = float(contact[i])
                lab_kind[nr] = 0
                lab_body[nr] = i
                if ref < 0:
                    c0[nr] = sg * V0
                    c1[nr] = sg * a
                    for j in range(nl):
                        A1[nr, j] = sg * W[i, j]
                        A2[nr, j] = 0.0
                else:
                    c0[nr] = 0.0
                    c1[nr] = 0.0
                    for j in range(nl):
                        A1[nr, j] = sg * (C[i, j] - C[ref, j])
                        A2[nr, j] = 0.0
                nr += 1
            f_slide = fext
            if ref >= 0:
                for i in range(p):
                    if i != ref:
                        f_slide += R[i]
                for s in range(2):
                    lab_kind[nr] = 1
                    lab_body[nr] = ref
                    c0[nr] = (-f_slide + fp[ref]) if s == 0 else (fm[ref] + f_slide)
                    c1[nr] = 0.0
                    sgn = -1.0 if s == 0 else 1.0
                    for j in range(nl):
                        A1[nr, j] = 0.0
                        A2[nr, j] = sgn * M * W[ref, j]
                    nr += 1
            # ---- search
            t_ev = ts
            n_hit = 0
            for i in range(p):
                hits[i] = False
            if nr > 0 and end > t0:
                for r in range(nr):
                    b2 = 0.0
                    b1 = 0.0
                    has1 = False
                    has2 = False
                    for j in range(nl):
                        a1 = abs(A1[r, j])
                        a2 = abs(A2[r, j])
                        if a1 != 0.0:
                            has1 = True
                        if a2 != 0.0:
                            has2 = True
                        b2 += a1 * jerk[j]
                        b1 += a2 * jerk[j]
                    if has2:
                        if has_snap:
                            for j in range(nl):
                                b2 += abs(A2[r, j]) * snap[j]
                        else:
                            b2 = math.inf
                    B2[r] = b2
                    B1[r] = b1 if (has2 and c1[r] == 0.0 and not has1) else math.inf
                tt, n_sev = _search_ws(t0, end, c0[:nr], c1[:nr], A1[:nr], A2[:nr], kind, freq,
                                       cosc, sinc, B2[:nr], B1[:nr], tol, cap, work,
                                       watch[:nr], hit[:nr])
                n_eval += n_sev
                if tt == -2.0:
                    status = NO_STEPS
                    break
                if tt < 0.0:
                    status = NONFINITE
                    break
                if math.isfinite(tt):
                    t_ev = tt
                    if t_ev >= end and end < ts:
                        t_ev = ts
                    for r in range(nr):
                        if hit[r]:
                            n_hit += 1
                            if lab_kind[r] == 0:
                                hits[lab_body[r]] = True
                    if ts - t_ev <= 4.0 * tol:
                        t_ev = ts
            # ---- close (ExactSolver._close)
            d = t_ev - t0
            if ref < 0:
                X = X + d * (V0 + 0.5 * a * d)
                V = V0 + a * d
                for i in range(p):
                    K[i] += R[i] * d
                    zero[i] = False
            else:
                lengths(t_ev, kind, freq, mean, cosc, sinc, l)
                rates(t_ev, kind, freq, cosc, sinc, ld, ldd, ld3)
                V = -_dot(W, ref, ld)
                X = x_ref - _dot(W, ref, l)
                for i in range(p):
                    if i != ref:
                        K[i] += R[i] * d
                    zero[i] = i == ref
                imp = M * (V - V0) - f_slide * d
                w = fp[ref] + fm[ref]
                if w > 0:
                    K[ref] += fm[ref] * d - ((-imp + fm[ref] * d) / w) * (fp[ref] + fm[ref])
            if n_hit > 0:
                if ref < 0:
                    rates(t_ev, kind, freq, cosc, sinc, ld, ldd, ld3)
                for i in range(p):
                    if hits[i]:
                        zero[i] = True
                        if ref < 0:
                            V = -_dot(W, i, ld)
            seg_f[n, 1] = t_ev
            n += 1
            tiny = t_ev - t0 <= _STALL_ULPS * _EPS * max(abs(t_ev), 1.0)
            guard = guard + 1 if tiny else 0
            t = t_ev
            if guard > _STALL_SEGMENTS:
                status = STALLED
                break
            if n_hit == 0 and not left and t >= ts:
                cache_ok = True     # ended on a smooth boundary: the next segment keeps the mode
                cache_a = a
            if k_next > 0 and t == k_next * T:
                # ---- period boundary (ExactSolver._period_boundary)
                same = ck_f[0] == k_next - 1 and ck_f[4] == ref
                if same:
                    for i in range(p):
                        if ck_contact[i] != contact[i] or ck_zero[i] != zero[i]:
                            same = False
                if same and ref < 0:
                    v_tol = 16.0 * (tol * v_acc + _EPS * (abs(V) + abs(ck_f[2])))
                    same = abs(V - ck_f[2]) <= v_tol
                if same and math.floor((t_end - t) / T * (1 + 4 * _EPS)) >= 1:
                    k_at = k_next
                    status = PERIODIC
                    break
                ck_f[0] = k_next
                ck_f[1] = X
                ck_f[2] = V
                ck_f[3] = x_ref
                ck_f[4] = ref
                ck_f[5] = n
                ck_f[6] = n_ev
                ck_f[7] = 1.0
                for i in range(p):
                    ck_K[i] = K[i]
                    ck_contact[i] = contact[i]
                    ck_zero[i] = zero[i]
        state[0] = t
        state[1] = X
        state[2] = V
        state[3] = x_ref
        state[4] = ref
        state[5] = guard
        state[6] = n
        state[7] = 1.0 if cache_ok else 0.0
        state[8] = cache_a
        state[9] = n_eval
        state[10] = n_ev
        state[11] = k_at
        return status


@njit(cache=True)
def gait_values(tau, kind, freq, mean, cosc, sinc, l, ld, ldd):
    """l, l' and l'' of a kernel gait at the times ``tau`` (rows of l, ld, ldd): the sampling
    of a run (``segments.evaluate_records``) without the numpy gait's dozen array operations."""
    ld3 = np.empty(l.shape[1])
    for k in range(tau.size):
        lengths(tau[k], kind, freq, mean, cosc, sinc, l[k])
        rates(tau[k], kind, freq, cosc, sinc, ld[k], ldd[k], ld3)


def coefficients(gait):
    """(kind, freq, P1, P2) of a Fourier / Sinusoid (kind FOURIER: cos and sin coefficients,
    shape (n_links, K)), Scallop (SCALLOP: rows amplitude, phase - pi r, c, s) or Cubic /
    PiecewiseCubic gait (CUBIC: rows of (l0, v0, a0, jerk) per linkage, and of (start, t0)
    per piece), or None."""
    from ..gaits import Cubic, Fourier, PiecewiseCubic, Scallop, Sinusoid
    cached = getattr(gait, '_kernel_coefficients', None)
    if cached is not None:
        return cached
    if type(gait) is Fourier:
        out = (FOURIER, gait.frequency, np.ascontiguousarray(gait.cos),
               np.ascontiguousarray(gait.sin))
    elif type(gait) is Sinusoid:
        # A sin(w t + phi) = A sin(phi) cos(w t) + A cos(phi) sin(w t)
        a = gait.amplitude
        out = (FOURIER, gait.frequency, (a * np.sin(gait.phase))[:, None].copy(),
               (a * np.cos(gait.phase))[:, None].copy())
    elif type(gait) is Scallop:
        n = gait.n_links
        rows = np.column_stack([gait.amplitude, gait.phase - math.pi * gait.asymmetry,
                                np.full(n, gait._c), np.full(n, gait._s)])
        out = (SCALLOP, gait.frequency, np.ascontiguousarray(rows), np.zeros((n, 1)))
    elif type(gait) in (Cubic, PiecewiseCubic):
        pieces = [gait] if type(gait) is Cubic else gait.pieces
        starts = [gait.t0] if type(gait) is Cubic else gait._starts
        coef = np.array([[x for row in pc._rows for x in row] for pc in pieces])
        out = (CUBIC, 1.0, coef, np.array([[st, pc.t0] for st, pc in zip(starts, pieces)]))
    else:
        return None
    gait._kernel_coefficients = out
    return out


def search(t0: float, end: float, rows, coef, B2, B1, tol: float, cap: float):
    """Run the compiled search; returns (t, hit rows as a bool array, number of evaluations)
    or (inf, empty, n)."""
    kind, freq, p1, p2 = coef
    return _search(float(t0), float(end), rows.c0, rows.c1, np.ascontiguousarray(rows.A1),
                   np.ascontiguousarray(rows.A2), kind, float(freq), p1, p2,
                   np.ascontiguousarray(B2, dtype=float), np.ascontiguousarray(B1, dtype=float),
                   float(tol), float(cap))


_WARM: set = set()


def warm(kind: tuple) -> bool:
    """Load (or compile) the search for one gait kind now with one tiny search, so the first
    real search of a real-time loop does not pay for it (about 0.1-1 s per process and kind
    with a warm disk cache). True if it was already loaded; the caller then loads ``drive``
    with a call that integrates nothing (``ExactSolver``: the argument types come from there)."""
    key = len(kind)        # a Custom kind holds a buffer: not hashable, and one type for all
    if key in _WARM:
        return True
    if key == 4:
        # a callback of zeros: the same compiled types, without calling the user's functions
        kind = (_ZEROS, np.zeros(6), 0, 0)
    one = np.ones(1)
    z = np.zeros((1, 1))
    _search(0.0, 1.0, one, one * 0.0, np.ones((1, 1)), z, kind, 1.0, z, z, one, one, 1e-13,
            1.0)
    _WARM.add(key)
    return False


_ZEROS = CALLBACK(lambda t, want: None)


def precompile() -> None:
    """Compile every kernel of the exact method, for each gait kind, into numba's disk cache
    (``make build`` runs it: the first compilation takes 10-20 s per kind, later processes load
    it in about a second)."""
    from ..gaits import Cubic, Custom, Fourier, Scallop
    from ..model import Crawler
    from ..stepper import simulate
    for gait in (Fourier(1.0, ([0.0], [0.3]), 1.0), Scallop(1.0, 0.3, 1.0, 0.3),
                 Cubic(0.0, [1.0], 0.3, 0.0, -0.1),
                 Custom(lambda t: 1.0 + 0.3 * math.sin(t), lambda t: 0.3 * math.cos(t),
                        lambda t: -0.3 * math.sin(t))):
        simulate(Crawler([1.0, 1.0], [0.5, 1.0]), gait, 2.0, t_eval=[0.0, 1.0, 2.0])
