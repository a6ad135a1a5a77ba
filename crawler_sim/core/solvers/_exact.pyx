# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""The exact method's segment loop, compiled: the one implementation of its rules.

``ExactCore.drive`` integrates from the current time towards ``t_end`` segment by segment
(MODEL.md section 2; ``exact.py`` documents the method and its guarantee):

* mode: the bodies at zero velocity stick or leave as the acceleration-level inclusion says
  (``_inclusion``), ties and groups of bodies at rest together decided by the same inclusion a
  short look-ahead later (``mode``);
* event rows: g = c0 + c1 (t - t0) + A1 . l' + A2 . l'', positive while the mode holds: a
  sliding body's velocity (``vel``), a stuck group's force slack to each bound (``force``), the
  relative velocity of two bodies stuck together (``rigid``);
* search: the first zero of the rows, each interval proven free of events from bounds of
  |g''| and |g'| on that interval (the gait's jerk and snap bounds there, ``gait_bounds``) and
  the rows' values and slopes at its ends (for a row of l' alone, whose curvature A1 . l''' is
  known at each point, also a bound of |g'''| and a Taylor bound of third order:
  ``cubic_low``, ``cubic_root``); where a row falls nearly straight onto zero the
  step goes just past the root Newton predicts, so the event is bracketed at once; the first
  bracketed zero narrowed (Newton from the nearer end, else the Illinois secant) to adjacent
  floats (``search``);
* close: the closed-form state at the event; a periodic gait's state is compared at every
  multiple of its period with the one a period earlier (the caller then skips the repeats).

Segments are written as records (``seg_*`` buffers) and contact changes as events (``ev_*``);
the caller drains them after each call. Units: s, m, m/s, N, N s.
"""
import numpy as np

from libc.math cimport cbrt, fabs, floor, isfinite, nextafter, sqrt, INFINITY, NAN
cimport cython
from cpython.mem cimport PyMem_Calloc, PyMem_Free, PyMem_Malloc
from cpython.buffer cimport (PyObject_GetBuffer, PyBuffer_Release, PyBUF_C_CONTIGUOUS,
                            PyBUF_FORMAT, PyBUF_WRITABLE)
from libc.string cimport memcpy
from cpython.bytes cimport PyBytes_AS_STRING, PyBytes_FromStringAndSize

from crawler_sim.core.solvers._gait cimport (CompiledGait, GaitData, FOURIER, SCALLOP,
                                             TABLE, PROXY, gait_eval, gait_rates,
                                             table_locate, table_run, piece_start,
                                             gait_lengths, gait_bounds,
                                             gait_next_break, gait_is_constant)
from crawler_sim.core.solvers._inclusion cimport inclusion
from crawler_sim.core.solvers._friction cimport ground_force, split_theta, split_force

__all__ = ['ExactCore', 'ClosedForm', 'REACHED', 'FULL', 'STALLED', 'NONFINITE', 'NO_STEPS',
           'PERIODIC']

# statuses of ``drive``
cdef enum:
    S_REACHED = 0      # t_end reached
    S_FULL = 2         # the record buffers are full: drain them and call again
    S_STALLED = 3      # segments that advance by a few floats, for ever
    S_NONFINITE = 4    # a gait value is not finite (``bad_time`` says where)
    S_NO_STEPS = 5     # the search ran out of steps
    S_PERIODIC = 6     # a period repeats the previous one (``k_at``): the caller skips
REACHED, FULL, STALLED, NONFINITE, NO_STEPS, PERIODIC = 0, 2, 3, 4, 5, 6

# search outcomes
cdef enum:
    F_OK = 0
    F_NONFINITE = 1
    F_NO_STEPS = 2

cdef double EPS = 2.220446049250313e-16
cdef int STALL_ULPS = 64          # a segment this short (in floats of t) makes no progress
cdef int STALL_SEGMENTS = 256     # consecutive such segments before the solver reports a stall
cdef double AMBIGUOUS = 1e-10     # relative slack below which a mode choice is decided later
cdef long MAX_STEPS = 10000000    # grid and narrowing steps of one search: a safety net
cdef int N_BUF = 256              # segment records per call


cdef inline int ev_records(int p) noexcept nogil:
    """Contact-change records per call: 2 N_BUF, and room for a segment's worst case on top
    when 2 N_BUF cannot hold it (2 p + 2: up to p changes where stale signs are corrected and
    p where the mode is set). ``drive`` starts a segment only with that room left, so with 2 N_BUF
    alone p >= 256 bodies never started one: every call returned 'full' with nothing done."""
    return 2 * N_BUF + (2 * p + 2 if 2 * p + 2 > 2 * N_BUF else 0)


cdef inline bint clear(double v, bint watched, double noise) noexcept nogil:
    """A row's value v (or a lower bound of it) clear of an event: an unwatched row > 0, a
    watched one (at zero to within its rounding ``noise``) >= -noise."""
    return v > 0.0 or (watched and v >= -noise)


cdef inline bint at_zero(double u, double scale, double rate, double t) noexcept nogil:
    """Whether a body's velocity u, a sum of terms of size ``scale``, is zero to within its
    rounding noise at time t: the search's (1e-13 of the terms: a watched row is an event below
    minus that) and the time's (its ``rate`` of change over four float spacings)."""
    return fabs(u) <= 1e-13 * scale + 4.0 * rate * (nextafter(fabs(t), INFINITY) - fabs(t))


cdef inline double dot(const double* W, int i, const double* x, int n) noexcept nogil:
    """Row i of the (., n) matrix W times x."""
    cdef double acc = 0.0
    cdef int j
    for j in range(n):
        acc += W[i * n + j] * x[j]
    return acc


cdef inline double quad_root(double g, double d, double c) noexcept nogil:
    """The first zero after 0 of g + d x + c x^2 / 2 (g >= 0), in the forms without
    cancellation: inf if there is none (a row at 0 that does not fall: 0 unless it rises)."""
    cdef double q
    if d <= 0.0:
        q = d * d - 2.0 * c * g
        if q < 0.0:                 # convex, no real zero
            return INFINITY
        q = sqrt(q)
        if q - d > 0.0:
            return 2.0 * g / (q - d)
        return INFINITY if g > 0.0 else 0.0        # d = 0 and c g = 0: constant
    if c >= 0.0:
        return INFINITY
    return (d + sqrt(d * d - 2.0 * c * g)) / -c


cdef inline double cubic(double g, double d, double c, double b3, double x) noexcept nogil:
    """L(x) = g + d x + c x^2 / 2 - b3 x^3 / 6: a row's Taylor lower bound of third order
    (value g, slope d and curvature c at an end, |g'''| <= b3 on the interval)."""
    return g + x * (d + x * (0.5 * c - x * (b3 / 6.0)))


cdef inline double cubic_low(double g, double d, double c, double b3, double h) noexcept nogil:
    """The smallest value of ``cubic`` on [0, h] (b3 >= 0): its ends, and its local minimum
    where that lies inside (L' = d + c x - b3 x^2 / 2 = 0 with L'' > 0: only where d < 0 < c)."""
    cdef double lo = min(g, cubic(g, d, c, b3, h)), q, x
    if d < 0.0 and c > 0.0:
        q = c * c + 2.0 * b3 * d
        if q >= 0.0:
            x = -2.0 * d / (c + sqrt(q))
            if x < h:
                lo = min(lo, cubic(g, d, c, b3, x))
    return lo


cdef double cubic_root(double g, double d, double c, double b3, double floor) noexcept nogil:
    """The first positive zero of ``cubic`` (g > 0, b3 >= 0), from below, or ``floor`` (>= 0, a
    step proven otherwise) where that is no shorter: a point x with L > 0 on [0, x). Within
    1e-2 of the zero where L falls concavely onto it (after its local maximum or inflection s:
    Newton's iterates from above, from the first zero of L's quadratic part, which L <= , or
    Fujiwara's bound on the roots if lower, and the chord from s bracket it: a step needs no
    more); Newton's first step from 0 where L falls convexly onto it (before its local minimum
    or inflection); inf if L has no zero."""
    cdef double s = 0.0, q, x, lo, hi, fl, fh
    cdef int k
    if not g > 0.0:
        return floor
    hi = quad_root(g, d, c)
    if hi <= floor or b3 == 0.0:
        return max(hi, floor)
    if d < 0.0 and c > 0.0:
        q = c * c + 2.0 * b3 * d
        # the local minimum, else the inflection (L falls throughout)
        x = -2.0 * d / (c + sqrt(q)) if q > 0.0 else c / b3
        if cubic(g, d, c, b3, x) <= 0.0:
            # Newton's first step from 0: short of the zero (``step`` then goes just past it)
            return max(g / -d, floor)
        s = (c + sqrt(q)) / b3 if q > 0.0 else x
    elif d >= 0.0:                                      # the local maximum
        q = sqrt(c * c + 2.0 * b3 * d)
        s = (c + q) / b3 if c >= 0.0 else 2.0 * d / (q - c)
    # from s (or the step proven otherwise, if further: where L <= 0 already, this bound
    # cannot lengthen it) L falls: below the zero wherever L > 0
    lo = max(s, floor)
    fl = cubic(g, d, c, b3, lo)
    if not fl > 0.0:
        return floor
    if hi > 4.0 * lo:
        hi = min(hi, 2.0 * max(max(3.0 * fabs(c) / b3, sqrt(6.0 * fabs(d) / b3)),
                               cbrt(3.0 * g / b3)))
    fh = cubic(g, d, c, b3, hi)
    for k in range(16):
        if fh >= 0.0 and hi >= lo:      # on the zero, to rounding (L falls from s to there)
            return max(hi, floor)
        if not (fl > 0.0 and fh < 0.0 and hi > lo) or hi - lo <= 1e-2 * lo:
            break
        lo += fl * (hi - lo) / (fl - fh)
        fl = cubic(g, d, c, b3, lo)
        hi -= fh / (d + hi * (c - 0.5 * b3 * hi))
        fh = cubic(g, d, c, b3, hi)
    return max(lo, floor)


cdef int _copy_into(object a, const void* src, Py_ssize_t nbytes) except -1:
    """Copy nbytes from src into the C-contiguous array ``a`` (of at least that size)."""
    cdef Py_buffer v
    PyObject_GetBuffer(a, &v, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE)
    try:
        if v.len < nbytes:
            raise ValueError('destination too small')
        memcpy(v.buf, src, nbytes)
    finally:
        PyBuffer_Release(&v)
    return 0


cdef double* _buf(object a, Py_buffer* v, Py_ssize_t itemsize, int ndim,
                  const char* name) except NULL:
    """The data of a C-contiguous array ``a`` of ``ndim`` dimensions and items of ``itemsize``
    bytes, through the buffer protocol (a typed memoryview costs several times more per
    argument, and ``ClosedForm.evaluate`` takes eleven)."""
    PyObject_GetBuffer(a, v, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT)
    if v.itemsize != itemsize or v.ndim != ndim:
        PyBuffer_Release(v)
        raise ValueError(f'{name.decode()}: expected a C-contiguous {ndim}-d array of '
                         f'{itemsize}-byte items')
    return <double*>v.buf


