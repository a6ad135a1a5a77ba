# cython: language_level=3
"""The compiled form of a gait: one struct, evaluated by the inline functions below.

Every solver (``_exact``, ``_stepping``) and every Python call of a gait (``Gait.__call__``,
``at``, ``breakpoints``, ``jerk_bound``) evaluates gaits through these functions, so each gait's
arithmetic exists once. Four kinds:

* FOURIER: l_j = mean_j + sum_k a_jk cos(k th) + b_jk sin(k th), th = 2 pi (f t mod 1)
  (``Sinusoid`` and ``Fourier``);
* SCALLOP: the warped cosine stroke of ``gaits.smooth.Scallop``;
* TABLE: constant-jerk pieces (l0, v0, a0, jerk) per linkage, ``Cubic``, ``PiecewiseCubic``,
  ``PiecewiseParabolic`` (jerk 0) and ``Spline``; periodic or not;
* CALLBACK: Python callables (``Custom`` and any other ``Gait`` subclass), l''' by a difference
  of l''.

Units: t [s], l [m], l' [m/s], l'' [m/s^2], l''' [m/s^3], l'''' [m/s^4].
"""
from cpython.mem cimport PyMem_Malloc, PyMem_Free
from libc.math cimport floor, fabs, sin, cos, M_PI, INFINITY, NAN

cdef enum:
    FOURIER = 0
    SCALLOP = 1
    TABLE = 2
    CALLBACK = 3



ctypedef struct GaitData:
    int kind
    int nl                  # number of linkages
    # FOURIER and SCALLOP
    double freq             # [Hz]
    int nk                  # FOURIER: harmonics
    double* mean            # (nl,) [m]
    double* p1              # FOURIER: cos coefficients (nl, nk); SCALLOP rows (nl, 6):
    double* p2              #   amplitude, phase - pi r, cos(pi r), sin(pi r), and the cosine
                            #   and sine of phase - pi r; FOURIER: sin (nl, nk)
    # TABLE: piece k, linkage j at coef[(k nl + j) 4 + 0..3] = (l0, v0, a0, jerk) from its origin
    int n                   # pieces
    double period           # > 0: periodic table (pieces of one period, between knots)
    double* knots           # periodic: (n + 1,) knot times of the period starting at knots[0]
    double* starts          # not periodic: (n,) piece starts (starts[0] may be -inf)
    double* anchors         # not periodic: (n,) time origin of each piece
    double* coef
    unsigned char* jump     # (n,) l'' may jump at the start of piece k (a breakpoint)
    unsigned char* jjump    # (n,) l''' jumps at the start of piece k (no snap bound across)
    unsigned char* rest     # (n,) l' = l'' = 0 on piece k
    int hint                # the piece found last (lookups are mostly near it)
    int n_jumps
    double* jump_times      # (n_jumps,) sorted breakpoint times (of one period when periodic)
    # derivative bounds: FOURIER constant (nl,); SCALLOP nb bins per period (nb, nl)
    int nb
    double* bj              # |l'''| [m/s^3]
    double* bs              # |l''''| [m/s^4]
    double* bj_all          # SCALLOP: the largest bin (nl,)
    double* bs_all
    bint constant           # l' = l'' = 0 at all times
    void* obj               # CALLBACK: the CompiledGait that owns this struct


cdef class CompiledGait:
    cdef GaitData d
    cdef readonly int n_links
    cdef readonly object period         # [s] or None
    cdef object _keep                   # the arrays the struct points into
    # CALLBACK kind
    cdef object _gait                   # the Python gait
    cdef object _fns                    # (l, l', l'') callables of one float, or None
    cdef bint _scalar                   # the callables return floats (one linkage)
    cdef object _jerk                   # user bound: None, an array (nl,) or a callable
    cdef public object estimate         # ``estimate.BoundEstimate``: bounds where none are given
    cdef public bint estimated          # the bounds in use are the estimate's
    cdef double[:, ::1] _buf            # rows l, l', l'', l''' of the last evaluation
    cdef double _t_len, _t_rates        # times of the values in _buf (NaN: none)
    cdef public double span_lo, span_hi  # the span being integrated: callables stay inside it
    cdef public int exceeded            # evaluations above the estimated jerk bound
    cdef public object lock             # CALLBACK: one solver at a time (its state is shared)
    cdef object _est_starts             # the estimate's arrays as last seen, and views of them
    cdef double[::1] _st
    cdef double[:, ::1] _d1, _d2
    cdef double _safety
    cdef int _sync(self) except -1
    cdef int _lookup(self, double a, double b, double* jerk, double* snap) except -1
    cdef bint _check(self, double t, double* ld3) except -1
    cdef double _diff_step(self, double t) except -1.0
    cdef int _fetch(self, double t, bint with_length) except -1
    cdef int cb_rates(self, double t, double* ld, double* ldd, double* ld3) except -1
    cdef int cb_lengths(self, double t, double* l) except -1
    cdef int cb_bounds(self, double a, double b, double* jerk, double* snap) except -1
    cdef double cb_next_break(self, double t) except? -1.0
    cdef int cb_is_constant(self, double a, double b) except -1


