"""Method "penalty": the seed's Moreau-Yosida regularisation (MODEL.md section 4).

Each friction law is replaced by the derivative of its Moreau-Yosida envelope,
R_i = -clip(n_i v_i, -f_minus_i, f_plus_i), giving an ODE with a Lipschitz right side whose
stiffness grows like n / M. It is integrated by backward Euler on the centre-of-mass velocity,

    M (V_{k+1} - V_k) / h = F_ext - sum_i clip(n_i (V_{k+1} + e_i'(t_{k+1})), -f_minus_i, f_plus_i),

a strictly monotone piecewise-linear equation in V_{k+1} solved exactly (sorted breakpoints), so
the scheme is stable for any h and any n (n = 1e12 included).

A priori error (seed, Prop. 1 with the mass factor restored): for the exact ODE solution,
sup_{[0,t]} |V^n - V| <= sqrt(2 t / M * sum_i max(f_plus_i, f_minus_i)^2 / n_i).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..gaits import Gait
from ..model import Crawler
from .implicit import TimeStepper

__all__ = ['PenaltySolver', 'penalty_bound', 'check_penalty']


def check_penalty(penalty: ArrayLike | None, p: int) -> NDArray[np.float64]:
    """Validate the seed's n: one float for every body or one per body, finite and > 0 [N s/m]."""
    if penalty is None:
        raise ValueError('penalty (the seed\'s n, finite and > 0 N s/m) is required for '
                         'method="penalty"')
    n = np.atleast_1d(np.asarray(penalty, dtype=float))
    if n.ndim != 1 or n.size not in (1, p):
        raise ValueError(f'penalty must be one float or {p} floats (one per body), got {n.size}')
    if not np.all(np.isfinite(n) & (n > 0)):
        raise ValueError(f'penalty must be finite and > 0 N s/m, got {n.tolist()}')
    return np.full(p, n[0]) if n.size == 1 else n


def penalty_bound(crawler: Crawler, penalty: ArrayLike, t: float | NDArray) -> float | NDArray:
    """The seed's a priori bound on |V^n(t) - V(t)| [m/s] (centre-of-mass and every body)."""
    n = check_penalty(penalty, crawler.p)
    f = np.maximum(crawler.friction, crawler.friction_backward)
    return np.sqrt(2.0 * np.asarray(t) / crawler.total_mass * np.sum(f ** 2 / n))


class PenaltySolver(TimeStepper):
    """Backward Euler on the penalised ODE, exact solve of each step's monotone equation."""

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, penalty: ArrayLike,
                 t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        self.n = check_penalty(penalty, crawler.p)
        super().__init__(crawler, gait, dt=dt, t0=t0, x0=x0, v0=v0)

    def _velocity(self, h: float, ep: NDArray):
        n, fp, fm = self.n, self._fp, self._fm
        c = self._M / h
        rhs0 = c * self.V + self._fext
        # G(V) = c V - rhs0 + sum clip(n (V + ep), -fm, fp): increasing, piecewise linear.
        brk = np.sort(np.concatenate([-ep + fp / n, -ep - fm / n]))

        def G(V: NDArray) -> NDArray:
            return c * V - rhs0 + np.clip(np.multiply.outer(V, n) + n * ep, -fm, fp).sum(axis=-1)

        g = G(brk)
        k = int(np.searchsorted(g, 0.0))   # first breakpoint with G >= 0
        if k < brk.size and g[k] == 0.0:
            V_new = float(brk[k])
        else:
            # locate the linear piece, then solve it in closed form (accurate for huge n)
            if k == 0:
                probe = brk[0] - 1.0
            elif k == brk.size:
                probe = brk[-1] + 1.0
            else:
                probe = 0.5 * (brk[k - 1] + brk[k])
            w = n * (probe + ep)
            lin = (w > -fm) & (w < fp)
            sat = np.where(w >= fp, fp, np.where(w <= -fm, -fm, 0.0))
            V_new = float((rhs0 - sat[~lin].sum() - np.sum(n[lin] * ep[lin])) /
                          (c + n[lin].sum()))
        v = V_new + ep
        nv = n * v
        F = np.clip(nv, -fm, fp)
        # saturated = sliding; inside the linear zone the regularised body counts as stuck
        contact = np.where((nv >= fp) & (v > 0), 1, np.where((nv <= -fm) & (v < 0), -1, 0))
        contact = contact.astype(np.int8)
        return V_new, -F, contact

    def bound(self, t: float) -> float:
        """The seed's a priori error bound at time t (elapsed from the start) [m/s]."""
        return float(penalty_bound(self.crawler, self.n, t))