cdef class ClosedForm:
    """The closed forms of one crawler's state inside a segment (MODEL.md s. 2), its constants
    kept as C arrays: ``evaluate`` samples many segments at once (``segments.Records``), and
    ``ExactCore.current`` one row. Units: s, m, m/s, N, N s."""

    cdef readonly int p, nl
    cdef double M, fext
    cdef double* mem
    cdef double* W            # (p, nl) offsets from the centre of mass
    cdef double* C            # (p, nl) offsets from body 0
    cdef double* m
    cdef double* fp
    cdef double* fm
    cdef double* grav
    cdef double* sfp          # static bounds (= fp, fm without stiction): a stuck group's split
    cdef double* sfm
    cdef double* e            # work: e, e', e'' of one row (3 p)

    def __cinit__(self, masses, fp, fm, double fext, grav, W, C, sfp=None, sfm=None):
        cdef int p = len(masses), nl = p - 1, i, j
        self.p = p
        self.nl = nl
        self.mem = <double*>PyMem_Calloc(2 * p * max(nl, 1) + 9 * p, sizeof(double))
        if self.mem == NULL:
            raise MemoryError()
        self.W = self.mem
        self.C = self.W + p * max(nl, 1)
        self.m = self.C + p * max(nl, 1)
        self.fp = self.m + p
        self.fm = self.fp + p
        self.grav = self.fm + p
        self.sfp = self.grav + p
        self.sfm = self.sfp + p
        self.e = self.sfm + p
        w, c = np.asarray(W, dtype=float), np.asarray(C, dtype=float)
        sfp = fp if sfp is None else sfp
        sfm = fm if sfm is None else sfm
        for i, (mi, a, b, g, sa, sb) in enumerate(zip(*(np.asarray(q, dtype=float).tolist()
                                                for q in (masses, fp, fm, grav, sfp, sfm)))):
            self.m[i], self.fp[i], self.fm[i], self.grav[i] = mi, a, b, g
            self.sfp[i], self.sfm[i] = sa, sb
            for j in range(nl):
                self.W[i * nl + j] = w[i, j]
                self.C[i * nl + j] = c[i, j]
        self.M = 0.0
        for i in range(p):
            self.M += self.m[i]
        self.fext = fext

    def __dealloc__(self):
        PyMem_Free(self.mem)

    def evaluate(self, l, ld, ldd, f, ref, group, contact, R, K0, owner, tau):
        """Row k of the outputs from the gait values ``l``, ``ld``, ``ldd`` (n, nl) at
        ``tau[k]`` (n,) and the constants of segment ``owner[k]`` (int64): ``f`` rows (t0, t1,
        X0, V0, a, x_ref), ``ref`` (int64), ``group`` (bool or uint8), ``contact`` (int8),
        ``R``, ``K0`` (``segments.Records``), every array C-contiguous.

        Slide: X quadratic in t; stick: the reference body fixed, the group's friction the
        affine split of what holds it (each member at the same fraction of its interval
        [-fp_i, fm_i]) and its impulse the integral of that split.

        Returns (x, v, friction, impulse) (n, p), linkage force (n, p - 1), contact (n, p) int8
        and indeterminate (n,) bool.
        """
        cdef Py_buffer b[11]
        cdef int nb = 0
        cdef Py_ssize_t n = len(tau)
        cdef int p = self.p
        blk = np.empty((4, n, p))
        lam = np.empty((n, max(p - 1, 0)))
        state = np.empty((n, p), np.int8)
        ind = np.empty(n, bool)
        cdef double[:, :, ::1] o = blk
        cdef double[:, ::1] lm = lam
        cdef signed char[:, ::1] st = state
        cdef unsigned char[::1] nd = ind.view(np.uint8)
        cdef double* pl
        cdef double* pld
        cdef double* pldd
        cdef double* pf
        cdef double* pR
        cdef double* pK0
        cdef double* pt
        cdef long* pref
        cdef long* pown
        cdef unsigned char* pg
        cdef signed char* pc
        try:
            pl = _buf(l, &b[0], 8, 2, b'l'); nb += 1
            pld = _buf(ld, &b[1], 8, 2, b'ld'); nb += 1
            pldd = _buf(ldd, &b[2], 8, 2, b'ldd'); nb += 1
            pf = _buf(f, &b[3], 8, 2, b'f'); nb += 1
            pref = <long*>_buf(ref, &b[4], 8, 1, b'ref'); nb += 1
            pg = <unsigned char*>_buf(group, &b[5], 1, 2, b'group'); nb += 1
            pc = <signed char*>_buf(contact, &b[6], 1, 2, b'contact'); nb += 1
            pR = _buf(R, &b[7], 8, 2, b'R'); nb += 1
            pK0 = _buf(K0, &b[8], 8, 2, b'K0'); nb += 1
            pown = <long*>_buf(owner, &b[9], 8, 1, b'owner'); nb += 1
            pt = _buf(tau, &b[10], 8, 1, b'tau'); nb += 1
            if b[0].shape[0] < n or b[9].shape[0] < n or (n and b[0].shape[1] != self.nl):
                raise ValueError('gait values and owner must have one row per time')
            if b[3].shape[1] != 6:
                raise ValueError('f: rows of (t0, t1, X0, V0, a, x_ref) expected')
            if n:
                self._rows(n, pl, pld, pldd, pf, pref, pg, pc, pR, pK0, pown, pt,
                           &o[0, 0, 0], &o[1, 0, 0], &o[2, 0, 0], &o[3, 0, 0],
                           &lm[0, 0] if p > 1 else NULL, &st[0, 0], &nd[0])
        finally:
            for i in range(nb):
                PyBuffer_Release(&b[i])
        return blk[0], blk[1], blk[2], blk[3], lam, state, ind

    def sample(self, CompiledGait gait, f, ref, group, contact, R, K0, tau):
        """``evaluate`` of consecutive segments (records as there, one gait, starts f[:, 0]
        increasing) at the sorted times ``tau`` [s], each time in the last segment starting at
        or before it (the first before the first start), the gait evaluated here too (a run's
        sampling, ``ExactSolver.sample``: no table of records, no search from Python).

        Returns (x, v, friction, impulse, linkage force, contact, indeterminate, l, l')."""
        cdef int nl = self.nl, j
        cdef Py_ssize_t n = len(tau), k, sg = 0, n_seg
        cdef const double[::1] tv = tau
        cdef const double[:, ::1] fv = f
        vals = np.empty((3, n, nl))
        own = np.zeros(n, np.int64)
        cdef double[:, :, ::1] gv = vals
        cdef long[::1] ow = own
        cdef double ld3[64]
        cdef double* w3 = ld3
        n_seg = fv.shape[0]
        if n and (n_seg == 0 or gait.d.nl != nl):
            raise ValueError('sample: no segments, or a gait of another crawler')
        # each time's segment: a merge of the sorted times with the sorted starts
        for k in range(n):
            while sg + 1 < n_seg and fv[sg + 1, 0] <= tv[k]:
                sg += 1
            ow[k] = sg
        if n and nl:
            if nl > 64:
                w3 = <double*>PyMem_Malloc(nl * sizeof(double))
                if w3 == NULL:
                    raise MemoryError()
            try:
                for k in range(n):
                    gait_eval(&gait.d, tv[k], &gv[0, k, 0], &gv[1, k, 0], &gv[2, k, 0], w3)
            finally:
                if w3 != ld3:
                    PyMem_Free(w3)
        out = self.evaluate(vals[0], vals[1], vals[2], f, ref, group, contact, R, K0, own, tau)
        return out + (vals[0], vals[1])

    cdef void _rows(self, Py_ssize_t n, const double* l, const double* ld, const double* ldd,
                    const double* f, const long* ref_s, const unsigned char* grp,
                    const signed char* contact_s, const double* Rseg, const double* K0_s,
                    const long* owner, const double* tau, double* x, double* v, double* R,
                    double* K, double* lam, signed char* state, unsigned char* ind) noexcept:
        cdef int p = self.p, nl = self.nl, i, j, r, n_group, c
        cdef Py_ssize_t k, sg, kp
        cdef double a0, a1, a2, d, X, V, A, sr, sdr, s, sd, f_slide, wg, fm_g, total
        cdef double theta, imp, q, w, acc
        cdef const double* fs
        cdef double* e = self.e
        cdef double* ep = self.e + p
        cdef double* epp = self.e + 2 * p
        for k in range(n):
            sg = owner[k]
            fs = f + 6 * sg
            kp = k * p
            for i in range(p):
                a0 = 0.0
                a1 = 0.0
                a2 = 0.0
                for j in range(nl):
                    a0 += l[k * nl + j] * self.W[i * nl + j]
                    a1 += ld[k * nl + j] * self.W[i * nl + j]
                    a2 += ldd[k * nl + j] * self.W[i * nl + j]
                e[i] = a0
                ep[i] = a1
                epp[i] = a2
            d = tau[k] - fs[0]
            r = ref_s[sg]
            if r < 0:
                X = fs[2] + d * (fs[3] + 0.5 * fs[4] * d)
                V = fs[3] + fs[4] * d
                for i in range(p):
                    x[kp + i] = X + e[i]
                    v[kp + i] = V + ep[i]
                A = fs[4]
            else:
                sr = 0.0
                sdr = 0.0
                for j in range(nl):
                    sr += l[k * nl + j] * self.C[r * nl + j]
                    sdr += ld[k * nl + j] * self.C[r * nl + j]
                for i in range(p):
                    s = 0.0
                    sd = 0.0
                    for j in range(nl):
                        s += l[k * nl + j] * self.C[i * nl + j]
                        sd += ld[k * nl + j] * self.C[i * nl + j]
                    x[kp + i] = fs[5] + (s - sr)
                    v[kp + i] = sd - sdr
                A = -epp[r]
                V = -ep[r]
            f_slide = 0.0
            n_group = 0
            for i in range(p):
                R[kp + i] = 0.0 if grp[sg * p + i] else Rseg[sg * p + i]
                f_slide += R[kp + i]
                K[kp + i] = K0_s[sg * p + i] + d * R[kp + i]
                if grp[sg * p + i]:
                    n_group += 1
            f_slide += self.fext
            if r >= 0:
                wg = 0.0
                fm_g = 0.0
                for i in range(p):
                    if grp[sg * p + i]:
                        # the documented split (core/friction.py: split_stuck): each member
                        # at the same point of its static interval
                        wg += self.sfp[i] + self.sfm[i]
                        fm_g += self.sfm[i]
                if wg > 0.0:
                    total = self.M * A - f_slide
                    theta = split_theta(total, fm_g, wg)
                    imp = self.M * (V - fs[3]) - f_slide * d
                    q = (-imp + fm_g * d) / wg
                    for i in range(p):
                        if grp[sg * p + i]:
                            w = self.sfp[i] + self.sfm[i]
                            R[kp + i] = split_force(theta, self.sfp[i], self.sfm[i])
                            K[kp + i] = K0_s[sg * p + i] + (self.sfm[i] * d - q * w)
                else:
                    for i in range(p):
                        if grp[sg * p + i]:
                            K[kp + i] = K0_s[sg * p + i]
            acc = 0.0
            for i in range(p - 1):
                acc += R[kp + i] + self.grav[i] - self.m[i] * (A + epp[i])
                lam[k * (p - 1) + i] = acc
            for i in range(p):
                c = contact_s[sg * p + i]
                if self.sfp[i] + self.sfm[i] == 0.0:      # frictionless (static >= kinetic)
                    c = 1 if v[kp + i] > 0 else (-1 if v[kp + i] < 0 else 0)
                state[kp + i] = c
            ind[k] = n_group > 1

    def row(self, CompiledGait gait, f, long ref, contact, group, R, K0, double t):
        """One output row (a dict, as ``ExactSolver.current`` gives) of the segment (f (6,),
        ref, contact, group, R, K0) at t [s]."""
        p = self.p
        l, ld, ldd = gait.values(np.array([t]))
        x, v, Rout, K, lam, state, ind = self.evaluate(
            l, ld, ldd, np.ascontiguousarray(f, dtype=float).reshape(1, 6),
            np.array([ref], np.int64), np.ascontiguousarray(group, dtype=np.uint8).reshape(1, p),
            np.ascontiguousarray(contact, dtype=np.int8).reshape(1, p),
            np.ascontiguousarray(R, dtype=float).reshape(1, p),
            np.ascontiguousarray(K0, dtype=float).reshape(1, p), np.zeros(1, np.int64),
            np.array([t]))
        return {'x': x[0], 'v': v[0], 'friction': Rout[0], 'impulse': K[0],
                'linkage_force': lam[0], 'lengths': l[0], 'rates': ld[0], 'contact': state[0],
                'indeterminate': bool(ind[0])}


