"""Audit any trajectory against the model: the seed's system (S_2) generalised to p bodies.

Sample checks (always):

* Momentum balance (line iii): M (V(t) - V(t0)) = F_ext (t - t0) + sum_i K_i(t), with V the
  centre-of-mass velocity and K_i the integrated ground force on body i (``impulse``).
* Friction law (lines iv-v; with stiction STICTION.md s.1, bounds from ``core.friction``): each
  reported ground force R_i is admissible for its body's velocity v_i: a stuck body's inside its
  static interval [-static_forward_i, static_backward_i], a sliding body's at its kinetic value
  (``contact``), and the dissipation gap phi_i(v_i) + R_i v_i (phi the kinetic potential) is
  zero (Fenchel equality). Without stiction the static bounds are the kinetic ones.

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
  shifted event changes the velocity the closed form reaches;
* with stiction (``Crawler.has_stiction``), the selection rule at every event and at the start
  (``rule_s``, STICTION.md s.5): the bodies at rest there are grouped into clusters rigid just
  after it, each a stick candidate when the force it needs (the others sliding their way) is
  inside its static interval. Rule S holds a cluster when one can hold: an incumbent (stuck on
  the piece before) first with ``stiction_rule='incumbent'``, else the largest static margin.
  A run that lets bodies slide (or holds a worse candidate) where a candidate could hold is
  flagged by that candidate's margin: a breakaway before the static bound, a body sliding on
  after arriving where it could stick, kinetic answers on a crawler with stiction. A breakaway
  at the bound has margin 0 and passes. At the start the incumbent is not known (``initial_
  stuck``): there only "nothing held where something could" is flagged.

Every check is judged beyond the rounding of the quantities it compares, estimated from their
sizes (``verify``: positions of ~1 m, times of ~1e4 s, a sampled gait's pieces), so a correct
run passes at any amplitude, frequency or horizon; a wrong history differs by far more.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .friction import (DEFAULT_RULE, Bounds, bounds, check_rule, dissipation, kinetic_force,
                       required_constants, stuck_interval)
from .gaits.base import BREAK_ULPS
from .model import kinematics
from .trajectory import Trajectory

if TYPE_CHECKING:
    from .gaits import Gait

__all__ = ['VerifyReport', 'verify']


_EPS = float(np.finfo(float).eps)

# A comparison's rounding allowance: this many roundings (eps) of the largest terms it combines
# (module doc). A correct run's differences are a few; a wrong event moves them by orders more.
ROUNDING = 16
SAMPLED = 64       # a sampled gait's pieces hold its values to 64 eps (``solvers.proxy``)


@dataclass(frozen=True)
class VerifyReport:
    """Worst violations over the samples. The plain fields are the largest raw differences;
    each ``*_rel`` is the largest part of a difference beyond the rounding of the quantities it
    compares (``verify``), over the check's scale (dimensionless; ``ok`` compares them).

    momentum [N s]: worst momentum-balance residual; scale M max(|V|, |v_i|) + (|F_ext| + sum f) T.
    friction_bound [N]: worst excess of a reported ground force beyond its interval; scale max f.
    complementarity [W]: worst dissipation gap phi(v) + R v; scale max f * max|v|.
    stuck_velocity [m/s]: largest |v| of a body reported stuck (creep), at the samples and, with
    the gait, at the start of every claimed stick; scale max|v|.
    contact [-]: number of samples whose contact state contradicts the velocity sign by more
    than 1e-9 max|v| plus a velocity's rounding (rounding at an event time is allowed), or whose
    sliding body does not feel its Coulomb force.
    slide_sign [m/s]: (gait known) largest velocity of a body claimed sliding one way but moving
    the other, between samples; scale max|v|.
    required_force [N]: (gait known) largest excess of the friction a stuck body (or cluster)
    requires beyond its admissible interval; scale max f + |F_ext| + M max|e''|.
    shooting [m/s], shooting_position [m]: (gait known) largest difference between the replayed
    and the sampled velocities / positions at the samples; scales max|v| and max|v| T.
    rule_s [N]: (gait known, crawler with stiction) largest static margin of a stick candidate
    the selection rule would have held at an event or the start, beyond the one the run chose
    (module doc); scale that of ``required_force``.
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
    rule_s: float = 0.0
    rule_s_rel: float = 0.0
    kinematic: bool = False

    @property
    def worst(self) -> float:
        """Largest of the relative violations."""
        return max(self.momentum_rel, self.friction_bound_rel, self.complementarity_rel,
                   self.stuck_velocity_rel, self.slide_sign_rel, self.required_force_rel,
                   self.shooting_rel, self.shooting_position_rel, self.rule_s_rel)

    def ok(self, tol: float = 1e-9) -> bool:
        """True when every relative violation is at most ``tol`` and contacts are consistent."""
        return self.worst <= tol and self.contact == 0


