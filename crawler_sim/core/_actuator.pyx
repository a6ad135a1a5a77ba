# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""The actuator's per-tick work, compiled (the model and its derivation: ``actuator.py``).

- :func:`jerk_law`: the saturated cascade and the feasible jerk interval of one linkage;
- :class:`Reference`: the evaluation of a ``TrajectoryReference`` (linear, cubic Hermite or
  quintic segments; the start row before the first knot, the last position at rest after the
  last one);
- :class:`Servo`: the state of every linkage and the tick: the reference or the target, settling
  to rest, the jerk, the end values of the constant-jerk piece. ``step`` emits one
  ``gaits.Cubic`` per tick; ``_run`` runs many ticks with no input in between into arrays.

This is the one implementation of the actuator's arithmetic: ``actuator.Actuator`` and
``actuator.TrajectoryReference`` are the Python side (validation, inputs, configuration) of the
classes here. It was written from the pure-Python model expression for expression, in the same
order of operations, with the clamps written as the same comparisons, so that it gives the same
floats bit for bit (test/core/actuator_oracle.py keeps that model as the tests' reference).
Python's math.sqrt is the correctly rounded IEEE square root, as libc's sqrt; the module is
compiled with -ffp-contract=off (no fused multiply-add), like the solvers.

Units: s, m, m/s, m/s^2, m/s^3; times of ``_run`` in integer nanoseconds.
"""
import numpy as np

from libc.math cimport INFINITY, fabs, isnan, sqrt

from crawler_sim.core.gaits.cubic import Cubic

__all__ = ['jerk_law', 'Reference', 'Servo']

# settling thresholds (module doc of actuator.py)
cdef double SETTLE_L = 1e-12    # m
cdef double SETTLE_V = 1e-10    # m/s
cdef double SETTLE_A = 1e-8     # m/s^2

# what one tick emitted (Servo._tick)
cdef enum:
    REST = 0        # the rest piece again (nothing moved, nothing written)
    NEW_REST = 1    # a new piece, and every linkage is now settled: it becomes the rest piece
    MOVING = 2      # a new piece

_from_rows = Cubic.from_rows


cdef inline double _sqrtp(double e, double kp, double amax) noexcept nogil:
    """The position law: kp e near 0, the braking curve sqrt(2 A_b (|e| - A_b/(2 kp^2)))
    beyond |e| = A_b / kp^2 (ArduPilot's sqrt_controller, A_b = A/2)."""
    cdef double linear = 0.5 * amax / (kp * kp)
    if e > linear:
        return sqrt(2.0 * (0.5 * amax) * (e - 0.5 * linear))
    if e < -linear:
        return -sqrt(2.0 * (0.5 * amax) * (-e - 0.5 * linear))
    return kp * e


cdef inline double _jerk(double l, double v, double a, double r, double rd, double rdd,
                         double dt, double kp, double kv, double ka, double vmax,
                         double amax, double lmin, double lmax) noexcept nogil:
    """The jerk law of ``jerk_law`` (same expressions in the same order, see there)."""
    cdef double e, v_d, a_d, j, dt2, hi, lo, x
    # The feed-forward is what the servo can do: a reference faster than max_speed or
    # max_acceleration (points 10 ms and 0.5 m apart) otherwise outweighs the position error
    # and drives the linkage far past the reference (0.3 m beyond max_length, issue 25).
    if -vmax > rd:
        rd = -vmax
    if vmax < rd:
        rd = vmax
    if -amax > rdd:
        rdd = -amax
    if amax < rdd:
        rdd = amax
    e = r - l
    v_d = rd + _sqrtp(e, kp, amax)
    # The length limits as targets the servo brakes for, as for a step command to them (a
    # step never overshoots): never faster towards a limit than the position law would go
    # towards a target there, from where this tick's motion already takes the linkage (a
    # coarse tick moves it max_speed dt before the law acts again).
    x = _sqrtp(lmax - (l + fabs(v) * dt), kp, amax)
    if x < v_d:
        v_d = x
    x = _sqrtp(lmin - (l - fabs(v) * dt), kp, amax)
    if x > v_d:
        v_d = x
    # Each clamp keeps Python's builtin min(max(x, lo), hi) choice exactly: the earlier
    # argument on ties, so also the sign of a zero (the model was written with min/max).
    if -vmax > v_d:
        v_d = -vmax
    if vmax < v_d:
        v_d = vmax
    a_d = rdd + kv * (v_d - v)
    if -amax > a_d:
        a_d = -amax
    if amax < a_d:
        a_d = amax
    j = ka * (a_d - a)
    # the feasible interval: |l''| <= A at the tick end, |l'| <= V inside the tick and the
    # viability invariant at its end (actuator.py, module doc)
    dt2 = dt * dt
    hi = (amax - a) / dt                    # min of three
    x = 2.0 * (vmax - v - a * dt) / dt2
    if x < hi:
        hi = x
    x = (vmax - v - 1.5 * a * dt) / dt2
    if x < hi:
        hi = x
    lo = (-amax - a) / dt                   # max of three
    x = 2.0 * (-vmax - v - a * dt) / dt2
    if x > lo:
        lo = x
    x = (-vmax - v - 1.5 * a * dt) / dt2
    if x > lo:
        lo = x
    if lo > hi:             # only through rounding at the boundary; -a/dt is always admissible
        return -a / dt
    if lo > j:
        j = lo
    if hi < j:
        j = hi
    return j


def jerk_law(double l, double v, double a, double r, double rd, double rdd, double dt, k,
             double max_speed, double max_acceleration, double min_length=-INFINITY,
             double max_length=INFINITY) -> float:
    """Jerk [m/s^3] for one linkage over one tick of ``dt`` [s]: a pure function of the state
    (l [m], v = l' [m/s], a = l'' [m/s^2]), the reference (r [m], rd [m/s], rdd [m/s^2]), the
    gains ``k`` = (kp, kv, ka) of ``actuator.gains`` and the limits (max_speed [m/s],
    max_acceleration [m/s^2]). Signs: e = r - l > 0 drives l up (positive jerk).

    Assumes the viability invariant at the start (``actuator`` module doc); the result keeps
    |l'| <= max_speed and |l''| <= max_acceleration over the whole tick, and the invariant at
    its end.
    """
    kp, kv, ka = k
    return _jerk(l, v, a, r, rd, rdd, dt, kp, kv, ka, max_speed, max_acceleration,
                 min_length, max_length)


cdef class Reference:
    """The compiled evaluation of one ``actuator.TrajectoryReference`` (which builds it).

    ``knots`` (m,) are times from ``t_start`` [s] (strictly increasing, knots[0] = 0 when the
    first segment starts at the actuator's state); ``P``, ``V``, ``A`` (m, n_links) the
    positions [m], rates [m/s] and accelerations [m/s^2] at the knots; ``order`` 1 (linear),
    3 (cubic Hermite) or 5 (quintic).
    """
    cdef double t_start
    cdef readonly double end_time       # t_start + the last knot [s]
    cdef int order
    cdef Py_ssize_t nl, m
    cdef double[::1] kt
    cdef double[:, ::1] P, V, A
    cdef double[:, ::1] coef            # (nl, 6) of the current segment
    cdef Py_ssize_t seg                 # the current segment (-1: none yet)
    cdef double h                       # its length [s]

    def __init__(self, double t_start, knots, P, V, A, int order):
        kt = np.ascontiguousarray(knots, dtype=np.float64)
        rows = [np.ascontiguousarray(x, dtype=np.float64) for x in (P, V, A)]
        if (kt.ndim != 1 or kt.size < 1 or order not in (1, 3, 5)
                or any(x.ndim != 2 or x.shape != rows[0].shape or x.shape[0] != kt.size
                       for x in rows)):
            raise ValueError('Reference: knots (m,) and P, V, A (m, n_links), order 1, 3 or 5')
        self.t_start = t_start
        self.kt = kt
        self.P, self.V, self.A = rows
        self.m = kt.size
        self.nl = rows[0].shape[1]
        self.order = order
        self.end_time = t_start + self.kt[self.m - 1]
        self.coef = np.zeros((self.nl, 6))
        self.seg = -1

    cdef int _segment(self, Py_ssize_t k) noexcept:
        """Make segment k current: its length and per-linkage coefficients on s in [0, 1]
        (order 1: p0, p1 - p0, slope; else the Hermite coefficients c0..c5)."""
        cdef Py_ssize_t i
        cdef double h = self.kt[k + 1] - self.kt[k]
        cdef double p0, p1, v0, v1, a0, a1, dp
        self.seg = k
        self.h = h
        for i in range(self.nl):
            p0 = self.P[k, i]
            p1 = self.P[k + 1, i]
            if self.order == 1:
                self.coef[i, 0] = p0
                self.coef[i, 1] = p1 - p0
                self.coef[i, 2] = (p1 - p0) / h
                continue
            # the Hermite data scaled to s: v h and a h^2 (written (a h) h, as in the model)
            v0 = self.V[k, i] * h
            a0 = self.A[k, i] * h * h
            v1 = self.V[k + 1, i] * h
            a1 = self.A[k + 1, i] * h * h
            dp = p1 - p0
            self.coef[i, 0] = p0
            self.coef[i, 1] = v0
            if self.order == 3:
                self.coef[i, 2] = 3.0 * dp - 2.0 * v0 - v1
                self.coef[i, 3] = -2.0 * dp + v0 + v1
                self.coef[i, 4] = 0.0
                self.coef[i, 5] = 0.0
            else:
                self.coef[i, 2] = 0.5 * a0
                self.coef[i, 3] = 10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1
                self.coef[i, 4] = -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1
                self.coef[i, 5] = 6.0 * dp - 3.0 * v0 - 3.0 * v1 - 0.5 * a0 + 0.5 * a1
        return 0

    cdef int eval(self, double t, double* r, double* rd, double* rdd) except -1:
        """(r [m], r' [m/s], r'' [m/s^2]) per linkage at sim time t [s] into the three rows."""
        cdef double tau = t - self.t_start
        cdef Py_ssize_t i, lo, hi, mid, m = self.m
        cdef double s, h, h2, c0, c1, c2, c3, c4, c5
        if tau >= self.kt[m - 1]:               # after the last point: hold it, at rest
            for i in range(self.nl):
                r[i] = self.P[m - 1, i]
                rd[i] = 0.0
                rdd[i] = 0.0
            return 0
        if tau <= self.kt[0]:
            for i in range(self.nl):
                r[i] = self.P[0, i]
                rd[i] = self.V[0, i]
                rdd[i] = self.A[0, i]
            return 0
        # A 1 kHz actuator evaluates each segment of a 50 Hz trajectory 20 times in a row: the
        # segment's coefficients are kept until tau leaves it (the same floats either way).
        if not (self.seg >= 0 and self.kt[self.seg] <= tau < self.kt[self.seg + 1]):
            if isnan(tau):
                raise ValueError(f'a trajectory reference needs a time, got {t!r}')
            lo = 0                              # bisect_right(knots, tau) - 1
            hi = m
            while lo < hi:
                mid = (lo + hi) >> 1
                if tau < self.kt[mid]:
                    hi = mid
                else:
                    lo = mid + 1
            self._segment(lo - 1)
        h = self.h
        s = (tau - self.kt[self.seg]) / h
        if self.order == 1:
            for i in range(self.nl):
                r[i] = self.coef[i, 0] + s * self.coef[i, 1]
                rd[i] = self.coef[i, 2]
                rdd[i] = 0.0
            return 0
        h2 = h * h
        for i in range(self.nl):
            c0 = self.coef[i, 0]
            c1 = self.coef[i, 1]
            c2 = self.coef[i, 2]
            c3 = self.coef[i, 3]
            c4 = self.coef[i, 4]
            c5 = self.coef[i, 5]
            # the model's expressions, every term also for a cubic (c4 = c5 = 0)
            r[i] = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
            rd[i] = (c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * 5.0 * c5)))) / h
            rdd[i] = (2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * 20.0 * c5))) / h2
        return 0

    def coefficients(self):
        """Every segment's polynomial in s = (tau - knot_k) / h_k on [0, 1] as
        (m - 1, n_links, 6) coefficients c0..c5 of r [m] (those ``eval`` uses: a linear segment
        is c0 + c1 s), for checks of the whole interpolant (``TrajectoryReference.outside``)."""
        cdef Py_ssize_t k, i, j
        out = np.zeros((max(self.m - 1, 0), self.nl, 6))
        cdef double[:, :, ::1] o = out
        for k in range(self.m - 1):
            self._segment(k)
            for i in range(self.nl):
                if self.order == 1:
                    o[k, i, 0] = self.coef[i, 0]
                    o[k, i, 1] = self.coef[i, 1]
                else:
                    for j in range(6):
                        o[k, i, j] = self.coef[i, j]
        self.seg = -1                        # the cached segment was overwritten
        return out

    def __call__(self, double t) -> tuple[list[float], list[float], list[float]]:
        """(r [m], r' [m/s], r'' [m/s^2]) per linkage at sim time t [s], as lists."""
        out = np.empty((3, max(self.nl, 1)))
        cdef double[:, ::1] o = out
        self.eval(t, &o[0, 0], &o[1, 0], &o[2, 0])
        rows = out[:, :self.nl].tolist()
        return rows[0], rows[1], rows[2]


