"""Audit any trajectory against the model: the seed's system (S_2) generalised to p bodies.

* Momentum balance (line iii): M (V(t) - V(t0)) = F_ext (t - t0) + sum_i K_i(t), with V the
  centre-of-mass velocity and K_i the integrated ground force on body i (``impulse``).
* Friction law (lines iv-v): each ground force R_i is admissible for its body's velocity v_i,
  i.e. -R_i in dphi_i(v_i). Equivalently R_i in [-f_plus_i, f_minus_i] and the dissipation gap
  phi_i(v_i) + R_i v_i (>= 0 for every admissible force) is zero (Fenchel equality).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .trajectory import Trajectory

__all__ = ['VerifyReport', 'verify']


@dataclass(frozen=True)
class VerifyReport:
    """Worst violations over the samples; ``*_rel`` are scaled to be dimensionless.

    momentum [N s]: worst momentum-balance residual; scale M max(|V|, |v_i|) + (|F_ext| + sum f) T.
    friction_bound [N]: worst excess of a ground force beyond its interval; scale max f.
    complementarity [W]: worst dissipation gap phi(v) + R v; scale max f * max|v|.
    stuck_velocity [m/s]: largest |v| of a body reported stuck (creep); scale max|v|.
    contact [-]: number of samples whose contact state contradicts the velocity sign by more
    than 1e-9 max|v| (rounding at an event time is allowed).
    """

    momentum: float
    momentum_rel: float
    friction_bound: float
    friction_bound_rel: float
    complementarity: float
    complementarity_rel: float
    stuck_velocity: float
    stuck_velocity_rel: float
    contact: int
    t_worst: float

    @property
    def worst(self) -> float:
        """Largest of the relative violations."""
        return max(self.momentum_rel, self.friction_bound_rel, self.complementarity_rel,
                   self.stuck_velocity_rel)

    def ok(self, tol: float = 1e-9) -> bool:
        """True when every relative violation is at most ``tol`` and contacts are consistent."""
        return self.worst <= tol and self.contact == 0


def verify(trajectory: Trajectory) -> VerifyReport:
    """Measure how well ``trajectory`` satisfies the momentum balance and the friction law."""
    tr = trajectory
    c = tr.crawler
    M = c.total_mass
    fp, fm = c.friction, c.friction_backward
    V = tr.com_velocity
    dt = tr.t - tr.t[0]
    K = tr.impulse - tr.impulse[0]
    mom = M * (V - V[0]) - c.external_force * dt - K.sum(axis=1)
    f_max = float(max(fp.max(), fm.max(), 1e-300))
    v_max = float(max(np.abs(tr.v).max(), 1e-300))
    # momentum scale: the largest body momentum the gait or friction can produce
    mom_scale = M * max(float(np.abs(V).max()), v_max) + (abs(c.external_force) +
                                                          fp.sum() + fm.sum()) * float(dt[-1])
    R, v = tr.friction, tr.v
    excess = np.maximum(np.maximum(R - fm, -fp - R), 0.0)
    phi = fp * np.maximum(v, 0.0) + fm * np.maximum(-v, 0.0)
    gap = np.maximum(phi + R * v, 0.0)
    tiny = 1e-9 * v_max
    contact_bad = int(np.sum(((tr.state > 0) & (v < -tiny)) | ((tr.state < 0) & (v > tiny))))
    stuck_v = float(np.abs(np.where(tr.state == 0, v, 0.0)).max())
    rel = np.maximum.reduce([np.abs(mom) / mom_scale, excess.max(axis=1) / f_max,
                             gap.max(axis=1) / (f_max * v_max)])
    return VerifyReport(momentum=float(np.abs(mom).max()),
                        momentum_rel=float(np.abs(mom).max() / mom_scale),
                        friction_bound=float(excess.max()),
                        friction_bound_rel=float(excess.max() / f_max),
                        complementarity=float(gap.max()),
                        complementarity_rel=float(gap.max() / (f_max * v_max)),
                        stuck_velocity=stuck_v, stuck_velocity_rel=stuck_v / v_max,
                        contact=contact_bad, t_worst=float(tr.t[int(np.argmax(rel))]))
