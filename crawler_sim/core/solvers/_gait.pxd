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
* PROXY: Python callables (``Custom``, any other ``Gait`` subclass), sampled into Chebyshev
  pieces (``proxy.ChebTable``) as the solver reaches them.

Units: t [s], l [m], l' [m/s], l'' [m/s^2], l''' [m/s^3], l'''' [m/s^4].
"""
from cpython.mem cimport PyMem_Malloc, PyMem_Free
from libc.math cimport floor, fabs, sin, cos, nextafter, M_PI, INFINITY, NAN

cdef enum:
    FOURIER = 0
    SCALLOP = 1
    TABLE = 2
    PROXY = 4

cdef enum:
    RANGE_LEVELS = 6        # range extremes of up to 2^6 items (a longer run: one per 64)


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
    # TABLE: per piece and linkage |jerk|, lo l', hi l', lo l'', hi l'' over the whole piece,
    # records (5, nl) of aligned blocks: level q (from record lev_off[q] on) the extremes over
    # pieces i 2^q .. (i + 1) 2^q - 1 (the last block clipped at n), about 2 n records in all
    # (``table_run``: the exact search's walk reads one as the ranges over a run of pieces;
    # ``table_jerk``); jjump counts over the pieces before each, (2 n + 1,) (two periods when
    # periodic)
    double* stat
    int lev_off[RANGE_LEVELS + 2]
    int* jj_before
    # derivative bounds: FOURIER constant (nl,); SCALLOP nb bins per period (nlev, nb, nl):
    # level q the largest of the 2^q bins from each bin on
    int nb
    int nlev
    double* bj              # |l'''| [m/s^3]
    double* bs              # |l''''| [m/s^4]
    double* bj_all          # SCALLOP: the largest bin (nl,)
    double* bs_all
    bint constant           # l' = l'' = 0 at all times
    void* obj               # PROXY: the CompiledGait that owns this struct
    # PROXY: n pieces between knots (n + 1,); series coef (n, nl, 4, stride) of l, l', l'',
    # l''' in u = (2 t - a - b) / (b - a), ncoef (n,) of them in use; bj, bs (n, nl) bounds
    # per piece; rest (n,); period > 0 once the pieces cover one period from knots[0]
    int* ncoef
    int stride


cdef class CompiledGait:
    cdef GaitData d
    cdef readonly int n_links
    cdef readonly object period         # [s] or None
    cdef object _keep                   # the arrays the struct points into
    # PROXY kind: the user's functions (read outside the pieces)
    cdef object _gait                   # a weak reference to the Python gait
    cdef object _fns                    # (l, l', l'') callables of one float, or None
    cdef bint _scalar                   # the callables return floats (one linkage)
    cdef double[:, ::1] _buf            # rows l, l', l'' of the last evaluation
    cdef double _t_len, _t_rates        # times of the values in _buf (NaN: none)
    cdef public double span_lo, span_hi  # the span being integrated: callables stay inside it
    cdef public object lock             # PROXY: one solver at a time (shared state)
    cdef int _fetch(self, double t, bint with_length) except -1
    cdef int cb_rates(self, double t, double* ld, double* ldd, double* ld3) except -1
    cdef int cb_lengths(self, double t, double* l) except -1
    # PROXY kind
    cdef public object table            # ``proxy.ChebTable``
    cdef int px_sync(self) except -1
    cdef int px_ensure(self, double t) except -1
    cdef bint _covers(self, double t) noexcept


# ----------------------------------------------------------------------------- tables
cdef inline int count_le(const double* x, int n, double t, double shift) noexcept nogil:
    """How many of the sorted x[0 .. n - 1], each plus ``shift``, are <= t (binary search)."""
    cdef int lo = 0, hi = n, mid
    while lo < hi:
        mid = (lo + hi) >> 1
        if x[mid] + shift <= t:
            lo = mid + 1
        else:
            hi = mid
    return lo