EVENT_TOL = 1e-13  # [s] the exact method's default event-time tolerance (``Stepper`` tol)
SLIVER = 10 * EVENT_TOL   # [s] a piece this short beside a breakpoint or between events: unchecked


def verify(trajectory: Trajectory, gait: Gait | None = None, *,
           substeps: int = 16, stiction_rule: str | None = None) -> VerifyReport:
    """Measure how well ``trajectory`` satisfies the momentum balance and the friction law.

    ``gait`` (the one the trajectory was simulated with; default ``trajectory.info['gait']`` when
    present) switches on the kinematic checks, which flag missed, shifted or wrong events; each
    piece between events is checked at ``substeps`` points. They hold to rounding for the exact
    method; the time-stepping methods ("implicit", "penalty") show their O(dt) error in them.
    ``stiction_rule`` ('incumbent' or 'margin', ``core.friction.RULES``) is the rule a crawler
    with stiction is audited against (``rule_s``); default the trajectory's
    ``info['stiction_rule']`` when present, else 'incumbent' (Rule S).

    Every difference is judged beyond the rounding of what it compares (``ROUNDING`` eps of the
    largest terms): an event's time is only known to eps |t| and the exact method's tolerance
    ``EVENT_TOL`` (dt), so a velocity is known to eps max|v| + a dt, a = (|F_ext| + sum f) / M +
    max|e''| the largest acceleration, a position to eps max|x| + max|v| dt, a required force to
    eps (its scale) + M max|e'''| dt; a gait's rates to eps |l| / tau (tau its period, else the
    run; 64 times that for a gait sampled into pieces); the replay between two samples adds the
    rounding of each of its steps, and the impulses that of their sums over the events. Pieces
    inside a run of events closer than ``SLIVER`` (modes flipped and back within the event
    tolerance) are not checked, their velocity change counted as rounding. A correct run at any
    amplitude, frequency or horizon then reads 0 where its differences are rounding (a 1e-9 m
    stroke at x ~ 1 m, a run of 1e5 s).
    """
    tr = trajectory
    c = tr.crawler
    M = c.total_mass
    b = bounds(c)
    fp, fm, fext = b.kinetic_forward, b.kinetic_backward, c.external_force
    sp, sm = b.static_forward, b.static_backward       # the kinetic ones without stiction
    info = tr.info if isinstance(tr.info, dict) else {}
    rule = check_rule(stiction_rule if stiction_rule is not None
                      else info.get('stiction_rule', DEFAULT_RULE))
    t, v, R = tr.t, tr.v, tr.friction
    V = tr.com_velocity
    dt = t - t[0]
    K = tr.impulse - tr.impulse[0]
    mom = M * (V - V[0]) - fext * dt - K.sum(axis=1)
    f_max = float(max(sp.max(), sm.max(), 1e-300))
    v_max = float(max(np.abs(v).max(), 1e-300))
    # momentum scale: the largest body momentum the gait or friction can produce
    mom_scale = M * max(float(np.abs(V).max()), v_max) + (abs(fext) +
                                                          fp.sum() + fm.sum()) * float(dt[-1])
    if gait is None:
        gait = tr.info.get('gait') if isinstance(tr.info, dict) else None
    kin = (_kinematic(tr, gait, max(int(substeps), 1), rule) if gait is not None and t.size >= 2
           else {})
    v_max = max(v_max, kin.get('v_scale', 0.0))
    u = ROUNDING * _EPS
    t_abs = float(np.abs(t).max())
    a_scale = max(_sampled_acceleration(tr), kin.get('a_scale', 0.0))
    # a velocity's rounding: an event's time is known to eps |t| and the search's tolerance
    dv = u * v_max + a_scale * (u * t_abs + EVENT_TOL)
    # the impulses are sums over the events (rounding grows like the root of their number)
    n_sums = 1.0 + math.sqrt(len(tr.events))
    mom_floor = M * dv + u * (M * (np.abs(V) + abs(V[0])) + abs(fext) * np.abs(dt)
                     + n_sums * (np.abs(tr.impulse).sum(axis=1) + np.abs(tr.impulse[0]).sum()))
    # a stuck body's force may reach its static bound; a sliding one's is checked at its
    # kinetic value below (``wrong_force``), inside the static interval too
    excess = np.maximum(np.maximum(R - sm, -sp - R), 0.0)
    phi = dissipation(b, v)
    gap = np.maximum(phi + R * v, 0.0)
    tiny = 1e-9 * v_max + dv
    # a contact state that contradicts the velocity, or the force: a body claimed sliding feels
    # its Coulomb force (-f_plus forward, +f_minus backward), even where its velocity is zero
    # (the instant it starts or stops)
    free = (fp == 0) & (fm == 0)
    coulomb = kinetic_force(b, tr.contact)
    wrong_force = (tr.contact != 0) & ~free & (np.abs(R - coulomb) > 1e-9 * f_max + u * f_max)
    contact_bad = int(np.sum(((tr.contact > 0) & (v < -tiny)) | ((tr.contact < 0) & (v > tiny))
                             | wrong_force))
    stuck_abs = np.abs(np.where(tr.contact == 0, v, 0.0)).max(axis=1)
    beyond = {'momentum': np.maximum(np.abs(mom) - mom_floor, 0.0) / mom_scale,
              'friction_bound': np.maximum(excess.max(axis=1) - u * f_max, 0.0) / f_max,
              # a stuck body's velocity is rounding, and so is its gap (f + |R|) |v|
              'complementarity': np.maximum(gap.max(axis=1) - 2.0 * f_max * dv, 0.0)
              / (f_max * v_max),
              'stuck_velocity': np.maximum(stuck_abs - dv, 0.0) / v_max}
    rel = {key: float(val.max()) for key, val in beyond.items()}
    worst_sample = max(rel.values())
    key = max(beyond, key=lambda k: rel[k])
    t_worst = float(t[int(np.argmax(beyond[key]))])
    stuck_v = float(stuck_abs.max())
    if kin:
        stuck_v = max(stuck_v, kin['stuck_velocity'])
        rel['stuck_velocity'] = max(rel['stuck_velocity'], kin['beyond']['stuck_velocity'] / v_max)
        if kin['rel_worst'] > worst_sample:
            t_worst = kin['t_worst']
    T = float(max(dt[-1], 1e-300))
    f_scale = kin.get('f_scale', f_max)
    beyond_kin = kin.get('beyond', {})
    return VerifyReport(momentum=float(np.abs(mom).max()), momentum_rel=rel['momentum'],
                        friction_bound=float(excess.max()),
                        friction_bound_rel=rel['friction_bound'],
                        complementarity=float(gap.max()),
                        complementarity_rel=rel['complementarity'],
                        stuck_velocity=stuck_v, stuck_velocity_rel=rel['stuck_velocity'],
                        contact=contact_bad, t_worst=t_worst,
                        slide_sign=kin.get('slide_sign', 0.0),
                        slide_sign_rel=beyond_kin.get('slide_sign', 0.0) / v_max,
                        required_force=kin.get('required_force', 0.0),
                        required_force_rel=beyond_kin.get('required_force', 0.0) / f_scale,
                        shooting=kin.get('shooting', 0.0),
                        shooting_rel=beyond_kin.get('shooting', 0.0) / v_max,
                        shooting_position=kin.get('shooting_position', 0.0),
                        shooting_position_rel=beyond_kin.get('shooting_position', 0.0)
                        / (v_max * T),
                        rule_s=kin.get('rule_s', 0.0),
                        rule_s_rel=beyond_kin.get('rule_s', 0.0) / f_scale,
                        kinematic=bool(kin))