# ----------------------------------------------------------------------------- tables
cdef inline int table_locate(const GaitData* g, double t, double* d, double* m) noexcept nogil:
    """Piece of a TABLE gait at t (closed on the left), the offset d = t - its origin and, when
    periodic, its period index m (knot k of period m sits at knots[k] + m T, the last one at
    knots[0] + (m + 1) T, computed so at every time ``breakpoints`` reports)."""
    cdef int lo, hi, mid, j
    cdef int K = g.n
    cdef double T, mm
    if g.period > 0.0:
        T = g.period
        mm = floor((t - g.knots[0]) / T)
        if g.knots[0] + (mm + 1.0) * T <= t:
            j = K + 1
        else:
            lo = 0
            hi = K
            while lo < hi:
                mid = (lo + hi) >> 1
                if g.knots[mid] + mm * T <= t:
                    lo = mid + 1
                else:
                    hi = mid
            j = lo
        if j == 0:
            mm -= 1.0
            j = K
        elif j > K:
            mm += 1.0
            j = 1
        d[0] = t - (g.knots[j - 1] + mm * T)
        m[0] = mm
        return j - 1
    j = g.hint
    if not (0 <= j < K and (j == 0 or g.starts[j] <= t) and (j == K - 1 or t < g.starts[j + 1])):
        lo = 0
        hi = K
        while lo < hi:
            mid = (lo + hi) >> 1
            if g.starts[mid] <= t:
                lo = mid + 1
            else:
                hi = mid
        j = lo - 1
        if j < 0:
            j = 0
        (<GaitData*>g).hint = j
    d[0] = t - g.anchors[j]
    m[0] = 0.0
    return j


cdef inline double piece_start(const GaitData* g, int k, double m) noexcept nogil:
    """Start time of piece k (of period m when periodic) [s]."""
    if g.period > 0.0:
        return g.knots[k] + m * g.period
    return g.starts[k]


cdef inline double next_jump(const GaitData* g, double t) noexcept nogil:
    """The first breakpoint of a TABLE gait after t (INFINITY when none)."""
    cdef int lo, hi, mid
    cdef double T, m, b
    cdef int nj = g.n_jumps
    if nj == 0:
        return INFINITY
    if g.period > 0.0:
        T = g.period
        m = floor((t - g.knots[0]) / T) - 1.0
        while True:
            # the first breakpoint of period m after t, else the next period
            lo = 0
            hi = nj
            while lo < hi:
                mid = (lo + hi) >> 1
                if g.jump_times[mid] + m * T <= t:
                    lo = mid + 1
                else:
                    hi = mid
            if lo < nj:
                return g.jump_times[lo] + m * T
            m += 1.0
    lo = 0
    hi = nj
    while lo < hi:
        mid = (lo + hi) >> 1
        if g.jump_times[mid] <= t:
            lo = mid + 1
        else:
            hi = mid
    return g.jump_times[lo] if lo < nj else INFINITY


