"""An independent reference for the exact solver's tests: implicit Euler (catching-up) on the
centre-of-mass velocity, MODEL.md section 3, with Richardson extrapolation.

Written from the model, not from the solver: each step minimises the convex function
M/(2h) (V - V_k)^2 - F_ext V + sum_i phi_i(V + e_i'(t_{k+1})) by scanning its kinks (O(p^2),
p is small), in a numba loop over precomputed e_i'(t_k). First order in h; 2 x(h/2) - x(h)
removes the first-order term. Accuracy is checked against closed forms in the tests.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _run(ep, h, M, fext, fp, fm, V0):
    n, p = ep.shape
    V = V0
    X = 0.0
    out = np.empty(n)
    out[0] = 0.0
    for k in range(1, n):
        # subgradient of the step objective at V: M/h (V - Vk) - fext + sum dphi_i(V + ep_i)
        # sorted kinks -ep_i; find where it crosses zero
        best = 0.0
        found = False
        # candidate: every kink, and the smooth pieces between them
        kinks = np.sort(-ep[k])
        # slope-free value of the subgradient just left / right of a kink u
        for j in range(p + 1):
            # piece between kinks[j-1] and kinks[j]: signs known
            s = 0.0
            for i in range(p):
                u_i = -ep[k, i]
                if j < p and u_i >= kinks[j]:
                    s -= fm[i]          # V + ep_i < 0 on this piece: -f_minus
                elif j == p or u_i < kinks[j]:
                    s += fp[i]
            # M/h (V - Vk) - fext + s = 0
            cand = V + h / M * (fext - s)
            lo = kinks[j - 1] if j > 0 else -np.inf
            hi = kinks[j] if j < p else np.inf
            if lo <= cand <= hi:
                best = cand
                found = True
                break
        if not found:
            # the zero is at a kink
            for j in range(p):
                u = kinks[j]
                lo_s = 0.0
                hi_s = 0.0
                for i in range(p):
                    w = u + ep[k, i]
                    if w > 0:
                        lo_s += fp[i]
                        hi_s += fp[i]
                    elif w < 0:
                        lo_s -= fm[i]
                        hi_s -= fm[i]
                    else:
                        lo_s -= fm[i]
                        hi_s += fp[i]
                    # (ties: several bodies at the same kink)
                base = M / h * (u - V) - fext
                if base + lo_s <= 0.0 <= base + hi_s:
                    best = u
                    found = True
                    break
        X += h * best
        V = best
        out[k] = X
    return out


def com_path(crawler, ep_fn, t_end: float, h: float, v0: float = 0.0) -> tuple:
    """Centre-of-mass X(t) on the grid k h (X(0) = 0) with step h; ``ep_fn(t)`` returns the
    body offsets' rates e'(t), shape (N, p), for an array of times."""
    n = int(round(t_end / h)) + 1
    t = np.linspace(0.0, t_end, n)
    ep = ep_fn(t)
    V0 = v0 - ep[0, 0]
    X = _run(ep, t_end / (n - 1), crawler.total_mass, crawler.external_force,
             np.asarray(crawler.friction, float), np.asarray(crawler.friction_backward, float),
             V0)
    return t, X


def body0_displacement(crawler, gait, t_end: float, h: float, v0: float = 0.0) -> float:
    """x_0(t_end) - x_0(0) by implicit Euler with step h and Richardson (h, h/2)."""
    m = crawler.masses

    def ep_fn(t):
        ld = np.array([np.atleast_1d(gait(float(tk))[1]) for tk in t]) if not hasattr(
            gait, '_eval') else gait(t)[1]
        s = np.zeros((t.size, m.size))
        s[:, 1:] = np.cumsum(ld, axis=1)
        return s - (s @ (m / m.sum()))[:, None]

    def e0(t):
        l = gait(np.array([t]))[0][0]
        s = np.concatenate([[0.0], np.cumsum(l)])
        return float(-(s @ (m / m.sum())))

    de0 = e0(t_end) - e0(0.0)
    x = []
    for hh in (h, h / 2):
        _, X = com_path(crawler, ep_fn, t_end, hh, v0)
        x.append(X[-1] + de0)
    return 2.0 * x[1] - x[0], x