def _sampled_acceleration(tr: Trajectory) -> float:
    """The largest acceleration [m/s^2] the samples show: the centre's under the whole friction
    and F_ext, plus the bodies' mean acceleration between samples far enough apart for their
    velocities' difference not to be rounding (the gait's own e'' adds to it when known)."""
    c = tr.crawler
    b = bounds(c)
    a = (abs(c.external_force) + float(b.kinetic_forward.sum() + b.kinetic_backward.sum())) / \
        c.total_mass
    h = np.diff(tr.t)
    wide = h > 1e6 * _EPS * np.maximum(np.abs(tr.t[1:]), 1e-300)
    if wide.any():
        a += float((np.abs(np.diff(tr.v, axis=0))[wide] / h[wide, None]).max())
    return a


def _inside(t: NDArray[np.float64], other: NDArray[np.float64]) -> NDArray[np.float64]:
    """Piece ends ``t`` moved ``BREAK_ULPS`` float spacings towards the pieces' other ends
    ``other`` (at most to their middles): l'' read there belongs to the piece, also beside a
    breakpoint listed within that rounding of its jump (as the sampler reads it)."""
    h = BREAK_ULPS * np.spacing(np.abs(t))
    mid = 0.5 * (t + other)
    return np.where(other > t, np.minimum(t + h, mid), np.maximum(t - h, mid))