@cython.final
cdef class ExactCore:
    """State and loop of one exact solve (``exact.ExactSolver`` wraps it). Its arrays live in
    two C blocks allocated once (a solver per ``simulate``: numpy arrays cost ~100 us)."""

    # crawler
    cdef readonly int p, nl, nr
    cdef double M, fext, f_total, v_acc
    cdef double* W                # (p, nl) offsets of the bodies from the centre of mass
    cdef double* C                # (p, nl) offsets from body 0
    cdef double* fp
    cdef double* fm
    cdef double* sfp              # static bounds [N] (core/friction.py; = fp, fm without stiction)
    cdef double* sfm
    cdef double* m_
    cdef double* grav
    cdef unsigned char* free
    # stiction (STICTION.md): Rule S decides the mode on top of the kinetic inclusion, only
    # when a static bound is above its kinetic one (else the code paths are today's, bit for
    # bit); ``margin_rule``: largest margin without incumbency (``stiction_rule='margin'``)
    cdef public bint stiction, margin_rule
    cdef unsigned char* inc       # (p,) the cluster stuck just before t (the incumbent)
    cdef unsigned char* ck_inc    # (p,) the incumbent a period earlier
    cdef int n_cons               # consistent continuations at the last decision (``rule_s``)
    cdef bint tie                 # ... and whether the margin had an exact tie
    cdef public long n_choice
    cdef double* ch_t             # (n_buf,) times where the rule chose (several consistent)
    cdef long* ch_n               # (2 n_buf,) their number of continuations, tie (0/1)
    # settings
    cdef public double tol, tscale, cap
    # state: body 0 follows from X, V and the gait (X, V: centre of mass [m, m/s])
    cdef public double t, X, V, x_ref
    # a periodic gait's frame: the loop runs in local time tl = t - origin, origin = origin_k T
    # (the float product of the period count and the period, never a running sum), so a
    # period's arithmetic is the first period's whatever the period count: event times to
    # ulp(T), not ulp(t), and the gait read at the same floats each period. ``t`` is absolute
    cdef public double tl, origin
    cdef public long origin_k
    cdef public bint skip         # a period that repeats the previous one stops ``drive``
    cdef public int ref
    cdef double* K
    cdef signed char* contact
    cdef unsigned char* zero
    # mode kept across a smooth segment boundary
    cdef public bint cache_ok
    cdef double cache_a
    cdef unsigned char* cache_group
    # periodic checkpoint: the state at the last multiple of the period
    cdef public bint ck_valid
    cdef public long ck_k, ck_nseg, ck_nev
    cdef public double ck_X, ck_V, ck_x_ref
    cdef public int ck_ref
    cdef double* ck_K
    cdef signed char* ck_contact
    cdef unsigned char* ck_zero
    # the last segment (the state between calls is its end)
    cdef public bint last_valid
    cdef double* last_f
    cdef public int last_ref
    cdef signed char* last_contact
    cdef unsigned char* last_group
    cdef double* last_R
    cdef double* last_K0
    cdef public object last_gait
    cdef public object closed     # ClosedForm of this crawler (``current``)
    # outputs of one call: segment records and contact changes (``records``, ``events``)
    cdef public long n_seg, n_ev, n_evals, seg_base, ev_base, k_at
    cdef public double bad_time
    cdef int n_buf
    cdef double* sf               # (n_buf, 6): t0, t1, X0, V0, a, x_ref
    cdef long* sref
    cdef signed char* scontact    # (n_buf, p)
    cdef unsigned char* sgroup    # (n_buf, p)
    cdef double* sR               # (n_buf, p)
    cdef double* sK0              # (n_buf, p)
    cdef double* et               # (2 n_buf,)
    cdef long* ei                 # (2 n_buf, 3)
    # work
    cdef double* l
    cdef double* ld
    cdef double* ldd
    cdef double* ld3
    cdef double* ld2
    cdef double* ldd2
    cdef double* e
    cdef double* ep
    cdef double* epp
    cdef double* ep2
    cdef double* epp2
    cdef double* R
    cdef double* sd
    cdef double* c0
    cdef double* c1
    cdef double* B2
    cdef double* B1
    cdef double* B3               # (nr,) |g'''| of a row of l' alone (inf for the others)
    cdef double h_watch           # a step the watched rows' cubic bounds prove (``step``)
    cdef double h_free            # a step the watched rows need no proof for (``proven``)
    cdef double* noise
    cdef double* RL               # (nr,) each row's smallest value (``range_lower``)
    cdef double* jerk
    cdef double* snap
    cdef double* kinks
    cdef double* fpz
    cdef double* fmz
    cdef double* A1               # (nr, nl)
    cdef double* A2               # (nr, nl)
    cdef double* wk               # (14, nr)
    cdef double* qd               # (4, nr) the rows' quadratics on a piece (``piece_lows``)
    cdef long* lab_kind
    cdef long* lab_body
    cdef unsigned char* watch
    cdef unsigned char* hit
    cdef unsigned char* mirror    # (nr,) row r is row r - 1 negated, but for c0 (a bound pair)
    cdef unsigned char* hits
    cdef unsigned char* group
    cdef unsigned char* group2
    cdef signed char* new_contact
    cdef signed char* new2
    cdef int* idx
    cdef int* zidx
    # the C blocks, and a snapshot of the state (``save`` / ``restore``)
    cdef char* _mem
    cdef char* _snap
    cdef Py_ssize_t _n_state
    cdef double _snap_f[24]
    cdef object _saved_gait

    def __cinit__(self, ClosedForm closed, double tol):
        cdef int p = closed.p, nl = max(p - 1, 1), nr = 3 * p + 2, n_buf = N_BUF
        cdef int n_evr = ev_records(p)
        cdef Py_ssize_t nd, nb, off
        self.p = p
        self.nl = p - 1
        self.nr = nr
        self.n_buf = n_buf
        # doubles: state first (K, ck_K, last_f, last_R, last_K0 are what ``save`` copies)
        nd = (p + p + 6 + p + p                       # K, ck_K, last_f, last_R, last_K0
              + 6 * p + 2 * p * nl                    # fp, fm, sfp, sfm, m_, grav, W, C
              + 8 * nl + 10 * p                       # l .. snap, e .. fmz
              + 7 * nr + 2 * nr * nl + 18 * nr        # c0 .. noise, RL, B3, A1 .. qd
              + 6 * n_buf + 2 * p * n_buf + n_evr)        # sf, sR, sK0, et
        nb = (p + p + p + p + p + p + p               # contact zero cache_group ck_contact ck_zero
              + p + p + p + p + p                     # last_contact last_group free hits group
              + p + p                                 # inc ck_inc
              + p + p + p                             # group2 new_contact new2
              + 3 * nr + 2 * p * n_buf)               # watch hit mirror, scontact sgroup
        self._mem = <char*>PyMem_Calloc(1, nd * sizeof(double) + nb + 16
                                        + (2 * nr + n_buf + 3 * n_evr) * sizeof(long)
                                        + 2 * p * sizeof(int) + 64)
        if self._mem == NULL:
            raise MemoryError()
        cdef double* d = <double*>self._mem
        self.K = d; d += p
        self.ck_K = d; d += p
        self.last_f = d; d += 6
        self.last_R = d; d += p
        self.last_K0 = d; d += p
        self._n_state = 3 * p + p + 6          # doubles of the state block above
        self.fp = d; d += p
        self.fm = d; d += p
        self.sfp = d; d += p
        self.sfm = d; d += p
        self.m_ = d; d += p
        self.grav = d; d += p
        self.W = d; d += p * nl
        self.C = d; d += p * nl
        self.l = d; d += nl
        self.ld = d; d += nl
        self.ldd = d; d += nl
        self.ld3 = d; d += nl
        self.ld2 = d; d += nl
        self.ldd2 = d; d += nl
        self.jerk = d; d += nl
        self.snap = d; d += nl
        self.e = d; d += p
        self.ep = d; d += p
        self.epp = d; d += p
        self.ep2 = d; d += p
        self.epp2 = d; d += p
        self.R = d; d += p
        self.sd = d; d += p
        self.kinks = d; d += p
        self.fpz = d; d += p
        self.fmz = d; d += p
        self.c0 = d; d += nr
        self.c1 = d; d += nr
        self.B2 = d; d += nr
        self.B1 = d; d += nr
        self.noise = d; d += nr
        self.RL = d; d += nr
        self.B3 = d; d += nr
        self.A1 = d; d += nr * nl
        self.A2 = d; d += nr * nl
        self.wk = d; d += 14 * nr
        self.qd = d; d += 4 * nr
        self.sf = d; d += 6 * n_buf
        self.sR = d; d += p * n_buf
        self.sK0 = d; d += p * n_buf
        self.et = d; d += n_evr
        cdef long* q = <long*>d
        self.lab_kind = q; q += nr
        self.lab_body = q; q += nr
        self.sref = q; q += n_buf
        self.ei = q; q += 3 * n_evr
        cdef int* ii = <int*>q
        self.idx = ii; ii += p
        self.zidx = ii; ii += p
        cdef unsigned char* u = <unsigned char*>ii
        self.contact = <signed char*>u; u += p
        self.zero = u; u += p
        self.cache_group = u; u += p
        self.ck_contact = <signed char*>u; u += p
        self.ck_zero = u; u += p
        self.last_contact = <signed char*>u; u += p
        self.last_group = u; u += p
        self.inc = u; u += p                # (after last_group: ``save`` copies them together)
        self.ck_inc = u; u += p
        self.free = u; u += p
        self.hits = u; u += p
        self.group = u; u += p
        self.group2 = u; u += p
        self.new_contact = <signed char*>u; u += p
        self.new2 = <signed char*>u; u += p
        self.watch = u; u += nr
        self.hit = u; u += nr
        self.mirror = u; u += nr
        self.scontact = <signed char*>u; u += p * n_buf
        self.sgroup = u; u += p * n_buf
        self._snap = <char*>PyMem_Calloc(1, self._n_state * sizeof(double) + 10 * p + 16)
        self.ch_t = <double*>PyMem_Calloc(n_buf, sizeof(double))
        self.ch_n = <long*>PyMem_Calloc(2 * n_buf, sizeof(long))
        if self._snap == NULL or self.ch_t == NULL or self.ch_n == NULL:
            raise MemoryError()

    def __dealloc__(self):
        PyMem_Free(self._mem)
        PyMem_Free(self._snap)
        PyMem_Free(self.ch_t)
        PyMem_Free(self.ch_n)

    def __init__(self, ClosedForm closed, double tol):
        """The segment loop of the crawler whose constants ``closed`` holds (its masses [kg],
        friction bounds [N], external and gravity forces [N], offset matrices), event times to
        ``tol`` [s]."""
        cdef int p = self.p, nl = self.nl, i
        cdef Py_ssize_t nw = p * nl
        self.closed = closed
        memcpy(self.m_, closed.m, p * sizeof(double))
        memcpy(self.fp, closed.fp, p * sizeof(double))
        memcpy(self.fm, closed.fm, p * sizeof(double))
        memcpy(self.sfp, closed.sfp, p * sizeof(double))
        memcpy(self.sfm, closed.sfm, p * sizeof(double))
        memcpy(self.grav, closed.grav, p * sizeof(double))
        if nw:
            memcpy(self.W, closed.W, nw * sizeof(double))
            memcpy(self.C, closed.C, nw * sizeof(double))
        fext = closed.fext
        self.M = 0.0
        self.f_total = 0.0
        for i in range(p):
            self.M += self.m_[i]
            self.f_total += self.fp[i] + self.fm[i]
            # frictionless: no static bound either (a body with kinetic 0 < static can stick)
            self.free[i] = (self.sfp[i] + self.sfm[i]) == 0.0
            if self.sfp[i] > self.fp[i] or self.sfm[i] > self.fm[i]:
                self.stiction = True
        self.fext = fext
        self.v_acc = (self.f_total + abs(fext)) / self.M
        self.tol = tol
        self.tscale = 1.0
        self.cap = 0.0
        self.ref = -1
        self.last_valid = False

    # ------------------------------------------------------------------ Python access
    @property
    def incumbent_array(self):
        """(p,) bool: the bodies of the cluster stuck just before t (STICTION.md s. 7)."""
        return np.array(<unsigned char[:self.p]>self.inc).astype(bool)

    @incumbent_array.setter
    def incumbent_array(self, value):
        cdef int i
        for i, x in enumerate(np.asarray(value).tolist()):
            self.inc[i] = bool(x)

    def choices(self, int n):
        """The call's first n instants where Rule S chose among several consistent
        continuations: a list of (time [s], number of continuations, exact tie of margins)."""
        return [(self.ch_t[k], self.ch_n[2 * k], bool(self.ch_n[2 * k + 1])) for k in range(n)]

    @property
    def K_array(self):
        return np.array(<double[:self.p]>self.K)

    @K_array.setter
    def K_array(self, value):
        cdef int i
        for i, x in enumerate(np.asarray(value, dtype=float).tolist()):
            self.K[i] = x

    @property
    def contact_array(self):
        return np.array(<signed char[:self.p]>self.contact)

    @contact_array.setter
    def contact_array(self, value):
        cdef int i
        for i, x in enumerate(np.asarray(value).tolist()):
            self.contact[i] = x

    @property
    def zero_array(self):
        return np.array(<unsigned char[:self.p]>self.zero).astype(bool)

    @zero_array.setter
    def zero_array(self, value):
        cdef int i
        for i, x in enumerate(np.asarray(value).tolist()):
            self.zero[i] = bool(x)

    @property
    def ck_K_array(self):
        return np.array(<double[:self.p]>self.ck_K)

    def signature(self):
        """(contact, zero set, ref): what must repeat at a period boundary."""
        return (bytes(<signed char[:self.p]>self.contact), bytes(<unsigned char[:self.p]>self.zero),
                self.ref)

    def last_record(self):
        """The last segment as (f, ref, contact, group, R, K0, gait) or None."""
        if not self.last_valid:
            return None
        return (np.array(<double[:6]>self.last_f), self.last_ref,
                np.array(<signed char[:self.p]>self.last_contact),
                np.array(<unsigned char[:self.p]>self.last_group).astype(bool),
                np.array(<double[:self.p]>self.last_R), np.array(<double[:self.p]>self.last_K0),
                self.last_gait)

    def records(self, int n):
        """Copies of the call's first n segment records: (f (n, 6), ref, contact (n, p),
        group (n, p) bool, R, K0)."""
        p = self.p
        out = (np.empty((n, 6)), np.empty(n, np.int64), np.empty((n, p), np.int8),
               np.empty((n, p), bool), np.empty((n, p)), np.empty((n, p)))
        if n:
            _copy_into(out[0], self.sf, n * 6 * sizeof(double))
            _copy_into(out[1], self.sref, n * sizeof(long))
            _copy_into(out[2], self.scontact, n * p)
            _copy_into(out[3], self.sgroup, n * p)        # 0 / 1 bytes: valid bools
            _copy_into(out[4], self.sR, n * p * sizeof(double))
            _copy_into(out[5], self.sK0, n * p * sizeof(double))
        return out

    def events(self, int n, make):
        """The call's first n contact changes as a list of ``make((time, body, old, new))``
        (``make`` builds an ``Event`` from its tuple)."""
        return event_records(core_event_records(self, n), make)

    def save(self):
        """Keep the state, so a call that raises can be undone (``restore``)."""
        self._save()

    cdef int _save(self) except -1:
        cdef int p = self.p
        memcpy(self._snap, self.K, self._n_state * sizeof(double))
        cdef char* b = self._snap + self._n_state * sizeof(double)
        memcpy(b, self.contact, 9 * p)           # contact .. last_group, inc, ck_inc
        self._snap_f[0] = self.t
        self._snap_f[1] = self.X
        self._snap_f[2] = self.V
        self._snap_f[3] = self.x_ref
        self._snap_f[4] = self.ref
        self._snap_f[5] = self.cache_ok
        self._snap_f[6] = self.cache_a
        self._snap_f[7] = self.ck_valid
        self._snap_f[8] = self.ck_k
        self._snap_f[9] = self.ck_nseg
        self._snap_f[10] = self.ck_nev
        self._snap_f[11] = self.ck_X
        self._snap_f[12] = self.ck_V
        self._snap_f[13] = self.ck_x_ref
        self._snap_f[14] = self.ck_ref
        self._snap_f[15] = self.last_valid
        self._snap_f[16] = self.last_ref
        self._snap_f[17] = self.tl
        self._snap_f[18] = self.origin
        self._snap_f[19] = self.origin_k
        self._saved_gait = self.last_gait
        return 0

    def restore(self):
        self._restore()

    cdef int _restore(self) except -1:
        cdef int p = self.p
        memcpy(self.K, self._snap, self._n_state * sizeof(double))
        memcpy(self.contact, self._snap + self._n_state * sizeof(double), 9 * p)
        self.t = self._snap_f[0]
        self.X = self._snap_f[1]
        self.V = self._snap_f[2]
        self.x_ref = self._snap_f[3]
        self.ref = <int>self._snap_f[4]
        self.cache_ok = self._snap_f[5] != 0.0
        self.cache_a = self._snap_f[6]
        self.ck_valid = self._snap_f[7] != 0.0
        self.ck_k = <long>self._snap_f[8]
        self.ck_nseg = <long>self._snap_f[9]
        self.ck_nev = <long>self._snap_f[10]
        self.ck_X = self._snap_f[11]
        self.ck_V = self._snap_f[12]
        self.ck_x_ref = self._snap_f[13]
        self.ck_ref = <int>self._snap_f[14]
        self.last_valid = self._snap_f[15] != 0.0
        self.last_ref = <int>self._snap_f[16]
        self.tl = self._snap_f[17]
        self.origin = self._snap_f[18]
        self.origin_k = <long>self._snap_f[19]
        self.last_gait = self._saved_gait
        self.n_seg = 0
        self.n_ev = 0
        self.n_choice = 0
        return 0

    def forget_mode(self):
        """The next segment chooses its mode anew (a gait switch that is not C2)."""
        self.cache_ok = False

    def reset(self, CompiledGait gait, double t0, double x0, double v0):
        """Start at t0 [s] with body 0 at x0 [m] moving at v0 [m/s]: the centre of mass
        from the gait, each body's contact the sign of its velocity (a frictionless body 0),
        the bodies at exactly zero velocity in the zero set. Returns False for a non-finite
        gait value."""
        cdef int p = self.p, nl = self.nl, i, j
        cdef double v
        gait_eval(&gait.d, t0, self.l, self.ld, self.ldd, self.ld3)
        for j in range(nl):
            if not (isfinite(self.l[j]) and isfinite(self.ld[j])):
                self.bad_time = t0
                return False
        self.t = t0
        self.tl = t0
        self.origin = 0.0
        self.origin_k = 0
        self.X = x0 - dot(self.W, 0, self.l, nl)
        self.V = v0 - dot(self.W, 0, self.ld, nl)
        for i in range(p):
            v = v0 + dot(self.C, i, self.ld, nl)    # exact zeros stay zero
            if self.free[i]:
                self.contact[i] = 0
                self.zero[i] = 0
            else:
                self.contact[i] = 1 if v > 0.0 else (-1 if v < 0.0 else 0)
                self.zero[i] = v == 0.0
            self.K[i] = 0.0
            self.inc[i] = 0       # no incumbent (``ExactSolver.reset``: initial_stuck sets one)
        self.ref = -1
        self.x_ref = 0.0
        self.cache_ok = False
        self.ck_valid = False
        self.last_valid = False
        self.last_gait = None
        self.n_evals = 0
        return True

    def skip_periods(self, long n, double T, long k):
        """Skip n repeats of the period just completed at k T: returns (D, dK), the
        displacement [m] and impulse [N s] of one period."""
        cdef int i, p = self.p
        D = self.X - self.ck_X
        dK = np.array(<double[:p]>self.K) - np.array(<double[:p]>self.ck_K)
        self.X += n * D
        self.x_ref += n * D
        for i in range(p):
            self.K[i] += n * dK[i]
        self.t = (k + n) * T
        self.origin_k = k + n         # the frame of period k + n: local time 0
        self.origin = self.t
        self.tl = 0.0
        self.last_valid = False
        self.ck_k = k + n
        self.ck_X = self.X
        self.ck_V = self.V
        self.ck_x_ref = self.x_ref
        self.ck_ref = self.ref
        for i in range(p):
            self.ck_K[i] = self.K[i]
            self.ck_contact[i] = self.contact[i]
            self.ck_zero[i] = self.zero[i]
            self.ck_inc[i] = self.inc[i]
        self.ck_valid = True
        return D, dK

    # ------------------------------------------------------------------ mode
    cdef int solve_mode(self, const double* epp, const signed char* contact, double slack,
                        bint merge, signed char* out, unsigned char* group, double* A,
                        int* ref) noexcept:
        """The instantaneous mode of the bodies at rest (``zero``): writes their contact in
        ``out`` (others copied), the group stuck together, the acceleration A [m/s^2] and
        the reference body; returns 1 when the choice is degenerate (a tie within ``slack``)."""
        cdef int p = self.p, i, k, nz = 0, r = -1, ambiguous = 0, order, v, j
        cdef double force = self.fext, acc_scale, f_scale, s = 0.0, a, rel, lo = 0.0, hi = 0.0
        cdef double x
        cdef int* zi = self.zidx
        for i in range(p):
            out[i] = contact[i]
            group[i] = 0
            if self.zero[i]:
                zi[nz] = i
                nz += 1
            else:       # a sliding body, or a frictionless one (0)
                force += ground_force(contact[i], self.fp[i], self.fm[i])
        acc_scale = (self.f_total + fabs(force)) / self.M
        for i in range(p):
            if fabs(epp[i]) > acc_scale:
                acc_scale = fabs(epp[i])
        if acc_scale < 1e-300:
            acc_scale = 1e-300
        f_scale = self.M * acc_scale
        for k in range(nz):
            i = zi[k]
            self.kinks[k] = -epp[i]
            self.fpz[k] = self.fp[i]
            self.fmz[k] = self.fm[i]
        if merge and nz > 1:
            # bodies rigidly linked have equal relative accelerations mathematically but not
            # always bitwise: kinks closer than 1e-13 of the scale are one kink
            for k in range(nz):
                self.idx[k] = k
            for k in range(1, nz):
                v = self.idx[k]
                j = k
                while j > 0 and self.kinks[self.idx[j - 1]] > self.kinks[v]:
                    self.idx[j] = self.idx[j - 1]
                    j -= 1
                self.idx[j] = v
            x = self.kinks[self.idx[0]]
            for k in range(1, nz):
                order = self.idx[k]
                if self.kinks[order] - x <= 1e-13 * acc_scale:
                    self.kinks[order] = x
                else:
                    x = self.kinks[order]
        a = inclusion(self.M, 0.0, force, self.kinks, self.fpz, self.fmz, nz,
                      self.idx, &s)
        for k in range(nz):
            i = zi[k]
            rel = a - self.kinks[k]
            if rel == 0.0:
                out[i] = 0
                group[i] = 1
                lo -= self.fm[i]
                hi += self.fp[i]
                if r < 0:
                    r = i
            else:
                out[i] = 1 if rel > 0.0 else -1
                if fabs(rel) <= slack * acc_scale:
                    ambiguous = 1
        if r >= 0:
            if self.ref >= 0 and group[self.ref]:
                r = self.ref
            if hi - lo > 0.0 and min(s - lo, hi - s) <= slack * f_scale:
                ambiguous = 1
        A[0] = a
        ref[0] = r
        return ambiguous

    cdef bint rigid(self, GaitData* g, const unsigned char* group, double t,
                    double span) except -1:
        """True if the group's relative velocities stay zero just after t (a rigid link)."""
        cdef int p = self.p, i, first, rep
        cdef double rel_dt, dt, mx, r0
        if span <= 0.0:
            return True
        for rep in range(2):
            # two look-aheads: the nearer one can round a slowly growing rate to exactly zero
            rel_dt = 1e-9 if rep == 0 else 1e-6
            dt = min(rel_dt * max(span, self.tscale), 0.5 * span)
            gait_rates(g, t + dt, self.ld2, self.ldd2, self.ld3)
            mx = 0.0
            for i in range(p):
                self.sd[i] = dot(self.C, i, self.ld2, self.nl)
                if fabs(self.sd[i]) > mx:
                    mx = fabs(self.sd[i])
            first = -1
            for i in range(p):
                if group[i]:
                    if first < 0:
                        first = i
                        r0 = self.sd[i]
                    elif fabs(self.sd[i] - r0) > 1e-13 * (mx + 1e-300):
                        return False
        return True

    cdef int mode(self, GaitData* g, double t, double ts, double* A, int* ref) except -1:
        """Contact mode at t for the bodies in ``zero``: new contact in ``new_contact``, the
        group in ``group``, acceleration A and reference body."""
        cdef int p = self.p, i, amb, n_group, loose, rep
        cdef double span, rel, dt, a2, tot
        cdef int ref2
        if not self._any_zero():
            tot = self.fext
            for i in range(p):
                self.new_contact[i] = self.contact[i]
                self.group[i] = 0
                tot += ground_force(self.contact[i], self.fp[i], self.fm[i])
            A[0] = tot / self.M
            ref[0] = -1
            return 0
        amb = self.select(self.epp, AMBIGUOUS, True, A, ref)
        span = max(ts - t, 0.0)
        n_group = 0
        for i in range(p):
            n_group += self.group[i]
        loose = n_group > 1 and not self.rigid(g, self.group, t, span)
        if amb or loose:
            # Decide by the inclusion a little later (same zero set); near t the deciding
            # quantities grow from zero, so only their sign matters: a tighter threshold
            # there. A link that is not rigid must not be merged into one kink either.
            for rep in range(3):
                rel = 1e-9 if rep == 0 else (1e-7 if rep == 1 else 1e-5)
                dt = min(rel * max(span, self.tscale), 0.5 * span) if span > 0.0 else 0.0
                if dt <= 0.0:
                    break
                gait_rates(g, t + dt, self.ld2, self.ldd2, self.ld3)
                for i in range(p):
                    self.epp2[i] = dot(self.W, i, self.ldd2, self.nl)
                amb = self.select(self.epp2, 1e-14, not loose, A, ref)
                if not amb:
                    break
        return 0

    cdef int select(self, const double* epp, double slack, bint merge, double* A,
                    int* ref) noexcept:
        """The mode of the bodies at rest into ``new_contact``, ``group``, A, ref: the kinetic
        inclusion (``solve_mode``), then, for a crawler with stiction, Rule S over it
        (``rule_s``). Returns 1 when the choice is degenerate (decided a little later)."""
        cdef int amb = self.solve_mode(epp, self.contact, slack, merge, self.new_contact,
                                       self.group, A, ref)
        self.n_cons = 1
        self.tie = False
        if self.stiction:
            amb = self.rule_s(slack, A, ref) or amb
        return amb

    cdef int rule_s(self, double slack, double* A, int* ref) noexcept:
        """Rule S (STICTION.md s. 3, 5) over the kinetic answer that ``solve_mode`` just
        wrote (its merged kinks in ``kinks``, the bodies at rest in ``zidx``): every cluster
        of bodies at rest (equal kinks, i.e. rigid at t+) is a stick candidate, consistent when
        the ground force it needs, the others sliding at their kinetic bounds in the
        directions its own acceleration gives them, is within its summed static interval
        [-sum sfp, sum sfm]. The incumbent's cluster (a member stuck just before t) holds
        first unless ``margin_rule``; otherwise the largest static margin, exact ties to the
        lowest body index (flagged: ``tie``). With no consistent candidate the kinetic answer
        stays (then the unique slide pattern). ``n_cons``: the consistent continuations (the
        candidates, and the slide pattern when the kinetic answer has no stuck body). Returns
        1 when a candidate's margin or two clusters' kinks are within ``slack`` of a tie
        (decided a little later, on t+ data)."""
        cdef int p = self.p, i, j, k, k2, nz = 0, best = -1, amb = 0, low, n_cons = 0
        cdef double force = self.fext, acc_scale, f_scale, kap, rc, lo, hi, margin
        cdef double best_m = -INFINITY
        cdef bint incm, best_inc = False, dup, tie = False
        cdef int* zi = self.zidx
        for i in range(p):
            if self.zero[i]:
                nz += 1
            else:
                force += ground_force(self.contact[i], self.fp[i], self.fm[i])
        acc_scale = (self.f_total + fabs(force)) / self.M
        for k in range(nz):
            if fabs(self.kinks[k]) > acc_scale:
                acc_scale = fabs(self.kinks[k])
        if acc_scale < 1e-300:
            acc_scale = 1e-300
        f_scale = self.M * acc_scale
        for k in range(nz):
            kap = self.kinks[k]
            dup = False
            for k2 in range(k):
                if self.kinks[k2] == kap:
                    dup = True
                    break
            if dup:
                continue            # the cluster was met at its lowest body (zidx ascends)
            # the ground force the cluster needs: M A = F_ext + sum of ground forces, A = kap
            rc = self.M * kap - force
            lo = 0.0
            hi = 0.0
            incm = False
            for k2 in range(nz):
                j = zi[k2]
                if self.kinks[k2] == kap:
                    lo -= self.sfp[j]
                    hi += self.sfm[j]
                    incm = incm or self.inc[j]
                else:
                    if fabs(self.kinks[k2] - kap) <= slack * acc_scale:
                        amb = 1
                    # j slides forward (its kink below the cluster's) or backward
                    rc -= ground_force(1 if self.kinks[k2] < kap else -1, self.fp[j], self.fm[j])
            if hi - lo == 0.0:
                continue
            margin = min(rc - lo, hi - rc)
            if fabs(margin) <= slack * f_scale:
                amb = 1
            if margin < 0.0:
                continue
            n_cons += 1
            incm = incm and not self.margin_rule
            if best < 0 or (incm and not best_inc) or (incm == best_inc and margin > best_m):
                best = k
                best_m = margin
                best_inc = incm
                tie = False
            elif incm == best_inc and margin == best_m:
                tie = True
        if ref[0] < 0:
            n_cons += 1                 # the slide pattern (the kinetic answer) is consistent
        self.n_cons = n_cons
        self.tie = tie
        if best < 0:
            return amb
        kap = self.kinks[best]
        if ref[0] >= 0 and A[0] == kap:
            return amb                  # the kinetic answer sticks the same cluster
        low = -1
        for k in range(nz):
            i = zi[k]
            if self.kinks[k] == kap:
                self.new_contact[i] = 0
                self.group[i] = 1
                if low < 0:
                    low = i
            else:
                self.new_contact[i] = 1 if kap > self.kinks[k] else -1
                self.group[i] = 0
        if self.ref >= 0 and self.group[self.ref]:
            low = self.ref
        A[0] = kap
        ref[0] = low
        return amb

    cdef int near_zero(self, GaitData* g, double t, int r0, double a) except -1:
        """With stiction: a sliding body whose velocity falls onto zero within 4 tol of t (the
        event times' accuracy) arrives at t, with the bodies the event stopped: the mode is
        decided once for all of them. Without it, arrivals a few floats apart (two linkages'
        reversals at one instant, rounded apart) are decided one by one, and a segment of a
        few floats between them makes a new incumbent (Rule S then anchors the wrong body;
        the kinetic inclusion needs no such care: its answer is continuous)."""
        cdef int p = self.p, nl = self.nl, i
        cdef double vel, acc, w
        gait_rates(g, t, self.ld, self.ldd, self.ld3)
        for i in range(p):
            if self.free[i] or self.zero[i]:
                continue
            vel = self.V + dot(self.W, i, self.ld, nl)
            acc = dot(self.W, i, self.ldd, nl)
            acc = acc + a if r0 < 0 else acc - dot(self.W, r0, self.ldd, nl)
            w = fabs(self.V) + fabs(dot(self.W, i, self.ld, nl))
            if vel * acc <= 0.0 and fabs(vel) <= 1e-13 * w + 4.0 * self.tol * fabs(acc):
                self.zero[i] = 1
        return 0

    cdef bint _any_zero(self) noexcept:
        cdef int i
        for i in range(self.p):
            if self.zero[i]:
                return True
        return False

    # ------------------------------------------------------------------ search
    cdef int row_bounds(self, GaitData* g, double a, double b, int nr) except -1:
        """B2 (|g''|), B1 (|g'|, force rows only) and B3 (|g'''|, rows of l' alone) of each
        row on [a, b]."""
        cdef int r, j, nl = self.nl, has_snap
        cdef bint has1, has2
        cdef double b2, b1, b3, x1, x2
        has_snap = gait_bounds(g, a, b, self.jerk, self.snap)
        for r in range(nr):
            b2 = 0.0
            b1 = 0.0
            has1 = False
            has2 = False
            for j in range(nl):
                x1 = fabs(self.A1[(r) * self.nl + j])
                x2 = fabs(self.A2[(r) * self.nl + j])
                if x1 != 0.0:
                    has1 = True
                if x2 != 0.0:
                    has2 = True
                b2 += x1 * self.jerk[j]
                b1 += x2 * self.jerk[j]
            if has2:
                if has_snap:
                    for j in range(nl):
                        b2 += fabs(self.A2[(r) * self.nl + j]) * self.snap[j]
                else:
                    b2 = INFINITY
            self.B2[r] = b2
            self.B1[r] = b1 if (has2 and self.c1[r] == 0.0 and not has1) else INFINITY
            # g'' = A1 . l''' is known at each point (``values``): |g'''| <= |A1| . snap
            # (not on a TABLE whose jerk jumps: its pieces are walked exactly, ``table_walk``,
            # and a cubic step sized on one piece, snap 0, overshoots the next)
            b3 = INFINITY
            if has_snap and not has2 and (g.kind != TABLE or g.jj_before[g.n] == 0):
                b3 = 0.0
                for j in range(nl):
                    b3 += fabs(self.A1[(r) * self.nl + j]) * self.snap[j]
            self.B3[r] = b3
        return 0

    cdef int values(self, GaitData* g, double t, double t0, int nr, double* gv,
                    double* dg, double* d2) except -1:
        """The rows, their slopes and A1 . l''' (a row's curvature where it has no l'' term)
        at t."""
        cdef int r, j, nl = self.nl
        cdef double v, dv, cv
        gait_rates(g, t, self.ld, self.ldd, self.ld3)
        for r in range(nr):
            v = self.c0[r] + self.c1[r] * (t - t0)
            dv = self.c1[r]
            cv = 0.0
            for j in range(nl):
                v += self.A1[(r) * self.nl + j] * self.ld[j] + self.A2[(r) * self.nl + j] * self.ldd[j]
                dv += self.A1[(r) * self.nl + j] * self.ldd[j] + self.A2[(r) * self.nl + j] * self.ld3[j]
                cv += self.A1[(r) * self.nl + j] * self.ld3[j]
            gv[r] = v
            dg[r] = dv
            d2[r] = cv
        return 0

    cdef double step(self, int nr, const double* ga, const double* da, const double* ca,
                     double tol, double cap) noexcept:
        """A step from a that ``proven`` accepts from a's values, slopes and curvatures alone
        (just inside the first zero of each row's Taylor lower bounds g + g' h - B2 h^2 / 2,
        g - B1 h, and g + g' h + g'' h^2 / 2 - B3 h^3 / 6 for a row of l' alone, whose g'' is
        known): near a simple root a Newton step from the left. ``h_watch``: a step over which
        the last bound proves every watched row >= -noise (0 if one has no such bound)."""
        cdef double h = INFINITY, gg, d, b2, ht, hr
        cdef bint watched = False
        cdef int r
        self.h_watch = INFINITY
        for r in range(nr):
            if self.watch[r]:
                watched = True
                if self.B3[r] < INFINITY and self.h_watch > 0.0:
                    self.h_watch = min(self.h_watch, 0.9999 * cubic_root(
                        ga[r] + self.noise[r], da[r], ca[r], self.B3[r], 0.0))
                else:
                    self.h_watch = 0.0
                continue
            gg = max(ga[r], 0.0)
            d = da[r]
            b2 = self.B2[r]
            ht = 0.0 if b2 == INFINITY else quad_root(gg, d, -b2)
            ht = max(ht, gg / self.B1[r] if self.B1[r] > 0.0 else INFINITY)
            if (0.9999 * ht < h and self.B3[r] < INFINITY
                    and cubic_low(gg, d, ca[r], self.B3[r], 2.0 * ht) > 0.0):
                # a row that may set the step, whose third-order bound proves twice it: that
                # bound's zero, from there (a smaller gain is not worth the root's iterations)
                ht = cubic_root(gg, d, ca[r], self.B3[r], 2.0 * ht)
            hr = 0.9999 * ht
            if d < 0.0 and gg > 0.0 and 0.8 * (gg / -d) <= hr < (gg / -d) * (1.0 + 1e-3):
                # falling onto zero, the rigorous step within 20 % of Newton's: the row is
                # nearly straight here, so step just past the root it predicts and bracket
                # the event (then narrowed) instead of creeping up on it from the left, one
                # rigorous step at a time, to within 64 tol (four or five steps an event);
                # every interval accepted is still proven (``proven``)
                hr = (gg / -d) * (1.0 + 1e-3)
            h = min(h, hr)
        # ``cap`` (a cost setting) only while a row is watched: it is checked at the search
        # points alone, so they stay dense; the others are proven whatever the step
        if watched:
            return min(max(h, 64.0 * tol), cap)
        return max(h, 64.0 * tol)

    cdef bint proven(self, int nr, double h, const double* ga, const double* gb,
                     const double* da, const double* db, const double* ca,
                     const double* cb) noexcept:
        """Every unwatched row > 0 on an interval of length h with these end values, slopes
        and curvatures: the best of seven lower bounds, each rigorous where |g''| <= B2 (chord:
        min - B2 h^2 / 8; Taylor from either end, concave), |g'| <= B1 (mean - B1 h / 2) or
        |g'''| <= B3 (Taylor of third order from either end, ``cubic_low``), or a TABLE gait's
        pieces walked over the interval (``RL``, ``range_lower``). A watched row is seen at
        the search points alone (``search`` keeps them dense) unless h > ``h_free`` and it
        has a bound B3: then the third-order bounds must prove it >= -noise."""
        cdef int r
        cdef double q, lo, b3
        for r in range(nr):
            b3 = self.B3[r]
            if self.watch[r]:
                if h <= self.h_free or b3 == INFINITY or max(
                        cubic_low(ga[r], da[r], ca[r], b3, h),
                        cubic_low(gb[r], -db[r], cb[r], b3, h)) >= -self.noise[r]:
                    continue
                return False
            q = self.B2[r] * (h * h)
            lo = max(min(ga[r], gb[r]) - q / 8.0, 0.5 * (ga[r] + gb[r]) - self.B1[r] * (h / 2.0))
            lo = max(lo, self.RL[r])
            lo = max(lo, min(ga[r], ga[r] + da[r] * h - q / 2.0))
            lo = max(lo, min(gb[r], gb[r] - db[r] * h - q / 2.0))
            if lo <= 0.0 and b3 < INFINITY:
                lo = max(cubic_low(ga[r], da[r], ca[r], b3, h),
                         cubic_low(gb[r], -db[r], cb[r], b3, h))
            if lo <= 0.0:
                return False
        return True

    cdef bint range_lower(self, GaitData* g, double a, double b, double t0, int nr) noexcept:
        """RL: each row's smallest value on [a, b], exact up to rounding for a TABLE gait (its
        pieces' quadratics, ``piece_lows``); -inf for the other kinds. Returns whether the
        rows are proven on [a, b]: every unwatched row > 0, every watched one >= -noise."""
        cdef int r
        if g.kind != TABLE:
            for r in range(nr):
                self.RL[r] = -INFINITY
            return False
        return self.table_walk(g, a, b, t0, nr, False) >= b

    cdef double table_walk(self, GaitData* g, double a, double b, double t0, int nr,
                           bint stop) noexcept:
        """A lower bound of each row over [a, b] into RL, the pieces walked from a: a run of
        2^q whole pieces at once where the gait's ranges of l' and l'' over it (its table of
        range extremes, one lookup per field) prove every row (``run_rows``: q grows after a
        run proven, shrinks after one that is not, and near a row's zero, where they fail,
        they are tried again only every few pieces), else one piece from its quadratics
        (``piece_lows``, exact up to rounding). With ``stop``, the walk ends in the first
        piece where a row is not proven (an unwatched row <= 0, a watched one < -noise):
        there just before its quadratic's first root, checked by its minimum up to there
        (else halved towards x). Returns the end of [a, x] on which RL proves every row (b
        when all of [a, b] is; a when none of it)."""
        cdef int r, k, it, k2, nl = self.nl, q, q_try = 3, wait = 0
        cdef double d, m, m2, hi, origin, nxt, x, y, lvl, te
        cdef int hint = g.hint
        cdef bint ok
        cdef double* low = self.qd + 3 * self.nr     # (qd: four blocks of self.nr)
        for r in range(nr):
            self.RL[r] = INFINITY
        x = a
        k = table_locate(g, x, &d, &m)
        origin = x - d
        while x < b:
            if wait == 0 and x == piece_start(g, k, m):
                # whole pieces from x's: the longest run of 2^q (q <= q_try) the ranges prove,
                # an aligned block of the table (k a multiple of 2^q, within one period)
                q = min(q_try, g.nlev - 1)
                while q >= 1 and ((k & ((1 << q) - 1)) != 0 or k + (1 << q) > g.n):
                    q -= 1
                while q >= 1:
                    k2 = k + (1 << q)
                    m2 = m
                    if g.period > 0.0:
                        if k2 >= g.n:
                            k2 -= g.n
                            m2 += 1.0
                        te = piece_start(g, k2, m2)
                    else:
                        te = g.starts[k2] if k2 < g.n else INFINITY
                    if te <= b and self.run_rows(g, q, k, x, te, t0, nr, low):
                        break
                    q -= 1
                if q >= 1:
                    for r in range(nr):
                        self.RL[r] = min(self.RL[r], low[r])
                    x = te
                    k = k2
                    m = m2
                    origin = piece_start(g, k, m) if g.period > 0.0 else g.anchors[k]
                    q_try = q + 1
                    continue
                q_try = 1
                wait = 4                # near a zero: a few pieces exactly before the next try
            elif wait > 0:
                wait -= 1
            if k + 1 < g.n:
                nxt = piece_start(g, k + 1, m)
            elif g.period > 0.0:
                nxt = piece_start(g, 0, m + 1.0)
            else:
                nxt = INFINITY
            hi = min(b, nxt)
            if not hi > x:                   # (no progress: a time the pieces cannot split)
                break
            # x's piece from its quadratics
            ok = self.piece_lows(g.coef + k * nl * 4, origin, t0, nr, x - origin, hi - origin,
                                 low, stop)
            if stop and not ok:
                # the first root of the rows that fail, then proven up to just before it
                y = hi
                for r in range(nr):
                    if not clear(low[r], self.watch[r], self.noise[r]):
                        lvl = -self.noise[r] if self.watch[r] else 0.0
                        y = min(y, origin + self.piece_root(r, x - origin, hi - origin, lvl))
                y = x + (y - x) * (1.0 - 1e-6)
                for it in range(8):
                    if y <= x:
                        break
                    if self.piece_lows(g.coef + k * nl * 4, origin, t0, nr, x - origin,
                                       y - origin, low, False):
                        for r in range(nr):
                            self.RL[r] = min(self.RL[r], low[r])
                        g.hint = hint
                        return y
                    y = x + 0.5 * (y - x)
                g.hint = hint
                return x
            for r in range(nr):
                self.RL[r] = min(self.RL[r], low[r])
            x = hi
            k += 1                      # the next piece (its start is x unless x = b)
            if k == g.n:
                k = 0
                m += 1.0
            origin = piece_start(g, k, m) if g.period > 0.0 else g.anchors[k if k < g.n else 0]
        g.hint = hint                   # the evaluations' piece (the walk ran ahead of it)
        if stop:
            return x
        for r in range(nr):
            if not clear(self.RL[r], self.watch[r], self.noise[r]):
                return a
        return b if x >= b else a

    cdef bint run_rows(self, GaitData* g, int q, int k, double ts, double te, double t0, int nr,
                       double* low) noexcept:
        """Each row's lower bound over the 2^q whole pieces from piece k ([ts, te]) from the
        extremes of l' and l'' over them (``stat`` level q: one record), less 16 eps of the
        sizes of its terms, into low (nr,). Returns whether every row is proven by it."""
        cdef int r, j, nl = self.nl
        cdef const double* rec = table_run(g, q, k)
        cdef double v, u, sz, e
        cdef bint ok = True
        for r in range(nr):
            u = min(self.c1[r] * (ts - t0), self.c1[r] * (te - t0))
            v = self.c0[r] + u
            sz = fabs(self.c0[r]) + fabs(u)
            for j in range(nl):
                e = self.A1[r * nl + j]
                if e != 0.0:
                    u = min(e * rec[nl + j], e * rec[2 * nl + j])
                    v += u
                    sz += fabs(u)
                e = self.A2[r * nl + j]
                if e != 0.0:
                    u = min(e * rec[3 * nl + j], e * rec[4 * nl + j])
                    v += u
                    sz += fabs(u)
            v -= 16.0 * EPS * sz
            low[r] = v
            if not clear(v, self.watch[r], self.noise[r]):
                ok = False
                break
        return ok

    cdef bint piece_lows(self, const double* row, double origin, double t0, int nr, double d0,
                         double d1, double* low, bint store) noexcept:
        """Each row on one constant-jerk piece (rows (nl, 4) = l0, v0, a0, jerk at ``row``,
        offsets d from ``origin``) is q0 + q1 d + q2 d^2 (l' = v0 + a0 d + jerk d^2 / 2,
        l'' = a0 + jerk d): its smallest value over offsets [d0, d1] (its ends and, when
        inside, its vertex) less 16 eps of the sizes of its terms (the combination's
        rounding), so that it bounds the exact row from below, into low (nr,); with
        ``store`` the quadratics into ``qd`` (blocks of self.nr: where ``piece_root`` reads
        them, whatever the number of rows). Returns whether every row is proven by it
        (unwatched > 0, watched >= -noise)."""
        cdef int r, j, nl = self.nl, stride = self.nr
        cdef double q0, q1, q2, x1, x2, v, sa, sb, big = max(fabs(d0), fabs(d1))
        cdef double p0 = 0.0, p1 = 0.0, p2 = 0.0, sp0 = 0.0, sp1 = 0.0, sp2 = 0.0
        cdef const double* c
        cdef bint ok = True
        # the arrays in locals: the stores to low and qd may alias self's fields otherwise
        cdef const double* A1 = self.A1
        cdef const double* A2 = self.A2
        cdef const double* c0 = self.c0
        cdef const double* c1 = self.c1
        cdef const unsigned char* mirror = self.mirror
        cdef const unsigned char* watch = self.watch
        cdef const double* noise = self.noise
        cdef double* qd = self.qd
        cdef double dt0 = origin - t0
        for r in range(nr):
            # the gait's part (A1 l' + A2 l''): a bound pair's second row is the first's
            # negated (exactly), so it is summed once
            if mirror[r]:
                p0 = -p0
                p1 = -p1
                p2 = -p2
            else:
                p0 = p1 = p2 = sp0 = sp1 = sp2 = 0.0
                for j in range(nl):
                    c = row + 4 * j
                    x1 = A1[r * nl + j]
                    x2 = A2[r * nl + j]
                    p0 += x1 * c[1] + x2 * c[2]
                    sp0 += fabs(x1 * c[1]) + fabs(x2 * c[2])
                    p1 += x1 * c[2] + x2 * c[3]
                    sp1 += fabs(x1 * c[2]) + fabs(x2 * c[3])
                    p2 += 0.5 * x1 * c[3]
                    sp2 += fabs(0.5 * x1 * c[3])
            q0 = c0[r] + c1[r] * dt0 + p0
            q1 = c1[r] + p1
            q2 = p2
            v = min(q0 + d0 * (q1 + d0 * q2), q0 + d1 * (q1 + d1 * q2))
            if q2 > 0.0:
                # the vertex, where the slope turns from - to + inside (one division, there)
                sa = q1 + 2.0 * q2 * d0
                sb = q1 + 2.0 * q2 * d1
                if sa < 0.0 < sb:
                    v = min(v, q0 - q1 * q1 / (4.0 * q2))
            v -= 16.0 * EPS * (
                fabs(c0[r]) + fabs(c1[r] * dt0) + sp0 + big * (fabs(c1[r]) + sp1 + big * sp2))
            low[r] = v
            if not clear(v, watch[r], noise[r]):
                ok = False
            if store:
                qd[r] = q0
                qd[stride + r] = q1
                qd[2 * stride + r] = q2
        return ok

    cdef double piece_root(self, int r, double d0, double d1, double lvl) noexcept:
        """The first offset in [d0, d1] where row r's quadratic (``piece_lows``: q0 + q1 d +
        q2 d^2 in offsets d from the piece's origin) comes down to ``lvl``: its Taylor form
        at d0 to its first zero (``quad_root``); where it has no real zero, its vertex when
        inside (its smallest point: rounding left it no root there); else d1."""
        cdef double q0 = self.qd[r] - lvl, q1 = self.qd[self.nr + r], q2 = self.qd[2 * self.nr + r]
        cdef double g = q0 + d0 * (q1 + d0 * q2), x, dv
        if g <= 0.0:
            return d0
        x = quad_root(g, q1 + 2.0 * q2 * d0, 2.0 * q2)
        if x < INFINITY:
            return min(d0 + x, d1)
        if q2 > 0.0:
            dv = -q1 / (2.0 * q2)
            if d0 < dv < d1:
                return dv
        return d1

    cdef bint bad_any(self, int nr, const double* gv) noexcept:
        cdef int r
        for r in range(nr):
            if not clear(gv[r], self.watch[r], self.noise[r]):
                return True
        return False

    cdef int search(self, GaitData* g, double t0, double end, int nr, double tol, double cap,
                    double* t_out) except -1:
        """First event of the rows in (t0, end]: its time in t_out (INFINITY when none) and
        the rows hit in ``hit``; returns F_OK, F_NONFINITE or F_NO_STEPS."""
        cdef double* ga = self.wk + 0 * self.nr
        cdef double* da = self.wk + 1 * self.nr
        cdef double* gm = self.wk + 2 * self.nr
        cdef double* dm = self.wk + 3 * self.nr
        cdef double* gb = self.wk + 4 * self.nr
        cdef double* db = self.wk + 5 * self.nr
        cdef double* gs = self.wk + 6 * self.nr
        cdef double* ds = self.wk + 7 * self.nr
        cdef double* fa = self.wk + 8 * self.nr
        cdef double* fb = self.wk + 9 * self.nr
        cdef double* ca = self.wk + 10 * self.nr      # g'' of the rows of l' alone
        cdef double* cm = self.wk + 11 * self.nr
        cdef double* cb = self.wk + 12 * self.nr
        cdef double* cs = self.wk + 13 * self.nr
        cdef int r, j, nl = self.nl, side = 0
        cdef double sc, sc0, sw, a, h, m, w, f, fr, den, ms, b = INFINITY, sb = INFINITY, lim, lvl
        cdef double w0 = INFINITY, w1 = INFINITY, w2 = INFINITY
        cdef bint have_b = False, saved = False, settled, fixed, ahead, ranged
        cdef double x2, by_range = NAN, rb_a = NAN, rb_b = NAN
        cdef long it, n_small = 0
        cdef double h_last = INFINITY
        for r in range(nr):
            self.hit[r] = 0
        self.values(g, t0, t0, nr, ga, da, ca)
        for r in range(nr):
            # the row's rounding over the span (its c1 (t - t0) grows to c1 (end - t0)) is its
            # noise; its rounding at t0 alone (sc0: no span term) decides whether it is at zero
            sc = fabs(self.c0[r]) + fabs(self.c1[r]) * (end - t0)
            sc0 = fabs(self.c0[r])
            for j in range(nl):
                sw = fabs(self.A1[(r) * self.nl + j] * self.ld[j]) + fabs(self.A2[(r) * self.nl + j] * self.ldd[j])
                sc += sw
                sc0 += sw
            self.noise[r] = 1e-13 * sc + 1e-300
            # a row at zero to within its rounding at t0 (a rigid pair, a body at rest) is
            # watched: a row of +1e-16 stuck there would otherwise need ~1e-9 s steps; the
            # mode declared it zero at t0, so at least its value there is noise. Judged by its
            # rounding at t0, not over the span: a sliding body's velocity of 6e-12 m/s at t0,
            # falling at 500 m/s^2 over a 1e3 s span (noise 5e-8 m/s), is not zero, and taken
            # for zero its stop was placed 1e-10 s late instead of at 1.3e-14 s
            self.watch[r] = ga[r] <= 1e-13 * sc0 + 1e-300
            if self.watch[r]:
                self.noise[r] = max(self.noise[r], 4.0 * fabs(ga[r]))
        # bounds independent of the interval: a FOURIER gait's hold everywhere, a PROXY
        # gait's on its piece (every join is a breakpoint: a search never crosses one)
        fixed = g.kind == FOURIER or g.kind == PROXY
        # bounds that vary inside a search, looked up in constant time (SCALLOP's range
        # maxima of its bins): each step is sized with its own interval's bounds too (a
        # TABLE's lookup walks its pieces: measured slower than the proof failures it saves)
        ahead = g.kind == SCALLOP
        # the rows' lower bounds from the pieces (TABLE: piecewise quadratics): a step is
        # walked over them, before the gait is evaluated, while they prove every row
        ranged = g.kind == TABLE
        for r in range(nr):
            self.RL[r] = -INFINITY
        a = t0
        self.row_bounds(g, t0, min(end, t0 + cap), nr)
        h = self.step(nr, ga, da, ca, tol, cap)
        for r in range(nr):
            if self.watch[r]:
                h_last = min(h, max(1e3 * tol, 1e-9 * (end - a)))
                h = min(h, max(h_last, self.h_watch))
                break
        lim = end
        for it in range(MAX_STEPS):
            by_range = NAN
            if have_b:
                m = 0.5 * (a + b)
                if not (a < m < b):
                    break
                w = b - a
                if w < 0.5 * w0:
                    f = 2.0                 # no point proposed: halve
                    for r in range(nr):
                        if clear(gb[r], self.watch[r], self.noise[r]):
                            continue
                        # Newton's step from the end nearer the root (the row's slope there is
                        # exact): quadratic convergence, where the secant of the ends gains a
                        # few digits a step; the (Illinois) secant where Newton leaves (a, b)
                        lvl = -self.noise[r] if self.watch[r] else 0.0
                        fr = -1.0
                        if lvl - gb[r] < ga[r] - lvl and db[r] < 0.0:
                            fr = 1.0 - (gb[r] - lvl) / (db[r] * w)
                        elif da[r] < 0.0:
                            fr = (ga[r] - lvl) / (-da[r] * w)
                        if not (0.0 < fr < 1.0 or (fr == 1.0 and gb[r] == 0.0
                                                   and not self.watch[r])):
                            den = fa[r] - fb[r]
                            fr = fa[r] / den if den != 0.0 else 2.0
                            if not (0.0 < fr < 1.0):
                                fr = 2.0
                        if fr < f:
                            f = fr
                    if 0.0 < f <= 1.0:
                        # f = 1: a falling row exactly 0 at b (Newton from b puts its root
                        # there): the float just below b, which ends the narrowing when it is
                        # good (halving towards b took ~30 steps);
                        # a secant point within one float of an end: the adjacent float
                        ms = a + f * w
                        if ms <= a:
                            ms = nextafter(a, INFINITY)
                        elif ms >= b:
                            ms = nextafter(b, -INFINITY)
                        if a < ms < b:
                            m = ms
                w0 = w1
                w1 = w2
                w2 = w
            else:
                if a >= lim:
                    if saved:        # the put-aside part is proven: back to its bracket
                        have_b = True
                        saved = False
                        b = sb
                        for r in range(nr):
                            gb[r] = gs[r]
                            db[r] = ds[r]
                            cb[r] = cs[r]
                            lvl = -self.noise[r] if self.watch[r] else 0.0
                            fa[r] = ga[r] - lvl
                            fb[r] = gb[r] - lvl
                        lim = end
                        side = 0
                        continue
                    t_out[0] = INFINITY
                    return F_OK
                # at least the next float: a step below the float spacing at a (the floors
                # 64 tol and tol / 2 are under it past t = 512 s at tol 1e-13; an eighth of a
                # span of a few floats) would leave a + h == a, a point that makes no progress
                # (the search then ran out of steps)
                m = min(max(a + h, nextafter(a, INFINITY)), lim)
                if ranged:
                    # the rows' minima walked piece by piece from a, up to the first piece
                    # where one may fail (there, to just before its quadratic's first root):
                    # the step, when longer than the Taylor step, before the gait is evaluated
                    x2 = self.table_walk(g, a, lim, t0, nr, True)
                    if x2 >= m or (x2 > a and x2 == lim):
                        m = x2
                        by_range = m
            self.values(g, m, t0, nr, gm, dm, cm)
            self.n_evals += 1
            for r in range(nr):
                if not (isfinite(gm[r]) and isfinite(dm[r])):
                    self.bad_time = m
                    return F_NONFINITE
            if self.bad_any(nr, gm):
                saved = False
                lim = end
                have_b = True
                b = m
                for r in range(nr):
                    gb[r] = gm[r]
                    db[r] = dm[r]
                    cb[r] = cm[r]
                    lvl = -self.noise[r] if self.watch[r] else 0.0
                    fb[r] = gm[r] - lvl
                    fa[r] = (ga[r] - lvl) * (0.5 if side == -1 else 1.0)
                side = -1
                continue
            # proven, unless within tol of a or its next float (nothing finer to resolve:
            # event times are known to tol or one float spacing, the module's guarantee)
            if m - a > tol and m > nextafter(a, INFINITY):
                if not fixed and not (a == rb_a and m <= rb_b):
                    # (also after a step the walk proved: the next step is sized with them;
                    # not again where the step was sized with its own interval's, ``ahead``)
                    self.row_bounds(g, a, m, nr)
                rb_a = NAN
                if ranged and m != by_range:
                    self.range_lower(g, a, m, t0, nr)
                self.h_free = 2.0 * h_last
                if m != by_range and not self.proven(nr, m - a, ga, gm, da, dm, ca, cm):
                    if have_b:           # scan [a, m] first, the bracket put aside
                        saved = True
                        sb = b
                        for r in range(nr):
                            gs[r] = gb[r]
                            ds[r] = db[r]
                            cs[r] = cb[r]
                        have_b = False
                        lim = m
                    h = max(0.25 * (m - a), 0.5 * tol)
                    continue
            for r in range(nr):
                if self.watch[r] and gm[r] > self.noise[r]:
                    self.watch[r] = 0
            n_small = n_small + 1 if m - a <= 1e-6 * (end - t0) else 0
            h_last = m - a
            a = m
            for r in range(nr):
                ga[r] = gm[r]
                da[r] = dm[r]
                ca[r] = cm[r]
            if have_b:
                for r in range(nr):
                    lvl = -self.noise[r] if self.watch[r] else 0.0
                    fa[r] = ga[r] - lvl
                    if side == 1:
                        fb[r] *= 0.5
                side = 1
            else:
                settled = False
                for r in range(nr):
                    # a row come down to its rounding noise with no slope to cross zero in
                    # the shortest step, for a hundred small steps, is zero as far as floats
                    # tell: an event here (a velocity settling onto zero with the command;
                    # a velocity that only touches zero passes in a few dozen steps)
                    if (n_small >= 100 and not self.watch[r] and ga[r] <= self.noise[r]
                            and fabs(da[r]) * (64.0 * tol) <= self.noise[r]):
                        self.hit[r] = 1
                        settled = True
                if settled:
                    t_out[0] = a
                    return F_OK
                h = self.step(nr, ga, da, ca, tol, cap)
                if ahead and h < end - a:
                    # the bounds of the step's own interval: a step sized with the bounds
                    # behind it fails its proof where the gait turns sharp ahead (they can
                    # only shrink the step, which the interval's bounds then still cover)
                    self.row_bounds(g, a, a + h, nr)
                    rb_a = a
                    rb_b = a + h
                    h = min(h, self.step(nr, ga, da, ca, tol, cap))
                for r in range(nr):
                    if self.watch[r]:
                        # a watched row is seen at the search points alone: they grow at most
                        # twofold from where it was last seen, so a row leaving zero slowly
                        # (a body leaving rest at a tie) is seen leaving it, or dipping; or
                        # further where every watched row's third-order bound proves it
                        h = min(h, max(2.0 * h_last, self.h_watch))
                        break
        if not have_b:
            return F_NO_STEPS
        for r in range(nr):
            # a row crossed at b, or one falling through zero within 2 tol of it: events
            # within the root tolerance of each other are simultaneous (two bodies whose
            # velocities vanish together stay together, no sliver segment between them)
            # (1: crossed; 2: taken with it, its velocity not necessarily zero at b)
            if not clear(gb[r], self.watch[r], self.noise[r]):
                self.hit[r] = 1
            elif not self.watch[r] and db[r] < 0.0 and gb[r] <= -db[r] * (2.0 * tol):
                self.hit[r] = 2
            else:
                self.hit[r] = 0
        t_out[0] = b
        return F_OK

    # ------------------------------------------------------------------ rows
    cdef int build_rows(self, const signed char* contact, const unsigned char* group, int r0,
                        double V0, double a) noexcept:
        """The segment's event rows (module doc); returns their number."""
        cdef int p = self.p, nl = self.nl, i, j, nr = 0, s
        cdef double sg, f_slide, lo, hi
        for i in range(p):
            if self.free[i] or (r0 >= 0 and group[i]):
                continue
            sg = <double>contact[i]
            self.mirror[nr] = 0
            self.lab_kind[nr] = 0
            self.lab_body[nr] = i
            if r0 < 0:
                self.c0[nr] = sg * V0
                self.c1[nr] = sg * a
                for j in range(nl):
                    self.A1[(nr) * self.nl + j] = sg * self.W[(i) * self.nl + j]
                    self.A2[(nr) * self.nl + j] = 0.0
            else:
                self.c0[nr] = 0.0
                self.c1[nr] = 0.0
                for j in range(nl):
                    self.A1[(nr) * self.nl + j] = sg * (self.C[(i) * self.nl + j] - self.C[(r0) * self.nl + j])
                    self.A2[(nr) * self.nl + j] = 0.0
            nr += 1
        if r0 < 0:
            return nr
        f_slide = self.fext
        lo = 0.0
        hi = 0.0
        for i in range(p):
            if group[i]:
                # static bounds (core/friction.py: stuck_interval): with stiction only these
                # constants differ from the kinetic rows (STICTION.md s. 7)
                lo -= self.sfp[i]
                hi += self.sfm[i]
            else:
                f_slide += self.R[i]
        # the ground force the group needs: -M W_r l'' - f_slide, within [lo, hi]
        for s in range(2):
            self.mirror[nr] = s
            self.lab_kind[nr] = 1
            self.lab_body[nr] = r0
            self.c0[nr] = (-f_slide - lo) if s == 0 else (hi + f_slide)
            self.c1[nr] = 0.0
            for j in range(nl):
                self.A1[(nr) * self.nl + j] = 0.0
                self.A2[(nr) * self.nl + j] = (-self.M if s == 0 else self.M) * self.W[(r0) * self.nl + j]
            nr += 1
        for i in range(p):
            if group[i] and i != r0:
                for s in range(2):
                    self.mirror[nr] = s
                    self.lab_kind[nr] = 2
                    self.lab_body[nr] = i
                    self.c0[nr] = 0.0
                    self.c1[nr] = 0.0
                    for j in range(nl):
                        self.A1[(nr) * self.nl + j] = (self.C[(i) * self.nl + j] - self.C[(r0) * self.nl + j]) * (1.0 if s == 0
                                                                         else -1.0)
                        self.A2[(nr) * self.nl + j] = 0.0
                    nr += 1
        return nr

    cdef void record_change(self, double t, const signed char* new) noexcept:
        cdef int i
        for i in range(self.p):
            if new[i] != self.contact[i]:
                self.et[self.n_ev] = self.origin + t        # (local t: absolute times out)
                self.ei[self.n_ev * 3 + 0] = i
                self.ei[self.n_ev * 3 + 1] = self.contact[i]
                self.ei[self.n_ev * 3 + 2] = new[i]
                self.n_ev += 1
                self.contact[i] = new[i]

    # ------------------------------------------------------------------ the loop
    def drive(self, CompiledGait gait, double t_abs, double T):
        """Integrate towards t_abs [s] (see the module doc); ``T`` > 0: the period whose
        multiples end segments and are compared (with ``skip``, a repeat stops the call), and,
        for a gait read from its period's frame (every kind but a Python gait's pieces not yet
        periodic), where the frame moves on (``tl``, ``origin``; without ``skip``, at the first
        segment end past a period's end: segments are not cut there). Returns a status."""
        return self._drive(gait, t_abs, T)

    cdef int _drive(self, CompiledGait gait, double t_abs, double T) except -1:
        cdef GaitData* g = &gait.d
        cdef int p = self.p, nl = self.nl, i, j, r, nr, r0, code, n_hit
        cdef int guard = 0, status = S_REACHED, n_max = self.n_buf
        cdef int ev_max = ev_records(p)
        cdef double t, ts, end, b, kT, t0, a, V0, X_s, V_s, t_ev, tt, d, f_slide, imp, w, fmg
        cdef double tol = self.tol, cap, Vi, t_end, t_look
        cdef long k_next
        cdef bint left, stale, moving, tiny, same, group_all, call_end
        self.n_seg = 0
        self.n_ev = 0
        self.n_choice = 0
        self.k_at = -1
        self.bad_time = NAN
        if T > 0.0 and self.tl >= T and (g.kind != PROXY or g.period > 0.0):
            # the frame of the period holding t (a run started at k T, or a call that ended
            # past a period's end): t is known to ulp(t) there, once
            self.origin_k += <long>floor(self.tl / T)
            self.origin = self.origin_k * T
            self.tl = self.t - self.origin
        t = self.tl
        t_end = t_abs - self.origin
        if g.kind == PROXY:
            gait.span_lo = t
            gait.span_hi = t_end
        while t < t_end:
            if self.n_seg == n_max or self.n_ev + 2 * p + 2 > ev_max:
                status = S_FULL
                break
            # ---- this segment's span: to t_end, the next breakpoint or multiple of T
            ts = t_end
            left = False
            b = gait_next_break(g, t)
            if b <= ts:
                ts = b
                left = True
            k_next = -1
            if T > 0.0 and self.skip:
                k_next = <long>floor(t / T * (1 + 4 * EPS) + 4 * EPS) + 1
                kT = k_next * T
                if kT < ts:
                    ts = kT
                    left = False
            end = nextafter(ts, -INFINITY) if left else ts
            # the segment ends only because the call does: no instant of the physics (with
            # stiction an event near it keeps its own time, see the search's close)
            call_end = ts == t_end and not left and not (k_next > 0 and ts == k_next * T)
            cap = self.cap if self.cap > 0.0 else max((ts - t) / 8.0, 1e-300)
            # ---- the state at t
            gait_lengths(g, t, self.l)
            gait_rates(g, t, self.ld, self.ldd, self.ld3)
            for j in range(nl):
                if not (isfinite(self.l[j]) and isfinite(self.ld[j]) and isfinite(self.ldd[j])):
                    self.bad_time = t
                    status = S_NONFINITE
                    break
            if status == S_NONFINITE:
                break
            for i in range(p):
                self.e[i] = dot(self.W, i, self.l, nl)
                self.ep[i] = dot(self.W, i, self.ld, nl)
                self.epp[i] = dot(self.W, i, self.ldd, nl)
            if self.ref >= 0:
                # stuck reference body: the centre of mass from the gait, exactly
                self.V = -self.ep[self.ref]
                self.X = self.x_ref - self.e[self.ref]
            # A sliding body whose velocity is zero or points against its contact sign (l' = 0
            # exactly at a breakpoint, a jump of l' where the actuator settles to rest): its
            # sign comes from the actual velocity; only a body at zero velocity (to the
            # rounding of V + e_i') joins the zero set, where the inclusion decides.
            stale = False
            for i in range(p):
                self.new2[i] = self.contact[i]
            for i in range(p):
                if self.zero[i] or self.free[i]:
                    continue
                Vi = self.V + self.ep[i]
                if self.contact[i] * Vi <= 0.0:
                    stale = True
                    if fabs(Vi) > 16.0 * EPS * (fabs(self.V) + fabs(self.ep[i])):
                        self.new2[i] = 1 if Vi > 0.0 else -1
                    else:
                        self.zero[i] = 1
            if stale:
                self.record_change(t, self.new2)
                self.cache_ok = False
            # ---- mode
            if self.cache_ok:
                a = self.cache_a
                r0 = self.ref
                for i in range(p):
                    self.new_contact[i] = self.contact[i]
                    self.group[i] = self.cache_group[i]
            else:
                if self.stiction:
                    # Rule S is not continuous in its data: its look-ahead (t+ data) must not
                    # depend on where a call ends, or a run cut there would choose otherwise
                    # (a streamed run differs from the whole one): it reaches to the gait's
                    # next breakpoint or one time scale, past the call's end (a Python gait's
                    # pieces, built only up to the call's end, excepted)
                    t_look = min(b, t + self.tscale)
                    if g.kind == PROXY and g.period <= 0.0:
                        t_look = min(t_look, ts)
                    self.mode(g, t, t_look, &a, &r0)
                else:
                    self.mode(g, t, ts, &a, &r0)
                if self.stiction and self.n_cons > 1:
                    # an instant where Rule S chose among several consistent continuations
                    self.ch_t[self.n_choice] = self.origin + t
                    self.ch_n[2 * self.n_choice] = self.n_cons
                    self.ch_n[2 * self.n_choice + 1] = self.tie
                    self.n_choice += 1
            self.cache_ok = False
            if r0 >= 0:
                if r0 != self.ref:
                    self.x_ref = self.X + self.e[r0]
            else:
                self.x_ref = 0.0
                for i in range(p):
                    # bodies leaving zero velocity start exactly from zero
                    if self.zero[i] and self.new_contact[i] != 0:
                        self.V = -self.ep[i]
                        break
            self.ref = r0
            group_all = r0 >= 0
            for i in range(p):
                self.R[i] = ground_force(self.new_contact[i], self.fp[i], self.fm[i])
                if not self.group[i]:
                    group_all = False
            V0 = -self.ep[r0] if r0 >= 0 else self.V
            t0 = t
            self.record_change(t0, self.new_contact)
            self.sf[self.n_seg * 6 + 0] = self.origin + t0
            self.sf[self.n_seg * 6 + 2] = self.X
            self.sf[self.n_seg * 6 + 3] = V0
            self.sf[self.n_seg * 6 + 4] = a
            self.sf[self.n_seg * 6 + 5] = self.x_ref
            self.sref[self.n_seg] = r0
            for i in range(p):
                self.scontact[self.n_seg * p + i] = self.contact[i]
                self.sgroup[self.n_seg * p + i] = self.group[i]
                self.sR[self.n_seg * p + i] = self.R[i]
                self.sK0[self.n_seg * p + i] = self.K[i]
            # ---- search
            t_ev = ts
            n_hit = 0
            for i in range(p):
                self.hits[i] = 0
            if group_all and gait_is_constant(g, t0, ts):
                pass            # at rest under a constant command: nothing can happen
            else:
                nr = self.build_rows(self.contact, self.group, r0, V0, a)
                if nr > 0 and end > t0:
                    if g.kind == PROXY:
                        gait.span_lo = t0
                        gait.span_hi = end
                    code = self.search(g, t0, end, nr, tol, cap, &tt)
                    if code == F_NO_STEPS:
                        status = S_NO_STEPS
                        break
                    if code == F_NONFINITE:
                        status = S_NONFINITE
                        break
                    if isfinite(tt):
                        t_ev = tt
                        if t_ev >= end and end < ts:
                            t_ev = ts     # the left limit at a breakpoint: the event is there
                        for r in range(nr):
                            if self.hit[r]:
                                n_hit += 1
                                if self.lab_kind[r] == 0:
                                    # 1 where a row of the body crossed, else 2
                                    i = self.lab_body[r]
                                    if self.hit[r] == 1 or self.hits[i] == 0:
                                        self.hits[i] = self.hit[r]
                        if ts - t_ev <= 4.0 * tol and not (self.stiction and call_end):
                            # an event within the root tolerance of a breakpoint happens
                            # there: no hit body is then at its zero for certain (with
                            # stiction not at a mere call end: the whole run, with no
                            # boundary there, decides at the event's own time)
                            if t_ev != ts:
                                for i in range(p):
                                    if self.hits[i]:
                                        self.hits[i] = 2
                            t_ev = ts
            # ---- close: the state at t_ev
            d = t_ev - t0
            if r0 < 0:
                self.X = self.X + d * (V0 + 0.5 * a * d)
                self.V = V0 + a * d
                for i in range(p):
                    self.K[i] += self.R[i] * d
                    self.zero[i] = 0
            else:
                gait_lengths(g, t_ev, self.l)
                gait_rates(g, t_ev, self.ld, self.ldd, self.ld3)
                self.V = -dot(self.W, r0, self.ld, nl)
                self.X = self.x_ref - dot(self.W, r0, self.l, nl)
                f_slide = self.fext
                w = 0.0
                fmg = 0.0
                for i in range(p):
                    if self.group[i]:
                        w += self.sfp[i] + self.sfm[i]
                        fmg += self.sfm[i]
                    else:
                        self.K[i] += self.R[i] * d
                        f_slide += self.R[i]
                    self.zero[i] = self.group[i]
                # the group's impulse: each member at the same fraction of its interval
                imp = self.M * (self.V - V0) - f_slide * d
                if w > 0.0:
                    for i in range(p):
                        if self.group[i]:
                            self.K[i] += self.sfm[i] * d - ((-imp + fmg * d) / w) * (
                                self.sfp[i] + self.sfm[i])
            if n_hit > 0:
                if r0 < 0:
                    gait_rates(g, t_ev, self.ld, self.ldd, self.ld3)
                for i in range(p):
                    if self.hits[i] == 2:
                        # a body taken with the event (its velocity falling through zero
                        # within 2 tol of it, or an event within 4 tol of a breakpoint moved
                        # there) is at its zero only where its velocity is zero to within its
                        # rounding there; else it is left sliding as it is, its own event
                        # found (or its sign taken from its velocity) next. Its velocity can
                        # be |e_i''| 4 tol from zero: 3.5e-7 m/s at 1 kHz with a 0.1 m stroke,
                        # where V put onto its zero was a momentum jump of M 3.5e-7 m/s, kept
                        # in every later period
                        Vi = dot(self.W, i, self.ld, nl)
                        if r0 < 0:
                            w = fabs(V0) + fabs(a) * d + fabs(Vi)
                            fmg = fabs(a + dot(self.W, i, self.ldd, nl))
                        else:
                            w = fabs(self.V) + fabs(Vi)
                            fmg = fabs(dot(self.W, i, self.ldd, nl)
                                       - dot(self.W, r0, self.ldd, nl))
                        if not at_zero(self.V + Vi, w, fmg, t_ev):
                            self.hits[i] = 0
                    if self.hits[i]:
                        self.zero[i] = 1
                if r0 < 0:
                    for i in range(p - 1, -1, -1):
                        if self.hits[i]:
                            # the body's velocity is exactly zero at the event
                            self.V = -dot(self.W, i, self.ld, nl)
                            break
            if self.stiction and not (call_end and t_ev == ts):
                # (not at a call's end: an arrival there is found at its own time next call,
                # as the whole run finds it)
                self.near_zero(g, t_ev, r0, a)
            # absolute: the call's end as asked, a period's end as the next frame's origin
            if t_ev == t_end:
                self.sf[self.n_seg * 6 + 1] = t_abs
            elif k_next > 0 and t_ev == k_next * T:
                self.sf[self.n_seg * 6 + 1] = (self.origin_k + k_next) * T
            else:
                self.sf[self.n_seg * 6 + 1] = self.origin + t_ev
            # the last segment, for ``current``
            self.last_valid = True
            for j in range(6):
                self.last_f[j] = self.sf[self.n_seg * 6 + j]
            self.last_ref = r0
            for i in range(p):
                self.last_contact[i] = self.contact[i]
                self.last_group[i] = self.group[i]
                # the incumbent of the next decision: the cluster stuck on this segment
                self.inc[i] = self.group[i] if r0 >= 0 else 0
                self.last_R[i] = self.R[i]
                self.last_K0[i] = self.sK0[self.n_seg * p + i]
            self.n_seg += 1
            tiny = t_ev - t0 <= STALL_ULPS * EPS * max(fabs(t_ev), 1.0)
            guard = guard + 1 if tiny else 0
            t = t_ev
            self.tl = t
            self.t = self.sf[(self.n_seg - 1) * 6 + 1]
            if (T > 0.0 and not self.skip and T <= t < t_end
                    and (g.kind != PROXY or g.period > 0.0)):
                # periods not compared: the frame moves on at the first segment end past a
                # period's end (segments are not cut there), by whole periods (one: t - T is
                # exact for T <= t <= 2 T)
                k_next = <long>floor(t / T)
                self.origin_k += k_next
                self.origin = self.origin_k * T
                t = t - k_next * T
                self.tl = t
                t_end = t_abs - self.origin
                k_next = -1
            if guard > STALL_SEGMENTS:
                status = S_STALLED
                break
            if n_hit == 0 and not left and t >= ts:
                # ended on a smooth boundary: the next segment keeps the mode
                self.cache_ok = True
                self.cache_a = a
                for i in range(p):
                    self.cache_group[i] = self.group[i]
            if k_next > 0 and t == k_next * T:
                # ---- period boundary: the state against the one a period earlier
                same = (self.ck_valid and self.ck_k == self.origin_k + k_next - 1
                        and self.ck_ref == self.ref)
                if same:
                    for i in range(p):
                        if self.ck_contact[i] != self.contact[i] or self.ck_zero[i] != self.zero[i]:
                            same = False
                if same and self.stiction:
                    # the incumbent is state too: two states with the same (t, V) and
                    # different incumbents can have different futures (STICTION.md s. 7)
                    for i in range(p):
                        if self.ck_inc[i] != self.inc[i]:
                            same = False
                if same and self.ref < 0:
                    # repeated to the solver's accuracy: event times are known to tol, so
                    # velocities to about tol times the largest friction acceleration
                    same = fabs(self.V - self.ck_V) <= 16.0 * (
                        tol * self.v_acc + EPS * (fabs(self.V) + fabs(self.ck_V)))
                if same and self.skip and floor((t_end - t) / T * (1 + 4 * EPS)) >= 1:
                    self.k_at = self.origin_k + k_next
                    status = S_PERIODIC
                    break
                self.ck_valid = True
                self.ck_k = self.origin_k + k_next
                self.ck_X = self.X
                self.ck_V = self.V
                self.ck_x_ref = self.x_ref
                self.ck_ref = self.ref
                self.ck_nseg = self.seg_base + self.n_seg
                self.ck_nev = self.ev_base + self.n_ev
                for i in range(p):
                    self.ck_K[i] = self.K[i]
                    self.ck_contact[i] = self.contact[i]
                    self.ck_zero[i] = self.zero[i]
                    self.ck_inc[i] = self.inc[i]
                if g.kind != PROXY or g.period > 0.0:
                    # the next period in its own frame (a Python gait's pieces only once they
                    # repeat: before, they are built at the times the solver reaches); its
                    # origin is where this segment ended, (origin_k + k_next) T
                    self.origin_k += k_next
                    self.origin = self.origin_k * T
                    t = 0.0
                    self.tl = 0.0
                    t_end = t_abs - self.origin
        self.tl = t
        if status == S_REACHED:
            self.t = t_abs          # reached: the time asked (its local image may round)
        elif self.n_seg == 0:
            self.t = self.origin + t
        if self.n_seg > 0:
            self.last_gait = gait
        return status

    # ------------------------------------------------------------------ output
    def current(self, CompiledGait gait):
        """The state at the current time as one output row (left limit at an event): the last
        segment's closed form when it ends now, else the mode the next segment would take."""
        cdef int p = self.p, i, r0
        cdef double a
        if self.last_valid and self.last_f[1] == self.t and self.last_gait is not None:
            rec = self.last_record()
            return self.closed.row(self.last_gait, rec[0], rec[1], rec[2], rec[3], rec[4],
                                   rec[5], self.t)
        # provisional: a zero-length segment at t in the mode the next one would use
        g = &gait.d
        gait_lengths(g, self.t, self.l)
        gait_rates(g, self.t, self.ld, self.ldd, self.ld3)
        for i in range(p):
            self.e[i] = dot(self.W, i, self.l, self.nl)
            self.ep[i] = dot(self.W, i, self.ld, self.nl)
            self.epp[i] = dot(self.W, i, self.ldd, self.nl)
        X = self.X
        V = self.V
        if self.ref >= 0:
            V = -self.ep[self.ref]
            X = self.x_ref - self.e[self.ref]
        self.mode(g, self.t, self.t, &a, &r0)
        if r0 >= 0:
            x_ref = self.x_ref if r0 == self.ref else X + self.e[r0]
            V = -self.ep[r0]
        else:
            x_ref = self.x_ref
        nc = np.array(<signed char[:p]>self.new_contact)
        R = np.array([ground_force(self.new_contact[i], self.fp[i], self.fm[i])
                      for i in range(p)])
        f = np.array([self.t, self.t, X, V, a, x_ref])
        return self.closed.row(gait, f, r0, nc, np.array(<unsigned char[:p]>self.group), R,
                               np.array(<double[:p]>self.K), self.t)

    # ------------------------------------------------------------------ the rules from Python
    def search_rows(self, CompiledGait gait, double t0, double end, c0, c1, A1, A2,
                    double tol, double cap):
        """The compiled search (``search``) on given rows g = c0 + c1 (t - t0) + A1 . l' +
        A2 . l'' (K rows): (t or inf, hit rows (K,) bool, evaluations)."""
        cdef int nr = len(c0), r, j
        cdef double tt
        if nr > self.nr:
            raise ValueError(f'at most {self.nr} rows for p = {self.p}')
        for r in range(nr):
            self.c0[r] = c0[r]
            self.c1[r] = c1[r]
            for j in range(self.nl):
                self.A1[(r) * self.nl + j] = A1[r][j]
                self.A2[(r) * self.nl + j] = A2[r][j]
        n0 = self.n_evals
        code = self.search(&gait.d, t0, end, nr, tol, cap, &tt)
        if code == F_NO_STEPS:
            raise RuntimeError('the search ran out of steps')
        if code == F_NONFINITE:
            raise ValueError('gait values must be finite')
        hits = np.array(<unsigned char[:nr]>self.hit).astype(bool)
        return (tt if isfinite(tt) else INFINITY), hits, self.n_evals - n0

    def taylor_step(self, ga, da, watch, B2, B1, double tol, double cap, ca=None,
                    B3=None) -> float:
        """The compiled ``step`` for rows with values ga, slopes da and (rows of l' alone,
        given B3) curvatures ca at a."""
        cdef int nr = len(ga), r
        cdef double[::1] g = np.asarray(ga, dtype=float), d = np.asarray(da, dtype=float)
        cdef double[::1] c = np.zeros(nr) if ca is None else np.asarray(ca, dtype=float)
        for r in range(nr):
            self.watch[r] = bool(watch[r])
            self.B2[r] = B2[r]
            self.B1[r] = B1[r]
            self.B3[r] = INFINITY if B3 is None else B3[r]
        return self.step(nr, &g[0], &d[0], &c[0], tol, cap)

    def row_minima(self, CompiledGait gait, double a, double b, double t0, c0, c1, A1, A2):
        """The compiled ``range_lower`` for rows c0 + c1 (t - t0) + A1 . l'(t) + A2 . l''(t)
        (A1, A2 of shape (nr, nl)) over [a, b]: each row's lower bound (-inf for a gait that
        is not a TABLE)."""
        cdef int nr = len(c0), r, j, nl = self.nl
        if nr > self.nr:
            raise ValueError(f'at most {self.nr} rows')
        for r in range(nr):
            self.c0[r] = c0[r]
            self.c1[r] = c1[r]
            self.watch[r] = 0
            for j in range(nl):
                self.A1[r * nl + j] = A1[r][j]
                self.A2[r * nl + j] = A2[r][j]
        self.range_lower(&gait.d, a, b, t0, nr)
        return np.array([self.RL[r] for r in range(nr)])

    def proven_interval(self, double h, ga, gb, da, db, watch, B2, B1, ca=None, cb=None,
                        B3=None, noise=None, double h_free=INFINITY) -> bool:
        """The compiled ``proven`` for an interval of length h (curvatures ca, cb and B3 for
        rows of l' alone; watched rows' noise, and the step ``h_free`` they need no proof
        for)."""
        cdef int nr = len(ga), r
        cdef double[::1] a_ = np.asarray(ga, dtype=float), b_ = np.asarray(gb, dtype=float)
        cdef double[::1] c_ = np.asarray(da, dtype=float), d_ = np.asarray(db, dtype=float)
        cdef double[::1] e_ = np.zeros(nr) if ca is None else np.asarray(ca, dtype=float)
        cdef double[::1] f_ = np.zeros(nr) if cb is None else np.asarray(cb, dtype=float)
        for r in range(nr):
            self.watch[r] = bool(watch[r])
            self.B2[r] = B2[r]
            self.B1[r] = B1[r]
            self.B3[r] = INFINITY if B3 is None else B3[r]
            self.noise[r] = 0.0 if noise is None else noise[r]
            self.RL[r] = -INFINITY
        self.h_free = h_free
        return self.proven(nr, h, &a_[0], &b_[0], &c_[0], &d_[0], &e_[0], &f_[0])

    # ------------------------------------------------------------------ a fast state read
    def read_state(self, double[::1] x, double[::1] v, signed char[::1] contact) -> bint:
        """x [m], v [m/s] and contact (p,) of ``current`` written into the arrays, without a
        row's dict and arrays (the environments' step reads only these, issue 41): the last
        segment's closed form when it ends now, through ``ClosedForm._rows`` as ``current``
        evaluates it (the same arithmetic, bit for bit). False, nothing written, when
        ``current`` would take its provisional path (no segment ending now): then read that."""
        cdef int p = self.p
        if x.shape[0] != p or v.shape[0] != p or contact.shape[0] != p:
            raise ValueError(f'read_state: arrays of {p} entries expected')
        return self._read(&x[0], &v[0], &contact[0]) == 1

    cdef int _read(self, double* x, double* v, signed char* contact) except -1:
        """``read_state`` into (p,) rows: 1 written, 0 not (the provisional path)."""
        cdef int p = self.p, nl = self.nl
        cdef CompiledGait g
        cdef ClosedForm cf = self.closed
        cdef long ref = self.last_ref, owner = 0
        cdef double t = self.t
        cdef double* w
        cdef unsigned char ind
        if not (self.last_valid and self.last_f[1] == self.t and self.last_gait is not None):
            return 0
        g = self.last_gait
        if g.d.kind == PROXY:
            return 0              # (``values`` may read the user's functions there)
        # gait values at t (``CompiledGait.values``' one call), then R, K, lam as scratch
        w = <double*>PyMem_Malloc((4 * max(nl, 1) + 2 * p + max(p - 1, 1)) * sizeof(double))
        if w == NULL:
            raise MemoryError()
        try:
            gait_eval(&g.d, t, w, w + nl, w + 2 * nl, w + 3 * nl)
            cf._rows(1, w, w + nl, w + 2 * nl, self.last_f, &ref, self.last_group,
                     self.last_contact, self.last_R, self.last_K0, &owner, &t, x, v,
                     w + 4 * max(nl, 1), w + 4 * max(nl, 1) + p,
                     w + 4 * max(nl, 1) + 2 * p, contact, &ind)
        finally:
            PyMem_Free(w)
        return 1

    def switch_gait(self, CompiledGait old, CompiledGait new) -> bint:
        """``ExactSolver._switch_gait``'s work on the core, compiled (the engine switches gait
        at every sync, issue 41): absolute time frame, both gaits read at t, the mode chosen
        anew unless (l, l', l'') continue exactly, and with no reference body X and V moved
        by W_0 . (old - new), summed in order from 0.0 as numpy's dot does it there (BLAS's
        ddot below 16 terms), so bit for bit the Python path. False, nothing changed, for a
        gait of Python functions (PROXY: read through its callables) or 16 linkages or more:
        then the Python path runs."""
        return self._switch(old, new) == 1

    cdef int _switch(self, CompiledGait old, CompiledGait new) except -1:
        cdef int nl = self.nl, j
        cdef double t = self.t, dx = 0.0, dv = 0.0
        cdef double* w
        cdef bint same = True
        if old.d.kind == PROXY or new.d.kind == PROXY or nl >= 16:
            return 0
        w = <double*>PyMem_Malloc(8 * nl * sizeof(double))
        if w == NULL:
            raise MemoryError()
        try:
            self.tl = t
            self.origin = 0.0
            self.origin_k = 0
            gait_eval(&old.d, t, w, w + nl, w + 2 * nl, w + 3 * nl)
            gait_eval(&new.d, t, w + 4 * nl, w + 5 * nl, w + 6 * nl, w + 7 * nl)
            self.ck_valid = False
            for j in range(3 * nl):
                if not (w[j] == w[4 * nl + j]):
                    same = False
            if not same:
                self.cache_ok = False          # ``forget_mode``
            if self.ref < 0:
                for j in range(nl):
                    dx += self.W[j] * (w[j] - w[4 * nl + j])
                for j in range(nl):
                    dv += self.W[j] * (w[nl + j] - w[5 * nl + j])
                self.X += dx
                self.V += dv
        finally:
            PyMem_Free(w)
        return 1