cdef inline int table_locate(const GaitData* g, double t, double* d, double* m) noexcept nogil:
    """Piece of a TABLE gait at t (closed on the left), the offset d = t - its origin and, when
    periodic, its period index m (knot k of period m sits at knots[k] + m T, the last one at
    knots[0] + (m + 1) T, computed so at every time ``breakpoints`` reports)."""
    cdef int j
    cdef int K = g.n
    cdef double T, mm
    if g.period > 0.0:
        T = g.period
        mm = floor((t - g.knots[0]) / T)
        if g.knots[0] + (mm + 1.0) * T <= t:
            j = K + 1
        else:
            j = count_le(g.knots, K, t, mm * T)
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
        j = count_le(g.starts, K, t, 0.0) - 1
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
    cdef int lo
    cdef double T, m, b
    cdef int nj = g.n_jumps
    if nj == 0:
        return INFINITY
    if g.period > 0.0:
        T = g.period
        m = floor((t - g.knots[0]) / T) - 1.0
        while True:
            # the first breakpoint of period m after t, else the next period
            lo = count_le(g.jump_times, nj, t, m * T)
            if lo < nj:
                return g.jump_times[lo] + m * T
            m += 1.0
    lo = count_le(g.jump_times, nj, t, 0.0)
    return g.jump_times[lo] if lo < nj else INFINITY


# ----------------------------------------------------------------------------- proxies
cdef inline int proxy_locate(GaitData* g, double t, double* u, double* m) except -1:
    """Piece of a PROXY gait holding t (built first when t lies outside the table), the
    variable u in [-1, 1] there and, once the pieces are periodic, the period index m."""
    cdef int k, K
    cdef double tt = t, a, b
    if g.period <= 0.0 and not (g.n > 0 and g.knots[0] <= t <= g.knots[g.n]):
        (<CompiledGait>g.obj).px_ensure(t)
    m[0] = 0.0
    if g.period > 0.0:
        m[0] = floor((t - g.knots[0]) / g.period)
        tt = t - m[0] * g.period
    K = g.n
    k = g.hint
    if not (0 <= k < K and g.knots[k] <= tt and (tt < g.knots[k + 1] or k == K - 1)):
        k = count_le(g.knots, K + 1, tt, 0.0) - 1
        if k < 0:
            k = 0
        if k > K - 1:
            k = K - 1
        g.hint = k
    a = g.knots[k]
    b = g.knots[k + 1]
    u[0] = (2.0 * tt - a - b) / (b - a) if b > a else 0.0
    return k


cdef inline double cheb_dot(const double* c, const double* T, int n) noexcept nogil:
    """sum c_q T_q, q < n, in four independent partial sums (short dependency chains)."""
    cdef double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0
    cdef int q = 0
    while q + 3 < n:
        s0 += c[q] * T[q]
        s1 += c[q + 1] * T[q + 1]
        s2 += c[q + 2] * T[q + 2]
        s3 += c[q + 3] * T[q + 3]
        q += 4
    while q < n:
        s0 += c[q] * T[q]
        q += 1
    return (s0 + s2) + (s1 + s3)


cdef inline void proxy_piece(const GaitData* g, int k, double u, double* l, double* ld,
                             double* ldd, double* ld3) noexcept nogil:
    """The four series of piece k at u (l skipped when NULL): the Chebyshev values T_q(u)
    once for all series and linkages, by doubling (T_(m+i) = 2 T_m T_i - T_(m-i), each level
    from the one before, so the chain is log2(n) long, not n as in Clenshaw's recurrence,
    which made an evaluation three times a Fourier gait's), then one sum per series."""
    cdef int j, q, m, top, nl = g.nl, nc = g.ncoef[k], st = g.stride
    cdef const double* c
    cdef double tm2
    cdef double T[64]
    T[0] = 1.0
    T[1] = u
    m = 1
    while m + 1 < nc:
        tm2 = 2.0 * T[m]             # held in a register (the stores below cannot alias it)
        top = min(2 * m, nc - 1)
        for q in range(m + 1, top + 1):
            T[q] = tm2 * T[q - m] - T[2 * m - q]
        m *= 2
    for j in range(nl):
        c = g.coef + (k * nl + j) * 4 * st
        if l != NULL:
            l[j] = cheb_dot(c, T, nc)
        ld[j] = cheb_dot(c + st, T, nc)
        ldd[j] = cheb_dot(c + 2 * st, T, nc)
        ld3[j] = cheb_dot(c + 3 * st, T, nc)


