"""Method "penalty": the seed's Moreau-Yosida regularisation (MODEL.md section 4).

Each friction law is replaced by the derivative of its Moreau-Yosida envelope,
R_i = -clip(n_i v_i, -f_minus_i, f_plus_i), giving an ODE with a Lipschitz right side whose
stiffness grows like n / M. It is integrated by backward Euler on the centre-of-mass velocity,

    M (V_{k+1} - V_k) / h = F_ext
                            - sum_i clip(n_i (V_{k+1} + e_i'(t_{k+1})), -f_minus_i, f_plus_i),

a strictly monotone piecewise-linear equation in V_{k+1} solved exactly (sorted breakpoints), so
the scheme is stable for any h and any n (n = 1e12 included).

A priori error (seed, Prop. 1 with the mass factor restored): for the exact ODE solution,
sup_{[0,t]} |V^n - V| <= sqrt(2 t / M * sum_i max(f_plus_i, f_minus_i)^2 / n_i).

No stiction: the regularisation is the derivative of a convex envelope, and a friction law
with static bounds above kinetic ones has no convex potential (STICTION.md s. 1, F1; a
Stribeck-type smoothing would select answers by its shape near v = 0, s. 9), so a crawler with
``has_stiction`` is refused (``STICTION_REFUSAL``).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..friction import bounds
from ..gaits import Gait
from ..model import Crawler
from . import _stepping
from .base import Capabilities, register
from .implicit import TimeStepper

__all__ = ['PenaltySolver', 'penalty_bound', 'check_penalty', 'STICTION_REFUSAL']

#: why method "penalty" refuses a crawler with static friction above kinetic (module doc)
STICTION_REFUSAL = ('the Moreau-Yosida regularisation has no stiction analogue: static above '
                    'kinetic friction has no convex potential to regularise')


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
    b = bounds(crawler)
    f = np.maximum(b.kinetic_forward, b.kinetic_backward)
    return np.sqrt(2.0 * np.asarray(t) / crawler.total_mass * np.sum(f ** 2 / n))


@register('penalty')
class PenaltySolver(TimeStepper):
    """Backward Euler on the penalised ODE, exact solve of each step's monotone equation
    (compiled: ``_stepping.StepCore.penalty_step``)."""

    capabilities = Capabilities(fixed_step=True, streaming=True)

    _method = _stepping.PENALTY
    method_name = 'penalty'
    #: why a crawler with stiction is refused (``stepper.check_stiction`` names it)
    stiction_refusal = STICTION_REFUSAL

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, penalty: ArrayLike,
                 t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        if crawler.has_stiction:
            raise ValueError(f"method 'penalty' cannot simulate static friction above kinetic "
                             f'(the crawler has static_friction > friction; '
                             f'{STICTION_REFUSAL})')
        self.n = check_penalty(penalty, crawler.p)
        super().__init__(crawler, gait, dt=dt, t0=t0, x0=x0, v0=v0, penalty=self.n)

    @classmethod
    def options(cls, *, dt: float | None = None, penalty: float | None = None,
                **_ignored: Any) -> dict:
        out = super().options(dt=dt)
        out['penalty'] = penalty
        return out

    def info(self, times: NDArray[np.float64]) -> dict:
        out = super().info(times)
        out['penalty'] = self.n.tolist()
        out['error_bound'] = penalty_bound(self.crawler, self.n, times)
        return out

    def bound(self, t: float) -> float:
        """The seed's a priori error bound at time t (elapsed from the start) [m/s]."""
        return float(penalty_bound(self.crawler, self.n, t))
