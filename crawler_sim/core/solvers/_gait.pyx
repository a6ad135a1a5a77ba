# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""``CompiledGait``: a gait's compiled form (``_gait.pxd``) and its Python interface.

Built by each gait class's ``compiled()`` (``gaits``) through the constructors below; the
gaits' own ``__call__``, ``at``, ``breakpoints``, ``jerk_bound`` and ``snap_bound`` call the
methods here, so the solvers and Python see one arithmetic.
"""
import contextlib
import math
import threading
import weakref

import numpy as np

from libc.math cimport (acosh, ceil, cos, cosh, fabs, isfinite, nextafter, pow, sin, sinh,
                        INFINITY, M_PI, NAN)
from cpython.mem cimport PyMem_Malloc, PyMem_Free
from libc.string cimport memcpy, memset
from cpython.bytearray cimport PyByteArray_FromStringAndSize, PyByteArray_AS_STRING

__all__ = ['CompiledGait', 'fourier', 'scallop', 'table', 'proxy']


_NO_LOCK = contextlib.nullcontext()


cdef double* _dptr(object arr) except? NULL:
    """Address of the first entry of a C-contiguous float64 array (NULL when empty)."""
    cdef double[::1] mv = arr.reshape(-1)
    if mv.shape[0] == 0:
        return NULL
    return &mv[0]


cdef unsigned char* _bptr(object arr) except? NULL:
    cdef unsigned char[::1] mv = arr.reshape(-1).view(np.uint8)
    if mv.shape[0] == 0:
        return NULL
    return &mv[0]


def _f64(a, shape=None):
    out = np.ascontiguousarray(a, dtype=np.float64)
    return out if shape is None else out.reshape(shape)


cdef class CompiledGait:
    """The compiled form of one gait (see ``_gait.pxd``). Evaluation methods take times in
    seconds and return lengths [m], rates [m/s] and accelerations [m/s^2]."""

    def __cinit__(self):
        self.d.obj = <void*>self
        self._t_len = NAN
        self._t_rates = NAN
        self.span_lo = -INFINITY
        self.span_hi = INFINITY
        self.lock = _NO_LOCK

    @property
    def kind(self) -> int:
        return self.d.kind

    # ------------------------------------------------------------------ evaluation
    def values(self, t):
        """(l, l', l'') at the times ``t`` (shape (N,)): arrays of shape (N, n_links)."""
        cdef double[::1] tt = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
        cdef Py_ssize_t n = tt.shape[0], k
        cdef int nl = self.d.nl
        l = np.empty((n, nl))
        ld = np.empty((n, nl))
        ldd = np.empty((n, nl))
        cdef double[:, ::1] L = l, LD = ld, LDD = ldd
        cdef double[::1] ld3 = np.empty(max(nl, 1))
        if n == 0 or nl == 0:
            return l, ld, ldd
        for k in range(n):
            if self.d.kind == PROXY and not self._covers(tt[k]):
                self._fetch(tt[k], True)
                for j in range(nl):
                    L[k, j] = self._buf[0, j]
                    LD[k, j] = self._buf[1, j]
                    LDD[k, j] = self._buf[2, j]
                continue
            gait_eval(&self.d, tt[k], &L[k, 0], &LD[k, 0], &LDD[k, 0], &ld3[0])
        return l, ld, ldd

    def at(self, double t):
        """(l, l', l'') at one time, each of shape (n_links,)."""
        l, ld, ldd = self.values(np.array([t]))
        return l[0], ld[0], ldd[0]

    def at1(self, double t):
        """(l, l', l'') of linkage 0 at one time, as floats."""
        cdef double l[1]
        cdef double ld3[1]
        cdef double ld[1]
        cdef double ldd[1]
        if self.d.nl != 1:
            a, b, c = self.at(t)
            return float(a[0]), float(b[0]), float(c[0])
        if self.d.kind == PROXY and not self._covers(t):
            self._fetch(t, True)
            return self._buf[0, 0], self._buf[1, 0], self._buf[2, 0]
        gait_eval(&self.d, t, l, ld, ldd, ld3)
        return l[0], ld[0], ldd[0]

    def finite_at(self, double t) -> bool:
        """True when l, l' and l'' are finite at t [s]; for a gait of Python functions, also
        that they give n_links values there (False on any failure: the caller checks the
        values again and names what is wrong)."""
        cdef int nl = self.d.nl, j
        cdef double* w
        if self.d.kind == PROXY:
            try:
                self._fetch(t, True)
            except Exception:         # noqa: BLE001 (reported by the caller's own checks)
                return False
            for j in range(nl):
                if not (isfinite(self._buf[0, j]) and isfinite(self._buf[1, j])
                        and isfinite(self._buf[2, j])):
                    return False
            return True
        if nl == 0:
            return True
        w = <double*>PyMem_Malloc(4 * nl * sizeof(double))
        if w == NULL:
            raise MemoryError()
        try:
            gait_eval(&self.d, t, w, w + nl, w + 2 * nl, w + 3 * nl)
            for j in range(3 * nl):
                if not isfinite(w[j]):
                    return False
            return True
        finally:
            PyMem_Free(w)

    def jerk(self, double t):
        """l''' at t [m/s^3]."""
        out = np.empty((4, max(self.d.nl, 1)))
        cdef double[:, ::1] o = out
        gait_rates(&self.d, t, &o[0, 0], &o[1, 0], &o[2, 0])
        return out[2, :self.d.nl].copy()

    def next_break(self, double t) -> float:
        """The first time after t [s] where l'' may jump (inf when none)."""
        return gait_next_break(&self.d, t)

    def breakpoints(self, double t0, double t1):
        """Sorted times in the open interval (t0, t1) where l'' may jump."""
        out = []
        cdef double b = t0
        while True:
            b = gait_next_break(&self.d, b)
            if not b < t1:
                break
            out.append(b)
        return np.array(out, dtype=np.float64)

    def is_constant(self, double t0, double t1) -> bool:
        return bool(gait_is_constant(&self.d, t0, t1))

    def bounds(self, double t0, double t1):
        """(jerk, snap) bounds per linkage on [t0, t1] [m/s^3, m/s^4]; snap is None where
        l''' may jump inside."""
        jerk = np.zeros(max(self.d.nl, 1))
        snap = np.zeros(max(self.d.nl, 1))
        cdef double[::1] j = jerk, s = snap
        ok = gait_bounds(&self.d, t0, t1, &j[0], &s[0])
        return jerk[:self.d.nl], (snap[:self.d.nl] if ok else None)

    # ------------------------------------------------------------------ the user's functions
    cdef int _fetch(self, double t, bint with_length) except -1:
        """The Python gait's l' and l'' (and l when asked) at t into ``_buf`` rows."""
        cdef int j, nl = self.d.nl
        if t == self._t_rates and (not with_length or t == self._t_len):
            return 0
        if self._fns is None:
            l, ld, ldd = self._gait().at(t)
            for j, v in enumerate(_row(l, nl)):
                self._buf[0, j] = v
            for j, v in enumerate(_row(ld, nl)):
                self._buf[1, j] = v
            for j, v in enumerate(_row(ldd, nl)):
                self._buf[2, j] = v
            self._t_len = t
        else:
            fl, fv, fa = self._fns
            if self._scalar:
                self._buf[1, 0] = fv(t)
                self._buf[2, 0] = fa(t)
                if with_length:
                    self._buf[0, 0] = fl(t)
            else:
                for j, v in enumerate(_row(fv(t), nl)):
                    self._buf[1, j] = v
                for j, v in enumerate(_row(fa(t), nl)):
                    self._buf[2, j] = v
                if with_length:
                    for j, v in enumerate(_row(fl(t), nl)):
                        self._buf[0, j] = v
            if with_length:
                self._t_len = t
        self._t_rates = t
        return 0

    cdef int cb_lengths(self, double t, double* l) except -1:
        cdef int j
        self._fetch(t, True)
        for j in range(self.d.nl):
            l[j] = self._buf[0, j]
        return 0

    cdef int cb_rates(self, double t, double* ld, double* ldd, double* ld3) except -1:
        """l' and l'' from the user's functions (a PROXY gait outside its pieces and outside
        any solve, where no search runs); l''' 0."""
        cdef int j, nl = self.d.nl
        self._fetch(t, False)
        for j in range(nl):
            ld[j] = self._buf[1, j]
            ldd[j] = self._buf[2, j]
            ld3[j] = 0.0
        return 0

    # ------------------------------------------------------------------ PROXY kind
    cdef bint _covers(self, double t) noexcept:
        """The table holds t: Python reads the pieces the solvers used there; elsewhere the
        user's functions (nothing is built outside a solve)."""
        return self.d.period > 0.0 or (self.d.n > 0 and self.d.knots[0] <= t
                                       and t <= self.d.knots[self.d.n])
    cdef int px_ensure(self, double t) except -1:
        """The table built up to t (inside the span being integrated), then read."""
        self.table.ensure(t, self.span_lo, self.span_hi)
        return self.px_sync()

    cdef int px_sync(self) except -1:
        """Point the struct at the table's arrays (kept alive here)."""
        tb = self.table
        knots, coef, ncoef, bj, bs = tb.knots, tb.coef, tb.ncoef, tb.bj, tb.bs
        rest = np.ascontiguousarray(tb.rest, dtype=np.uint8)
        self._keep = (knots, coef, ncoef, bj, bs, rest)
        cdef int[::1] nc = ncoef
        self.d.n = <int>ncoef.shape[0]
        self.d.knots = _dptr(knots)
        self.d.coef = _dptr(coef)
        self.d.ncoef = &nc[0] if self.d.n else NULL
        self.d.bj = _dptr(bj)
        self.d.bs = _dptr(bs)
        self.d.rest = _bptr(rest)
        if coef.shape[3] > 64:     # ``proxy_piece`` keeps T_q(u) for q < 64
            raise ValueError(f'proxy series of {coef.shape[3]} coefficients (at most 64)')
        self.d.stride = coef.shape[3]
        self.d.period = float(tb.period) if tb.periodic else 0.0
        self.d.hint = 0
        return 0


def _row(v, int nl):
    """A user value as a tuple of nl floats."""
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != nl:
        raise ValueError(f'gait values must have {nl} entries (one per linkage), got {a.size}')
    return a.tolist()


# ---------------------------------------------------------------------- constructors
def fourier(double freq, mean, cos_c, sin_c) -> CompiledGait:
    """l_j = mean_j + sum_k cos_c[j, k] cos((k + 1) th) + sin_c[j, k] sin((k + 1) th),
    th = 2 pi (freq t mod 1). ``mean`` (nl,) [m], coefficients (nl, K) [m], freq [Hz]."""
    cdef CompiledGait g = CompiledGait()
    mean = _f64(mean)
    a = _f64(cos_c)
    b = _f64(sin_c)
    nl, nk = a.shape
    wk = 2.0 * math.pi * freq * np.arange(1, nk + 1, dtype=float)
    amp = np.abs(a) + np.abs(b)
    bj = _f64(amp @ wk ** 3)
    bs = _f64(amp @ wk ** 4)
    g._keep = (mean, a, b, bj, bs)
    g.d.kind = FOURIER
    g.d.nl = nl
    g.d.nk = nk
    g.d.freq = freq
    g.d.mean = _dptr(mean)
    g.d.p1 = _dptr(a)
    g.d.p2 = _dptr(b)
    g.d.bj = _dptr(bj)
    g.d.bs = _dptr(bs)
    g.d.constant = not (np.any(a) or np.any(b))
    g.n_links = nl
    g.period = 1.0 / freq
    return g



# n! (n <= 6) and C(n, k) (n, k <= 4, at 5 n + k) for ``scallop_bins``
cdef double _FACT[7]
cdef double _COMB[25]
for _n in range(7):
    _FACT[_n] = math.factorial(_n)
for _n in range(5):
    for _k in range(_n + 1):
        _COMB[5 * _n + _k] = math.comb(_n, _k)


def scallop_bins(double c, double s, double w, amp, phase, double pa, t0, t1, int group,
                 int n_radii):
    """A Scallop's bounds of |l'''| [m/s^3] and |l''''| [m/s^4] on each bin [t0, t1] (arrays
    (B,)), per linkage: two arrays (B, nl) (``Scallop._bounds`` documents the method; l =
    mean + amp f(x), f = s sin x / (1 - c cos x), x = w t + phase - pa, c = cos(pi r), s =
    sin(pi r), pa = pi r). Each is the smaller of Cauchy's estimate, per group of ``group``
    bins, the best of ``n_radii`` radii evenly from 0.05 to 0.95 of the poles' distance and 5
    beyond it, and the derivative's values at the bin's ends (Leibniz on
    f D = s sin x, with a bound of their rounding) plus the chord's error, h^2 / 8 times
    Cauchy's bound two orders higher. Loops, not array calls: a new gait's tables were most
    of a sweep scene's and an optimiser candidate's set-up (0.6 ms in numpy)."""
    cdef const double[::1] A = _f64(amp), P = _f64(phase), T0 = _f64(t0), T1 = _f64(t1)
    cdef Py_ssize_t nb = T0.shape[0], nl = A.shape[0], ng = (nb + group - 1) // group
    cdef Py_ssize_t g, i, j, k, n, o, q, nr = n_radii + 5
    cdef double rho0, x0, span, lo, width, m, sh, den, r, x, cx, sx, D, acc, mag, prop, term
    cdef double cb, h2, ends, chord, a3, step
    cdef double best[4]
    cdef double f[5]
    cdef double err[5]
    cdef double Dm[5]
    cdef double sn[4]
    cdef double cs[4]
    cdef double EPS_ = 2.220446049250313e-16
    cauchy = np.empty((4, ng, nl))
    cdef double[:, :, ::1] C = cauchy
    top_arr = np.empty((2, nb + 1, nl))
    cdef double[:, :, ::1] top = top_arr
    jerk_arr = np.empty((nb, nl))
    snap_arr = np.empty((nb, nl))
    cdef double[:, ::1] J = jerk_arr
    cdef double[:, ::1] S = snap_arr
    # Cauchy's estimates of orders 3 .. 6, per group of bins; what depends on the radius
    # alone once per radius (n! s cosh rho, rho^n, sinh^2 of the poles' distance less rho)
    rho0 = acosh(1.0 / fabs(c)) if fabs(c) >= 1e-12 else 0.0
    radii = np.empty(nr)
    cdef double[::1] R = radii
    step = (0.95 - 0.05) / (n_radii - 1)          # as numpy.linspace(0.05, 0.95, n_radii)
    for q in range(n_radii):
        R[q] = rho0 * (0.95 if q == n_radii - 1 else q * step + 0.05)
    for q in range(5):
        R[n_radii + q] = (0.25, 0.5, 1.0, 2.0, 3.0)[q]
    per_r = np.empty((nr, 9))
    cdef double[:, ::1] PR = per_r
    for q in range(nr):
        r = R[q]
        sh = sinh(max(rho0 - r, 0.0) / 2.0)
        PR[q, 0] = sh * sh
        for o in range(4):
            PR[q, 1 + o] = _FACT[3 + o] * s * cosh(r)
            PR[q, 5 + o] = pow(r, 3.0 + o)
    for g in range(ng):
        lo = T0[g * group]
        r = T1[min(g * group + group - 1, nb - 1)]
        span = w * (r - lo)
        for j in range(nl):
            if fabs(c) < 1e-12:           # r = 1/2: a plain cosine stroke
                for o in range(4):
                    C[o, g, j] = fabs(A[j]) * pow(w, 3.0 + o) * (1.0 + 1e-12)
                continue
            x0 = w * lo + P[j] - pa + (M_PI if c < 0.0 else 0.0)
            for o in range(4):
                best[o] = INFINITY
            for q in range(nr):
                r = R[q]
                x = 0.5 * (x0 - r)                    # Re(z') / 2 over [x, x + width]
                width = 0.5 * (span + 2.0 * r)
                if ceil(x / M_PI) * M_PI <= x + width:
                    m = 0.0
                else:
                    cx = sin(x)
                    sx = sin(x + width)
                    m = min(cx * cx, sx * sx)
                den = 2.0 * fabs(c) * (m + PR[q, 0])
                if den > 0.0:
                    for o in range(4):
                        best[o] = min(best[o], PR[q, 1 + o] / den / PR[q, 5 + o])
            for o in range(4):
                C[o, g, j] = fabs(A[j]) * pow(w, 3.0 + o) * best[o] * (1.0 + 1e-12)
    # f''' and f'''' at the bins' ends, with their rounding
    for i in range(nb + 1):
        for j in range(nl):
            x = w * (T0[i] if i < nb else T1[nb - 1]) + P[j] - pa
            cx = cos(x)
            sx = sin(x)
            sn[0] = sx
            sn[1] = cx
            sn[2] = -sx
            sn[3] = -cx
            cs[0] = cx
            cs[1] = -sx
            cs[2] = -cx
            cs[3] = sx
            D = 1.0 - c * cx
            Dm[0] = D
            for k in range(1, 5):
                Dm[k] = -c * cs[k % 4]
            for n in range(5):
                acc = s * sn[n % 4]
                mag = fabs(acc) + fabs(s)
                prop = 0.0
                for k in range(n):
                    cb = _COMB[5 * n + k]
                    term = cb * f[k] * Dm[n - k]
                    acc = acc - term
                    mag = mag + fabs(term)
                    prop = prop + cb * err[k] * fabs(Dm[n - k])
                f[n] = acc / D
                err[n] = (8.0 * EPS_ * mag + prop) / fabs(D)
            top[0, i, j] = fabs(f[3]) + err[3]
            top[1, i, j] = fabs(f[4]) + err[4]
    for i in range(nb):
        g = i // group
        h2 = (w * (T1[i] - T0[i])) ** 2 / 8.0
        for j in range(nl):
            a3 = fabs(A[j])
            ends = max(top[0, i, j], top[0, i + 1, j]) * a3 * pow(w, 3.0)
            chord = (ends + h2 * C[2, g, j] / pow(w, 2.0)) * (1.0 + 1e-12)
            J[i, j] = min(C[0, g, j], chord)
            ends = max(top[1, i, j], top[1, i + 1, j]) * a3 * pow(w, 4.0)
            chord = (ends + h2 * C[3, g, j] / pow(w, 2.0)) * (1.0 + 1e-12)
            S[i, j] = min(C[1, g, j], chord)
    return jerk_arr, snap_arr


def scallop(double freq, mean, rows, bins_jerk, bins_snap) -> CompiledGait:
    """The Scallop stroke: ``rows`` (nl, 4) = amplitude [m], phase - pi r [rad], cos(pi r),
    sin(pi r); derivative bounds per bin, ``bins_*`` (nb, nl) (nb bins per period). Kept with
    the cosine and sine of each row's phase, so an evaluation takes one cosine and one sine
    for all linkages (angle addition), not one pair per linkage."""
    cdef CompiledGait g = CompiledGait()
    mean = _f64(mean)
    rows = np.asarray(rows, dtype=float)
    rows = _f64(np.column_stack([rows, np.cos(rows[:, 1]), np.sin(rows[:, 1])]))
    bj = _range_levels(np.asarray(bins_jerk, dtype=float), 1.0)
    bs = _range_levels(np.asarray(bins_snap, dtype=float), 1.0)
    bj_all = _f64(bj[0].max(axis=0))
    bs_all = _f64(bs[0].max(axis=0))
    g._keep = (mean, rows, bj, bs, bj_all, bs_all)
    g.d.kind = SCALLOP
    g.d.nl = rows.shape[0]
    g.d.freq = freq
    g.d.mean = _dptr(mean)
    g.d.p1 = _dptr(rows)
    g.d.nb = bj.shape[1]
    g.d.nlev = bj.shape[0]
    g.d.bj = _dptr(bj)
    g.d.bs = _dptr(bs)
    g.d.bj_all = _dptr(bj_all)
    g.d.bs_all = _dptr(bs_all)
    g.d.constant = not np.any(rows[:, 0])
    g.n_links = g.d.nl
    g.period = 1.0 / freq
    return g


def _table_stats(coef, d0, d1):
    """Per piece and linkage over its whole extent (offsets d0 .. d1 from its origin):
    |jerk|, the smallest and largest l' (ends and vertex) and l'' (ends) (``piece_ranges``),
    shape (n, 5, nl); a piece without an end (the last of a table that is not periodic) or a
    start (a first one from -inf) has unbounded ranges. Then ``_aligned_levels``: the extremes
    over aligned blocks of 2^q pieces, so a run of pieces is a few lookups."""
    cdef const double[:, :, ::1] c = coef
    cdef const double[::1] lo = _f64(d0), hi = _f64(d1)
    cdef Py_ssize_t n = c.shape[0], nl = c.shape[1], k, j
    st_arr = np.empty((n, 5, nl))
    cdef double[:, :, ::1] st = st_arr
    cdef double[::1] rg = np.empty(4 * nl)
    cdef bint bounded
    for k in range(n):
        bounded = isfinite(lo[k]) and isfinite(hi[k])
        for j in range(nl):
            st[k, 0, j] = fabs(c[k, j, 3])
            rg[j] = INFINITY if bounded else -INFINITY
            rg[nl + j] = -rg[j]
            rg[2 * nl + j] = rg[j]
            rg[3 * nl + j] = -rg[j]
        if bounded:
            piece_ranges(&c[k, 0, 0], <int>nl, lo[k], hi[k], &rg[0])
        for j in range(4 * nl):
            st[k, 1 + j // nl, j % nl] = rg[j]
    return _aligned_levels(st_arr, np.array([1.0, -1.0, 1.0, -1.0, 1.0])[:, None])


def _counts_before(flags):
    """(2 n + 1,) how many of ``flags`` (n,), repeated twice, come before each index."""
    cdef const unsigned char[::1] f = np.ascontiguousarray(flags, dtype=np.uint8)
    cdef Py_ssize_t n = f.shape[0], i
    out = np.empty(2 * n + 1, dtype=np.intc)
    cdef int[::1] o = out
    o[0] = 0
    for i in range(2 * n):
        o[i + 1] = o[i] + f[i % n]
    return out


def _n_levels(Py_ssize_t n):
    """Levels of range extremes over n items: runs of up to 2^RANGE_LEVELS, and not past n."""
    cdef Py_ssize_t L = 1
    while L <= RANGE_LEVELS and (1 << L) <= n:
        L += 1
    return L


cdef void _fill_levels(double* o, const int* off, Py_ssize_t L, Py_ssize_t n, Py_ssize_t w,
                       const double* sg, Py_ssize_t nl) noexcept nogil:
    """Levels 1..L-1 of ``_aligned_levels`` in the records ``o`` (rows of w doubles, level 0
    already in rows 0..n-1, level q from row off[q]): the largest of each pair of the level
    below where column c's sign is +1, the smallest where -1; the sign is sg[c], or with
    sg = NULL +1 on even and -1 on odd blocks of nl columns (a table's rows: ``table_of_run``)."""
    cdef Py_ssize_t q, i, c, lo, hi, cnt, prev = n
    cdef double x, y
    cdef bint mx
    for q in range(1, L):
        cnt = (prev + 1) // 2
        for i in range(cnt):
            lo = off[q - 1] + 2 * i
            hi = lo + 1 if 2 * i + 1 < prev else lo
            for c in range(w):
                x = o[lo * w + c]
                y = o[hi * w + c]
                mx = sg[c] > 0.0 if sg != NULL else ((c // nl) % 2) == 0
                o[(off[q] + i) * w + c] = (x if x >= y else y) if mx else (x if x <= y else y)
        prev = cnt


def _aligned_levels(st, sign):
    """Items (n, ...) -> (records (R, ...), level offsets (L,)): level q, from record
    offsets[q] on, holds the extremes of the items i 2^q .. (i + 1) 2^q - 1 (the last block
    clipped at n), the largest where ``sign`` (broadcast over an item) is +1, the smallest
    where -1; about 2 n records in all (a table's pieces: ``table_run``, ``table_jerk``; the
    overlapping levels of ``_range_levels`` take n records per level, 3.5 times the memory,
    which a long table's walk reads from out of the caches)."""
    st = _f64(st)
    cdef Py_ssize_t n = st.shape[0], w = st.size // max(n, 1), q, cnt
    cdef Py_ssize_t L = _n_levels(n)
    offsets = np.zeros(L, dtype=np.intc)
    cnt = n
    for q in range(1, L):
        offsets[q] = offsets[q - 1] + cnt
        cnt = (cnt + 1) // 2
    out_arr = np.empty((int(offsets[L - 1]) + cnt,) + st.shape[1:])
    flat = out_arr.reshape(out_arr.shape[0], w)
    flat[:n] = st.reshape(n, w)
    cdef double[:, ::1] o = flat
    cdef const int[::1] off = offsets
    cdef const double[::1] sg = _f64(np.broadcast_to(sign, st.shape[1:]).reshape(-1))
    if w and n:
        _fill_levels(&o[0, 0], &off[0], L, n, w, &sg[0], 0)
    return out_arr, offsets


def _range_levels(st, sign):
    """Items (n, ...) of one period -> (levels, n, ...): level q holds the extreme of the 2^q
    items from each on (wrapping around), the largest where ``sign`` (broadcast over an item)
    is +1, the smallest where -1. So the extreme over any run of items is two lookups
    (``run_extreme``): a Scallop's bins of bounds (built with every such gait: loops, not
    array calls, for small tables)."""
    st = _f64(st)
    cdef Py_ssize_t n = st.shape[0], w = st.size // max(n, 1), q, k, k2, c, sh
    cdef Py_ssize_t L = _n_levels(n)
    out_arr = np.empty((L,) + st.shape)
    cdef double[:, :, ::1] o = out_arr.reshape(L, n, w)
    cdef const double[::1] sg = _f64(np.broadcast_to(sign, st.shape[1:]).reshape(-1))
    cdef const double[:, ::1] s0 = st.reshape(n, w)
    cdef double x, y
    o[0, :, :] = s0
    for q in range(1, L):
        sh = 1 << (q - 1)
        for k in range(n):
            k2 = k + sh
            if k2 >= n:
                k2 -= n
            for c in range(w):
                x = o[q - 1, k, c]
                y = o[q - 1, k2, c]
                o[q, k, c] = (x if x >= y else y) if sg[c] > 0.0 else (x if x <= y else y)
    return out_arr


def table(coef, *, starts=None, anchors=None, knots=None, period=None,
          jumps=None) -> CompiledGait:
    """Constant-jerk pieces: ``coef`` (n, nl, 4) = (l0 [m], v0 [m/s], a0 [m/s^2], jerk
    [m/s^3]) of each piece and linkage from the piece's time origin.

    Not periodic: piece k holds from ``starts[k]`` [s] (starts[0] may be -inf; before it the
    first piece continues) with origin ``anchors[k]``. Periodic: ``knots`` (n + 1,) of one
    period, piece k from knots[k] + m T, origin the same. ``jumps`` (n,) bool: l'' jumps at the
    start of piece k (by default, where the previous piece's l'' at the join differs from a0).
    """
    cdef CompiledGait g = CompiledGait()
    coef = _f64(coef)
    n, nl, _ = coef.shape
    periodic = period is not None
    if periodic:
        knots = _f64(knots)
        origins = knots[:knots.size - 1]
        starts_ = origins
    else:
        starts_ = _f64(starts)
        origins = _f64(anchors)
    if jumps is None:
        # l'' of piece k - 1 at the start of piece k (its own expression a0 + d j) against a0
        prev = np.roll(coef, 1, axis=0)
        d = starts_ - np.roll(origins, 1)
        d[0] = knots[knots.size - 1] - origins[origins.size - 1] if periodic else 0.0
        end_acc = prev[:, :, 2] + d[:, None] * prev[:, :, 3]
        # a join is a jump only beyond the rounding of that expression and of d (a difference
        # of two times of size |start|): pieces meant to join C2 (the actuator's, a spline's,
        # ``cubic_values`` continued) differ there by a few ulps, and a breakpoint at every
        # join ended a segment at each (15 times the segments of the events on 5 ms pieces)
        eps = np.finfo(float).eps
        size = np.abs(starts_) + np.abs(np.roll(origins, 1))
        size[~np.isfinite(size)] = 0.0         # a first piece from -inf: no join there
        noise = 4.0 * eps * (np.abs(prev[:, :, 2]) + np.abs(d[:, None] * prev[:, :, 3])
                             + size[:, None] * np.abs(prev[:, :, 3]))
        jumps = np.any(np.abs(end_acc - coef[:, :, 2]) > noise, axis=1)
        if not periodic:
            jumps[0] = False
    jumps = np.ascontiguousarray(jumps, dtype=bool)
    jj = np.any(coef[:, :, 3] != np.roll(coef[:, :, 3], 1, axis=0), axis=1)
    if not periodic:
        jj[0] = False
    jj = np.ascontiguousarray(jj)
    rest = np.ascontiguousarray(np.all(coef[:, :, 1:] == 0.0, axis=(1, 2)))
    jump_times = _f64(starts_[jumps])
    ends = knots[1:] if periodic else np.append(starts_[1:], np.inf)
    stat, lev_off = _table_stats(coef, starts_ - origins, ends - origins)
    jj_before = _counts_before(jj)
    g._keep = (coef, knots if periodic else starts_, origins, jumps, jj, rest, jump_times,
               stat, jj_before)
    g.d.kind = TABLE
    g.d.nl = nl
    g.d.n = n
    g.d.coef = _dptr(coef)
    g.d.jump = _bptr(jumps)
    g.d.jjump = _bptr(jj)
    g.d.rest = _bptr(rest)
    g.d.n_jumps = jump_times.size
    g.d.jump_times = _dptr(jump_times)
    g.d.stat = _dptr(stat)
    g.d.nlev = lev_off.size
    for q in range(lev_off.size):
        g.d.lev_off[q] = lev_off[q]
    cdef int[::1] jb = jj_before
    g.d.jj_before = &jb[0]
    if periodic:
        g.d.period = float(period)
        g.d.knots = _dptr(knots)
    else:
        g.d.period = 0.0
        g.d.starts = _dptr(starts_)
        g.d.anchors = _dptr(origins)
    g.d.constant = bool(np.all(rest))
    g.n_links = nl
    g.period = float(period) if periodic else None
    return g


cdef CompiledGait _python_gait(int kind, gait, int n_links, fns):
    """The part of the PROXY kind that reads the user's functions (``_fetch``):
    the gait, its callables, the buffer of their values, one solver at a time."""
    cdef CompiledGait g = CompiledGait()
    g.d.kind = kind
    g.d.nl = n_links
    g.d.constant = False
    g.n_links = n_links
    g.period = gait.period
    g._gait = weakref.ref(gait)     # (the gait owns this form: no cycle, see Gait._compile)
    g._fns = fns
    g.lock = threading.Lock()
    g._buf = np.zeros((4, max(n_links, 1)))
    g._scalar = False
    if fns is not None and n_links == 1:
        try:
            g._scalar = all(isinstance(f(0.0), (float, int)) for f in fns)
        except Exception:       # not defined at 0: the general conversion
            g._scalar = False
    return g


def proxy(gait, int n_links, table, fns=None) -> CompiledGait:
    """A Python gait, evaluated in the solvers from the Chebyshev pieces of
    ``table`` (``proxy.ChebTable``, built as they reach new times); from Python (``values``,
    ``at``), the user's functions ``fns`` = (l, l', l'') (else ``gait.at``)."""
    cdef CompiledGait g = _python_gait(PROXY, gait, n_links, fns)
    g.table = table
    g.span_lo = INFINITY          # no solve yet: outside the pieces, the user's functions
    g.span_hi = -INFINITY
    g.px_sync()
    return g


# ---------------------------------------------------------------------- PROXY tables
# The arithmetic of ``proxy.ChebTable`` (its module doc): Chebyshev series of sampled pieces.

def cheb_fit(const double[:, :, ::1] f, const double[:, ::1] dct, const double[::1] a,
             const double[::1] b, const double[::1] scale):
    """Series of l'' on each piece from its values at the N + 1 nodes (``f`` (K, N + 1, nl),
    node 0 at the piece's end b); the coefficients below the rounding of the values (64 eps
    of their scale, the piece's or ``scale``, plus eps |t| times the series' own l''' bound)
    set to zero. Returns (c (K, N + 1, nl), last (K,) index of the last kept coefficient,
    tail (K,): the largest of the last three coefficients over the piece's largest value,
    tol (K, nl): that rounding [m/s^2])."""
    cdef Py_ssize_t K = f.shape[0], n1 = f.shape[1], nl = f.shape[2], k, i, q, j
    c_arr = np.zeros((K, n1, nl))
    last_arr = np.full(K, -1, dtype=np.intp)
    tail_arr = np.zeros(K)
    tol_arr = np.zeros((K, nl))
    cdef double[:, ::1] tols = tol_arr
    cdef double[:, :, ::1] c = c_arr
    cdef Py_ssize_t[::1] last = last_arr
    cdef double[::1] tail = tail_arr
    cdef double s, vs, local, jb, tol, w, tm, eps = 2.220446049250313e-16
    cdef double col[64]          # one linkage's values at the nodes, contiguous
    if n1 > 64:
        raise ValueError(f'cheb_fit: at most 64 nodes, got {n1}')
    for k in range(K):
        w = b[k] - a[k]
        tm = max(fabs(a[k]), fabs(b[k]))
        for j in range(nl):
            local = 0.0
            for i in range(n1):
                local = max(local, fabs(f[k, i, j]))
            vs = max(scale[j], local)
            jb = 0.0
            for i in range(n1):
                col[i] = f[k, i, j]
            for q in range(n1):
                # ``cheb_dot``'s partial sums: short dependency chains (one chain of n1 adds
                # was most of a window's fit)
                s = cheb_dot(&dct[q, 0], col, <int>n1)
                c[k, q, j] = s
                jb += <double>(q * q) * fabs(s)
            jb = jb * 2.0 / w if w > 0.0 else 0.0
            if not isfinite(jb):
                jb = 0.0
            tol = 64.0 * eps * vs + eps * tm * jb + 1e-300
            tols[k, j] = tol
            for q in range(max(n1 - 3, 0), n1):
                # over the piece's own values: the noise of the user's arithmetic is a share
                # of what it computes there (a share of the largest value seen is too coarse
                # where the gait is slow)
                tail[k] = max(tail[k], fabs(c[k, q, j]) / (local + 1e-300))
            for q in range(n1 - 1, -1, -1):
                if fabs(c[k, q, j]) > tol:
                    if q > last[k]:
                        last[k] = q
                    break
        for q in range(last[k] + 1, n1):
            for j in range(nl):
                c[k, q, j] = 0.0
    return c_arr, last_arr, tail_arr, tol_arr


def cheb_series(const double[:, :, ::1] acc, const double[::1] a, const double[::1] b,
                const double[:, :, ::1] states, int width, const double[::1] quiet,
                double h, const double[:, ::1] grid):
    """The four series of each piece from its l'' series ``acc`` (K, N + 1, nl) and the
    user's (l, l') at its start, ``states`` (K + 1, 2, nl) (the last row: the end of the last
    piece): l' and l by integration from u = -1, l''' and l'''' by differentiation, in time
    units (d/dt = (2 / w) d/du).

    Returns (coef (K, nl, 4, width), ncoef (K,), bj, bs (K, nl) = bounds of |l'''| and
    |l''''| on each piece (``_sampled_bound`` at the points of ``grid`` (M, width): T_q at M
    evenly spaced u from -1 to 1), rest (K,), ends (K, 2, nl) = l and l'
    of the series at each piece's end, mismatch: None, or (k, d, j) of the first end where
    the series' l (d = 0) or l' (d = 1) misses the user's (``states[k + 1]``) by more than
    1e-6 of the scales and the rounding of the user's arithmetic (64 eps of ``quiet`` [m/s^2]
    times h^2, h for l': ``quiet`` moves l by its own size over the window's length h))."""
    cdef Py_ssize_t K = acc.shape[0], n1 = acc.shape[1], nl = acc.shape[2], k, j, q, d, nc
    coef_arr = np.zeros((K, nl, 4, width))
    ncoef_arr = np.ones(K, dtype=np.intc)
    bj_arr = np.zeros((K, nl))
    bs_arr = np.zeros((K, nl))
    rest_arr = np.ones(K, dtype=bool)
    ends_arr = np.zeros((K, 2, nl))
    cdef double[:, :, :, ::1] coef = coef_arr
    cdef int[::1] ncoef = ncoef_arr
    cdef double[:, ::1] bj = bj_arr, bs = bs_arr
    cdef unsigned char[::1] rest = rest_arr.view(np.uint8)
    cdef double[:, :, ::1] ends = ends_arr
    cdef double half, inv, v, sgn, s, amax, w, tol, eps = 2.220446049250313e-16
    cdef Py_ssize_t bad[3]
    cdef double* c
    cdef double* snap = <double*>PyMem_Malloc(3 * width * sizeof(double))
    cdef double* d5 = snap + width         # l^(5), l^(6): the bounds' second derivatives
    cdef double* d6 = snap + 2 * width
    cdef double gap = 2.0 / (grid.shape[0] - 1), h2
    if snap == NULL:
        raise MemoryError()
    bad[0] = -1
    try:
        for k in range(K):
            half = 0.5 * (b[k] - a[k])
            # d/dt = (1 / half) d/du, at most the largest float: a piece of a few floats near
            # 0 (a first step of 1e-310 s) has 1 / half = inf, and inf times the zero series
            # the fit leaves there (``cheb_fit``: nothing above the rounding) made NaN
            inv = min(1.0 / half, 1.7976931348623157e308) if half > 0.0 else 0.0
            h2 = gap * gap / 8.0 * half * half      # d^2/du^2 = half^2 d^2/dt^2
            for j in range(nl):
                c = &coef[k, j, 0, 0]
                # series 2: l''
                for q in range(n1):
                    c[2 * width + q] = acc[k, q, j]
                # series 1 = integral of series 2, series 0 = integral of series 1
                for d in range(2, 0, -1):
                    _cheb_integrate(c + d * width, c + (d - 1) * width, width, half,
                                    states[k, d - 1, j])
                # series 3: l''' (derivative of series 2); l'''' only as a bound
                _cheb_derive(c + 2 * width, c + 3 * width, width, inv)
                _cheb_derive(c + 3 * width, snap, width, inv)
                _cheb_derive(snap, d5, width, inv)
                _cheb_derive(d5, d6, width, inv)
                # (over the whole width: the bounds steer the exact method's event search,
                # so a tighter bound here moves its rounding and a Custom run's results)
                bj[k, j] = _sampled_bound(c + 3 * width, d5, width, grid, h2)
                bs[k, j] = _sampled_bound(snap, d6, width, grid, h2)
                amax = 0.0
                for q in range(n1):
                    amax += fabs(acc[k, q, j])
                for d in range(1, -1, -1):              # l' first: l follows from it
                    v = 0.0
                    for q in range(width):
                        v += c[d * width + q]          # T_q(1) = 1
                    ends[k, d, j] = v
                    # against the user's value there: within 1e-6 of the scales, or the
                    # rounding of the user's arithmetic (64 eps of l, of l / h for l')
                    w = 2.0 * half
                    if d == 1:
                        tol = (1e-6 * (fabs(states[k + 1, 1, j]) + w * amax)
                               + 64.0 * eps * h * quiet[j])
                    else:
                        tol = (1e-6 * (fabs(states[k + 1, 0, j]) + w * fabs(states[k + 1, 1, j])
                                       + w * w * amax) + 64.0 * eps * h * h * quiet[j] + 1e-300)
                    if bad[0] < 0 and not fabs(v - states[k + 1, d, j]) <= tol:
                        bad[0] = k
                        bad[1] = d
                        bad[2] = j
                for d in range(4):
                    for q in range(width - 1, -1, -1):
                        if c[d * width + q] != 0.0:
                            if q + 1 > ncoef[k]:
                                ncoef[k] = <int>(q + 1)
                            if d == 1 or d == 2:
                                rest[k] = 0
                            break
    finally:
        PyMem_Free(snap)
    mismatch = None if bad[0] < 0 else (bad[0], bad[1], bad[2])
    return coef_arr, ncoef_arr, bj_arr, bs_arr, rest_arr, ends_arr, mismatch


cdef void _cheb_integrate(const double* c, double* out, Py_ssize_t n, double scale,
                          double start) noexcept:
    """out = start + scale * (integral of the series c from u = -1), both of length n (the
    integral's top term dropped: c's last two are zero here)."""
    cdef Py_ssize_t q
    cdef double v = 0.0, sgn = -1.0
    for q in range(n):
        out[q] = 0.0
    if n > 1:
        out[1] = c[0] - (0.5 * c[2] if n > 2 else 0.0)
    for q in range(2, n):
        out[q] = (c[q - 1] - (c[q + 1] if q + 1 < n else 0.0)) / (2.0 * q)
    for q in range(1, n):
        v += sgn * out[q]                # value at u = -1: T_q(-1) = (-1)^q
        sgn = -sgn
    out[0] = -v
    for q in range(n):
        out[q] *= scale
    out[0] += start


cdef inline Py_ssize_t _nonzero_length(const double* c, Py_ssize_t n) noexcept:
    """The length of the series c of length n without its zero top coefficients."""
    while n > 0 and c[n - 1] == 0.0:
        n -= 1
    return n


cdef double _sampled_bound(const double* c, const double* c2, Py_ssize_t n,
                           const double[:, ::1] grid, double h2) noexcept:
    """A bound of |series c| on [-1, 1]: its largest magnitude at the points of ``grid``
    ((M, n): T_q at M evenly spaced points) plus the error of the line through neighbouring
    points, h2 max |c''| (h2 = h^2 / 8 times the scale that turns ``c2``, the series of the
    second derivative in its own units, into d^2/du^2; max |c2| is at most the sum of its
    |coefficients|, |T_q| <= 1), plus the rounding of the values (4 n eps of the sum of c's
    |coefficients|). Never above that sum, itself a bound."""
    cdef Py_ssize_t i, q, M = grid.shape[0]
    cdef double s = 0.0, s2 = 0.0, top = 0.0
    for q in range(n):
        s += fabs(c[q])
        s2 += fabs(c2[q])
    for i in range(M):
        top = max(top, fabs(cheb_dot(c, &grid[i, 0], <int>n)))
    return min(s, top + h2 * s2 + 4.0 * n * 2.220446049250313e-16 * s)


cdef void _cheb_derive(const double* c, double* out, Py_ssize_t n, double scale) noexcept:
    """out = scale * (derivative of the series c), both of length n."""
    cdef Py_ssize_t q
    for q in range(n):
        out[q] = 0.0
    for q in range(n - 1, 0, -1):
        out[q - 1] = (out[q + 1] if q + 1 < n else 0.0) + 2.0 * q * c[q]
    out[0] *= 0.5
    for q in range(n):
        out[q] *= scale


cdef inline double one_sided(double x, double other, double ulps) noexcept:
    """x moved ``ulps`` float spacings of |x| towards ``other`` (the piece's other end), at most
    to the piece's middle: where a piece that starts or ends on a breakpoint reads l''."""
    cdef double h = ulps * (nextafter(fabs(x), INFINITY) - fabs(x))
    cdef double mid = 0.5 * (x + other)
    if other > x:
        return x + h if x + h < mid else mid
    return x - h if x - h > mid else mid


def cheb_sample(fn, const double[::1] a, const double[::1] b, bl, br, const double[::1] nodes,
                int nl, double ulps):
    """The user's l'' (``fn`` of one float) at each piece's nodes: shape (K, len(nodes), nl),
    node i of piece k at its centre + half its width times ``nodes[i]`` (from +1 down to -1:
    its end b first, its start a last, exactly); a node on a breakpoint (``bl``, ``br``: the
    piece starts / ends at one) read ``ulps`` float spacings of its time inside the piece, on
    the side it belongs to (``one_sided``: a jump that close to a listed time is that one).
    Values are checked: nl entries each, finite. A piece's start that is the end of the piece
    before it (no breakpoint between) takes that piece's value (one call, not two).
    Returns (values, their largest magnitude per linkage (nl,))."""
    cdef Py_ssize_t K = a.shape[0], n1 = nodes.shape[0], k, i, j
    cdef double t, v
    top_arr = np.zeros(nl)
    cdef double[::1] top = top_arr
    cdef const unsigned char[::1] left = np.ascontiguousarray(bl, dtype=np.uint8)
    cdef const unsigned char[::1] right = np.ascontiguousarray(br, dtype=np.uint8)
    out = np.empty((K, n1, nl))
    cdef double[:, :, ::1] o = out
    for k in range(K):
        for i in range(n1):
            if (i == n1 - 1 and n1 > 1 and k > 0 and a[k] == b[k - 1] and not left[k]
                    and not right[k - 1]):
                for j in range(nl):
                    o[k, i, j] = o[k - 1, 0, j]
                continue
            if i == 0:
                t = one_sided(b[k], a[k], ulps) if right[k] else b[k]
            elif i == n1 - 1:
                t = one_sided(a[k], b[k], ulps) if left[k] else a[k]
            else:
                t = 0.5 * (a[k] + b[k]) + 0.5 * (b[k] - a[k]) * nodes[i]
            x = fn(t)
            if nl == 1 and type(x) is float:
                o[k, i, 0] = <double>x
            else:
                row = np.asarray(x, dtype=float).reshape(-1)
                if row.shape[0] != nl:
                    raise ValueError(f'gait values must have {nl} entries (one per linkage), '
                                     f'got {row.shape[0]}')
                for j in range(nl):
                    o[k, i, j] = row[j]
            for j in range(nl):
                v = fabs(o[k, i, j])
                if not isfinite(v):
                    raise ValueError(f'gait acceleration must be finite, got a non-finite '
                                     f'value at t = {t!r} s')
                if v > top[j]:
                    top[j] = v
    return out, top_arr


def cheb_states(fn, ts, int nl, first=None):
    """The user's (l, l') (``fn`` of one float, returning the pair) at each time of the list
    ``ts``: shape (len(ts), 2, nl), checked (nl entries each, finite); with ``first`` (2, nl)
    given, that row comes first: shape (len(ts) + 1, 2, nl)."""
    cdef Py_ssize_t n = len(ts), k, i, j, off = 0 if first is None else 1
    out = np.empty((n + off, 2, nl))
    cdef double[:, :, ::1] o = out
    cdef double t
    if off:
        out[0] = first
    for k in range(off, n + off):
        t = ts[k - off]
        x = fn(t)
        if nl == 1 and type(x) is tuple and len(x) == 2 and type(x[0]) is float \
                and type(x[1]) is float:
            o[k, 0, 0] = <double>x[0]
            o[k, 1, 0] = <double>x[1]
        else:
            try:
                row = np.asarray(x, dtype=float).reshape(2, nl)
            except ValueError:
                raise ValueError(f'gait values must have {nl} entries (one per linkage)') \
                    from None
            for i in range(2):
                for j in range(nl):
                    o[k, i, j] = row[i, j]
        for i in range(2):
            for j in range(nl):
                if not isfinite(o[k, i, j]):
                    raise ValueError(f"gait {('length', 'velocity')[i]} must be finite, got "
                                     f'a non-finite value at t = {t!r} s')
    return out


def cheb_split(const double[::1] a, const double[::1] b, const double[:, :, ::1] f,
               const double[::1] nodes, bl, br, const double[::1] tail, double wide):
    """The pieces that replace each unresolved piece [a, b] (l'' ``f`` (K, N + 1, nl) at its
    ``nodes``, from +1 down to -1; ``bl`` / ``br`` it starts / ends on a breakpoint, ``tail``
    its fit's relative tail, ``cheb_fit``): cut in two where the slope of l'' turns far more
    than anywhere else (a kink or a jump: where the lines through the samples either side
    meet, exact for a kinked line; ``proxy._split_points`` in numpy), else in four where
    ``tail`` > ``wide`` (a series that has not begun to converge: halving lowers a
    converging one's last coefficients by about 2^-N, so a tail that far above the rounding
    needs two halvings, sampled at once rather than one round after the other), else halved.

    Returns (a, b, bl, br, parent) of the new pieces, in order of their parent and then of
    time; ``parent`` the tail of the piece each one replaces."""
    cdef Py_ssize_t K = a.shape[0], n1 = f.shape[1], nl = f.shape[2], N = n1 - 1
    cdef Py_ssize_t m
    cdef const unsigned char[::1] left = np.ascontiguousarray(bl, dtype=np.uint8)
    cdef const unsigned char[::1] right = np.ascontiguousarray(br, dtype=np.uint8)
    cdef double t[64]
    cdef double best[4]
    cdef double cuts[5]
    cdef double* slope
    if n1 > 64:
        raise ValueError(f'cheb_split: at most 64 nodes, got {n1}')
    slope = <double*>PyMem_Malloc(max(N * nl, 1) * sizeof(double))
    if slope == NULL:
        raise MemoryError()
    out_a = np.empty(4 * K)
    out_b = np.empty(4 * K)
    out_l = np.zeros(4 * K, dtype=bool)
    out_r = np.zeros(4 * K, dtype=bool)
    out_p = np.empty(4 * K)
    cdef double[::1] oa = out_a, ob = out_b, op = out_p
    cdef unsigned char[::1] ol = out_l.view(np.uint8), orr = out_r.view(np.uint8)
    m = 0
    try:
        _split_all(a, b, f, nodes, left, right, tail, wide, slope, t, best, cuts,
                   oa, ob, ol, orr, op, &m)
    finally:
        PyMem_Free(slope)
    return out_a[:m], out_b[:m], out_l[:m], out_r[:m], out_p[:m]


cdef void _split_all(const double[::1] a, const double[::1] b, const double[:, :, ::1] f,
                     const double[::1] nodes, const unsigned char[::1] left,
                     const unsigned char[::1] right, const double[::1] tail, double wide,
                     double* slope, double* t, double* best, double* cuts, double[::1] oa,
                     double[::1] ob, unsigned char[::1] ol, unsigned char[::1] orr,
                     double[::1] op, Py_ssize_t* count) noexcept:
    """``cheb_split``'s loop over the pieces (into the output arrays, ``count`` set)."""
    cdef Py_ssize_t K = a.shape[0], n1 = f.shape[1], nl = f.shape[2], N = n1 - 1
    cdef Py_ssize_t k, i, j, kk, jj, kl, kr, m = 0, cnt, q
    cdef double mid, half, top, d, x, y, sl, sr, fl, fr, tl, tr, meet, lo, hi
    for k in range(K):
        mid = 0.5 * (a[k] + b[k])
        half = 0.5 * (b[k] - a[k])
        for i in range(n1):                      # ascending: node N - i
            t[i] = mid + half * nodes[N - i]
        for i in range(N):
            d = t[i + 1] - t[i]
            for j in range(nl):
                slope[i * nl + j] = (f[k, N - i - 1, j] - f[k, N - i, j]) / d
        # the turn of the slope at each inner node (its largest over the linkages)
        kk = 0
        top = -1.0
        best[0] = best[1] = best[2] = best[3] = 0.0
        for i in range(N - 1):
            x = 0.0
            for j in range(nl):
                d = fabs(slope[(i + 1) * nl + j] - slope[i * nl + j])
                if d > x:
                    x = d
            if not isfinite(x):
                x = 0.0
            if x > top:
                top = x
                kk = i
            # the four largest, sorted down (best[3]: the fourth)
            for q in range(4):
                if x > best[q]:
                    y = best[q]
                    best[q] = x
                    x = y
        cnt = 0
        if N >= 5 and top > 16.0 * best[3]:
            # the kink sits in gap kk or kk + 1: where the line through the gap before them
            # meets the line through the gap after them
            jj = 0
            x = -1.0
            for j in range(nl):
                d = fabs(slope[(kk + 1) * nl + j] - slope[kk * nl + j])
                if d > x:
                    x = d
                    jj = j
            kl = kk - 1 if kk >= 1 else 0
            kr = kk + 2 if kk + 2 <= N - 1 else N - 1
            sl, sr = slope[kl * nl + jj], slope[kr * nl + jj]
            fl, fr = f[k, N - (kl + 1), jj], f[k, N - kr, jj]
            tl, tr = t[kl + 1], t[kr]
            meet = (fr - fl + sl * tl - sr * tr) / (sl - sr)
            lo, hi = t[kk], t[kk + 2 if kk + 2 <= N else N]
            if not (isfinite(meet) and meet > lo and meet < hi):
                meet = t[kk + 1]
            if meet > a[k] + 1e-9 * (b[k] - a[k]) and meet < b[k] - 1e-9 * (b[k] - a[k]):
                cuts[1] = meet
                cnt = 2
        if cnt == 0:
            if tail[k] > wide:
                cnt = 4
                for q in range(1, 4):
                    cuts[q] = a[k] + (b[k] - a[k]) * (0.25 * q)
            else:
                cnt = 2
                cuts[1] = mid
        cuts[0] = a[k]
        cuts[cnt] = b[k]
        for q in range(cnt):
            oa[m] = cuts[q]
            ob[m] = cuts[q + 1]
            ol[m] = left[k] if q == 0 else 0
            orr[m] = right[k] if q == cnt - 1 else 0
            op[m] = tail[k]
            m += 1
    count[0] = m


def cheb_times(const double[::1] a, const double[::1] b, bl, br, const double[::1] nodes,
               double ulps):
    """The times ``cheb_sample`` reads each piece [a, b] at (its arithmetic, to the float):
    shape (K, len(nodes)), node 0 at b, the last at a (with more than one node), a piece's end
    on a breakpoint (``bl``, ``br``) read ``ulps`` float spacings inside (``one_sided``). For
    functions of an array of times (``Custom(vectorized=True)``): one call for them all."""
    cdef Py_ssize_t K = a.shape[0], n1 = nodes.shape[0], k, i
    cdef const unsigned char[::1] left = np.ascontiguousarray(bl, dtype=np.uint8)
    cdef const unsigned char[::1] right = np.ascontiguousarray(br, dtype=np.uint8)
    out = np.empty((K, n1))
    cdef double[:, ::1] o = out
    cdef double mid, half
    for k in range(K):
        mid = 0.5 * (a[k] + b[k])
        half = 0.5 * (b[k] - a[k])
        for i in range(n1):
            o[k, i] = mid + half * nodes[i]
        o[k, 0] = one_sided(b[k], a[k], ulps) if right[k] else b[k]
        if n1 > 1:
            o[k, n1 - 1] = one_sided(a[k], b[k], ulps) if left[k] else a[k]
    return out


def cheb_jerk_check(const double[:, :, :, ::1] coef, const double[::1] a, const double[::1] b,
                    const double[:, ::1] bj, const double[:, ::1] bound,
                    const double[::1] scale, double noise, const double[:, ::1] tnodes):
    """The pieces' l''' (series 3 of ``coef`` (K, nl, 4, width)) at their nodes within
    ``bound`` (K, nl) [m/s^3] times 1 + 1e-9, beyond the rounding of the fit (Markov: an
    error e of degree N on a piece of width w has a slope up to 2 N^2 e / w; e = ``noise``
    times the sum of the l'' series' |coefficients| + 64 eps ``scale`` (nl,) + eps |t| |l'''|
    at the node). A piece and linkage whose bound of |l'''| on the whole piece (``bj``) is
    within the limit with the smallest slack is within it at its nodes (the slack only grows
    with the values there): their series are not read at the nodes. Returns None, or (k, j,
    node, |l'''| there) of the first piece and linkage (in that order) over the limit
    (``proxy.ChebTable._check_jerk``)."""
    cdef Py_ssize_t K = coef.shape[0], nl = coef.shape[1], w = coef.shape[3]
    cdef Py_ssize_t n1 = tnodes.shape[0], k, j, i, q, nc, at
    cdef double markov, err0, limit, top, v, tm, eps = 2.220446049250313e-16
    if tnodes.shape[1] < w:
        raise ValueError(f'cheb_jerk_check: {tnodes.shape[1]} columns of T_q for {w} '
                         f'coefficients')
    for k in range(K):
        markov = 2.0 * (n1 - 1) * (n1 - 1) / (b[k] - a[k]) if b[k] > a[k] else INFINITY
        tm = max(fabs(a[k]), fabs(b[k]))
        for j in range(nl):
            err0 = 0.0
            for q in range(w):
                err0 += fabs(coef[k, j, 2, q])
            err0 = noise * err0 + 64.0 * eps * scale[j]
            limit = bound[k, j] * (1.0 + 1e-9)
            if not bj[k, j] > limit + markov * err0:
                continue                 # (NaN: a piece of a few floats, inf * 0: no check)
            nc = _nonzero_length(&coef[k, j, 3, 0], w)
            top = 0.0
            at = 0
            for i in range(n1):
                v = fabs(cheb_dot(&coef[k, j, 3, 0], &tnodes[i, 0], <int>nc))
                if v > top:
                    top = v
                    at = i
            if top > limit + markov * (err0 + eps * tm * top):
                return k, j, at, top
    return None


# ---------------------------------------------------------------------- a run of pieces
# The engine builds one TABLE per sync from the actuator's run of pieces (issue 41: half of an
# env-step went to ``table`` with ``table_jumps``, numpy calls on 10 pieces). ``table_of_run``
# computes the same struct in compiled loops: the same expressions on the same doubles in the
# same order (``table_jumps``'s loop, ``table``'s jj / rest, ``_table_stats``,
# ``_aligned_levels``, ``_counts_before``), so the gait is bit for bit ``table``'s.

#: 4 ulp(1) (``table_jumps``' scale 4 eps), once: np.finfo per call was a tenth of the build
_FOUR_EPS = 4.0 * float(np.finfo(float).eps)


def table_of_run(starts, anchors, coef) -> CompiledGait:
    """``table(coef, starts=starts, anchors=anchors, jumps=table_jumps(starts, anchors,
    coef))`` (``gaits.cubic``) of a table that is not periodic: ``starts``, ``anchors`` (n,)
    [s] and ``coef`` (n, nl, 4) C-contiguous float64 (copied into the gait's block), n >= 1."""
    cdef const double[::1] s = starts, o = anchors
    cdef const double[:, :, ::1] c = coef
    cdef Py_ssize_t n = c.shape[0], nl = c.shape[1]
    if n == 0 or nl == 0 or s.shape[0] != n or o.shape[0] != n:
        raise ValueError(f'table_of_run: n >= 1 pieces with one start and anchor each, got '
                         f'{s.shape[0]} starts, {o.shape[0]} anchors, {n} pieces')
    cdef CompiledGait g = run_table(n, nl)
    memcpy(g.d.starts, &s[0], n * sizeof(double))
    memcpy(g.d.anchors, &o[0], n * sizeof(double))
    memcpy(g.d.coef, &c[0, 0, 0], n * nl * 4 * sizeof(double))
    run_table_fill(g)
    return g


cdef CompiledGait run_table(Py_ssize_t n, Py_ssize_t nl):
    """A TABLE gait (not periodic) of ``n`` >= 1 pieces of ``nl`` >= 1 linkages whose arrays
    live in one block it owns: ``d.starts``, ``d.anchors`` (n,) [s] and ``d.coef`` (n, nl, 4)
    are for the caller to write (the engine's actuator writes its run of ticks there, issue
    41), then ``run_table_fill`` computes the rest. One allocation (a bytearray: cheaper than
    a numpy array), no Python call per piece."""
    cdef CompiledGait g = CompiledGait()
    cdef Py_ssize_t w = 5 * nl, L = _n_levels(n), q, cnt, nrec
    cdef int* off = g.d.lev_off
    # level offsets as ``_aligned_levels``
    off[0] = 0
    cnt = n
    for q in range(1, L):
        off[q] = off[q - 1] + cnt
        cnt = (cnt + 1) // 2
    nrec = off[L - 1] + cnt
    # doubles: starts, anchors (n each), coef (n nl 4), the stat records (nrec, 5, nl), the
    # jump times (at most n); then jj_before (2 n + 1) as ints; then the flags jump, jj, rest
    cdef Py_ssize_t n_dbl = 3 * n + n * nl * 4 + nrec * w
    mem = PyByteArray_FromStringAndSize(NULL, n_dbl * sizeof(double)
                                        + (2 * n + 1) * sizeof(int) + 3 * n)
    cdef double* base = <double*>PyByteArray_AS_STRING(mem)
    g._keep = mem
    g.d.kind = TABLE
    g.d.nl = <int>nl
    g.d.n = <int>n
    g.d.nlev = <int>L
    g.d.starts = base
    g.d.anchors = base + n
    g.d.coef = base + 2 * n
    g.d.stat = base + 2 * n + n * nl * 4
    g.d.jump_times = g.d.stat + nrec * w
    g.d.jj_before = <int*>(base + n_dbl)
    g.d.jump = <unsigned char*>(g.d.jj_before + 2 * n + 1)
    g.d.jjump = g.d.jump + n
    g.d.rest = g.d.jump + 2 * n
    g.d.period = 0.0
    g.n_links = <int>nl
    g.period = None
    return g


cdef int run_table_fill(CompiledGait g) except -1:
    """The struct of a ``run_table`` gait from its starts, anchors and coef: the same
    expressions on the same doubles in the same order as ``table`` with ``table_jumps``
    (``table_jumps``' loop, ``table``'s jj / rest, ``_table_stats``, ``_aligned_levels``,
    ``_counts_before``), so the gait is bit for bit ``table``'s."""
    cdef GaitData* gd = &g.d
    cdef Py_ssize_t n = gd.n, nl = gd.nl, k, j, i, nj, q, cnt
    cdef Py_ssize_t w = 5 * nl, L = gd.nlev
    cdef const double* s = gd.starts
    cdef const double* o = gd.anchors
    cdef const double* c = gd.coef
    cdef double* st = gd.stat
    cdef double* jt
    cdef int* jb = gd.jj_before
    cdef unsigned char* jmp = gd.jump
    cdef unsigned char* jj = gd.jjump
    cdef unsigned char* rest = gd.rest
    cdef double scale = _FOUR_EPS, before, d, size, a, jk, dj, d0, d1
    cdef bint bounded
    cdef double* rg
    # the jump times after the records (``run_table``'s layout; the pointer is NULL in a
    # table without jumps, so it is found again here when a block is refilled)
    cnt = n
    for q in range(1, L):
        cnt = (cnt + 1) // 2
    jt = st + (gd.lev_off[L - 1] + cnt) * w
    gd.jump_times = jt
    memset(jmp, 0, 3 * n)
    # jumps (``table_jumps``' loop; piece 0 never jumps), jj (l''' changes; not at piece 0),
    # rest (v0, a0, jerk all 0); piece k, linkage j, coefficient q at c[(k nl + j) 4 + q]
    nj = 0
    for k in range(n):
        rest[k] = 1
        for j in range(nl):
            if not (c[(k * nl + j) * 4 + 1] == 0.0 and c[(k * nl + j) * 4 + 2] == 0.0
                    and c[(k * nl + j) * 4 + 3] == 0.0):
                rest[k] = 0
                break
        if k == 0:
            continue
        for j in range(nl):
            if c[(k * nl + j) * 4 + 3] != c[((k - 1) * nl + j) * 4 + 3]:
                jj[k] = 1
                break
        before = o[k - 1]
        d = s[k] - before
        size = fabs(s[k]) + fabs(before)
        if not isfinite(size):
            size = 0.0
        for j in range(nl):
            a = c[((k - 1) * nl + j) * 4 + 2]
            jk = c[((k - 1) * nl + j) * 4 + 3]
            dj = d * jk
            if fabs((a + dj) - c[(k * nl + j) * 4 + 2]) > \
                    scale * ((fabs(a) + fabs(dj)) + size * fabs(jk)):
                jmp[k] = 1
                nj += 1
                break
    i = 0
    for k in range(n):
        if jmp[k]:
            jt[i] = s[k]
            i += 1
    # per piece (``_table_stats``): |jerk|, lo / hi l', lo / hi l'' over [d0, d1]
    for k in range(n):
        d0 = s[k] - o[k]
        d1 = (s[k + 1] if k + 1 < n else INFINITY) - o[k]
        bounded = isfinite(d0) and isfinite(d1)
        rg = st + k * w + nl
        for j in range(nl):
            st[k * w + j] = fabs(c[(k * nl + j) * 4 + 3])
            rg[j] = INFINITY if bounded else -INFINITY
            rg[nl + j] = -rg[j]
            rg[2 * nl + j] = rg[j]
            rg[3 * nl + j] = -rg[j]
        if bounded:
            piece_ranges(c + k * nl * 4, <int>nl, d0, d1, rg)
    # the aligned levels (``_aligned_levels``: max of rows 0, 2, 4, min of rows 1, 3)
    _fill_levels(st, gd.lev_off, L, n, w, NULL, nl)
    jb[0] = 0                                        # ``_counts_before(jj)``
    for i in range(2 * n):
        jb[i + 1] = jb[i] + jj[i % n]
    gd.n_jumps = <int>nj
    if not nj:
        gd.jump_times = NULL
    gd.hint = 0
    gd.constant = True
    for k in range(n):
        if not rest[k]:
            gd.constant = False
            break
    return 0


def run_arrays(CompiledGait g):
    """(starts (n,) [s], anchors (n,) [s], coef (n, nl, 4)) of a TABLE gait that is not
    periodic, as new arrays: what ``gaits.PiecewiseCubic.from_arrays`` takes (a gait the
    plant's compiled step built in place, made a Python gait when one is asked for)."""
    cdef GaitData* d = &g.d
    cdef Py_ssize_t n = d.n, nl = d.nl
    if d.kind != TABLE or d.period > 0.0 or n < 1:
        raise ValueError('run_arrays reads a TABLE gait that is not periodic')
    starts = np.empty(n)
    anchors = np.empty(n)
    coef = np.empty((n, nl, 4))
    cdef double[::1] s = starts, o = anchors
    cdef double[:, :, ::1] c = coef
    memcpy(&s[0], d.starts, n * sizeof(double))
    memcpy(&o[0], d.anchors, n * sizeof(double))
    memcpy(&c[0, 0, 0], d.coef, n * nl * 4 * sizeof(double))
    return starts, anchors, coef


def table_struct(CompiledGait g):
    """The struct of a TABLE gait that is not periodic as copies (a dict of arrays and
    numbers): what two builders of one table must agree on, bit for bit (tests)."""
    cdef GaitData* d = &g.d
    cdef Py_ssize_t n = d.n, nl = d.nl, i, nrec
    if d.kind != TABLE or d.period > 0.0:
        raise ValueError('table_struct reads a TABLE gait that is not periodic')
    nrec = d.lev_off[d.nlev - 1]
    i = n
    for _ in range(1, d.nlev):
        i = (i + 1) // 2
    nrec += i if d.nlev > 1 else 0
    if d.nlev == 1:
        nrec = n
    return {
        'n': n, 'nl': nl, 'constant': bool(d.constant), 'nlev': d.nlev,
        'lev_off': [d.lev_off[q] for q in range(d.nlev)],
        'coef': np.array([d.coef[i] for i in range(n * nl * 4)]),
        'starts': np.array([d.starts[i] for i in range(n)]),
        'anchors': np.array([d.anchors[i] for i in range(n)]),
        'jump': np.array([d.jump[i] for i in range(n)]),
        'jjump': np.array([d.jjump[i] for i in range(n)]),
        'rest': np.array([d.rest[i] for i in range(n)]),
        'jump_times': np.array([d.jump_times[i] for i in range(d.n_jumps)]),
        'stat': np.array([d.stat[i] for i in range(nrec * 5 * nl)]),
        'jj_before': np.array([d.jj_before[i] for i in range(2 * n + 1)]),
    }