cdef inline double proxy_next_break(GaitData* g, double t) except? -1.0:
    """The first join of a PROXY gait's pieces after t (INFINITY at the end of the span)."""
    cdef double u, m, x
    cdef int k
    cdef CompiledGait cg = <CompiledGait>g.obj
    if g.period <= 0.0 and not (g.n > 0 and t < g.knots[g.n]):
        if t >= cg.span_hi:
            return INFINITY
        proxy_locate(g, nextafter(t, INFINITY), &u, &m)
    k = proxy_locate(g, t, &u, &m)
    while True:
        k += 1
        if k > g.n:
            if g.period <= 0.0:
                return INFINITY
            k = 1
            m += 1.0
        x = g.knots[k] + m * g.period if g.period > 0.0 else g.knots[k]
        if x > t:
            return x


cdef inline int proxy_walk(GaitData* g, double a, double b, double* jerk, double* snap,
                           bint* rest) except -1:
    """Over the pieces whose interiors [a, b] touches: the largest bounds per linkage and
    whether every one is at rest. Returns the number of pieces."""
    cdef double u, m, start
    cdef int k, j, nl = g.nl, count = 0
    if b > a:
        proxy_locate(g, b, &u, &m)          # built up to b first (a build may start afresh)
    k = proxy_locate(g, a, &u, &m)
    rest[0] = True
    for j in range(nl):
        jerk[j] = 0.0
        snap[j] = 0.0
    while True:
        count += 1
        for j in range(nl):
            if g.bj[k * nl + j] > jerk[j]:
                jerk[j] = g.bj[k * nl + j]
            if g.bs[k * nl + j] > snap[j]:
                snap[j] = g.bs[k * nl + j]
        if not g.rest[k]:
            rest[0] = False
        k += 1
        if k == g.n:
            if g.period <= 0.0:
                break
            k = 0
            m += 1.0
        start = g.knots[k] + m * g.period if g.period > 0.0 else g.knots[k]
        if start >= b or count > g.n:
            break
    return count


# ----------------------------------------------------------------------------- evaluation
cdef inline int gait_eval(GaitData* g, double t, double* l, double* ld, double* ldd,
                          double* ld3) except -1:
    """l (when ``l`` is not NULL), l', l'' and l''' at t: the one evaluation of every kind
    (lengths share the trigonometric values of the rates). Returns 0."""
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
            ld[j] = piece_rate(row + 4 * j, d)
            ldd[j] = piece_acc(row + 4 * j, d)
            ld3[j] = jk
        return 0
    if g.kind == PROXY:
        if (g.period <= 0.0 and not (g.n > 0 and g.knots[0] <= t <= g.knots[g.n])
                and not ((<CompiledGait>g.obj).span_lo <= t <= (<CompiledGait>g.obj).span_hi)):
            # outside the pieces and outside any solve (a solver reading its first state):
            # the user's functions, as from Python; nothing is built
            if l != NULL:
                (<CompiledGait>g.obj).cb_lengths(t, l)
            return (<CompiledGait>g.obj).cb_rates(t, ld, ldd, ld3)
        k = proxy_locate(g, t, &d, &m)
        proxy_piece(g, k, d, l, ld, ldd, ld3)
        return 0
    ft = g.freq * t
    th = 2.0 * M_PI * (ft - floor(ft))          # the phase in cycles first (large t)
    w = 2.0 * M_PI * g.freq
    # one cosine and one sine of th for both kinds, taken together (the compiler makes them
    # one sincos call; written in each branch, it did so for FOURIER only)
    c1 = cos(th)
    s1 = sin(th)
    if g.kind == SCALLOP:
        # sin phi = s sin x / D, cos phi = (cos x - c) / D, D = 1 - c cos x;
        # phi''' = -s c (cos x / D^2 - 2 c sin^2 x / D^3),
        # l''' = amp w^3 (cos phi (phi''' - phi'^3) - 3 sin phi phi' phi'')
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
    if g.kind == PROXY:
        return proxy_next_break(g, t)
    return INFINITY


