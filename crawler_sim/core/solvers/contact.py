"""The one-dimensional monotone inclusion behind every method (MODEL.md sections 2.3 and 3).

Find the unique ``u`` with

    0  in  c (u - u_ref) - force + sum_i dphi_i(u - k_i),
    phi_i(w) = f_plus_i max(w, 0) + f_minus_i max(-w, 0),

a convex, piecewise-quadratic minimisation in one variable. With c = M/h, u = V_{k+1} it is the
implicit (Moreau-Jean) step; with c = M, u = the centre-of-mass acceleration and k_i = -e_i''
it selects the contact mode at an instant. Solved exactly by sorting the kinks k_i: O(p log p).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ['solve_inclusion', 'solve_inclusion_batch', 'split_friction']


def solve_inclusion(c: float, u_ref: float, force: float, kinks: NDArray, f_plus: NDArray,
                    f_minus: NDArray) -> tuple[float, float]:
    """Solve the inclusion for one crawler.

    Returns
    -------
    u : float
        The solution. Bodies with ``kinks == u`` (exactly) sit at their kink (stick).
    s : float
        Sum of dphi_i selections of the bodies at the kink [N]; 0 when none is.
    """
    n = kinks.size
    if n == 0:
        return u_ref + force / c, 0.0
    order = np.argsort(kinks, kind='stable')
    k = kinks[order]
    a = f_plus[order]
    b = f_minus[order]
    below_a = np.cumsum(a) - a            # sum of f_plus of kinks strictly before index
    above_b = b.sum() - (np.cumsum(b) - b)  # sum of f_minus of kinks at or after index
    g_low = c * (k - u_ref) - force + below_a - above_b
    g_high = g_low + a + b
    hit = np.nonzero(g_high >= 0.0)[0]
    if hit.size == 0:
        u = u_ref + (force - a.sum()) / c
    else:
        i = int(hit[0])
        u = float(k[i]) if g_low[i] <= 0.0 else u_ref + (force - below_a[i] + above_b[i]) / c
    at = k == u      # also when a free solution rounds onto a kink
    if not at.any():
        return u, 0.0
    # All bodies at this kink share it; their selections sum to s.
    base = c * (u - u_ref) - force + a[k < u].sum() - b[k > u].sum()
    lo, hi = -b[at].sum(), a[at].sum()
    return u, min(max(-base, lo), hi)


def split_friction(total: float | NDArray, f_plus: NDArray, f_minus: NDArray) -> NDArray:
    """Split a total dphi selection among bodies stuck together, each at the same fraction of
    its own interval [-f_minus_i, f_plus_i] (the documented choice; only the total is unique).

    ``total`` is a float or shape (N,); returns shape (n,) or (N, n).
    """
    width = f_plus + f_minus
    w = width.sum()
    lo = -f_minus.sum()
    theta = np.clip((np.asarray(total) - lo) / w, 0.0, 1.0) if w > 0 else np.zeros_like(
        np.asarray(total, dtype=float))
    return -f_minus + np.multiply.outer(theta, width)


def solve_inclusion_batch(c: NDArray, u_ref: NDArray, force: NDArray, kinks: NDArray,
                          f_plus: NDArray, f_minus: NDArray) -> tuple[NDArray, NDArray]:
    """Vectorised ``solve_inclusion`` for B crawlers with the same p.

    ``c``, ``u_ref``, ``force``: shape (B,); ``kinks``, ``f_plus``, ``f_minus``: shape (B, p).
    Returns ``(u, at_kink)`` with shapes (B,) and (B, p) bool.
    """
    B, p = kinks.shape
    order = np.argsort(kinks, axis=1)
    rows = np.arange(B)[:, None]
    k = kinks[rows, order]
    a = f_plus[rows, order]
    b = f_minus[rows, order]
    ca = np.cumsum(a, axis=1)
    cb = np.cumsum(b, axis=1)
    below_a = ca - a
    above_b = cb[:, -1:] - (cb - b)
    g_low = (c * (-u_ref) - force)[:, None] + c[:, None] * k + below_a - above_b
    g_high = g_low + a + b
    ok = g_high >= 0.0
    i = np.argmax(ok, axis=1)
    any_ok = ok[np.arange(B), i]
    i_safe = i
    gl = g_low[np.arange(B), i_safe]
    ki = k[np.arange(B), i_safe]
    free = u_ref + (force - below_a[np.arange(B), i_safe] + above_b[np.arange(B), i_safe]) / c
    right = u_ref + (force - ca[:, -1]) / c
    u = np.where(any_ok, np.where(gl <= 0.0, ki, free), right)
    at_kink = kinks == u[:, None]
    return u, at_kink
