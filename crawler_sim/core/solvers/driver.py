"""The exact method's segment loop compiled, for the gaits the kernel evaluates (``kernel``).

``ExactSolver._segment`` in Python costs about 0.2 ms per segment (numpy calls on arrays of p
entries), twenty times the event search itself. ``drive`` runs the same loop in numba for the
common segments and hands the rest back to Python, so the two paths share every rule:

* mode choice with at most one body at zero velocity (``ExactSolver._solve_mode_one``), or the
  mode kept from a smooth segment boundary;
* event rows ``vel`` and ``force`` (``ExactSolver._rows``), their bounds (``Rows.bounds``) and
  the compiled search (``kernel._search``);
* the closed-form end of a segment (``ExactSolver._close``).

It returns to Python (status ``NEED_PYTHON``) before a segment that needs more: two or more
bodies at zero velocity (groups, rigid links), a mode choice decided by look-ahead, a contact
sign contradicted by the velocity (after a jump of l'), a non-finite gait value. Segments are
written to flat arrays that ``ExactSolver`` turns into ``Segment`` objects.

Numbers: bounds of l''' and l'''' are those of the whole span [t, t_stop] of one call (a span
never crosses a gait breakpoint or a period boundary), computed by the gait in Python.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel import _search_ws, rates

REACHED, NEED_PYTHON, FULL, STALLED, NONFINITE, NO_STEPS, PERIODIC = 0, 1, 2, 3, 4, 5, 6
_EPS = 2.220446049250313e-16
_STALL_ULPS = 64
_STALL_SEGMENTS = 256
_AMBIGUOUS = 1e-10

if True:  # (one block, indented)
    @njit(cache=True)
    def lengths(t, kind, freq, mean, cosc, sinc, l):
        """l(t) of the kernel's gaits (the expressions of the gaits' ``_eval``)."""
        if kind == 2:
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
        if kind == 1:
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