cdef inline int gait_is_constant(GaitData* g, double a, double b) except -1:
    """1 when l' = l'' = 0 on all of [a, b] (pieces judged on their interiors)."""
    cdef int k
    cdef double d, m
    cdef double buf[64]
    cdef bint rest
    if g.constant:
        return 1
    if g.kind == PROXY:
        if g.nl > 32:
            return 0
        proxy_walk(g, a, b, buf, buf + 32, &rest)
        return 1 if rest else 0
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


cdef inline void run_extreme(const double* lev, int n, int nlev, int width, int i0,
                             int count, bint largest, int nl, double* out) noexcept nogil:
    """The extreme (largest, else smallest) over ``count`` consecutive items from i0 on
    (indices mod n; i0 + count <= 2 n) of a table of range extremes, merged into out (nl,):
    ``lev`` the item 0, level 0 entry, ``width`` doubles per item, n items per level, level q
    the extreme over the 2^q items from each on (SCALLOP's bins). Runs of
    2^q items (the widest level within the run), the last one ending at the run's end: two
    lookups for runs up to 2^nlev items, one per 2^(nlev - 1) beyond."""
    cdef int q = 0, w, last, kk, j
    cdef const double* row
    while q + 1 < nlev and (2 << q) <= count:
        q += 1
    w = 1 << q
    last = i0 + count - w
    kk = i0
    while True:
        if kk > last:
            kk = last
        row = lev + (q * n + (kk if kk < n else kk - n)) * width
        # an unconditional select (maxsd / minsd), not a branch on the data
        if largest:
            for j in range(nl):
                out[j] = row[j] if row[j] > out[j] else out[j]
        else:
            for j in range(nl):
                out[j] = row[j] if row[j] < out[j] else out[j]
        if kk == last:
            break
        kk += w


cdef inline const double* table_run(const GaitData* g, int q, int k) noexcept nogil:
    """A TABLE gait's record (``stat``) of the block of 2^q pieces from piece k, a multiple
    of 2^q (the last block of a level is clipped at n)."""
    return g.stat + (g.lev_off[q] + (k >> q)) * 5 * g.nl


cdef inline void table_jerk(const GaitData* g, int i0, int count, double* out) noexcept nogil:
    """The largest |jerk| (field 0 of ``stat``) of a TABLE gait's ``count`` pieces from i0 on
    (indices mod n, i0 + count <= 2 n), merged into out: the run cut into aligned blocks, at
    each piece the widest that starts there and fits (a few lookups at either end, one per
    2^(nlev - 1) pieces between)."""
    cdef int i = i0, end = i0 + count, ii, q, j
    cdef const double* row
    while i < end:
        ii = i if i < g.n else i - g.n
        q = 0
        while (q + 1 < g.nlev and (ii & ((2 << q) - 1)) == 0 and (2 << q) <= end - i
               and ii + (2 << q) <= g.n):
            q += 1
        row = table_run(g, q, ii)
        for j in range(g.nl):
            out[j] = row[j] if row[j] > out[j] else out[j]
        i += 1 << q


cdef inline int table_span(const GaitData* g, double a, double b, int* k0) noexcept nogil:
    """The pieces a TABLE gait's [a, b] touches (a piece starting at b or later is not): the
    first, k0 (index mod n), and how many (more than n: every piece, more than once). b is
    looked for in the next few pieces first (most intervals are short)."""
    cdef double d, m0, m
    cdef int k, count = 1
    k0[0] = table_locate(g, a, &d, &m0)
    k = k0[0]
    m = m0
    while True:
        # does piece k (of period m) end after b? (its successor starts at b or later)
        if k + 1 < g.n:
            if piece_start(g, k + 1, m) >= b:
                break
            k += 1
        elif g.period > 0.0:
            if piece_start(g, 0, m + 1.0) >= b:
                break
            k = 0
            m += 1.0
        else:
            break                        # the last piece holds everything after it
        count += 1
        if count > 4:
            return _table_span_far(g, b, k0[0], m0)
    return count


