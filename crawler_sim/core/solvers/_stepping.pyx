# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""The fixed-step methods, compiled for every gait kind: "implicit" and "penalty".

Implicit (MODEL.md section 3): the Moreau-Jean (catching-up) step, one proximal problem in the
centre-of-mass velocity V solved exactly by the inclusion (``_inclusion``). A step whose
contact mode changes is split at the transition, located by bisection on the *instantaneous*
mode of the old mode's continuation (MODEL.md 2.3) to ``BISECT_REL`` of the step. Without the
split every transition lands on a step end and its O(h) velocity error integrates into a
position error whose size jumps from one dt to the next; with it the first-order error is the
quadrature X_{k+1} = X_k + h V_{k+1}, about (h / 2) (V(t) - V(0)): order 1, a steady constant.

Implicit with stiction (a crawler whose static bounds exceed its kinetic ones, STICTION.md): the
step is no longer one convex minimisation, so ``st_step`` continues the current mode in closed
form (sliding: V affine under the kinetic forces; a stuck cluster: V = -e_r') and, where the
mode stops holding inside the step (located as above), selects the next one by Rule S from the
instant's data (``st_decide``: the incumbent cluster with its static bounds, then the arriving
clusters, then the unique kinetic slide pattern). The incumbent is the cluster stuck on the
piece before the instant: a body whose relative velocity only passes through zero there is an
arrival, never incumbent (STICTION.md s. 9's pitfall). Position is the same quadrature
X_{k+1} = X_k + h V_{k+1}; order 1. Without stiction the kinetic path above runs unchanged.

Penalty (MODEL.md section 4): backward Euler on the seed's Moreau-Yosida ODE,

    M (V_{k+1} - V_k) / h = F_ext - sum_i clip(n_i (V_{k+1} + e_i'(t_{k+1})), -f_minus_i, f_plus_i),

a strictly monotone piecewise-linear equation in V_{k+1} solved exactly (sorted breakpoints):
stable for any h and any n.

``StepCore.advance`` steps to a time; ``StepCore.run`` steps through a list of output times and
fills the output rows there (every step, by default), all in compiled code. Sign conventions:
``R[i]`` is the ground's force on body i [N]; ``contact`` is +1 / 0 / -1.
"""
import numpy as np

from libc.math cimport ceil, fabs, isfinite, INFINITY, NAN

from crawler_sim.core.solvers._gait cimport (CompiledGait, GaitData, gait_eval, gait_rates,
                                             gait_lengths)
from crawler_sim.core.solvers._inclusion cimport inclusion
# the friction law's compiled side (its one home: ``core/friction.py``)
from crawler_sim.core.solvers._friction cimport (ground_force, penalty_force, split_force_fwd,
                                                 split_theta_fwd)

__all__ = ['StepCore', 'batch_step', 'IMPLICIT', 'PENALTY', 'MAX_DEPTH', 'BISECT_REL',
           'RULE_INCUMBENT', 'RULE_MARGIN']

IMPLICIT, PENALTY = 0, 1
#: Rule S at a coincident rest (``core.friction.RULES``, in that order)
RULE_INCUMBENT, RULE_MARGIN = 0, 1
#: most transitions placed inside one step (more fall back to the plain Moreau-Jean step)
MAX_DEPTH = 8
#: the most choice instants (Rule S with several consistent continuations) whose times are kept
MAX_CHOICE_TIMES = 10 ** 6
#: bisection stops when the bracket is below this fraction of the step (about 1e-12 h)
BISECT_REL = 2.0 ** -40
cdef int C_MAX_DEPTH = 8
cdef double C_BISECT_REL = 9.094947017729282e-13
cdef int BISECT = 60
cdef int SCAN = 16         # points of the scan for the first transition of a step

# statuses
REACHED, FULL, NONFINITE = 0, 1, 2


cdef inline void rel_rates(const double* w, const double* ld, double* out, int p) noexcept nogil:
    """Body rates relative to the centre of mass from linkage rates: out_i = s_i - sum w_k s_k,
    s_0 = 0, s_i = ld_0 + ... + ld_{i-1}; w = masses / M. Used for e' and e''."""
    cdef double mean = 0.0, s = 0.0
    cdef int i
    for i in range(p):
        if i > 0:
            s += ld[i - 1]
        mean += w[i] * s
    s = 0.0
    for i in range(p):
        if i > 0:
            s += ld[i - 1]
        out[i] = s - mean


cdef inline int first_stuck(const signed char* contact, int p) noexcept nogil:
    cdef int i
    for i in range(p):
        if contact[i] == 0:
            return i
    return -1


cdef inline double slide_sum(const signed char* contact, const double* fp, const double* fm,
                             int p) noexcept nogil:
    """Total friction of the sliding bodies [N]."""
    cdef double s = 0.0
    cdef int i
    for i in range(p):
        if contact[i] != 0:
            s += ground_force(contact[i], fp[i], fm[i])
    return s


cdef class StepCore:
    """State and loop of a fixed-step solve (``implicit.ImplicitSolver``,
    ``penalty.PenaltySolver``)."""

    cdef readonly int p, method, max_depth
    cdef readonly bint stiction       # static bounds above kinetic ones: ``st_step``
    cdef readonly int rule            # RULE_INCUMBENT or RULE_MARGIN (Rule S at a coincident rest)
    cdef public long n_choices        # instants where more than one continuation was consistent
    cdef public list choice_t         # their times [s] (the first MAX_CHOICE_TIMES since reset)
    cdef double M, fext
    cdef double[::1] w, fp, fm, m_, grav, n_pen
    cdef double[::1] sfp, sfm         # static bounds [N] (the kinetic ones without stiction)
    cdef signed char[::1] inc0        # the incumbent at t0 (1: counts as stuck before t0)
    cdef int[::1] clus
    cdef public double t, X, V, A, dt
    cdef public double scan_step      # largest spacing of the transition scan [s]
    cdef signed char[::1] contact
    cdef signed char[::1] rmode     # the mode the friction R is of (a row's contact state)
    cdef double[::1] R, K
    cdef public long n_steps, n_ev
    cdef public double bad_time
    cdef public object ev_t, ev_b, ev_o, ev_n
    cdef double[::1] et
    cdef long[::1] eb
    cdef signed char[::1] eo, en
    # the gait and the rates at the last step end, as the step used them
    cdef public double last_t
    cdef double[::1] last_ep, last_epp, lb, ldb, lddb, ld3b
    # work
    cdef double[::1] ld, ldd, ld3, epb, eppb, ep, epp, kinks, kbuf, fpb, fmb, brk, l, e
    cdef int[::1] idx
    cdef unsigned char[::1] zmask, memb
    cdef signed char[::1] newc, tmp, kmode, snew

    def __init__(self, masses, fp, fm, double fext, grav, double dt, int method,
                 int max_depth, penalty=None, static_fp=None, static_fm=None, int rule=0):
        p = len(masses)
        self.p = p
        self.method = method
        self.max_depth = max_depth
        m = np.array(masses, dtype=np.float64)
        self.M = float(m.sum())
        self.m_ = m
        self.w = m / self.M
        self.fp = np.array(fp, dtype=np.float64)
        self.fm = np.array(fm, dtype=np.float64)
        self.sfp = np.array(fp if static_fp is None else static_fp, dtype=np.float64)
        self.sfm = np.array(fm if static_fm is None else static_fm, dtype=np.float64)
        self.stiction = bool(np.any(np.asarray(self.sfp) > np.asarray(self.fp))
                             or np.any(np.asarray(self.sfm) > np.asarray(self.fm)))
        self.rule = rule
        self.n_choices = 0
        self.choice_t = []
        self.inc0 = np.zeros(p, np.int8)
        self.clus = np.zeros(p, np.intc)
        self.grav = np.array(grav, dtype=np.float64)
        self.n_pen = np.array(penalty if penalty is not None else np.ones(p), dtype=np.float64)
        self.fext = fext
        self.dt = dt
        self.scan_step = INFINITY
        self.contact = np.zeros(p, np.int8)
        self.rmode = np.zeros(p, np.int8)
        self.R = np.zeros(p)
        self.K = np.zeros(p)
        cap = 64 * p * (C_MAX_DEPTH + 1)
        self.ev_t = np.zeros(cap)
        self.ev_b = np.zeros(cap, np.int_)
        self.ev_o = np.zeros(cap, np.int8)
        self.ev_n = np.zeros(cap, np.int8)
        self.et = self.ev_t
        self.eb = self.ev_b
        self.eo = self.ev_o
        self.en = self.ev_n
        nl = max(p - 1, 1)
        self.ld = np.zeros(nl)
        self.ldd = np.zeros(nl)
        self.ld3 = np.zeros(nl)
        self.l = np.zeros(nl)
        self.epb = np.zeros(p)
        self.eppb = np.zeros(p)
        self.ep = np.zeros(p)
        self.epp = np.zeros(p)
        self.e = np.zeros(p)
        self.kinks = np.zeros(p)
        self.kbuf = np.zeros(p)
        self.fpb = np.zeros(p)
        self.fmb = np.zeros(p)
        self.brk = np.zeros(2 * p)
        self.last_ep = np.zeros(p)
        self.last_epp = np.zeros(p)
        self.lb = np.zeros(nl)
        self.ldb = np.zeros(nl)
        self.lddb = np.zeros(nl)
        self.ld3b = np.zeros(nl)
        self.idx = np.zeros(2 * p, np.intc)
        self.zmask = np.zeros(p, np.uint8)
        self.memb = np.zeros(p, np.uint8)
        self.newc = np.zeros(p, np.int8)
        self.tmp = np.zeros(p, np.int8)
        self.kmode = np.zeros(p, np.int8)
        self.snew = np.zeros(p, np.int8)
        self.last_t = NAN

    # ------------------------------------------------------------------ Python access
    @property
    def contact_array(self):
        return np.asarray(self.contact).copy()

    @property
    def R_array(self):
        return np.asarray(self.R).copy()

    @property
    def K_array(self):
        return np.asarray(self.K).copy()

    # ------------------------------------------------------------------ rates and modes
    cdef int rates(self, GaitData* g, double t, double* ep, double* epp) except -1:
        """e'(t), e''(t); 1 (and ``bad_time``) when a gait value is not finite."""
        cdef int j, nl = self.p - 1
        gait_rates(g, t, &self.ld[0], &self.ldd[0], &self.ld3[0])
        for j in range(nl):
            if not (isfinite(self.ld[j]) and isfinite(self.ldd[j])):
                self.bad_time = t
                return 1
        rel_rates(&self.w[0], &self.ld[0], ep, self.p)
        rel_rates(&self.w[0], &self.ldd[0], epp, self.p)
        return 0

    cdef double accel_mode(self, double force, const double* epp, signed char* out,
                           double* s) noexcept:
        """Instantaneous mode of the bodies in zmask (at zero velocity): the acceleration
        inclusion M a in force - sum dphi_i(a + e_i''); writes out[i] for them, returns a."""
        cdef int i, n = 0, p = self.p
        cdef double a
        for i in range(p):
            if self.zmask[i]:
                self.kbuf[n] = -epp[i]
                self.fpb[n] = self.fp[i]
                self.fmb[n] = self.fm[i]
                n += 1
        a = inclusion(self.M, 0.0, force, &self.kbuf[0], &self.fpb[0], &self.fmb[0], n,
                      &self.idx[0], s)
        for i in range(p):
            if self.zmask[i]:
                out[i] = 0 if a == -epp[i] else (1 if a + epp[i] > 0.0 else -1)
        return a

    cdef int moved(self, const signed char* contact, double V, const double* ep) noexcept:
        """The kinematic part of a mode's end at an instant where the centre of mass moves at
        V and the bodies' relative rates are ep: -2 when a sliding body is at or past zero
        velocity or the stuck cluster splits (a member's e' differs), -1 when nobody is stuck,
        else the first stuck body (``zmask`` then marks the stuck ones)."""
        cdef int p = self.p, i, j
        for i in range(p):
            if contact[i] > 0 and V + ep[i] <= 0.0:
                return -2
            if contact[i] < 0 and V + ep[i] >= 0.0:
                return -2
        j = first_stuck(contact, p)
        if j < 0:
            return -1
        for i in range(p):
            self.zmask[i] = contact[i] == 0
            if self.zmask[i] and ep[i] != ep[j]:
                return -2
        return j

    cdef bint changed(self, const signed char* contact, double V, const double* ep,
                      const double* epp) noexcept:
        """Whether the mode ``contact`` no longer holds at an instant where the centre of mass
        moves at V (its continuation) and the bodies' relative rates are ep, epp."""
        cdef int p = self.p, i, j = self.moved(contact, V, ep)
        cdef double s
        if j < 0:
            return j == -2
        self.accel_mode(self.fext + slide_sum(contact, &self.fp[0], &self.fm[0], p), epp,
                        &self.tmp[0], &s)
        for i in range(p):
            if self.zmask[i] and self.tmp[i] != 0:
                return True
        return False

    cdef void new_mode(self, const signed char* contact, double V, const double* ep,
                       const double* epp, signed char* out) noexcept:
        """The mode right after a transition of ``contact``'s continuation (V, ep, epp there):
        bodies that crossed zero join the stuck ones and the acceleration inclusion decides."""
        cdef int p = self.p, i, j = first_stuck(contact, p), sgn
        cdef double force = self.fext, v, s
        cdef bint z
        for i in range(p):
            v = V + ep[i]
            if contact[i] == 0:
                z = ep[i] == ep[j]
                sgn = 1 if v > 0.0 else -1
            else:
                z = (contact[i] > 0 and v <= 0.0) or (contact[i] < 0 and v >= 0.0)
                sgn = contact[i]
            self.zmask[i] = z
            if not z:
                out[i] = sgn
                force += ground_force(sgn, self.fp[i], self.fm[i])
        self.accel_mode(force, epp, out, &s)

    cdef void interval_friction(self, const signed char* contact, double V0, double V1,
                                double h, double* R, const double* sp,
                                const double* sm) noexcept:
        """Mean friction [N] on an interval of length h > 0 from V0 to V1 in mode ``contact``:
        sliding bodies their Coulomb force, stuck ones share what momentum balance requires
        (each at the same fraction of its stuck interval [-sp_i, sm_i], ``friction.split_stuck``:
        only the total is unique; sp, sm the static bounds, the kinetic ones without
        stiction)."""
        cdef int p = self.p, i
        cdef double total = self.M * (V1 - V0) / h - self.fext, lo = 0.0, width = 0.0, theta
        for i in range(p):
            self.rmode[i] = contact[i]
            if contact[i] != 0:
                R[i] = ground_force(contact[i], self.fp[i], self.fm[i])
                total -= R[i]
            else:
                lo -= sp[i]
                width += sp[i] + sm[i]
        theta = 0.0 if width <= 0.0 else split_theta_fwd(total, -lo, width)
        for i in range(p):
            if contact[i] == 0:
                R[i] = split_force_fwd(theta, sp[i], sm[i])

    cdef double add_piece(self, const signed char* contact, double V0, double V1, double hh,
                          double X, const double* sp, const double* sm, bint last) noexcept:
        """A piece of a step of length hh >= 0 in mode ``contact`` from V0 to V1: its mean
        friction (``interval_friction``, stuck bounds sp, sm) into R and its impulse into K;
        returns X + hh V1 (the quadrature). An empty piece changes nothing unless ``last``
        (the step's final piece adds hh = 0 as the step always did)."""
        cdef int i
        if hh > 0.0:
            self.interval_friction(contact, V0, V1, hh, &self.R[0], sp, sm)
        elif not last:
            return X
        for i in range(self.p):
            self.K[i] += hh * self.R[i]
        return X + hh * V1

    cdef void log_changes(self, double t, signed char* contact, const signed char* newc) noexcept:
        cdef int i
        for i in range(self.p):
            if newc[i] != contact[i]:
                self.et[self.n_ev] = t
                self.eb[self.n_ev] = i
                self.eo[self.n_ev] = contact[i]
                self.en[self.n_ev] = newc[i]
                self.n_ev += 1
                contact[i] = newc[i]

    # ------------------------------------------------------------------ transitions
    cdef bint mode_ends(self, bint st, const signed char* contact, double V, const double* ep,
                        const double* epp) noexcept:
        """Whether the mode no longer holds: the convex law's test (``changed``), or with
        stiction Rule S's (``st_changed``)."""
        if st:
            return self.st_changed(contact, V, ep, epp)
        return self.changed(contact, V, ep, epp)

    cdef int scan(self, GaitData* g, double lo, double tb, double V, double a_lo, int j,
                  const signed char* contact, bint st, double* ab) except -1:
        """The first probe of (lo, tb] where the mode ``contact`` (continued from V at lo: its
        stuck body j's -e_j', else V + a_lo (t - lo)) no longer holds: a scan of the step (a
        long step can hold several transitions, and the instant tb alone or a bisection may
        miss the first: the piece before it would then hold a mode that did not hold). Writes
        ab = (last probe where it held, first where it did not or tb, 1.0 if found else 0.0);
        1 when a gait value is not finite."""
        cdef int it, n_scan = SCAN
        cdef double mid, vm
        ab[0] = lo
        ab[1] = tb
        ab[2] = 0.0
        if (tb - lo) / SCAN > self.scan_step:      # a step longer than the gait's scale
            n_scan = <int>min(4096.0, ceil((tb - lo) / self.scan_step))
        for it in range(n_scan):
            # the first probe just after lo: the mode the step started in (the implicit
            # step's O(h) stick test at the previous step end) may not hold at all
            mid = lo + (tb - lo) * (C_BISECT_REL if it == 0 else <double>it / n_scan)
            if not (ab[0] < mid < ab[1]):
                continue
            if self.rates(g, mid, &self.ep[0], &self.epp[0]):
                return 1
            vm = -self.ep[j] if j >= 0 else V + a_lo * (mid - lo)
            if self.mode_ends(st, contact, vm, &self.ep[0], &self.epp[0]):
                ab[1] = mid
                ab[2] = 1.0
                return 0
            ab[0] = mid
        return 0

    cdef int bisect(self, GaitData* g, double lo, double V, double a_lo, int j,
                    const signed char* contact, bint st, double* ab) except -1:
        """Bisection of the bracket ab[0] < ab[1] (the mode holds at ab[0], not at ab[1]) to
        ``BISECT_REL`` of the step; 1 when a gait value is not finite."""
        cdef int it
        cdef double mid, vm
        for it in range(BISECT):
            if ab[1] - ab[0] <= C_BISECT_REL * self.dt:
                break
            mid = ab[0] + 0.5 * (ab[1] - ab[0])
            if self.rates(g, mid, &self.ep[0], &self.epp[0]):
                return 1
            vm = -self.ep[j] if j >= 0 else V + a_lo * (mid - lo)
            if self.mode_ends(st, contact, vm, &self.ep[0], &self.epp[0]):
                ab[1] = mid
            else:
                ab[0] = mid
        return 0

    # ------------------------------------------------------------------ one step
    cdef int implicit_step(self, GaitData* g, double tb) except -1:
        """One Moreau-Jean step [t, tb] with e', e'' at tb in epb, eppb, split at each
        transition inside it (at most max_depth)."""
        cdef int p = self.p, i, j, depth
        cdef double lo = self.t, h, u = self.V, s, a_lo, uc, tau, vt
        cdef double V = self.V, X = self.X, V0 = self.V
        cdef double ab[3]
        cdef bint same
        cdef signed char* contact = &self.contact[0]
        cdef signed char* newc = &self.newc[0]
        cdef double* epb = &self.epb[0]
        cdef double* eppb = &self.eppb[0]
        for depth in range(self.max_depth + 1):
            h = tb - lo
            if h <= 0.0:                    # a transition exactly at the step end
                u = V
                for i in range(p):
                    newc[i] = contact[i]
                break
            for i in range(p):
                self.kinks[i] = -epb[i]
            u = inclusion(self.M / h, V, self.fext, &self.kinks[0], &self.fp[0], &self.fm[0],
                          p, &self.idx[0], &s)
            same = True
            for i in range(p):
                newc[i] = 0 if u == self.kinks[i] else (1 if u + epb[i] > 0.0 else -1)
                same = same and newc[i] == contact[i]
            if same and (first_stuck(contact, p) < 0 or not self.changed(contact, u, epb, eppb)):
                break
            if depth == self.max_depth or h <= C_BISECT_REL * self.dt:
                break
            j = first_stuck(contact, p)
            a_lo = (self.fext + slide_sum(contact, &self.fp[0], &self.fm[0], p)) / self.M
            uc = -epb[j] if j >= 0 else V + a_lo * h
            # the first time in (lo, tb] where the mode no longer holds: a scan of the step
            # first, then bisection in the first interval where it shows
            if self.scan(g, lo, tb, V, a_lo, j, contact, False, ab):
                return 1
            if ab[2] == 0.0 and not self.changed(contact, uc, epb, eppb):
                u = uc                      # the prox's change was its O(h) stick test
                for i in range(p):
                    newc[i] = contact[i]
                break
            if self.bisect(g, lo, V, a_lo, j, contact, False, ab):
                return 1
            tau = ab[1]
            if self.rates(g, tau, &self.ep[0], &self.epp[0]):
                return 1
            vt = -self.ep[j] if j >= 0 else V + a_lo * (tau - lo)
            self.new_mode(contact, vt, &self.ep[0], &self.epp[0], newc)
            X = self.add_piece(contact, V, vt, tau - lo, X, &self.fp[0], &self.fm[0], False)
            self.log_changes(tau, contact, newc)
            V = vt
            lo = tau
        X = self.add_piece(newc, V, u, tb - lo, X, &self.fp[0], &self.fm[0], True)
        self.log_changes(tb, contact, newc)
        self.A = (u - V0) / (tb - self.t)
        self.V = u
        self.X = X
        return 0

    cdef bint two_body_step(self, double tb) noexcept:
        """The implicit step of two bodies while the mode holds (no transition, at most one
        body stuck within its friction bounds): the same inclusion and tests as
        ``implicit_step``, inline. False when the general step is needed."""
        cdef double h = tb - self.t, u, s, ri, rj
        cdef double ep0 = self.epb[0], ep1 = self.epb[1]
        cdef signed char c0, c1
        cdef int i, j
        self.kinks[0] = -ep0
        self.kinks[1] = -ep1
        u = inclusion(self.M / h, self.V, self.fext, &self.kinks[0], &self.fp[0], &self.fm[0],
                      2, &self.idx[0], &s)
        c0 = 0 if u == self.kinks[0] else (1 if u + ep0 > 0.0 else -1)
        c1 = 0 if u == self.kinks[1] else (1 if u + ep1 > 0.0 else -1)
        if c0 != self.contact[0] or c1 != self.contact[1]:
            return False
        if c0 != 0 and c1 != 0:
            # both slide: R is the two Coulomb forces already
            self.rmode[0] = c0
            self.rmode[1] = c1
        elif c0 != c1:
            j = 0 if c0 == 0 else 1
            i = 1 - j
            # the stuck body's required force at tb (the acceleration test of ``changed``)
            ri = ground_force(self.contact[i], self.fp[i], self.fm[i])
            rj = -self.M * self.eppb[j] - self.fext - ri
            if not (-self.fp[j] <= rj <= self.fm[j]):
                return False
            self.interval_friction(&self.contact[0], self.V, u, h, &self.R[0], &self.fp[0],
                                   &self.fm[0])
        else:
            return False
        self.X += h * u
        self.K[0] += h * self.R[0]
        self.K[1] += h * self.R[1]
        self.A = (u - self.V) / h
        self.V = u
        return True

    # ------------------------------------------------------------------ stiction (Rule S)
    cdef double st_need(self, int r, const unsigned char* member, const signed char* sig,
                        const double* epp, double* lo, double* hi) noexcept:
        """The ground force [N] a stuck cluster (``member``[i] != 0, representative r) needs
        at an instant where the other bodies slide with signs ``sig`` under their kinetic
        forces: M V' = F_ext + sum R with V' = -e_r'' (STICTION.md s. 2, with the friction
        sign of ``core.friction``); lo, hi receive the cluster's static interval
        [-sum static_forward, +sum static_backward] (``friction.stuck_interval``)."""
        cdef int i
        cdef double need = -self.M * epp[r] - self.fext
        lo[0] = 0.0
        hi[0] = 0.0
        for i in range(self.p):
            if member[i]:
                lo[0] -= self.sfp[i]
                hi[0] += self.sfm[i]
            else:
                need -= ground_force(1 if sig[i] > 0 else -1, self.fp[i], self.fm[i])
        return need

    cdef bint st_changed(self, const signed char* contact, double V, const double* ep,
                         const double* epp) noexcept:
        """Whether the mode ``contact`` no longer holds (Rule S, persistence) at an instant
        where its continuation moves the centre of mass at V: a sliding body at or past zero
        velocity, the stuck cluster splitting (a member's e' differs), or the force the stuck
        cluster needs outside its static interval (closed: on the bound it holds)."""
        cdef int j = self.moved(contact, V, ep)
        cdef double need, lo, hi
        if j < 0:
            return j == -2
        need = self.st_need(j, &self.zmask[0], contact, epp, &lo, &hi)
        return not (lo <= need <= hi)

    cdef void st_decide(self, double t, double V, const double* ep, const double* epp,
                        const signed char* contact, signed char* out) noexcept:
        """Rule S at an instant (STICTION.md s. 3 and 5): the mode after it, given the mode
        ``contact`` on the piece before it and the continuation's centre-of-mass velocity V.

        The bodies at rest: the incumbent (stuck before: contact 0) and the arrivals (sliding
        bodies at or past zero velocity), grouped into clusters rigid just after the instant
        (equal e' and e''). A cluster is a stick candidate when the force it needs, the others
        sliding their way (bodies at rest by the sign of their relative e'', else e'), is
        inside its static interval. 'incumbent': an incumbent cluster that can hold holds (the
        largest margin among them), else the arriving one with the largest margin; 'margin':
        the largest margin of all. Exact ties go to the lowest body index. Without a
        candidate, the kinetic inclusion (the unique slide pattern). ``n_choices`` counts the
        instants with more than one consistent continuation, ``choice_t`` keeps their times t."""
        cdef int p = self.p, i, k, r, nc = 0, best = -1, n_ok = 0
        cdef int* clus = &self.clus[0]
        cdef signed char* sig = &self.tmp[0]
        cdef unsigned char* member = &self.memb[0]
        cdef double v, d, need, lo, hi, margin, best_margin = -1.0, force, s
        cdef bint inc, best_inc = False, slide_ok
        # who is at rest, and the sliding bodies' signs
        for i in range(p):
            v = V + ep[i]
            if contact[i] == 0:
                self.zmask[i] = True
            else:
                self.zmask[i] = (contact[i] > 0 and v <= 0.0) or (contact[i] < 0 and v >= 0.0)
            out[i] = 0 if self.zmask[i] else contact[i]
            clus[i] = -1
        # clusters of the bodies at rest (rigid just after: equal e' and e'')
        for i in range(p):
            if self.zmask[i] and clus[i] < 0:
                for k in range(i, p):
                    if self.zmask[k] and clus[k] < 0 and ep[k] == ep[i] and epp[k] == epp[i]:
                        clus[k] = i          # a cluster is named by its lowest body
                nc += 1
        # the stick candidates
        for r in range(p):
            if clus[r] != r:
                continue
            inc = False
            for i in range(p):
                member[i] = clus[i] == r
                inc = inc or (member[i] and contact[i] == 0)
                if self.zmask[i] and not member[i]:
                    d = epp[i] - epp[r]
                    if d == 0.0:
                        d = ep[i] - ep[r]
                    sig[i] = 1 if d > 0.0 else -1
                elif not member[i]:
                    sig[i] = out[i]
            need = self.st_need(r, member, sig, epp, &lo, &hi)
            if not (lo <= need <= hi):
                continue
            n_ok += 1
            margin = min(need - lo, hi - need)
            if self.rule == RULE_INCUMBENT and best >= 0 and best_inc != inc:
                if inc:                     # an incumbent beats any arrival
                    best, best_inc, best_margin = r, inc, margin
                continue
            if best < 0 or margin > best_margin:
                best, best_inc, best_margin = r, inc, margin
        # the slide pattern (kinetic inclusion); consistent iff it leaves nobody stuck
        force = self.fext + slide_sum(out, &self.fp[0], &self.fm[0], p)
        self.accel_mode(force, epp, &self.kmode[0], &s)
        slide_ok = True
        for i in range(p):
            if self.zmask[i] and self.kmode[i] == 0:
                slide_ok = False
        if n_ok + (1 if slide_ok else 0) > 1:
            self.n_choices += 1
            if len(self.choice_t) < MAX_CHOICE_TIMES:
                self.choice_t.append(t)
        if best < 0:
            for i in range(p):
                if self.zmask[i]:
                    out[i] = self.kmode[i]
            return
        for i in range(p):
            if self.zmask[i]:
                if clus[i] == best:
                    out[i] = 0
                else:
                    d = epp[i] - epp[best]
                    if d == 0.0:
                        d = ep[i] - ep[best]
                    out[i] = 1 if d > 0.0 else -1

    cdef int st_step(self, GaitData* g, double tb) except -1:
        """One step [t, tb] of a crawler with stiction (module doc): the mode continued in
        closed form, split where it stops holding (scan and bisection as ``implicit_step``)
        and continued in the mode Rule S selects there (at most max_depth times; beyond, the
        selection is made at tb)."""
        cdef int p = self.p, i, j, depth
        cdef double lo = self.t, h, u = self.V, a_lo, tau, vt
        cdef double V = self.V, X = self.X, V0 = self.V
        cdef double ab[3]
        cdef bint chg = False
        cdef signed char* contact = &self.contact[0]
        cdef signed char* newc = &self.snew[0]
        cdef double* epb = &self.epb[0]
        cdef double* eppb = &self.eppb[0]
        for depth in range(self.max_depth + 1):
            h = tb - lo
            chg = False
            if h <= 0.0:                    # a transition exactly at the step end
                u = V
                break
            j = first_stuck(contact, p)
            a_lo = (self.fext + slide_sum(contact, &self.fp[0], &self.fm[0], p)) / self.M
            u = -epb[j] if j >= 0 else V + a_lo * h
            chg = self.st_changed(contact, u, epb, eppb)
            if not chg and h / SCAN <= self.scan_step:
                break
            if depth == self.max_depth or h <= C_BISECT_REL * self.dt:
                break
            if self.scan(g, lo, tb, V, a_lo, j, contact, True, ab):
                return 1
            if ab[2] == 0.0 and not chg:
                break                       # a long step whose mode holds throughout
            if self.bisect(g, lo, V, a_lo, j, contact, True, ab):
                return 1
            tau = ab[1]
            if self.rates(g, tau, &self.ep[0], &self.epp[0]):
                return 1
            vt = -self.ep[j] if j >= 0 else V + a_lo * (tau - lo)
            self.st_decide(tau, vt, &self.ep[0], &self.epp[0], contact, newc)
            X = self.add_piece(contact, V, vt, tau - lo, X, &self.sfp[0], &self.sfm[0], False)
            self.log_changes(tau, contact, newc)
            V = vt
            lo = tau
        X = self.add_piece(contact, V, u, tb - lo, X, &self.sfp[0], &self.sfm[0], True)
        if chg:                             # out of splits: the selection at the step end
            self.st_decide(tb, u, epb, eppb, contact, newc)
            self.log_changes(tb, contact, newc)
        self.A = (u - V0) / (tb - self.t)
        self.V = u
        self.X = X
        return 0

    cdef void penalty_step(self, double tb) noexcept:
        """Backward Euler on the penalised ODE (module doc): the monotone piecewise-linear
        equation G(V) = c V - rhs0 + sum clip(n (V + e'), -fm, fp) = 0 solved exactly."""
        cdef int p = self.p, i, k, nb = 2 * p, lo, hi, mid
        cdef double h = tb - self.t, c = self.M / h, rhs0, gk, probe, wv, num, den, v, nv, F
        cdef double V_new, x
        cdef double* ep = &self.epb[0]
        rhs0 = c * self.V + self.fext
        for i in range(p):
            self.brk[2 * i] = -ep[i] + self.fp[i] / self.n_pen[i]
            self.brk[2 * i + 1] = -ep[i] - self.fm[i] / self.n_pen[i]
        for i in range(1, nb):                  # insertion sort: 2 p breakpoints
            x = self.brk[i]
            k = i
            while k > 0 and self.brk[k - 1] > x:
                self.brk[k] = self.brk[k - 1]
                k -= 1
            self.brk[k] = x
        # the first breakpoint with G >= 0 (G increases)
        lo = 0
        hi = nb
        while lo < hi:
            mid = (lo + hi) >> 1
            if self.penalty_G(self.brk[mid], c, rhs0) < 0.0:
                lo = mid + 1
            else:
                hi = mid
        k = lo
        if k < nb and self.penalty_G(self.brk[k], c, rhs0) == 0.0:
            V_new = self.brk[k]
        else:
            # the linear piece, then its closed form (accurate for huge n)
            if k == 0:
                probe = self.brk[0] - 1.0
            elif k == nb:
                probe = self.brk[nb - 1] + 1.0
            else:
                probe = 0.5 * (self.brk[k - 1] + self.brk[k])
            num = rhs0
            den = c
            for i in range(p):
                wv = self.n_pen[i] * (probe + ep[i])
                if wv >= self.fp[i]:
                    num -= self.fp[i]
                elif wv <= -self.fm[i]:
                    num += self.fm[i]
                else:
                    num -= self.n_pen[i] * ep[i]
                    den += self.n_pen[i]
            V_new = num / den
        for i in range(p):
            v = V_new + ep[i]
            nv = self.n_pen[i] * v
            F = penalty_force(nv, self.fp[i], self.fm[i])
            self.R[i] = -F
            # saturated = sliding; inside the linear zone the regularised body counts as stuck
            self.newc[i] = 1 if (nv >= self.fp[i] and v > 0) else (
                -1 if (nv <= -self.fm[i] and v < 0) else 0)
        self.X += h * V_new
        for i in range(p):
            self.K[i] += h * self.R[i]
        self.log_changes(tb, &self.contact[0], &self.newc[0])
        for i in range(p):
            self.rmode[i] = self.contact[i]
        self.A = (V_new - self.V) / h
        self.V = V_new

    cdef double penalty_G(self, double V, double c, double rhs0) noexcept:
        cdef double gsum = c * V - rhs0, x
        cdef int i
        for i in range(self.p):
            x = self.n_pen[i] * (V + self.epb[i])
            gsum += penalty_force(x, self.fp[i], self.fm[i])
        return gsum

    cdef int one_step(self, GaitData* g, double tb) except -1:
        """A step to tb of the solver's method; 1 when a value is not finite."""
        cdef int j, nl = self.p - 1
        gait_eval(g, tb, &self.lb[0], &self.ldb[0], &self.lddb[0], &self.ld3b[0])
        for j in range(nl):
            if not (isfinite(self.lb[j]) and isfinite(self.ldb[j]) and isfinite(self.lddb[j])):
                self.bad_time = tb
                return 1
        rel_rates(&self.w[0], &self.ldb[0], &self.epb[0], self.p)
        rel_rates(&self.w[0], &self.lddb[0], &self.eppb[0], self.p)
        if self.method == PENALTY:
            self.penalty_step(tb)
        elif self.stiction:
            if self.st_step(g, tb):
                return 1
        elif not (self.p == 2 and self.two_body_step(tb)):
            if self.implicit_step(g, tb):
                return 1
        self.t = tb
        self.n_steps += 1
        self.last_t = tb
        for j in range(self.p):
            self.last_ep[j] = self.epb[j]
            self.last_epp[j] = self.eppb[j]
        if not (isfinite(self.X) and isfinite(self.V)):
            self.bad_time = tb
            return 1
        return 0

    # ------------------------------------------------------------------ loops
    def advance(self, CompiledGait gait, double t1):
        """Steps of ``dt`` to t1 (the last one shortened to land on t1). Returns REACHED,
        FULL (the event buffers may overflow: drain them and call again) or NONFINITE."""
        cdef GaitData* g = &gait.d
        cdef double tb, dt = self.dt
        cdef int cap = self.et.shape[0], p = self.p
        self.n_ev = 0
        while self.t < t1:
            if self.n_ev + p * (C_MAX_DEPTH + 1) > cap:
                return FULL
            tb = t1 if (t1 - self.t) / dt <= 1.0 + 1e-9 else self.t + dt
            if self.one_step(g, tb):
                return NONFINITE
        return REACHED

    def run(self, CompiledGait gait, const double[::1] times, long k0, double[:, ::1] x,
            double[:, ::1] v, double[:, ::1] fr, double[:, ::1] imp, double[:, ::1] lam,
            double[:, ::1] lengths, double[:, ::1] rates, signed char[:, ::1] contact, indet):
        """Step through ``times[k0:]`` (sorted, >= t), filling row k of the outputs at
        times[k] (x, v [m, m/s], friction, impulse [N, N s], linkage force [N], lengths,
        rates, contact, indeterminate). Returns (status, next row to fill)."""
        cdef GaitData* g = &gait.d
        cdef unsigned char[::1] ind = indet.view(np.uint8)
        cdef double tk, tb, dt = self.dt, acc, V
        cdef Py_ssize_t k, n = times.shape[0]
        cdef int cap = self.et.shape[0], p = self.p, nl = self.p - 1, i, j, n_stuck
        self.n_ev = 0
        for k in range(k0, n):
            tk = times[k]
            while self.t < tk:
                if self.n_ev + p * (C_MAX_DEPTH + 1) > cap:
                    return FULL, k
                tb = tk if (tk - self.t) / dt <= 1.0 + 1e-9 else self.t + dt
                if self.one_step(g, tb):
                    return NONFINITE, k
            # the row at tk: the step's own gait values and e', e'' there (a stuck body's
            # velocity is then exactly zero), else the gait's
            if self.last_t != tk:
                gait_eval(g, tk, &self.lb[0], &self.ldb[0], &self.lddb[0], &self.ld3b[0])
                rel_rates(&self.w[0], &self.ldb[0], &self.last_ep[0], p)
                rel_rates(&self.w[0], &self.lddb[0], &self.last_epp[0], p)
                self.last_t = tk
            rel_rates(&self.w[0], &self.lb[0], &self.e[0], p)
            acc = 0.0
            n_stuck = 0
            for i in range(p):
                x[k, i] = self.X + self.e[i]
                v[k, i] = self.V + self.last_ep[i]
                fr[k, i] = self.R[i]
                imp[k, i] = self.K[i]
                # the state of the last piece, whose friction this is (the left limit of a
                # transition at the step end, as the exact method reports it)
                contact[k, i] = self.rmode[i]
                if self.rmode[i] == 0:
                    n_stuck += 1
                if i < nl:
                    acc += self.R[i] + self.grav[i] - self.m_[i] * (self.A + self.last_epp[i])
                    lam[k, i] = acc
            for j in range(nl):
                lengths[k, j] = self.lb[j]
                rates[k, j] = self.ldb[j]
            ind[k] = n_stuck > 1
        return REACHED, n

    def reset(self, CompiledGait gait, double t0, double x0, double v0,
              int initial_stuck=-1):
        """Back to t0 with body 0 at x0 [m] moving at v0 [m/s]; the contact state at t0 is the
        instantaneous mode (bodies at zero velocity stick or leave as the inclusion says; with
        stiction as Rule S selects, body ``initial_stuck`` (>= 0, at rest) counting as stuck
        just before t0)."""
        cdef GaitData* g = &gait.d
        cdef int p = self.p, i
        cdef double force = self.fext, a, s, vi, tot, wsum = 0.0, fps = 0.0, th
        gait_lengths(g, t0, &self.l[0])
        if self.rates(g, t0, &self.ep[0], &self.epp[0]):
            return NONFINITE
        for i in range(p - 1):
            if not isfinite(self.l[i]):
                self.bad_time = t0
                return NONFINITE
        rel_rates(&self.w[0], &self.l[0], &self.e[0], p)
        self.t = t0
        self.X = x0 - self.e[0]
        self.V = v0 - self.ep[0]
        self.n_choices = 0
        self.choice_t = []
        if self.stiction:
            self.st_mode0(initial_stuck)
        else:
            for i in range(p):
                vi = self.V + self.ep[i]
                self.zmask[i] = vi == 0.0
                if not self.zmask[i]:
                    self.contact[i] = 1 if vi > 0 else -1
                    force += ground_force(self.contact[i], self.fp[i], self.fm[i])
            a = self.accel_mode(force, &self.epp[0], &self.contact[0], &s)
            for i in range(p):
                self.R[i] = ground_force(self.contact[i], self.fp[i], self.fm[i])
                if self.contact[i] == 0:
                    wsum += self.fp[i] + self.fm[i]
                    fps += self.fp[i]
            if wsum > 0.0:
                tot = self.M * a - force
                th = split_theta_fwd(tot, fps, wsum)
                for i in range(p):
                    if self.contact[i] == 0:
                        self.R[i] = split_force_fwd(th, self.fp[i], self.fm[i])
            self.A = a
        for i in range(p):
            self.K[i] = 0.0
            self.rmode[i] = self.contact[i]
        self.n_steps = 0
        self.n_ev = 0
        self.last_t = NAN
        return REACHED

    cdef void st_mode0(self, int initial_stuck) noexcept:
        """The mode at the reset's t0 of a crawler with stiction (e', e'' at t0 in ep, epp):
        Rule S (``st_decide``) with body ``initial_stuck`` the incumbent (none when < 0; the
        candidate cluster holding it, the bodies rigid with it just after t0, is incumbent;
        any other body at rest is an arrival); the stuck cluster's friction what it needs at
        t0, split as ``friction.split_stuck``."""
        cdef int p = self.p, i, j
        cdef double vi
        for i in range(p):
            vi = self.V + self.ep[i]
            self.inc0[i] = i == initial_stuck
            self.snew[i] = 0 if self.inc0[i] else (1 if vi >= 0.0 else -1)
        self.st_decide(self.t, self.V, &self.ep[0], &self.epp[0], &self.snew[0],
                       &self.contact[0])
        j = first_stuck(&self.contact[0], p)
        for i in range(p):
            self.R[i] = ground_force(self.contact[i], self.fp[i], self.fm[i])
        if j >= 0:
            self.A = -self.epp[j]
            # the split of ``interval_friction`` at the force needed (M A - F_ext - slides)
            self.interval_friction(&self.contact[0], 0.0, self.A, 1.0, &self.R[0],
                                   &self.sfp[0], &self.sfm[0])
        else:
            self.A = (self.fext + slide_sum(&self.contact[0], &self.fp[0], &self.fm[0], p)) \
                / self.M

    @property
    def incumbent0(self):
        """The bodies counted as stuck just before the reset's t0 (bool, p)."""
        return np.asarray(self.inc0).astype(bool)

    def row(self, CompiledGait gait):
        """The state at the current time as one output row (dict of arrays)."""
        p = self.p
        out = [np.empty((1, p)) for _ in range(4)]
        lam = np.empty((1, p - 1))
        l = np.empty((1, p - 1))
        ld = np.empty((1, p - 1))
        contact = np.empty((1, p), np.int8)
        ind = np.empty(1, bool)
        k0 = self.n_ev
        status, _ = self.run(gait, np.array([self.t]), 0, out[0], out[1], out[2], out[3], lam,
                             l, ld, contact, ind)
        self.n_ev = k0
        return {'t': self.t, 'x': out[0][0], 'v': out[1][0], 'friction': out[2][0],
                'impulse': out[3][0], 'linkage_force': lam[0], 'lengths': l[0], 'rates': ld[0],
                'contact': contact[0], 'indeterminate': bool(ind[0])}


def batch_step(double h, const double[:, ::1] rates, const double[:, ::1] w,
               const double[::1] M, double[::1] V, double[::1] X, const double[::1] fext,
               const double[:, ::1] fp, const double[:, ::1] fm):
    """One plain Moreau-Jean step of B crawlers (``ImplicitBatch``): rates (1 or B, p - 1) are
    l'(t + h), shared when there is one row; V, X (B,) are updated in place."""
    cdef Py_ssize_t B = fp.shape[0], b
    cdef int p = fp.shape[1], i
    cdef bint shared = rates.shape[0] == 1
    cdef double[::1] ep = np.empty(p)
    cdef int[::1] idx = np.empty(p, np.intc)
    cdef double u, s
    for b in range(B):
        rel_rates(&w[b, 0], &rates[0 if shared else b, 0], &ep[0], p)
        for i in range(p):
            ep[i] = -ep[i]
        u = inclusion(M[b] / h, V[b], fext[b], &ep[0], &fp[b, 0], &fm[b, 0], p, &idx[0], &s)
        V[b] = u
        X[b] += h * u
