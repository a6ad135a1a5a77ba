"""Audit any trajectory against the model: the seed's system (S_2) generalised to p bodies.

Sample checks (always):

* Momentum balance (line iii): M (V(t) - V(t0)) = F_ext (t - t0) + sum_i K_i(t), with V the
  centre-of-mass velocity and K_i the integrated ground force on body i (``impulse``).
* Friction law (lines iv-v): each reported ground force R_i is admissible for its body's velocity
  v_i, i.e. -R_i in dphi_i(v_i): R_i in [-f_plus_i, f_minus_i] and the dissipation gap
  phi_i(v_i) + R_i v_i (>= 0 for every admissible force) is zero (Fenchel equality).

Kinematic checks (when the gait is known: ``verify(tr, gait)``). These do not trust the friction
the solver reports (a solver clips it to the bound); they recompute what the kinematics require
(MODEL.md section 2). Between consecutive samples the contact history the trajectory claims
(its state at t0 and its ``events``) is replayed in closed form from the sampled centre-of-mass
state, and checked on a sub-grid of every piece between events:

* sliding bodies: v_i = V + e_i'(t) keeps the claimed sign (a missed stick or a late
  slide-to-stick event makes it cross zero), with V linear in t under the sliding forces;
* stuck bodies (a cluster C, V = -e_j'(t)): their velocity is zero when the stick starts, and the
  friction the momentum balance requires, F_C = F_ext - sum_{i not in C} F_i + M e_j''(t), stays in
  [-sum_C f_minus, sum_C f_plus] (a missed slip or a late release leaves it);
* at the next sample the replayed state equals the sampled one (``shooting``): a wrong mode or a
  shifted event changes the velocity the closed form reaches.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .model import kinematics
from .trajectory import Trajectory

if TYPE_CHECKING:
    from .gaits import Gait

__all__ = ['VerifyReport', 'verify']


@dataclass(frozen=True)
class VerifyReport:
    """Worst violations over the samples; ``*_rel`` are scaled to be dimensionless.

    momentum [N s]: worst momentum-balance residual; scale M max(|V|, |v_i|) + (|F_ext| + sum f) T.
    friction_bound [N]: worst excess of a reported ground force beyond its interval; scale max f.
    complementarity [W]: worst dissipation gap phi(v) + R v; scale max f * max|v|.
    stuck_velocity [m/s]: largest |v| of a body reported stuck (creep), at the samples and, with
    the gait, at the start of every claimed stick; scale max|v|.
    contact [-]: number of samples whose contact state contradicts the velocity sign by more
    than 1e-9 max|v| (rounding at an event time is allowed).
    slide_sign [m/s]: (gait known) largest velocity of a body claimed sliding one way but moving
    the other, between samples; scale max|v|.
    required_force [N]: (gait known) largest excess of the friction a stuck body (or cluster)
    requires beyond its admissible interval; scale max f + |F_ext| + M max|e''|.
    shooting [m/s], shooting_position [m]: (gait known) largest difference between the replayed
    and the sampled velocities / positions at the samples; scales max|v| and max|v| T.
    kinematic : whether the kinematic checks ran (a gait was given).
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
    slide_sign: float = 0.0
    slide_sign_rel: float = 0.0
    required_force: float = 0.0
    required_force_rel: float = 0.0
    shooting: float = 0.0
    shooting_rel: float = 0.0
    shooting_position: float = 0.0
    shooting_position_rel: float = 0.0
    kinematic: bool = False

    @property
    def worst(self) -> float:
        """Largest of the relative violations."""
        return max(self.momentum_rel, self.friction_bound_rel, self.complementarity_rel,
                   self.stuck_velocity_rel, self.slide_sign_rel, self.required_force_rel,
                   self.shooting_rel, self.shooting_position_rel)

    def ok(self, tol: float = 1e-9) -> bool:
        """True when every relative violation is at most ``tol`` and contacts are consistent."""
        return self.worst <= tol and self.contact == 0


SLIVER = 1e-12     # [s] a piece this short beside a breakpoint is not checked (see _kinematic)