cdef inline int _table_span_far(const GaitData* g, double b, int k0, double m0) noexcept nogil:
    """``table_span``'s count for a b beyond the next few pieces: b located by binary
    search."""
    cdef double d1, m1
    cdef int k1, u, hint = g.hint
    k1 = table_locate(g, b, &d1, &m1)
    (<GaitData*>g).hint = hint      # the evaluations' piece (b lies far ahead of it)
    u = <int>((m1 - m0) * g.n) + k1 - k0
    if u > 0 and piece_start(g, k1, m1) >= b:
        u -= 1                      # b at the start of piece k1: that piece is not touched
    return u + 1


cdef inline double piece_rate(const double* r, double d) noexcept nogil:
    """l' [m/s] of a constant-jerk row r = (l0, v0, a0, jerk) at offset d [s] from its
    origin (``gait_eval`` and the tables of pieces: one expression)."""
    return r[1] + d * (r[2] + 0.5 * d * r[3])


cdef inline double piece_acc(const double* r, double d) noexcept nogil:
    """l'' [m/s^2] of a constant-jerk row r at offset d [s]."""
    return r[2] + d * r[3]


cdef inline void piece_ranges(const double* row, int nl, double d0, double d1,
                              double* rg) noexcept nogil:
    """l' (ends, vertex) and l'' (ends) between offsets d0 <= d1 of the constant-jerk piece
    whose rows (nl, 4) start at ``row``, merged into rg (4, nl)."""
    cdef int j
    cdef double x, dv
    cdef const double* r
    for j in range(nl):
        r = row + 4 * j
        for x in (piece_acc(r, d0), piece_acc(r, d1)):
            rg[2 * nl + j] = min(rg[2 * nl + j], x)
            rg[3 * nl + j] = max(rg[3 * nl + j], x)
        for x in (piece_rate(r, d0), piece_rate(r, d1)):
            rg[j] = min(rg[j], x)
            rg[nl + j] = max(rg[nl + j], x)
        if r[3] != 0.0:
            dv = -r[2] / r[3]
            if d0 < dv < d1:
                x = piece_rate(r, dv)
                rg[j] = min(rg[j], x)
                rg[nl + j] = max(rg[nl + j], x)


cdef inline int gait_bounds(GaitData* g, double a, double b, double* jerk,
                            double* snap) except -1:
    """Bounds of |l'''| and |l''''| per linkage on [a, b] (between breakpoints). Returns 1, or
    0 when l''' may jump inside (no snap bound: ``snap`` is then left undefined)."""
    cdef int j, k0, k1, nl = g.nl, nb, count
    cdef double u0, x
    cdef bint rest
    if g.kind == FOURIER:
        for j in range(nl):
            jerk[j] = g.bj[j]
            snap[j] = g.bs[j]
        return 1
    if g.kind == PROXY:
        # the bounds of the pieces' series; across a join the jerk may jump (no snap bound)
        return 1 if proxy_walk(g, a, b, jerk, snap, &rest) == 1 else 0
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
        # bins k0 .. k1 (range maxima: a few lookups)
        run_extreme(g.bj, nb, g.nlev, nl, k0, k1 - k0 + 1, True, nl, jerk)
        run_extreme(g.bs, nb, g.nlev, nl, k0, k1 - k0 + 1, True, nl, snap)
        return 1
    # TABLE: the pieces [a, b] touches; jerk constant on each, so snap 0 unless a join inside
    # changes it (range maxima of |jerk|, counts of such joins: no walk over the pieces)
    for j in range(nl):
        jerk[j] = 0.0
        snap[j] = 0.0
    count = table_span(g, a, b, &k0)
    if count > g.n:
        table_jerk(g, 0, g.n, jerk)
        return 0 if g.jj_before[g.n] > 0 else 1
    table_jerk(g, k0, count, jerk)
    # joins inside: the starts of the pieces after k0 (those after a), count - 1 of them
    return 0 if g.jj_before[k0 + count] - g.jj_before[k0 + 1] > 0 else 1


# ----------------------------------------------------------------------------- a run's table
# The engine's table of a run of constant-jerk pieces, built in place (``_gait.pyx``:
# ``table_of_run`` is these two on copies of its arrays; the plant's compiled step,
# ``core/plant/_batch.pyx``, has the actuator write the pieces into the block directly).
cdef CompiledGait run_table(Py_ssize_t n, Py_ssize_t nl)
cdef int run_table_fill(CompiledGait g) except -1