def _kinematic(tr: Trajectory, gait, n_sub: int, rule: str = DEFAULT_RULE) -> dict:
    """Replay the claimed contact history between samples against the gait's kinematics: the
    largest raw difference of each check, and (``beyond``) the largest part beyond its
    rounding, which the replay carries along its steps (``verify``)."""
    c = tr.crawler
    m, M = c.masses, c.total_mass
    b = bounds(c)
    fp, fm, fext = b.kinetic_forward, b.kinetic_backward, c.external_force
    sp, sm = b.static_forward, b.static_backward       # the kinetic ones without stiction
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
    # pieces inside a run of events less than SLIVER apart (see ``sliver`` below)
    prev_ev = np.searchsorted(ev_t, a_pts, side='right') - 1
    next_ev = np.searchsorted(ev_t, b_pts, side='left')
    inside = (prev_ev >= 0) & (next_ev < ev_t.size)
    flips = np.zeros(a_pts.size, bool)
    flips[inside] = ev_t[next_ev[inside]] - ev_t[prev_ev[inside]] <= SLIVER
    frac = (np.arange(n_sub) + 0.5) / n_sub
    sub = a_pts[:, None] + (b_pts - a_pts)[:, None] * frac[None, :]
    # each piece read just inside its ends (``_inside``), so a gait breakpoint there reads the
    # piece's own l''
    pts = np.concatenate([_inside(a_pts, b_pts)[:, None], sub, _inside(b_pts, a_pts)[:, None]],
                         axis=1)
    l, ld, ldd = (np.asarray(arr, float) for arr in gait(pts.ravel()))
    e, ed, edd = (arr.reshape(pts.shape + (c.p,)) for arr in kinematics(m, l, ld, ldd))
    le, lde, _ = (np.asarray(arr, float) for arr in gait(t))
    e_s, ed_s, _ = kinematics(m, le, lde, lde)
    v_scale = float(max(np.abs(tr.v).max(), np.abs(ed).max(), 1e-300))
    f_scale = float(max(sp.max(), sm.max()) + abs(fext) + M * np.abs(edd).max()) or 1e-300
    # rounding scales: the largest acceleration (the centre's under friction and F_ext, plus
    # e''), e''' (for the required force; from the gait's bound or the points of each piece,
    # which lie on one side of every breakpoint), the largest |x|
    a_scale = (abs(fext) + float(fp.sum() + fm.sum())) / M + float(np.abs(edd).max())
    j_scale = _jerk_scale(gait, float(t[0]), float(t[-1]), pts, edd)
    x_abs = float(max(np.abs(tr.x).max(), np.abs(e).max()))
    u = ROUNDING * _EPS
    # a gait's lengths are known to eps |l|, so over its time scale (its period, else the run)
    # its rates to eps |l| / tau and its l'' to eps |l| / tau^2; a gait of Python functions is
    # sampled to 64 times that (``solvers.proxy``, cheb_fit's rounding: a 1e-9 m stroke of a
    # 1 m linkage is resolved to about 1e-6 of its l'')
    tau = float(getattr(gait, 'period', None) or 0.0) or max(float(t[-1] - t[0]), 1e-300)
    l_rate = float(np.abs(l).max()) / tau * (SAMPLED if _sampled(gait) else 1.0)
    sample_of = np.searchsorted(t, a_pts, side='right') - 1     # sample at or before each piece
    keys = ('slide_sign', 'required_force', 'shooting', 'shooting_position', 'stuck_velocity',
            'rule_s')
    worst = dict.fromkeys(keys, 0.0)
    beyond = {key: (0.0, 0.0) for key in keys}
    scale = dict(slide_sign=v_scale, required_force=f_scale, shooting=v_scale,
                 shooting_position=v_scale * max(float(t[-1] - t[0]), 1e-300),
                 stuck_velocity=v_scale, rule_s=f_scale)
    # the instants where the selection rule decides (stiction only): the events and the start
    decisions = set(ev_t.tolist()) | {float(t[0])} if c.has_stiction else set()

    def note(key: str, value: float, floor: float, when: float) -> None:
        worst[key] = max(worst[key], float(value))
        if value - floor > beyond[key][0]:
            beyond[key] = (float(value - floor), float(when))

    free = (fp == 0) & (fm == 0)
    X = V = None
    rx = rv = 0.0               # the replayed X's and V's rounding so far [m], [m/s]
    cur_sample = -1
    for k, (ta, tb, s) in enumerate(zip(a_pts, b_pts, modes)):
        if sample_of[k] != cur_sample and t[sample_of[k]] == ta:
            cur_sample = sample_of[k]
            X, V = float(X_s[cur_sample]), float(V_s[cur_sample])
            rx, rv = u * x_abs, u * v_scale
        # a velocity, a position and a force read at a time of size |t| (known to eps |t|)
        # (and the event search's tolerance): an event moved by dt_t moves V by a dt_t
        dt_t = u * max(abs(float(ta)), abs(float(tb))) + EVENT_TOL
        dv_t = u * (v_scale + l_rate) + a_scale * dt_t
        # a sliver (1e-12 s: 10 times the exact method's default tol) beside a breakpoint, or
        # inside a run of events that close (modes flipped and back within the event search's
        # tolerance, as where several bodies switch at one instant, or a sampled gait's
        # velocity touches zero), holds no violation worth the name: its mode, or the side of
        # the breakpoint its l'' is read on, is rounding, and so is its velocity change (a h)
        sliver = flips[k] or (tb - ta <= SLIVER and (np.any(np.abs(breaks - ta) <= SLIVER)
                                                      or np.any(np.abs(breaks - tb) <= SLIVER)))
        # a frictionless body feels no friction whatever its claimed contact state (solvers
        # need not report its events): it is free, never part of a stick, no sign to check
        stuck = np.nonzero((s == 0) & ~free)[0]
        slide = np.nonzero((s != 0) & ~free)[0]
        force = np.where(free, 0.0, -kinetic_force(b, s))   # F_i = -ground force, sliding
        taus = pts[k]
        dtb = tb - ta
        if float(ta) in decisions and not sliver:
            # e', e'' just inside the piece (its own side of a breakpoint): the t+ data
            f_floor = u * (f_scale + M * l_rate / tau) + M * j_scale * dt_t
            held = _rule_s(b, M, fext, V, ed[k, 0], edd[k, 0], s,
                           modes[k - 1] if k > 0 else None, free, rv + dv_t,
                           u * float(np.abs(edd[k, 0]).max()) + u, rule)
            note('rule_s', held, f_floor, ta)
        if stuck.size == 0:
            acc = (fext - float(force.sum())) / M
            if slide.size and not sliver:
                Vt = V + acc * (taus - ta)
                vel = Vt[:, None] + ed[k][:, slide]
                note('slide_sign', float(np.max(-s[slide] * vel)), rv + dv_t, ta)
            rx += u * (abs(X) + abs(V) * dtb + abs(acc) * dtb * dtb) + v_scale * dt_t
            rv += u * (abs(V) + abs(acc) * dtb) + dv_t + (a_scale * dtb if sliver else 0.0)
            X, V = X + V * dtb + 0.5 * acc * dtb * dtb, V + acc * dtb
        else:
            j = int(stuck[0])
            if not sliver:
                note('stuck_velocity', abs(V + ed[k, 0, j]), rv + dv_t, ta)
                rel_v = ed[k][:, stuck] - ed[k][:, [j]]
                note('stuck_velocity', float(np.abs(rel_v).max()), dv_t, ta)
                if slide.size:
                    vel = ed[k][:, slide] - ed[k][:, [j]]
                    note('slide_sign', float(np.max(-s[slide] * vel)), dv_t, ta)
                F = fext - float(force[slide].sum()) + M * edd[k][:, j]
                up, dn = float(sp[stuck].sum()), float(sm[stuck].sum())   # static
                note('required_force', float(np.max(np.maximum(F - up, -dn - F))),
                     u * (f_scale + M * l_rate / tau) + M * j_scale * dt_t, ta)
            # closed form to tb: x_j stays put, V = -e_j'(tb)
            ltb, ldtb, _ = (np.asarray(arr, float) for arr in gait(np.array([tb])))
            etb, edtb, _ = kinematics(m, ltb, ldtb, ldtb)
            X = X - (float(etb[0, j]) - float(e[k, 0, j]))
            V = -float(edtb[0, j])
            rx += u * (abs(X) + x_abs) + v_scale * dt_t
            rv = dv_t
        kb = sample_of[k] + 1
        if kb < t.size and t[kb] == tb:
            note('shooting', abs(V - V_s[kb]), rv + dv_t, tb)
            note('shooting_position', float(np.max(np.abs(X + e_s[kb] - tr.x[kb]))),
                 rx + u * x_abs + v_scale * dt_t, tb)
    rels = {key: beyond[key][0] / scale[key] for key in keys}
    key = max(rels, key=rels.get)
    return dict(worst, beyond={key: val for key, (val, _) in beyond.items()}, v_scale=v_scale,
                f_scale=f_scale, a_scale=a_scale, rel_worst=rels[key], t_worst=beyond[key][1])