def verify(trajectory: Trajectory, gait: Gait | None = None, *,
           substeps: int = 16) -> VerifyReport:
    """Measure how well ``trajectory`` satisfies the momentum balance and the friction law.

    ``gait`` (the one the trajectory was simulated with; default ``trajectory.info['gait']`` when
    present) switches on the kinematic checks, which flag missed, shifted or wrong events; each
    piece between events is checked at ``substeps`` points. They hold to rounding for the exact
    method; the time-stepping methods ("implicit", "penalty") show their O(dt) error in them.
    """
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
    # a contact state that contradicts the velocity, or the force: a body claimed sliding feels
    # its Coulomb force (-f_plus forward, +f_minus backward), even where its velocity is zero
    # (the instant it starts or stops)
    free = (fp == 0) & (fm == 0)
    coulomb = np.where(tr.contact > 0, -fp, fm)
    wrong_force = (tr.contact != 0) & ~free & (np.abs(R - coulomb) > 1e-9 * f_max)
    contact_bad = int(np.sum(((tr.contact > 0) & (v < -tiny)) | ((tr.contact < 0) & (v > tiny))
                             | wrong_force))
    stuck_v = float(np.abs(np.where(tr.contact == 0, v, 0.0)).max())
    rel = np.maximum.reduce([np.abs(mom) / mom_scale, excess.max(axis=1) / f_max,
                             gap.max(axis=1) / (f_max * v_max)])
    t_worst = float(tr.t[int(np.argmax(rel))])
    worst_sample = float(rel.max())
    kin = {}
    if gait is None:
        gait = tr.info.get('gait') if isinstance(tr.info, dict) else None
    if gait is not None and tr.t.size >= 2:
        kin = _kinematic(tr, gait, max(int(substeps), 1))
        v_max = max(v_max, kin['v_scale'])
        stuck_v = max(stuck_v, kin['stuck_velocity'])
        if kin['rel_worst'] > worst_sample:
            t_worst = kin['t_worst']
    T = float(max(dt[-1], 1e-300))
    f_scale = kin.get('f_scale', f_max)
    return VerifyReport(momentum=float(np.abs(mom).max()),
                        momentum_rel=float(np.abs(mom).max() / mom_scale),
                        friction_bound=float(excess.max()),
                        friction_bound_rel=float(excess.max() / f_max),
                        complementarity=float(gap.max()),
                        complementarity_rel=float(gap.max() / (f_max * v_max)),
                        stuck_velocity=stuck_v, stuck_velocity_rel=stuck_v / v_max,
                        contact=contact_bad, t_worst=t_worst,
                        slide_sign=kin.get('slide_sign', 0.0),
                        slide_sign_rel=kin.get('slide_sign', 0.0) / v_max,
                        required_force=kin.get('required_force', 0.0),
                        required_force_rel=kin.get('required_force', 0.0) / f_scale,
                        shooting=kin.get('shooting', 0.0),
                        shooting_rel=kin.get('shooting', 0.0) / v_max,
                        shooting_position=kin.get('shooting_position', 0.0),
                        shooting_position_rel=kin.get('shooting_position', 0.0) / (v_max * T),
                        kinematic=bool(kin))