cdef class Servo:
    """The state and the tick of ``actuator.Actuator`` (its base class; the inputs, their
    validation and the configuration are there). Per linkage: l [m], v = l' [m/s],
    a = l'' [m/s^2], the target [m] of a step command and whether it has settled at rest."""
    cdef readonly Py_ssize_t n_links
    cdef public double dt                  # nominal tick [s] of the jerk law
    cdef double kp, kv, ka, vmax, amax, lmin, lmax
    cdef object _limits, _k_obj
    cdef object _store                      # the arrays the pointers below point into
    cdef double* l
    cdef double* v
    cdef double* a
    cdef double* tgt
    cdef double* l0                         # the piece of the last tick: start state, jerk
    cdef double* v0
    cdef double* a0
    cdef double* jk
    cdef double* r                          # the reference at the last tick
    cdef double* rd
    cdef double* rdd
    cdef unsigned char* settled
    cdef object traj                        # the TrajectoryReference followed, or None
    cdef Reference ref                      # its compiled evaluation
    cdef object rest                        # the rest piece (a Cubic), or None
    cdef double rest_t0                     # its start time and rows (l0, v0, a0, jerk)
    cdef double[:, ::1] rest_coef

    def __cinit__(self, *args, **kwargs):
        self.n_links = 0
        self.traj = None
        self.ref = None
        self.rest = None

    def _alloc(self, Py_ssize_t n):
        """Storage for ``n`` linkages (the state is set by ``reset``)."""
        cdef double[:, ::1] st
        cdef unsigned char[::1] fl
        if n < 1:
            raise ValueError('the actuator needs at least one linkage')
        self.n_links = n
        store = np.zeros((11, n))
        flags = np.ones(n, dtype=np.uint8)
        self._store = (store, flags)
        st = store
        fl = flags
        self.l, self.v, self.a, self.tgt = &st[0, 0], &st[1, 0], &st[2, 0], &st[3, 0]
        self.l0, self.v0, self.a0, self.jk = &st[4, 0], &st[5, 0], &st[6, 0], &st[7, 0]
        self.r, self.rd, self.rdd = &st[8, 0], &st[9, 0], &st[10, 0]
        self.settled = &fl[0]
        self.rest_coef = np.zeros((n, 4))

    # ------------------------------------------------------------------ state as Python lists
    cdef list _get(self, double* x):
        return [x[i] for i in range(self.n_links)]

    cdef int _put(self, double* x, values) except -1:
        cdef Py_ssize_t i
        if len(values) != self.n_links:
            raise ValueError(f'expected {self.n_links} values, got {len(values)}')
        for i in range(self.n_links):
            x[i] = values[i]
        return 0

    @property
    def l(self) -> list[float]:
        """Lengths [m] at the current tick start (a copy)."""
        return self._get(self.l)

    @l.setter
    def l(self, values):
        self._put(self.l, values)

    @property
    def v(self) -> list[float]:
        """Rates l' [m/s] at the current tick start (a copy)."""
        return self._get(self.v)

    @v.setter
    def v(self, values):
        self._put(self.v, values)

    @property
    def a(self) -> list[float]:
        """Accelerations l'' [m/s^2] at the current tick start (a copy)."""
        return self._get(self.a)

    @a.setter
    def a(self, values):
        self._put(self.a, values)

    @property
    def target(self) -> list[float]:
        """The step targets [m] (after a trajectory: its last reference)."""
        return self._get(self.tgt)

    @target.setter
    def target(self, values):
        self._put(self.tgt, values)

    def _command(self, list new):
        """A step command's new targets (``Actuator.set_target``: ``n_links`` Python floats,
        checked there): a linkage whose target changes is no longer settled."""
        cdef Py_ssize_t i
        if len(new) != self.n_links:
            raise ValueError(f'expected {self.n_links} values, got {len(new)}')
        for i in range(self.n_links):
            self._retarget(i, new[i])

    cdef inline void _retarget(self, Py_ssize_t i, double x) noexcept:
        """Linkage i's new step target x [m]: unsettled if it changes (``_command``)."""
        if x != self.tgt[i]:
            self.settled[i] = 0
        self.tgt[i] = x

    @property
    def _settled(self) -> list[bool]:
        return [bool(self.settled[i]) for i in range(self.n_links)]

    @_settled.setter
    def _settled(self, values):
        if len(values) != self.n_links:
            raise ValueError(f'expected {self.n_links} flags, got {len(values)}')
        for i in range(self.n_links):
            self.settled[i] = bool(values[i])

    @property
    def trajectory(self):
        """The ``TrajectoryReference`` being followed, or None."""
        return self.traj

    @trajectory.setter
    def trajectory(self, trajectory):
        self.ref = None if trajectory is None else <Reference?>trajectory._c
        self.traj = trajectory

    @property
    def _rest_piece(self):
        """The constant piece a settled actuator hands out again (None: moving, or not made
        yet). Setting it to None forgets it; a Cubic sets it."""
        return self.rest

    @_rest_piece.setter
    def _rest_piece(self, piece):
        if piece is not None:
            rows = piece._rows
            self.rest_t0 = piece.t0
            for i in range(self.n_links):
                for c in range(4):
                    self.rest_coef[i, c] = rows[i][c]
        self.rest = piece

    @property
    def limits(self):
        """``ActuatorLimits`` in use."""
        return self._limits

    @limits.setter
    def limits(self, lim):
        self.vmax = lim.max_speed
        self.amax = lim.max_acceleration
        self.lmin = lim.min_length
        self.lmax = lim.max_length
        self._limits = lim

    @property
    def _k(self) -> tuple[float, float, float]:
        """The gains (kp, kv, ka) in use."""
        return self._k_obj

    @_k.setter
    def _k(self, k):
        self.kp, self.kv, self.ka = k
        self._k_obj = tuple(k)

    # ------------------------------------------------------------------ ticks
    cdef int _tick(self, double t0, double t1) except -1:
        """One tick on [t0, t1]: its piece into l0, v0, a0, jk and the state to t1. Returns
        REST (the rest piece again, nothing written), NEW_REST or MOVING."""
        cdef double d = t1 - t0
        cdef Py_ssize_t i, n = self.n_links
        cdef bint follow = self.traj is not None
        cdef double rr, rdv, rddv, j, lx, vx, ax
        if follow:
            self.ref.eval(t0, self.r, self.rd, self.rdd)
            if t0 >= self.ref.end_time:
                # hold the last reference as a plain target (this tick still follows it)
                self.traj = None
                self.ref = None
                for i in range(n):
                    self.tgt[i] = self.r[i]
        elif self.rest is not None:
            return REST
        for i in range(n):
            self.l0[i] = self.l[i]
            self.v0[i] = self.v[i]
            self.a0[i] = self.a[i]
            self.jk[i] = 0.0
        for i in range(n):
            if not follow:
                if self.settled[i]:
                    continue
                rr = self.tgt[i]
                rdv = 0.0
                rddv = 0.0
                if (fabs(rr - self.l0[i]) <= SETTLE_L and fabs(self.v0[i]) <= SETTLE_V
                        and fabs(self.a0[i]) <= SETTLE_A):
                    # at rest: l' and l'' exactly 0, l kept (so l stays continuous)
                    self.settled[i] = 1
                    self.v0[i] = 0.0
                    self.a0[i] = 0.0
                    self.v[i] = 0.0
                    self.a[i] = 0.0
                    continue
            else:
                rr = self.r[i]
                rdv = self.rd[i]
                rddv = self.rdd[i]
            lx = self.l0[i]
            vx = self.v0[i]
            ax = self.a0[i]
            j = _jerk(lx, vx, ax, rr, rdv, rddv, self.dt, self.kp, self.kv, self.ka,
                      self.vmax, self.amax, self.lmin, self.lmax)
            self.jk[i] = j
            # the piece at its end: the expression of gaits.cubic_values (and of the solvers'
            # TABLE kind), so the next piece starts bit-identically where this one ends
            self.l[i] = lx + d * (vx + d * (0.5 * ax + d * j / 6.0))
            self.v[i] = vx + d * (ax + 0.5 * d * j)
            self.a[i] = ax + d * j
        if follow:
            return MOVING
        for i in range(n):
            if not self.settled[i]:
                return MOVING
        return NEW_REST

    cdef object _piece(self, double t0):
        """The Cubic of the last tick (started at t0): ``Cubic.trusted`` of its rows."""
        cdef Py_ssize_t i
        cdef bint constant = True
        for i in range(self.n_links):
            # Cubic.trusted's test: any(v0) or any(a0) or any(jerk) (-0.0 counts as zero)
            if self.v0[i] != 0.0 or self.a0[i] != 0.0 or self.jk[i] != 0.0:
                constant = False
        rows = [(self.l0[i], self.v0[i], self.a0[i], self.jk[i]) for i in range(self.n_links)]
        return _from_rows(t0, rows, constant)

    cdef int _keep_rest(self, double t0, object piece) except -1:
        """The last tick's piece (started at t0) is the rest piece from now on."""
        cdef Py_ssize_t i
        self.rest = piece
        self.rest_t0 = t0
        for i in range(self.n_links):
            self.rest_coef[i, 0] = self.l0[i]
            self.rest_coef[i, 1] = self.v0[i]
            self.rest_coef[i, 2] = self.a0[i]
            self.rest_coef[i, 3] = self.jk[i]
        return 0

    def step(self, double t0, t1=None):
        """The constant-jerk piece (a ``gaits.Cubic``) on [t0, t1] [s] (t1 defaults to
        t0 + dt); advances the state to t1.

        The jerk uses the nominal ``dt``; pass ``t1`` so that the end state is computed with
        the exact float ``t1 - t0`` the solver will use. A settled actuator with no trajectory
        hands out the same constant piece (the same object) until the next input.
        """
        cdef double t_end = t0 + self.dt if t1 is None else <double>t1
        cdef int status = self._tick(t0, t_end)
        if status == REST:
            return self.rest
        piece = self._piece(t0)
        if status == NEW_REST:
            self._keep_rest(t0, piece)
        return piece

    def _run(self, long long t0_ns, long long dt_ns, Py_ssize_t n):
        """``n`` ticks of ``dt_ns`` from ``t0_ns`` [ns], each as ``step(t0_ns / 1e9,
        t1_ns / 1e9)``: (starts (n,) [s], anchors (n,) [s], coef (n, n_links, 4),
        rest_from, rest_piece); see ``actuator.Pieces``."""
        if n < 0 or dt_ns <= 0:
            raise ValueError(f'a run needs n >= 0 ticks of dt_ns > 0, got {n}, {dt_ns}')
        starts = np.empty(n)
        anchors = np.empty(n)
        coef = np.empty((n, self.n_links, 4))
        cdef double[::1] st = starts, an = anchors
        cdef double[:, :, ::1] cf = coef
        cdef Py_ssize_t rest_from = n
        if n:
            rest_from = servo_run(self, t0_ns, dt_ns, n, &st[0], &an[0], &cf[0, 0, 0])
        return starts, anchors, coef, rest_from, (self.rest if rest_from < n else None)