def solve_inclusion(double c, double u_ref, double force, kinks, f_plus, f_minus):
    """The inclusion of ``_inclusion`` from Python: (u, s) for one crawler (module doc of
    ``_inclusion``)."""
    cdef double[::1] k = np.ascontiguousarray(kinks, dtype=float)
    cdef double[::1] a = np.ascontiguousarray(f_plus, dtype=float)
    cdef double[::1] b = np.ascontiguousarray(f_minus, dtype=float)
    cdef int n = k.shape[0]
    cdef int[::1] idx = np.zeros(max(n, 1), np.intc)
    cdef double s = 0.0, u
    if n == 0:
        return u_ref + force / c, 0.0
    u = inclusion(c, u_ref, force, &k[0], &a[0], &b[0], n, &idx[0], &s)
    return u, s


# ---------------------------------------------------------------------- from C (_exact.pxd)
# ``ExactSolver.advance``'s work on its core, for the plant's compiled step
# (``core/plant/_batch.pyx``, issue 41): the same methods as from Python, without a call.

cdef int core_switch(object core, CompiledGait old, CompiledGait new) except -1:
    """``ExactCore.switch_gait``: 1 done, 0 the Python path must run (nothing changed)."""
    return (<ExactCore?>core)._switch(old, new)


cdef int core_drive(object core, CompiledGait gait, double t1, long ev_base,
                    long* counts) except -1:
    """One pass of ``ExactSolver.advance``'s loop with ``T`` = 0 (a gait that is not
    periodic) and no kept segments: ``seg_base`` 0, ``ev_base``, ``save``, ``drive`` towards
    t1 [s]. Returns drive's status with counts = (n_seg, n_ev, n_choice) of the call; a call
    that failed (a status but REACHED or FULL) or raised is undone (``restore``), as there."""
    cdef ExactCore c = <ExactCore?>core
    cdef int status
    c.seg_base = 0
    c.ev_base = ev_base
    c._save()
    try:
        status = c._drive(gait, t1, 0.0)
    except BaseException:
        c._restore()
        raise
    if status != S_REACHED and status != S_FULL:
        c._restore()
    counts[0] = c.n_seg
    counts[1] = c.n_ev
    counts[2] = c.n_choice
    return status


