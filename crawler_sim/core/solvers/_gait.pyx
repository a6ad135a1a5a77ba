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

import numpy as np

from libc.math cimport fabs, isfinite, nextafter, INFINITY, NAN
from cpython.mem cimport PyMem_Malloc, PyMem_Free

__all__ = ['CompiledGait', 'fourier', 'scallop', 'table', 'callback']


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
        self.estimate = None
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
            if self.d.kind == CALLBACK:
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
        if self.d.kind == CALLBACK:
            self._fetch(t, True)
            return self._buf[0, 0], self._buf[1, 0], self._buf[2, 0]
        gait_eval(&self.d, t, l, ld, ldd, ld3)
        return l[0], ld[0], ldd[0]

    def finite_at(self, double t) -> bool:
        """True when l, l' and l'' are finite at t [s]; False for a CALLBACK gait (its
        values come from Python: the caller checks their shapes and values there)."""
        cdef int nl = self.d.nl, j
        cdef double* w
        if self.d.kind == CALLBACK:
            return False
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
        """l''' at t [m/s^3] (a CALLBACK gait: a difference of its l'')."""
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

    # ------------------------------------------------------------------ CALLBACK kind
    cdef int _fetch(self, double t, bint with_length) except -1:
        """The Python gait's l' and l'' (and l when asked) at t into ``_buf`` rows."""
        cdef int j, nl = self.d.nl
        if t == self._t_rates and (not with_length or t == self._t_len):
            return 0
        if self._fns is None:
            l, ld, ldd = self._gait.at(t)
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
        cdef int j, nl = self.d.nl
        cdef double s, dd, x
        self._fetch(t, False)
        for j in range(nl):
            ld[j] = self._buf[1, j]
            ldd[j] = self._buf[2, j]
            ld3[j] = 0.0
        if not self.estimated:
            # rigorous bounds given: the search needs no slope of l''
            return 0
        # l''' by a difference of l'' inside the span being integrated (estimate.py)
        dd = self._diff_step(t)
        s = t + dd
        if s > self.span_hi:
            s = t - dd
            if s < self.span_lo:
                s = self.span_hi if self.span_hi != t else self.span_lo
        if s == t or not isfinite(s):
            return 0
        if self._fns is None:
            acc = _row(self._gait.at(s)[2], nl)
        elif self._scalar:
            acc = (float(self._fns[2](s)),)
        else:
            acc = _row(self._fns[2](s), nl)
        for j in range(nl):
            x = (acc[j] - ldd[j]) / (s - t)
            ld3[j] = x
        if self._check(t, ld3):
            self.exceeded += 1
            return 1
        return 0

    cdef int cb_bounds(self, double a, double b, double* jerk, double* snap) except -1:
        cdef int j, nl = self.d.nl
        jb = self._jerk
        if callable(jb):
            jb = jb(a, b)
            if jb is not None:
                jb = _user_bound(jb, nl, a, b)
        if jb is None:
            # no bound given (here): the estimate's, and the checks of every value against it
            self.estimated = True
            est = self.estimate
            if not (est.lo <= a and b <= est.hi):
                est.ensure(a, b, self.span_lo, self.span_hi)
            return self._lookup(a, b, jerk, snap)
        for j in range(nl):
            jerk[j] = jb[j]
        if self._fns is None:       # a Gait subclass: its own snap bound, if any
            sb = self._gait.snap_bound(a, b)
            if sb is not None:
                sb = np.broadcast_to(np.asarray(sb, dtype=float), (nl,))
                for j in range(nl):
                    snap[j] = sb[j]
                return 1
        return 0

    # the estimate's cells (``estimate.BoundEstimate``), read through views kept until its
    # arrays change
    cdef int _sync(self) except -1:
        est = self.estimate
        st = est.starts
        if st is not self._est_starts:
            self._est_starts = st
            self._st = st
            self._d1 = est.d1
            self._d2 = est.d2
            self._safety = est.SAFETY
        return 0

    cdef int _lookup(self, double a, double b, double* jerk, double* snap) except -1:
        """``SAFETY`` times the largest differences of the cells [a, b] touches, each cell with
        its two neighbours (its end samples may miss a rise inside it)."""
        cdef int n, k, j, k0, k1, nl = self.d.nl
        self._sync()
        n = self._st.shape[0]
        k0 = _cell(self._st, a)
        k1 = _cell(self._st, b)
        if k1 > k0 and self._st[k1] >= b:
            k1 -= 1
        k0 = max(k0 - 1, 0)
        k1 = min(k1 + 1, n - 1)
        for j in range(nl):
            jerk[j] = 0.0
            snap[j] = 0.0
        for k in range(k0, k1 + 1):
            for j in range(nl):
                if self._d1[k, j] > jerk[j]:
                    jerk[j] = self._d1[k, j]
                if self._d2[k, j] > snap[j]:
                    snap[j] = self._d2[k, j]
        for j in range(nl):
            jerk[j] *= self._safety
            snap[j] *= self._safety
        return 1

    cdef bint _check(self, double t, double* ld3) except -1:
        """True, with the cell of t grown to the jerk it saw (its snap in proportion), when the
        jerk at t exceeds the bound the cells give there."""
        cdef double bound, x, ratio
        cdef int n, k, j, kk, nl = self.d.nl
        cdef bint grew = False
        self._sync()
        n = self._st.shape[0]
        if n == 0:
            return False
        k = _cell(self._st, t)
        for j in range(nl):
            bound = 0.0
            for kk in range(max(k - 1, 0), min(k + 2, n)):
                if self._d1[kk, j] > bound:
                    bound = self._d1[kk, j]
            x = fabs(ld3[j])
            if x > self._safety * bound:
                ratio = x / max(self._d1[k, j], 1e-300)
                if ratio < 1.0:
                    ratio = 1.0
                self._d1[k, j] = max(self._d1[k, j], x)
                self._d2[k, j] = self._d2[k, j] * ratio
                grew = True
        return grew

    cdef double _diff_step(self, double t) except -1.0:
        """The difference step of the jerk: 1e-4 of the width of the cell of t, and at least
        64 floats of t (``estimate.BoundEstimate.diff_step``)."""
        cdef int n, k
        cdef double w
        self._sync()
        n = self._st.shape[0]
        if n == 0:
            return self.estimate.diff_step(t)
        k = _cell(self._st, t)
        w = (self._st[k + 1] if k + 1 < n else <double>self.estimate.hi) - self._st[k]
        return max(1e-4 * w, 64.0 * (nextafter(fabs(t), INFINITY) - fabs(t)) + 1e-300)

    cdef double cb_next_break(self, double t) except? -1.0:
        cdef double w
        if self._fns is not None:          # a Custom gait: its sorted breakpoints
            br = self._keep
            i = np.searchsorted(br, t, side='right')
            return float(br[i]) if i < br.size else INFINITY
        # a Gait subclass: its breakpoints() over the span being integrated (growing windows
        # outside a solve)
        if isfinite(self.span_hi) and self.span_hi > t:
            b = self._gait.breakpoints(t, self.span_hi)
            return float(b[0]) if len(b) else INFINITY
        w = 1.0
        while w < 1e12:
            b = self._gait.breakpoints(t, t + w)
            if len(b):
                return float(b[0])
            w *= 16.0
        return INFINITY

    cdef int cb_is_constant(self, double a, double b) except -1:
        return 1 if self._gait.is_constant(a, b) else 0