# ---------------------------------------------------------------------- from C (_actuator.pxd)
cdef Py_ssize_t servo_run(object servo, long long t0_ns, long long dt_ns, Py_ssize_t n,
                          double* st, double* an, double* cf) except -1:
    """``n`` >= 1 ticks of ``dt_ns`` > 0 from ``t0_ns`` [ns] (``Servo._run``'s loop, its one
    home) written into starts ``st``, anchors ``an`` (n,) [s] and ``cf`` (n, n_links, 4)
    (l0, v0, a0, jerk); returns rest_from (n: none at rest). The plant's compiled step writes
    them straight into its table (``_gait.run_table``, issue 41)."""
    cdef Servo self = <Servo?>servo
    cdef Py_ssize_t k, i, nl = self.n_links, rest_from = n
    cdef long long t_ns
    cdef double t0, t1
    cdef int status
    for k in range(n):
        t_ns = t0_ns + k * dt_ns
        # the engine's times: integer ns to float seconds (Python's int / float converts
        # the int to the nearest double first, as this cast does)
        t0 = <double>t_ns / 1e9
        t1 = <double>(t_ns + dt_ns) / 1e9
        st[k] = t0
        status = self._tick(t0, t1)
        if status == REST:
            if rest_from == n:
                rest_from = k
            an[k] = self.rest_t0
            for i in range(nl):
                cf[(k * nl + i) * 4 + 0] = self.rest_coef[i, 0]
                cf[(k * nl + i) * 4 + 1] = self.rest_coef[i, 1]
                cf[(k * nl + i) * 4 + 2] = self.rest_coef[i, 2]
                cf[(k * nl + i) * 4 + 3] = self.rest_coef[i, 3]
            continue
        an[k] = t0
        for i in range(nl):
            cf[(k * nl + i) * 4 + 0] = self.l0[i]
            cf[(k * nl + i) * 4 + 1] = self.v0[i]
            cf[(k * nl + i) * 4 + 2] = self.a0[i]
            cf[(k * nl + i) * 4 + 3] = self.jk[i]
        if status == NEW_REST:
            # one Cubic object, handed out again by the ticks after this one (and by step)
            self._keep_rest(t0, self._piece(t0))
            rest_from = k
    return rest_from


cdef int servo_target(object servo, const double* new) except -1:
    """A step command of n_links targets [m] (``Actuator._set_target``: the trajectory
    cancelled, the rest piece forgotten, then ``_command``'s rule), from C."""
    cdef Servo self = <Servo?>servo
    cdef Py_ssize_t i
    self.traj = None
    self.ref = None
    self.rest = None
    for i in range(self.n_links):
        self._retarget(i, new[i])
    return 0


cdef int servo_state(object servo, double* l, double* v, double* a) except -1:
    """l [m], l' [m/s], l'' [m/s^2] per linkage at the current tick start into three rows
    (the ``l``, ``v``, ``a`` lists' values)."""
    cdef Servo self = <Servo?>servo
    cdef Py_ssize_t i
    for i in range(self.n_links):
        l[i] = self.l[i]
        v[i] = self.v[i]
        a[i] = self.a[i]
    return 0


cdef bint servo_following(object servo) except -1:
    """Whether the servo follows a trajectory reference."""
    return (<Servo?>servo).traj is not None