def _sampled(gait) -> bool:
    """Whether the solvers read ``gait`` from sampled pieces (a gait of Python functions)."""
    from .solvers.proxy import ChebTable
    compiled = getattr(gait, 'compiled', None)
    return callable(compiled) and isinstance(getattr(compiled(), 'table', None), ChebTable)


def _jerk_scale(gait, t0: float, t1: float, pts: NDArray[np.float64],
                edd: NDArray[np.float64]) -> float:
    """A scale of |e'''| [m/s^3] on [t0, t1]: the gait's ``jerk_bound`` (e''' is l''' weighted
    by mass shares, each at most 1) where it gives one, else twice the largest slope of e''
    between the points of a piece (on one side of every breakpoint) far enough apart for the
    difference of e'' not to be rounding."""
    bound = gait.jerk_bound(t0, t1) if hasattr(gait, 'jerk_bound') else None
    if bound is not None and np.all(np.isfinite(bound)):
        return float(np.sum(bound))
    h = np.diff(pts, axis=1)
    wide = h > 1e6 * _EPS * np.maximum(np.abs(pts[:, 1:]), 1e-300)
    if not wide.any():
        return 0.0
    slope = np.abs(np.diff(edd, axis=1)).max(axis=2)[wide] / h[wide]
    return 2.0 * float(slope.max())