def _kinematic(tr: Trajectory, gait, n_sub: int) -> dict:
    """Replay the claimed contact history between samples against the gait's kinematics."""
    c = tr.crawler
    m, M = c.masses, c.total_mass
    fp, fm, fext = c.friction, c.friction_backward, c.external_force
    t = tr.t
    X_s, V_s = tr.com, tr.com_velocity
    events = sorted((ev for ev in tr.events if t[0] < ev.time <= t[-1]), key=lambda e: e.time)
    ev_t = np.array([ev.time for ev in events])
    # pieces: consecutive times of the merged sample/event/breakpoint timeline, each with its
    # claimed mode; a breakpoint is a cut so that l'' is read on each piece's own side of it
    # (an event placed within the root tolerance of a breakpoint is at the breakpoint)
    breaks = np.asarray(gait.breakpoints(float(t[0]), float(t[-1])), float) \
        if hasattr(gait, 'breakpoints') else np.empty(0)
    cuts = np.union1d(np.union1d(t, ev_t), breaks)
    state = tr.contact[0].astype(int).copy()
    modes, k_ev = [], 0
    for ta in cuts[:-1]:
        while k_ev < len(events) and events[k_ev].time <= ta:
            state[events[k_ev].body] = events[k_ev].new
            k_ev += 1
        modes.append(state.copy())
    a_pts = cuts[:-1]
    b_pts = cuts[1:]
    frac = (np.arange(n_sub) + 0.5) / n_sub
    sub = a_pts[:, None] + (b_pts - a_pts)[:, None] * frac[None, :]
    # piece start (right limit), midpoints, and the end's left limit (one ulp before it, so a
    # gait breakpoint at the end reads the piece's own l'')
    end = np.nextafter(b_pts, -np.inf)[:, None]
    pts = np.concatenate([a_pts[:, None], sub, np.maximum(end, a_pts[:, None])], axis=1)
    l, ld, ldd = (np.asarray(arr, float) for arr in gait(pts.ravel()))
    e, ed, edd = (arr.reshape(pts.shape + (c.p,)) for arr in kinematics(m, l, ld, ldd))
    le, lde, _ = (np.asarray(arr, float) for arr in gait(t))
    e_s, ed_s, _ = kinematics(m, le, lde, lde)
    v_scale = float(max(np.abs(tr.v).max(), np.abs(ed).max(), 1e-300))
    f_scale = float(max(fp.max(), fm.max()) + abs(fext) + M * np.abs(edd).max()) or 1e-300
    sample_of = np.searchsorted(t, a_pts, side='right') - 1     # sample at or before each piece
    worst = dict(slide_sign=(0.0, 0.0), required_force=(0.0, 0.0), shooting=(0.0, 0.0),
                 shooting_position=(0.0, 0.0), stuck_velocity=(0.0, 0.0))
    scale = dict(slide_sign=v_scale, required_force=f_scale, shooting=v_scale,
                 shooting_position=v_scale * max(float(t[-1] - t[0]), 1e-300),
                 stuck_velocity=v_scale)

    def note(key: str, value: float, when: float) -> None:
        if value > worst[key][0]:
            worst[key] = (float(value), float(when))

    free = (fp == 0) & (fm == 0)
    X = V = None
    cur_sample = -1
    for k, (ta, tb, s) in enumerate(zip(a_pts, b_pts, modes)):
        if sample_of[k] != cur_sample and t[sample_of[k]] == ta:
            cur_sample = sample_of[k]
            X, V = float(X_s[cur_sample]), float(V_s[cur_sample])
        # a sliver between an event and a breakpoint within the root tolerance of each other
        # (1e-12 s: 10 times the exact method's default tol) holds no violation worth the name:
        # which side of the breakpoint its l'' is read on is rounding
        sliver = tb - ta <= SLIVER and (np.any(np.abs(breaks - ta) <= SLIVER)
                                          or np.any(np.abs(breaks - tb) <= SLIVER))
        # a frictionless body feels no friction whatever its claimed contact state (solvers
        # need not report its events): it is free, never part of a stick, no sign to check
        stuck = np.nonzero((s == 0) & ~free)[0]
        slide = np.nonzero((s != 0) & ~free)[0]
        force = np.where(free, 0.0, np.where(s > 0, fp, -fm))   # friction F_i of a sliding body
        taus = pts[k]
        if stuck.size == 0:
            acc = (fext - float(force.sum())) / M
            if slide.size and not sliver:
                Vt = V + acc * (taus - ta)
                vel = Vt[:, None] + ed[k][:, slide]
                note('slide_sign', float(np.max(-s[slide] * vel)), ta)
            dtb = tb - ta
            X, V = X + V * dtb + 0.5 * acc * dtb * dtb, V + acc * dtb
        else:
            j = int(stuck[0])
            if not sliver:
                note('stuck_velocity', abs(V + ed[k, 0, j]), ta)
                rel_v = ed[k][:, stuck] - ed[k][:, [j]]
                note('stuck_velocity', float(np.abs(rel_v).max()), ta)
                if slide.size:
                    vel = ed[k][:, slide] - ed[k][:, [j]]
                    note('slide_sign', float(np.max(-s[slide] * vel)), ta)
                F = fext - float(force[slide].sum()) + M * edd[k][:, j]
                up, dn = float(fp[stuck].sum()), float(fm[stuck].sum())
                note('required_force', float(np.max(np.maximum(F - up, -dn - F))), ta)
            # closed form to tb: x_j stays put, V = -e_j'(tb)
            ltb, ldtb, _ = (np.asarray(arr, float) for arr in gait(np.array([tb])))
            etb, edtb, _ = kinematics(m, ltb, ldtb, ldtb)
            X = X - (float(etb[0, j]) - float(e[k, 0, j]))
            V = -float(edtb[0, j])
        kb = sample_of[k] + 1
        if kb < t.size and t[kb] == tb:
            note('shooting', abs(V - V_s[kb]), tb)
            note('shooting_position', float(np.max(np.abs(X + e_s[kb] - tr.x[kb]))), tb)
    out = {key: val for key, (val, _) in worst.items()}
    rels = {key: worst[key][0] / scale[key] for key in worst}
    key = max(rels, key=rels.get)
    out.update(v_scale=v_scale, f_scale=f_scale, rel_worst=rels[key], t_worst=worst[key][1])
    return out