cdef double core_time(object core) except? -1.0:
    """The core's time t [s]."""
    return (<ExactCore?>core).t


cdef int core_settle(object core, bint skip, double tscale, double cap) except -1:
    """``advance``'s settings of a call: ``skip``, ``tscale`` [s], ``cap`` [s]."""
    cdef ExactCore c = <ExactCore?>core
    c.skip = skip
    c.tscale = tscale
    c.cap = cap
    return 0


cdef int core_forget(object core) except -1:
    """``ExactSolver.forget_history``'s work on the core: the periodic check starts anew."""
    (<ExactCore?>core).ck_valid = False
    return 0


cdef int core_read(object core, double* x, double* v, signed char* contact) except -1:
    """``ExactCore.read_state`` into (p,) rows: 1 written, 0 not (read ``current`` then)."""
    return (<ExactCore?>core)._read(x, v, contact)


cdef object core_event_records(object core, long n):
    """The call's first n contact changes as ``EVENT_RECORD`` records (t [s], body, old, new)
    packed in one bytes object (not a tracked object per event: ``Engine.pop_events`` makes
    the ``Event`` tuples when they are asked for)."""
    cdef ExactCore c = <ExactCore?>core
    out = PyBytes_FromStringAndSize(NULL, n * sizeof(EventRecord))
    cdef EventRecord* r = <EventRecord*>PyBytes_AS_STRING(out)
    cdef long k
    for k in range(n):
        r[k].t = c.et[k]
        r[k].body = c.ei[3 * k]
        r[k].old = c.ei[3 * k + 1]
        r[k].new = c.ei[3 * k + 2]
    return out


def event_records(bytes records, make) -> list:
    """The events of ``core_event_records``' bytes as a list of ``make((time, body, old,
    new))``, what ``ExactCore.events`` returns for them."""
    cdef const EventRecord* r = <const EventRecord*>PyBytes_AS_STRING(records)
    cdef Py_ssize_t k, n = len(records) // sizeof(EventRecord)
    cdef list out = []
    for k in range(n):
        out.append(make((r[k].t, r[k].body, r[k].old, r[k].new)))
    return out