def _rule_s(b: Bounds, M: float, fext: float, V: float, ed: NDArray[np.float64],
            edd: NDArray[np.float64], after: NDArray, before: NDArray | None,
            free: NDArray[np.bool_], tol_v: float, tol_a: float, rule: str) -> float:
    """How far the mode ``after`` an instant departs from the selection rule there [N]: the
    static margin of the stick candidate the rule would hold, beyond that of the one the run
    holds (0 when the run holds it, or when no candidate can hold: the kinetic slide pattern is
    then the answer and the other checks judge it). ``ed``, ``edd``: e', e'' at the instant's
    right side [m/s, m/s^2]; V the centre of mass's velocity; ``before`` the mode on the piece
    before (None at the start: no incumbent known, only "nothing held where a candidate could"
    is judged). Candidates and margins from ``core.friction`` (module doc)."""
    vel = V + ed
    rest = np.nonzero((np.abs(vel) <= tol_v) & ~free)[0]
    if rest.size == 0:
        return 0.0
    # clusters of the bodies at rest that stay rigid just after: equal e' and e''
    cluster = {}
    for i in rest:
        for r in cluster:
            if abs(ed[i] - ed[r]) <= tol_v and abs(edd[i] - edd[r]) <= tol_a:
                cluster[r].append(int(i))
                break
        else:
            cluster[int(i)] = [int(i)]
    stuck_after = [int(i) for i in rest if after[i] == 0]
    chosen, candidates = None, []
    for r, members in cluster.items():
        sig = np.where(vel > 0, 1, -1)
        for j in rest:
            if j not in members:
                d = edd[j] - edd[r]
                sig[j] = 1 if (d if abs(d) > tol_a else ed[j] - ed[r]) > 0 else -1
        need = -M * float(edd[r]) + required_constants(b, members, sig, fext)
        lo, hi = stuck_interval(b, members)
        margin = min(need - lo, hi - need)
        incumbent = before is not None and bool(np.any(before[members] == 0))
        if stuck_after and stuck_after[0] in members:
            chosen = (margin, incumbent)
        if margin >= 0.0:
            candidates.append((margin, incumbent))
    if not candidates:
        return 0.0
    if before is None:              # the start: the incumbent is not known
        return 0.0 if chosen is not None else max(m for m, _ in candidates)
    if rule == 'incumbent' and any(inc for _, inc in candidates):
        candidates = [(m, inc) for m, inc in candidates if inc]
    best = max(m for m, _ in candidates)
    if chosen is None or (rule == 'incumbent' and candidates[0][1] and not chosen[1]):
        return best
    return max(best - chosen[0], 0.0)