# ----------------------------------------------------------------------------- evaluation
cdef inline int gait_eval(GaitData* g, double t, double* l, double* ld, double* ldd,
                          double* ld3) except -1:
    """l (when ``l`` is not NULL), l', l'' and l''' at t: the one evaluation of every kind
    (lengths share the trigonometric values of the rates). Returns 0, or 1 when a CALLBACK
    gait's value contradicts its estimated bounds (they have been grown: the caller redoes
    what relied on them)."""
    cdef int j, k, nl = g.nl, nk, code
    cdef double d, m, a0, jk, ft, th, w, amp, c, s, x, cx, sx, inv_d, sin_phi, cos_phi
    cdef double dphi, ddphi, dddphi, c1, s1, cc, ss, cn, wk, wk2, wk3, a_, b_
    cdef double* row
    if g.kind == TABLE:
        k = table_locate(g, t, &d, &m)
        row = g.coef + k * nl * 4
        for j in range(nl):
            a0 = row[4 * j + 2]
            jk = row[4 * j + 3]
            if l != NULL:
                l[j] = row[4 * j] + d * (row[4 * j + 1] + d * (0.5 * a0 + d * jk / 6.0))
            ld[j] = row[4 * j + 1] + d * (a0 + 0.5 * d * jk)
            ldd[j] = a0 + d * jk
            ld3[j] = jk
        return 0
    if g.kind == CALLBACK:
        if l != NULL:
            (<CompiledGait>g.obj).cb_lengths(t, l)
        return (<CompiledGait>g.obj).cb_rates(t, ld, ldd, ld3)
    ft = g.freq * t
    th = 2.0 * M_PI * (ft - floor(ft))          # the phase in cycles first (large t)
    w = 2.0 * M_PI * g.freq
    if g.kind == SCALLOP:
        # sin phi = s sin x / D, cos phi = (cos x - c) / D, D = 1 - c cos x;
        # phi''' = -s c (cos x / D^2 - 2 c sin^2 x / D^3),
        # l''' = amp w^3 (cos phi (phi''' - phi'^3) - 3 sin phi phi' phi'')
        c1 = cos(th)
        s1 = sin(th)
        for j in range(nl):
            row = g.p1 + 6 * j
            amp = row[0]
            c = row[2]
            s = row[3]
            # x = th + (phase - pi r): cos x and sin x by angle addition
            cx = c1 * row[4] - s1 * row[5]
            sx = s1 * row[4] + c1 * row[5]
            inv_d = 1.0 / (1.0 - c * cx)
            sin_phi = s * sx * inv_d
            cos_phi = (cx - c) * inv_d
            dphi = s * inv_d
            ddphi = -s * c * sx * inv_d * inv_d
            dddphi = -s * c * (cx * inv_d * inv_d - 2.0 * c * sx * sx * inv_d * inv_d * inv_d)
            if l != NULL:
                l[j] = g.mean[j] + amp * sin_phi
            ld[j] = amp * w * cos_phi * dphi
            ldd[j] = amp * (w * w) * (cos_phi * ddphi - sin_phi * dphi * dphi)
            ld3[j] = amp * (w * w * w) * (cos_phi * (dddphi - dphi * dphi * dphi)
                                          - 3.0 * sin_phi * dphi * ddphi)
        return 0
    # FOURIER: harmonics by the angle-addition recurrence from cos th, sin th (two
    # trigonometric calls per time instead of two per harmonic; rounding ~k eps)
    nk = g.nk
    c1 = cos(th)
    s1 = sin(th)
    for j in range(nl):
        if l != NULL:
            l[j] = 0.0
        ld[j] = 0.0
        ldd[j] = 0.0
        ld3[j] = 0.0
    cc = c1
    ss = s1
    for k in range(nk):
        wk = w * (k + 1)
        wk2 = wk * wk
        wk3 = wk2 * wk
        for j in range(nl):
            a_ = g.p1[j * nk + k]
            b_ = g.p2[j * nk + k]
            if l != NULL:
                l[j] += a_ * cc + b_ * ss
            ld[j] += wk * (b_ * cc - a_ * ss)
            ldd[j] -= wk2 * (a_ * cc + b_ * ss)
            ld3[j] += wk3 * (a_ * ss - b_ * cc)
        cn = cc * c1 - ss * s1
        ss = ss * c1 + cc * s1
        cc = cn
    if l != NULL:
        for j in range(nl):
            l[j] = g.mean[j] + l[j]
    return 0


cdef inline int gait_rates(GaitData* g, double t, double* ld, double* ldd,
                           double* ld3) except -1:
    """l', l'' and l''' at t (``gait_eval`` without the lengths)."""
    return gait_eval(g, t, NULL, ld, ldd, ld3)