def _row(v, int nl):
    """A user value as a tuple of nl floats."""
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != nl:
        raise ValueError(f'gait values must have {nl} entries (one per linkage), got {a.size}')
    return a.tolist()


cdef int _cell(double[::1] starts, double t) noexcept:
    """The estimate's cell holding t (the first or last cell outside its span)."""
    cdef Py_ssize_t lo = 0, hi = starts.shape[0], mid
    while lo < hi:
        mid = (lo + hi) >> 1
        if starts[mid] <= t:
            lo = mid + 1
        else:
            hi = mid
    return <int>max(lo - 1, 0)


def _user_bound(jb, int nl, double a, double b):
    arr = np.broadcast_to(np.asarray(jb, dtype=float), (nl,))
    if np.any(np.isnan(arr)) or np.any(arr < 0):
        raise ValueError(f'jerk_bound({a}, {b}) must return values >= 0 m/s^3, '
                         f'got {arr.tolist()}')
    return arr


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


def scallop(double freq, mean, rows, bins_jerk, bins_snap) -> CompiledGait:
    """The Scallop stroke: ``rows`` (nl, 4) = amplitude [m], phase - pi r [rad], cos(pi r),
    sin(pi r); derivative bounds per bin, ``bins_*`` (nb, nl) (nb bins per period). Kept with
    the cosine and sine of each row's phase, so an evaluation takes one cosine and one sine
    for all linkages (angle addition), not one pair per linkage."""
    cdef CompiledGait g = CompiledGait()
    mean = _f64(mean)
    rows = np.asarray(rows, dtype=float)
    rows = _f64(np.column_stack([rows, np.cos(rows[:, 1]), np.sin(rows[:, 1])]))
    bj = _f64(bins_jerk)
    bs = _f64(bins_snap)
    bj_all = _f64(bj.max(axis=0))
    bs_all = _f64(bs.max(axis=0))
    g._keep = (mean, rows, bj, bs, bj_all, bs_all)
    g.d.kind = SCALLOP
    g.d.nl = rows.shape[0]
    g.d.freq = freq
    g.d.mean = _dptr(mean)
    g.d.p1 = _dptr(rows)
    g.d.nb = bj.shape[0]
    g.d.bj = _dptr(bj)
    g.d.bs = _dptr(bs)
    g.d.bj_all = _dptr(bj_all)
    g.d.bs_all = _dptr(bs_all)
    g.d.constant = not np.any(rows[:, 0])
    g.n_links = g.d.nl
    g.period = 1.0 / freq
    return g


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
    g._keep = (coef, knots if periodic else starts_, origins, jumps, jj, rest, jump_times)
    g.d.kind = TABLE
    g.d.nl = nl
    g.d.n = n
    g.d.coef = _dptr(coef)
    g.d.jump = _bptr(jumps)
    g.d.jjump = _bptr(jj)
    g.d.rest = _bptr(rest)
    g.d.n_jumps = jump_times.size
    g.d.jump_times = _dptr(jump_times)
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


def callback(gait, int n_links, estimate, fns=None, jerk=None,
             breakpoints=None) -> CompiledGait:
    """A Python gait: ``fns`` = (l, l', l'') callables of one float (else ``gait.at``);
    ``jerk``: a bound of |l'''| [m/s^3] (an array (nl,), or a callable (t0, t1) -> bounds or
    None), else (or where it gives None) the bounds of ``estimate``
    (``estimate.BoundEstimate``); ``breakpoints``: the sorted times where l'' jumps (None:
    ``gait.breakpoints``)."""
    cdef CompiledGait g = CompiledGait()
    g.d.kind = CALLBACK
    g.d.nl = n_links
    g.n_links = n_links
    g.period = gait.period
    g._gait = gait
    g._fns = fns
    g._jerk = jerk
    g.estimate = estimate
    g.estimated = jerk is None
    g.lock = threading.Lock()
    g._buf = np.zeros((4, max(n_links, 1)))
    g._scalar = False
    if fns is not None and n_links == 1:
        try:
            g._scalar = all(isinstance(f(0.0), (float, int)) for f in fns)
        except Exception:       # not defined at 0: the general conversion
            g._scalar = False
    g._keep = _f64(breakpoints) if breakpoints is not None else None
    g.d.constant = False
    return g
