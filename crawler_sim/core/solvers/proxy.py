"""A gait of Python functions (a ``Custom`` gait, a user's ``Gait`` subclass), sampled into
Chebyshev series to machine precision: the compiled kind PROXY of ``_gait.pxd`` evaluates
them, so the solvers' loops run as fast as for a built-in gait and the user's functions are
called only to build the pieces.

A piece [a, b] takes l'' at the N + 1 = 33 Chebyshev points of its own interval, its series by
a discrete cosine transform, and is kept when its last coefficients have fallen to the
rounding of the values (``_gait.cheb_fit``: 64 eps of the values' scale, the largest of the
piece's, of all seen so far and of the l'' that would move l by its own size over the window,
plus what rounding a time of size |t| does to l'' through l'''); else it is split and sampled
again. A tail at the noise floor that splitting no longer lowers (the user's own rounding, such
as sin(w t) at t = 1e6 s) is accepted. l' and l are
the series' integrals from the user's l'(a) and l(a), checked against l'(b) and l(b) (the
next piece's anchors); l''' and l'''' are its derivatives, bounded on the piece by their
largest magnitude at 17 evenly spaced points plus the error of the line between neighbouring
points (h^2 / 8 times a bound of their second derivative, the sum of its series' coefficients'
magnitudes, |T_k| <= 1; ``_gait._sampled_bound``): within 1.02-1.46 times the true largest
value where the sums alone were 1.3-3 times it, and the search's steps grow as the bound
shrinks. Every join of two pieces is reported as a breakpoint, so the solvers never assume l''
continuous across one.

Sampling density (what the build can see): pieces are 32 cells wide and a cell is
``T / 1024`` for a periodic gait, ``max_step / 8`` when one is given, else 1/256 of the run
so far (from the first span's start to the end of the one being integrated: a run streamed in
short steps is sampled as the same run in one call is, a piece per step at most, not eight
pieces of 1/256 of each step; never finer than before), as the bound scan it replaces:
33 points per 32 cells (the points crowd at the ends: the widest gap is pi / 2 cells). A
feature narrower than that between two points is not seen; a sharp one that a point touches
makes its piece unhappy and is resolved by halving where it is. A periodic gait is sampled
over one period and repeated.

Where the density is the user's (a period's 1024 cells, max_step's) rather than one the
function needs, neighbouring pieces are then joined where one series holds both (``_join``:
read from the pieces, no new calls, and checked against each piece at its own nodes, the
user's samples): every join ends a segment of the solver, and a sine's period sampled as 32
pieces is one series.

l'' that jumps (a contract breach: jumps must be listed in ``breakpoints=``) keeps a piece
unhappy down to ``MIN_WIDTH`` of a cell: the jump is refused with its time (to the float, by
halving) and the listed time nearest to it. A piece that starts or ends on a breakpoint, or on
a window's end (a run may start or end on a jump), reads l'' there ``BREAK_ULPS`` float
spacings inside (``_gait.one_sided``), so a listed time matches a jump that close. l''' that jumps
(l'' with a kink) is legal: where the slope of the samples turns far more than elsewhere, the
piece is split where the lines through the samples on either side meet, which is the kink of
a kinked line (list such times in ``breakpoints=`` and each side is one polynomial at once).
Other pieces are halved. (``WIDE``, off: cutting in four where a series has not begun to
converge would sample a long first window's l'' about 30 % less often, but it changes the
pieces and so the rounding of every Custom run, up to 3e-12 m on the fuzz scenes: Custom runs
stay bit for bit those of the releases before.)

A bound of |l'''| the user gives (``jerk_bound``) is checked against every piece: the series'
l''' at the piece's nodes must stay within it, beyond the rounding of the fit (else the bound
or the functions are wrong, and the gait is refused naming ``jerk_bound``).

The user's functions are only called inside the span being integrated.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from ..gaits.base import BREAK_ULPS
from . import _gait

__all__ = ['ChebTable', 'N', 'L']

N = 32                  # degree of a sampled piece (N + 1 Chebyshev points)
L = N + 3               # coefficients per series (l has degree N + 2)
PIECE = 32              # cells per piece
PER_PERIOD = 1024       # cells per period of a periodic gait
FIRST = 256             # cells of a span without a period or max_step
WINDOW = 128            # most pieces built at once (before halving)
MIN_WIDTH = 1e-6        # of a cell: the narrowest piece halving makes
KEEP = 1 << 21          # most coefficients kept (the oldest pieces go)
_JUMP = 1e-3            # l'' differing across a narrowest piece by this share of its scale
NOISE = 1e-8            # a tail (over the piece's values) this small that splitting keeps: noise
WIDE = math.inf         # a tail above this is cut in four: off (see the module's docstring)
MAX_PIECES = 100_000    # most pieces sampled in one build
_EPS = np.finfo(float).eps
_BIG = np.finfo(float).max

_U = np.cos(np.pi * np.arange(N + 1) / N)                # nodes, from +1 down to -1
_ONE = np.array([1.0])                                   # the one node of an instant


def _dct() -> NDArray:
    """Values at the nodes -> series: c_q = (2 / N) sum'' f_i cos(pi i q / N), the first and
    last terms (in i and in q) halved (DCT-I)."""
    q = np.arange(N + 1)[:, None]
    i = np.arange(N + 1)[None, :]
    dct = (2.0 / N) * np.cos(np.pi * i * q / N)
    dct[:, [0, N]] *= 0.5
    dct[[0, N], :] *= 0.5
    return np.ascontiguousarray(dct)


_DCT = _dct()
# T_q at the nodes: row i, column q < L, cos(pi i q / N) (``_at_own_nodes``)
_T_NODES = np.ascontiguousarray(np.cos(np.pi * np.outer(np.arange(N + 1), np.arange(L)) / N))
BOUND_POINTS = 17       # where a piece's l''' and l'''' are read for their bounds
# T_q at BOUND_POINTS evenly spaced u in [-1, 1] (``_gait.cheb_series``' bounds)
_GRID = np.ascontiguousarray(np.cos(np.outer(np.arccos(np.linspace(-1.0, 1.0, BOUND_POINTS)),
                                             np.arange(L))))


class ChebTable:
    """Pieces of one gait: ``knots`` (n + 1,) [s]; ``coef`` (n, nl, 4, L): the series of l
    [m], l' [m/s], l'' [m/s^2] and l''' [m/s^3] in u in [-1, 1] over each piece; ``ncoef``
    (n,) coefficients in use; ``bj`` / ``bs`` (n, nl) bounds of |l'''| [m/s^3] and |l''''|
    [m/s^4] on each piece; ``rest`` (n,) l' = l'' = 0 on the piece. ``periodic``: the pieces
    cover one period exactly, repeated from ``knots[0]``.

    ``accel(t)`` gives the user's l'' at one time, ``state(t)`` its (l, l') (two values of
    nl entries); ``breaks(t0, t1)`` the times in (t0, t1) where l'' may jump; ``jerk(t0,
    t1)`` the user's bounds of |l'''| [m/s^3] on [t0, t1] ((nl,) or None), which the pieces
    are checked against (or those bounds, (nl,), when they hold at all times).

    ``batch`` = (accel, state) of arrays, when the user's functions take an array of times
    (``Custom(vectorized=True)``): ``accel(ts)`` (n,) -> (n, nl), ``state(ts)`` -> (l, l'),
    each (n, nl), checked by the caller; every node of a round of sampling (all the pieces
    of a window, or all the halves of the unresolved ones) is then one call, and every
    piece end of a window one call of ``state``. The times are those of the scalar path, to
    the float: the pieces are the same. ``calls`` counts the times evaluated either way,
    ``batches`` the calls of the array functions."""

    def __init__(self, accel: Callable[[float], object],
                 state: Callable[[float], tuple], n_links: int,
                 period: float | None = None, max_step: float | None = None,
                 breaks: Callable[[float, float], NDArray] | None = None,
                 jerk: Callable[[float, float], NDArray | None] | NDArray | None = None,
                 batch: tuple[Callable[[NDArray], NDArray],
                              Callable[[NDArray], tuple]] | None = None) -> None:
        self._accel = accel
        self._state = state
        self._batch = batch
        self.batches = 0                # calls of the array functions (``batch``)
        self._breaks = breaks
        self._jerk = jerk
        self.nl = n_links
        self.period = period
        self.max_step = max_step
        self.spacing = math.inf         # cell width [s], set by the first build
        self.scale = np.zeros(n_links)  # largest |l''| seen [m/s^2]
        self.keep = max(2 * WINDOW, KEEP // (4 * L * max(n_links, 1)))
        self.calls = 0                  # evaluations of the user's functions
        self._reset()

    def _reset(self) -> None:
        nl = self.nl
        self.knots = np.zeros(0)
        self.coef = np.zeros((0, nl, 4, L))
        self.ncoef = np.zeros(0, dtype=np.intc)
        self.bj = np.zeros((0, nl))
        self.bs = np.zeros((0, nl))
        self.rest = np.zeros(0, dtype=bool)
        self.periodic = False
        self._end_state = None          # (l, l') at knots[-1], shape (2, nl)
        self._ahead = None              # (times, (l, l') there) read ahead (``_build``)
        self._quiet = np.zeros(nl)      # see ``_build`` [m/s^2]
        self._span = 0.0                # length of the window being built [s]
        self._origin = math.nan         # start of the first span since the table began [s]

    @property
    def lo(self) -> float:
        return float(self.knots[0]) if self.knots.size else math.inf

    @property
    def hi(self) -> float:
        return float(self.knots[-1]) if self.knots.size else -math.inf

    # ------------------------------------------------------------------ building
    def ensure(self, t: float, span_lo: float, span_hi: float) -> None:
        """Pieces up to t: continued from the last piece when t lies ahead of it and the
        span starts inside the table, else a fresh table from the span's start (from t
        outside the span); a window at a time, never
        past ``span_hi`` when t is inside the span (the user's functions are evaluated
        where the solver integrates). A build that raises (the user's function, a refused
        gait) leaves the table as it was: the gait serves later runs as a fresh one would."""
        if self.periodic or (self.knots.size and self.lo <= t <= self.hi):
            return
        # every field is replaced, never changed in place (arrays are concatenated or sliced
        # anew): a shallow copy is the table's whole state
        saved = dict(self.__dict__)
        try:
            self._ensure(t, span_lo, span_hi)
        except BaseException:
            calls = self.calls
            self.__dict__.clear()
            self.__dict__.update(saved)
            self.calls = calls          # (the user's functions were called: counted)
            raise

    def _ensure(self, t: float, span_lo: float, span_hi: float) -> None:
        if self.knots.size and self.hi < t and self.lo <= span_lo <= self.hi:
            start = self.hi
            self._forget(span_lo)
        else:
            if self.knots.size:
                self._reset()
            start = span_lo if math.isfinite(span_lo) and span_lo <= t <= span_hi else t
        stop = span_hi if (math.isfinite(span_hi) and span_hi >= t) else t
        if stop <= start and not self.knots.size:
            # a time outside any span (a solver reading its first state): that instant only
            self._point(t)
            return
        self._set_spacing(start, stop)
        while not self.knots.size or (self.hi < t and not self.periodic):
            s = self.hi if self.knots.size else start
            end = s + WINDOW * PIECE * self.spacing
            if stop > s:
                end = min(end, stop)
            end = max(end, t)
            if self.period:
                # one period from the table's start at most, whatever time is asked: the
                # pieces repeat from there (a time past it, asked before the period was
                # complete, made a table longer than the period, read modulo the period: a
                # stream started at 3 periods was 4.5e-4 m off)
                end = min(end, (self.lo if self.knots.size else s) + self.period)
            self._build(s, end)
            if self.period and self.hi >= self.lo + self.period:
                self.periodic = True

    def _forget(self, t: float) -> None:
        """Drop the pieces that end before t (a solver never goes back before the span it
        integrates; outside the pieces Python reads the user's functions): streaming in
        short steps then copies a few pieces per step, not the whole table."""
        k = int(np.searchsorted(self.knots, t, side='right')) - 1
        if k > 0 and not self.period:
            self.knots, self.coef = self.knots[k:], self.coef[k:]
            self.ncoef, self.bj, self.bs = self.ncoef[k:], self.bj[k:], self.bs[k:]
            self.rest = self.rest[k:]

    def _point(self, t: float) -> None:
        """A table of the one instant t: constant series of the user's values there."""
        nl = self.nl
        st = self._states([t])
        acc, _ = self._sample(np.array([t]), np.array([t]), np.zeros(1, bool),
                              np.zeros(1, bool), nodes=False)
        self.coef = np.zeros((1, nl, 4, L))
        self.coef[0, :, :2, 0] = st[0].T
        self.coef[0, :, 2, 0] = acc[0, 0]
        self.knots = np.array([t, t])
        self.ncoef = np.ones(1, dtype=np.intc)
        self.bj = np.zeros((1, nl))
        self.bs = np.zeros((1, nl))
        self.rest = np.array([not (st[0, 1].any() or acc.any())])
        self._end_state = st[0]

    def _states(self, ts: list, first: NDArray | None = None) -> NDArray:
        """The user's (l, l') at the times ``ts``, shape (len(ts), 2, nl), checked, after the
        row ``first`` when given (``_gait.cheb_states``)."""
        self.calls += 2 * len(ts)
        if self._batch is None:
            return _gait.cheb_states(self._state, ts, self.nl, first)
        self.batches += 1
        l, v = self._batch[1](np.asarray(ts, dtype=float))
        out = np.stack((l, v), axis=1)              # (n, 2, nl)
        return out if first is None else np.concatenate((np.asarray(first)[None], out))

    def _set_spacing(self, start: float, stop: float) -> None:
        cands = [self.period / PER_PERIOD if self.period else None,
                 self.max_step / 8.0 if self.max_step else None]
        cands = [c for c in cands if c]
        if cands:
            self.spacing = min(cands)
        elif stop > start or math.isinf(self.spacing):
            # 1/FIRST of the run so far (from the first span's start to this one's end: a
            # run streamed in short steps is sampled as the same run in one call is, not at
            # 1/FIRST of each step), never finer than before: a long run on a gait object
            # that served a short one first costs what a fresh one does
            if math.isnan(self._origin):
                self._origin = start
            grid = max(stop - min(self._origin, start), 1e-300) / FIRST
            self.spacing = grid if math.isinf(self.spacing) else max(self.spacing, grid)

    def _build(self, a: float, b: float) -> None:
        """Pieces over [a, b]: split at the gait's breakpoints, then into pieces of
        ``PIECE`` cells (at most ``WINDOW`` per stretch), each halved until happy."""
        # the breakpoints inside (a, b], b included: a span may end at one (its end value is
        # then read as the left limit)
        cuts = ([float(x) for x in self._breaks(a, math.nextafter(b, math.inf))]
                if self._breaks is not None and b > a else [])
        edges = [a] + [c for c in cuts if a < c < b] + [b]
        lefts, rights, brk = [], [], []
        for x0, x1 in zip(edges[:-1], edges[1:]):
            n = min(max(1, math.ceil((x1 - x0) / (PIECE * self.spacing) - 1e-9)), WINDOW)
            e = x0 + (x1 - x0) * np.arange(n + 1.0) / n      # x0 + (x1 - x0) i / n
            e[-1] = x1
            lefts.append(e[:-1])
            rights.append(e[1:])
            r = np.zeros(n, bool)
            r[-1] = True                # a breakpoint, or the window's end
            brk.append(r)
        # the window's ends are read as one-sided limits too (``BREAK_ULPS`` inside): a run
        # may start or end on a jump of l'' (a stroke run for whole periods), which is no event,
        # and a window's end is a join of pieces, which the solver takes as a breakpoint anyway
        first_left = True
        self._ahead = None
        lefts, rights, brk = map(np.concatenate, (lefts, rights, brk))
        if self._end_state is None and self._batch is not None and not (
                self.period or self.max_step):
            # array functions: (l, l') at the window's start and at the pieces' ends in one
            # call; ``_append`` takes the ends when no piece was split (the common window;
            # not where pieces are joined: their ends then move)
            ends = rights
            st = self._states([a] + ends.tolist())
            self._end_state, self._ahead = st[0], (ends, st[1:])
        elif self._end_state is None:
            self._end_state = self._states([a])[0]
        # the l'' that moves l by its own size over the window [m/s^2]: 64 eps of it is
        # below what the user's arithmetic resolves (a tanh step's flat tails are quantised)
        l0, v0 = np.abs(self._end_state)
        self._span = b - a
        self._quiet = _quiet(l0, v0, self._span)
        pieces = self._happy(lefts, rights, brk, first_left)
        if self.period or self.max_step:
            # a density the user asked for (a period's 1024 cells, or max_step's), not one
            # the function needs: join what one series holds (every join ends a segment)
            pieces = self._join(*pieces)
        self._append(*pieces)

    def _sample(self, a: NDArray, b: NDArray, bl: NDArray, br: NDArray,
                nodes: bool = True) -> tuple[NDArray, NDArray]:
        """l'' at each piece's nodes, shape (K, N + 1, nl) (at a only, (K, 1, nl), without
        ``nodes``), and its largest magnitude per linkage (``_gait.cheb_sample``)."""
        u = _U if nodes else _ONE
        if self._batch is None:
            out, top = _gait.cheb_sample(self._accel, a, b, bl, br, u, self.nl, BREAK_ULPS)
            self.calls += out.shape[0] * out.shape[1]
            return out, top
        # one call for every node of every piece, at the times ``cheb_sample`` reads (its
        # arithmetic, elementwise: the same floats), a start shared with the piece before
        # read again rather than copied (the same time: the same value)
        t = _gait.cheb_times(a, b, bl, br, u, BREAK_ULPS)
        out = self._batch[0](t.reshape(-1)).reshape(t.shape + (self.nl,))
        self.calls += t.size
        self.batches += 1
        top = np.abs(out).max(axis=(0, 1)) if t.size else np.zeros(self.nl)
        return out, top

    def _happy(self, a: NDArray, b: NDArray, br: NDArray, first_left: bool):
        """(a, b, right end a breakpoint, l'' series (K, N + 1, nl)) of the pieces, sorted;
        the unhappy ones halved until happy."""
        bl = np.concatenate(([first_left], br[:-1]))
        min_w = MIN_WIDTH * self.spacing
        wide = math.inf if self.period or self.max_step else WIDE
        parent = np.full(a.size, np.inf)        # the tail of the piece each one halves
        out, count = [], 0
        while a.size:
            count += a.size
            if count > MAX_PIECES:
                raise ValueError(
                    f'gait acceleration (l\'\') could not be resolved on [{float(a.min())!r}, '
                    f'{float(b.max())!r}] s ({MAX_PIECES} pieces): is it continuous there? '
                    'List the times where it jumps in breakpoints=')
            f, top = self._sample(a, b, bl, br)
            self.scale = np.maximum(self.scale, top)
            c, last, tail, _ = _gait.cheb_fit(f, _DCT, a, b,
                                              np.maximum(self.scale, self._quiet))
            if not out and last.max() <= N - 3:
                return a, b, br, c     # the common window: every piece resolved at once
            happy = last <= N - 3
            w = b - a
            tiny = w <= np.maximum(min_w, 64.0 * np.spacing(np.maximum(np.abs(a), np.abs(b))))
            # rounding of the user's arithmetic above ours: a tail at the noise floor that
            # halving no longer lowers (a smooth function's falls by orders at each halving)
            noise = (tail <= NOISE) & (tail > 0.25 * parent)
            for k in np.nonzero(~happy & ~noise & tiny)[0].tolist():
                self._refuse_jump(float(a[k]), float(b[k]), f[k])
            ok = happy | noise | tiny
            out.append((a[ok], b[ok], br[ok], c[ok]))
            split = ~ok
            if not split.any():
                break
            # halved (at a kink where there is one), in four where the series has not
            # begun to converge (``_gait.cheb_split``: one round fewer), unless the pieces
            # are to be joined (a density the user asked for: ``_join`` joins halves)
            a, b, bl, br, parent = _gait.cheb_split(a[split], b[split], f[split], _U,
                                                    bl[split], br[split], tail[split], wide)
        if len(out) == 1:
            return out[0]             # nothing split: still in order
        a, b, br, c = (np.concatenate(x) for x in zip(*out))
        order = np.argsort(a, kind='stable')
        return a[order], b[order], br[order], c[order]

    def _join(self, a: NDArray, b: NDArray, br: NDArray, c: NDArray):
        """Neighbouring pieces (no breakpoint between them) joined, pair by pair and again,
        where one series holds both: the pieces' series read at the joined piece's nodes
        (no call of the user's functions), kept when happy (``cheb_fit``) and equal to the
        pieces at their own nodes, the user's samples, to the rounding ``cheb_fit`` allows.
        What the sampling saw is kept; only the joins go."""
        scale = np.maximum(self.scale, self._quiet)
        while a.size > 1:
            k = np.arange(0, a.size - 1, 2)
            k = k[~br[k]]
            if not k.size:
                break
            lo, hi, mid = a[k], b[k + 1], b[k]
            t = _nodes(lo, hi)
            right = t > mid[:, None]
            # both pieces' series at the joined nodes, in one evaluation (pieces stacked)
            both = np.concatenate((k, k + 1))
            fb = _series_at(c[both], a[both], b[both], np.concatenate((t, t)))
            f = np.where(right[:, :, None], fb[k.size:], fb[:k.size])
            cc, last, _, tol = _gait.cheb_fit(np.ascontiguousarray(f), _DCT, lo, hi, scale)
            ok = last <= N - 3
            # the joined series at each piece's own nodes (one evaluation for both sides),
            # against the pieces there (their series at their own nodes: a fixed matrix)
            ts = np.concatenate((_nodes(a[k], b[k]), _nodes(a[k + 1], b[k + 1])), axis=1)
            off = np.abs(_series_at(cc, lo, hi, ts)
                         - np.concatenate(np.split(_at_own_nodes(c[both]), 2), axis=1))
            ok &= (off <= tol[:, None, :]).all(axis=(1, 2))
            if not ok.any():
                break
            keep = np.ones(a.size, bool)
            keep[k[ok] + 1] = False
            b = b.copy()
            b[k[ok]] = hi[ok]
            br = br.copy()
            br[k[ok]] = br[k[ok] + 1]
            c = c.copy()
            c[k[ok]] = cc[ok]
            a, b, br, c = a[keep], b[keep], br[keep], c[keep]
        return a, b, br, c

    def _refuse_jump(self, a: float, b: float, f: NDArray) -> None:
        """A narrowest piece [a, b] whose l'' still differs across it by a sizeable share of
        its scale: l'' jumps there (ValueError naming ``breakpoints=``, the jump's time to the
        float and the listed time nearest to it); a kink passes."""
        d = f[0] - f[N]
        j = int(np.argmax(np.abs(d)))
        if abs(d[j]) > _JUMP * self.scale[j] and abs(d[j]) > 1e-9 * self._quiet[j]:
            # the first float on the far side: halving [a, b] (tens of calls, once)
            lo, hi = a, b
            while lo < 0.5 * (lo + hi) < hi:
                mid = 0.5 * (lo + hi)
                v = float(np.asarray(self._accel(mid), dtype=float).reshape(-1)[j])
                self.calls += 1
                lo, hi = (mid, hi) if abs(v - f[N, j]) <= abs(v - f[0, j]) else (lo, mid)
            w = max(self._span, b - a)
            listed = (np.asarray(self._breaks(hi - w, hi + w), dtype=float)
                      if self._breaks is not None else np.zeros(0))
            if listed.size:
                near = float(listed[np.argmin(np.abs(listed - hi))])
                where = (f'the nearest listed breakpoint, {near!r} s, is {hi - near:.3g} s '
                         f'from it')
            else:
                where = f'none is listed within {w:.3g} s of it'
            raise ValueError(
                f"gait acceleration (l'') of linkage {j} jumps by {d[j]:.6g} m/s^2 at "
                f"t = {hi!r} s ({where}): a Custom gait must list the times where l'' jumps in "
                f"breakpoints=, each within {BREAK_ULPS} float spacings of its jump (l'' must "
                "be continuous between breakpoints)")

    def _append(self, a: NDArray, b: NDArray, br: NDArray, acc_c: NDArray) -> None:
        """The pieces' series of l and l' from the user's values at their starts, checked at
        their ends; the derivative series and the bounds."""
        if self._ahead is not None and (self._ahead[0] is b or
                                        np.array_equal(self._ahead[0], b)):
            st = np.concatenate((self._end_state[None], self._ahead[1]))
        else:
            st = self._states(b.tolist(), self._end_state)
        self._ahead = None
        coef, ncoef, bj, bs, rest, ends, bad = _gait.cheb_series(
            acc_c, a, b, st, L, np.asarray(self._quiet, dtype=float), self._span, _GRID)
        if bad is not None:
            _refuse_ends(a, b, ends, st[1:], *bad)
        if self._jerk is not None:
            self._check_jerk(a, b, coef, bj)
        self._end_state = st[-1]
        # (concatenations and leading-axis slices stay C-contiguous, as the struct reads them)
        if not self.knots.size:         # a fresh table: the window's arrays as they are
            self.knots = np.concatenate((a, b[-1:]))
            self.coef, self.ncoef, self.bj, self.bs, self.rest = coef, ncoef, bj, bs, rest
        else:
            self.knots = np.concatenate([self.knots[:-1], a, b[-1:]])
            self.coef = np.concatenate([self.coef, coef])
            self.ncoef = np.concatenate([self.ncoef, ncoef])
            self.bj = np.concatenate([self.bj, bj])
            self.bs = np.concatenate([self.bs, bs])
            self.rest = np.concatenate([self.rest, rest])
        if self.rest.size > self.keep and not self.period:
            drop = self.rest.size - self.keep
            self.knots, self.coef = self.knots[drop:], self.coef[drop:]
            self.ncoef, self.bj, self.bs = self.ncoef[drop:], self.bj[drop:], self.bs[drop:]
            self.rest = self.rest[drop:]

    def _check_jerk(self, a: NDArray, b: NDArray, coef: NDArray, bj: NDArray) -> None:
        """The pieces' l''' at their nodes within the user's ``jerk_bound``, beyond what the
        fit's rounding does to a derivative and 1e-9 of the bound (``_gait.cheb_jerk_check``:
        e, the rounding ``cheb_fit`` allows or the noise floor a piece may keep). A ValueError
        names the first piece where l''' exceeds it. ``bj`` (K, nl): the pieces' bounds of
        |l'''| (``cheb_series``), at least its values at the nodes."""
        # the bounds of every piece, then one check (a loop of comparisons, piece by piece,
        # was a quarter of a short run's cost); None: no bound there
        bound = np.empty((a.size, self.nl))
        if not callable(self._jerk):
            bound[:] = self._jerk           # one bound for all times (checked by the gait)
        for k in range(a.size if callable(self._jerk) else 0):
            got = self._jerk(float(a[k]), float(b[k]))
            bound[k] = math.inf if got is None else np.asarray(got, dtype=float)
        over = _gait.cheb_jerk_check(coef, a, b, bj, bound,
                                     np.maximum(self.scale, self._quiet), NOISE, _T_NODES)
        if over is not None:
            k, j, i, top = over
            t = _nodes(a[k:k + 1], b[k:k + 1])[0, i]
            raise ValueError(
                f"gait jerk_bound of linkage {j} on [{float(a[k])!r}, {float(b[k])!r}] s "
                f"is {float(bound[k, j]):.6g} m/s^3, but the gait's l''' reaches "
                f"{float(top):.6g} m/s^3 at t = {float(t)!r} s: "
                "jerk_bound must bound |l'''| (or be left out)")


def _quiet(l0: NDArray, v0: NDArray, h: float) -> NDArray:
    """The l'' [m/s^2] that moves l by its own size over a window of h [s], (|l| + |l'| h) /
    h^2 per linkage (0 for an empty window), at most the largest float: for a window of a few
    floats near 0 (a first step of 1e-200 s) it overflows, and an infinite scale made the
    checks' tolerances inf * 0 = NaN, which refused every value."""
    if not h > 0.0:
        return 0.0 * l0
    # in floats (a few linkages: numpy's error state and five array operations cost more);
    # an overflow to inf, or h^2 rounding to 0, gives the largest float, as ``nan_to_num`` did
    h2 = h * h
    out = []
    for l, v in zip(l0.tolist(), v0.tolist()):
        try:
            q = (l + v * h) / h2
        except ZeroDivisionError:
            q = _BIG
        out.append(_BIG if q != q else min(q, _BIG))
    return np.array(out)


def _nodes(a: NDArray, b: NDArray) -> NDArray:
    """The Chebyshev nodes of the pieces [a, b] (K,): times (K, N + 1), from b down to a."""
    return 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * _U[None, :]


def _series_at(c: NDArray, a: NDArray, b: NDArray, t: NDArray) -> NDArray:
    """Series ``c`` (K, n, nl) of the pieces [a, b] (K,) at the times ``t`` (K, M): values
    (K, M, nl). T_q(u) by doubling, T_(m+j) = 2 T_m T_j - T_(m-j) for j = 1 .. m at once
    (2 cos a cos b = cos(a + b) + cos(a - b): six blocks for 33 terms, where the three-term
    recurrence took 32 steps of two array operations each), then one batched product: 5-8x
    faster than numpy's ``chebval`` broadcast (whose Clenshaw steps run on (K, M, nl)
    arrays), which made joining a period's pieces most of a short run; the values agree with
    it to 1e-15 of their scale."""
    u = (2.0 * t - (a + b)[:, None]) / (b - a)[:, None]
    n = c.shape[1]
    tq = np.empty((n,) + u.shape)
    tq[0] = 1.0
    if n > 1:
        tq[1] = u
    m = 1
    while m < n - 1:
        hi = min(2 * m, n - 1)
        np.multiply(2.0 * tq[m], tq[1:hi - m + 1], out=tq[m + 1:hi + 1])
        tq[m + 1:hi + 1] -= tq[2 * m - hi:m][::-1]
        m = hi
    return np.matmul(np.moveaxis(tq, 0, 2), c)


def _at_own_nodes(c: NDArray) -> NDArray:
    """Series ``c`` (K, n <= L, nl) at their pieces' own nodes (``_nodes``' order): (K, N + 1,
    nl), through the fixed matrix T_q(u_i) = cos(pi i q / N)."""
    return np.matmul(_T_NODES[:, :c.shape[1]], c)


def _refuse_ends(a: NDArray, b: NDArray, ends: NDArray, user: NDArray, k: int, i: int,
                 j: int) -> None:
    """The series of piece k miss the user's l (i = 0) or l' (i = 1) of linkage j at the
    piece's end (``_gait.cheb_series``): the gait's length and velocity are not the
    integrals of its acceleration (its pieces would not join)."""
    name, what = (('velocity', "l' from the integral of l''") if i else
                  ('length', "l from the integral of l'"))
    raise ValueError(
        f'gait {name} of linkage {j} at t = {float(b[k])!r} s is {float(user[k, i, j])!r}, '
        f'but {what} from t = {float(a[k])!r} s gives {float(ends[k, i, j])!r}: a gait\'s '
        'length, velocity and acceleration must be each other\'s derivatives')