cdef inline int gait_lengths(GaitData* g, double t, double* l) except -1:
    """l(t) [m] (``gait_eval``'s lengths, the rates into scratch)."""
    cdef double buf[96]
    cdef double* w
    cdef int nl = g.nl
    if g.kind == CALLBACK:
        return (<CompiledGait>g.obj).cb_lengths(t, l)
    if nl <= 32:
        gait_eval(g, t, l, buf, buf + 32, buf + 64)
        return 0
    w = <double*>PyMem_Malloc(3 * nl * sizeof(double))
    if w == NULL:
        raise MemoryError()
    try:
        gait_eval(g, t, l, w, w + nl, w + 2 * nl)
    finally:
        PyMem_Free(w)
    return 0


cdef inline double gait_next_break(GaitData* g, double t) except? -1.0:
    """The first time after t where l'' may jump [s] (INFINITY when none)."""
    if g.kind == TABLE:
        return next_jump(g, t)
    if g.kind == CALLBACK:
        return (<CompiledGait>g.obj).cb_next_break(t)
    return INFINITY


cdef inline int gait_is_constant(GaitData* g, double a, double b) except -1:
    """1 when l' = l'' = 0 on all of [a, b] (pieces judged on their interiors)."""
    cdef int k
    cdef double d, m
    if g.constant:
        return 1
    if g.kind == CALLBACK:
        return (<CompiledGait>g.obj).cb_is_constant(a, b)
    if g.kind != TABLE:
        return 0
    if g.period > 0.0 and b - a >= g.period:
        return 0
    k = table_locate(g, a, &d, &m)
    while True:
        if not g.rest[k]:
            return 0
        k += 1
        if k == g.n:
            if g.period <= 0.0:
                return 1
            k = 0
            m += 1.0
        if piece_start(g, k, m) >= b:
            return 1


cdef inline int gait_bounds(GaitData* g, double a, double b, double* jerk,
                            double* snap) except -1:
    """Bounds of |l'''| and |l''''| per linkage on [a, b] (between breakpoints). Returns 1, or
    0 when l''' may jump inside (no snap bound: ``snap`` is then left undefined)."""
    cdef int j, k, k0, k1, kk, nl = g.nl, nb, first
    cdef double d, m, u0, x, st
    if g.kind == FOURIER:
        for j in range(nl):
            jerk[j] = g.bj[j]
            snap[j] = g.bs[j]
        return 1
    if g.kind == CALLBACK:
        return (<CompiledGait>g.obj).cb_bounds(a, b, jerk, snap)
    if g.kind == SCALLOP:
        # bins k0 .. k1 that [a, b] touches (wrapping); each bin bound holds on its closed bin
        nb = g.nb
        u0 = g.freq * a
        k0 = <int>floor((u0 - floor(u0)) * nb)
        x = floor(g.freq * (b - a) * nb)
        if x + 2.0 >= nb or k0 < 0 or k0 >= nb:
            for j in range(nl):
                jerk[j] = g.bj_all[j]
                snap[j] = g.bs_all[j]
            return 1
        k1 = k0 + <int>x + 1
        for j in range(nl):
            jerk[j] = 0.0
            snap[j] = 0.0
        for kk in range(k0, k1 + 1):
            k = kk % nb
            for j in range(nl):
                if g.bj[k * nl + j] > jerk[j]:
                    jerk[j] = g.bj[k * nl + j]
                if g.bs[k * nl + j] > snap[j]:
                    snap[j] = g.bs[k * nl + j]
        return 1
    # TABLE: the pieces [a, b] touches; jerk constant on each, so snap 0 unless a join inside
    # changes it
    for j in range(nl):
        jerk[j] = 0.0
        snap[j] = 0.0
    k = table_locate(g, a, &d, &m)
    first = 1
    kk = 0
    while True:
        if not first:
            st = piece_start(g, k, m)
            if st >= b:
                break
            if g.jjump[k] and st > a:
                kk = 1
        first = 0
        for j in range(nl):
            x = fabs(g.coef[(k * nl + j) * 4 + 3])
            if x > jerk[j]:
                jerk[j] = x
        k += 1
        if k == g.n:
            if g.period <= 0.0:
                break
            k = 0
            m += 1.0
        if g.period > 0.0 and b - a >= 2.0 * g.period and k == 0:
            # every piece seen once, the rest repeats: no snap bound if a join changes the jerk
            for k1 in range(g.n):
                if g.jjump[k1]:
                    kk = 1
            break
    return 0 if kk else 1
