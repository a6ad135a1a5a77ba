"""The arithmetic of ``segments.evaluate_rows`` compiled: one loop over the sample rows.

``evaluate_rows`` gathers each row's segment constants and the gait values (one vectorised
gait call, any gait) and hands them to ``closed_form``, which applies the closed forms of
``Segment.evaluate`` row by row. The numpy version cost about 60 array operations whatever the
number of rows (0.2 ms for the two rows of a ``t_eval=[0, T]`` run, more than the exact
integration of ten periods).
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def closed_form(l, ld, ldd, W, C, m, fp, fm, fext, grav, f, ref_s, group_s, contact_s, Rseg,
                K0_s, owner, tau, x, v, R, K, lam, state, indeterminate):
    """Row k of the outputs (x, v, R = friction, K = impulse, lam = linkage force, state =
    contact, indeterminate) from the gait values at ``tau[k]`` and the constants of segment
    ``owner[k]`` of the table (``f`` rows (t0, X0, V0, a, x_ref), ``ref_s``, ``group_s``,
    ``contact_s``, ``Rseg``, ``K0_s``: ``segments.Records``), gathered here rather than by numpy
    fancy indexing (a dozen array operations per call); see ``segments.evaluate_records`` for
    the formulas and sign conventions."""
    n, p = x.shape
    nl = l.shape[1]
    M = 0.0
    for i in range(p):
        M += m[i]
    e = np.empty(p)
    ep = np.empty(p)
    epp = np.empty(p)
    for k in range(n):
        sg = owner[k]
        for i in range(p):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for j in range(nl):
                a0 += l[k, j] * W[i, j]
                a1 += ld[k, j] * W[i, j]
                a2 += ldd[k, j] * W[i, j]
            e[i] = a0
            ep[i] = a1
            epp[i] = a2
        d = tau[k] - f[sg, 0]
        r = ref_s[sg]
        if r < 0:
            X = f[sg, 1] + d * (f[sg, 2] + 0.5 * f[sg, 3] * d)
            V = f[sg, 2] + f[sg, 3] * d
            for i in range(p):
                x[k, i] = X + e[i]
                v[k, i] = V + ep[i]
            A = f[sg, 3]
        else:
            sr = 0.0
            sdr = 0.0
            for j in range(nl):
                sr += l[k, j] * C[r, j]
                sdr += ld[k, j] * C[r, j]
            for i in range(p):
                s = 0.0
                sd = 0.0
                for j in range(nl):
                    s += l[k, j] * C[i, j]
                    sd += ld[k, j] * C[i, j]
                x[k, i] = f[sg, 4] + (s - sr)
                v[k, i] = sd - sdr
            A = -epp[r]
            V = -ep[r]
        f_slide = 0.0
        n_group = 0
        for i in range(p):
            R[k, i] = 0.0 if group_s[sg, i] else Rseg[sg, i]
            f_slide += R[k, i]
            K[k, i] = K0_s[sg, i] + d * R[k, i]
            if group_s[sg, i]:
                n_group += 1
        f_slide += fext
        if r >= 0:
            # the group's friction: each member at the same fraction of its interval
            # (``contact.split_friction``), and its impulse, the integral of that split
            wg = 0.0
            fm_g = 0.0
            for i in range(p):
                if group_s[sg, i]:
                    wg += fp[i] + fm[i]
                    fm_g += fm[i]
            if wg > 0:
                total = M * A - f_slide
                theta = min(max((-total + fm_g) / wg, 0.0), 1.0)
                imp = M * (V - f[sg, 2]) - f_slide * d
                q = (-imp + fm_g * d) / wg
                for i in range(p):
                    if group_s[sg, i]:
                        w = fp[i] + fm[i]
                        R[k, i] = fm[i] - theta * w
                        K[k, i] = K0_s[sg, i] + (fm[i] * d - q * w)
            else:
                for i in range(p):
                    if group_s[sg, i]:
                        K[k, i] = K0_s[sg, i]
        acc = 0.0
        for i in range(p - 1):
            acc += R[k, i] + grav[i] - m[i] * (A + epp[i])
            lam[k, i] = acc
        for i in range(p):
            c = contact_s[sg, i]
            if fp[i] + fm[i] == 0.0:
                c = 1 if v[k, i] > 0 else (-1 if v[k, i] < 0 else 0)
            state[k, i] = c
        indeterminate[k] = n_group > 1
