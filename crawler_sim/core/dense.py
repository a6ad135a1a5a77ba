"""Dense output of an exact run: its state at any time of the run, from the closed forms.

``simulate`` (method "exact") keeps the solver's closed-form pieces with the ``Trajectory``
it returns (``Trajectory.dense``), and ``Trajectory.state_at`` evaluates them: the same
pieces and the same evaluation (``ExactSolver.sample``) as a run sampled at those times, so
``state_at(t)`` equals ``simulate(..., t_eval=[..., t, ...])`` at t bit for bit. Inside a
block of periodically skipped periods a time is mapped onto the block's template period and
shifted by whole periods' displacements, as the samples of the run are; nothing is
interpolated and nothing is integrated again.

What it needs: the crawler, the gait the run used (kept alive by the ``Trajectory``) and the
pieces (one record per segment between events, about 100 bytes; a skipped block is stored
once). A built-in gait is immutable. A gait of Python functions (``gaits.Custom``, a user's
``Gait`` subclass) is read through the Chebyshev pieces it was sampled into during the run
(``solvers/proxy.py``), which the gait keeps: its functions are not called again, so a later
change of what they return does not change ``state_at``.
"""
from __future__ import annotations

import math
import pickle
from typing import Callable

import numpy as np
from numpy.typing import NDArray

from .gaits import Gait
from .model import Crawler
from .solvers.exact import ExactSolver
from .solvers.segments import SegmentList

__all__ = ['DenseOutput']

_EPS = float(np.finfo(float).eps)
_GL_U, _GL_W = np.polynomial.legendre.leggauss(12)
_PROBE = 25         # interior points of each piece where a sign change is sought (9 missed
#                     a root pair a few ms apart: 8 bodies, test_trajectory_dense)
_ITERATIONS = 80    # Illinois steps (each at most halves the bracket, about every third)
_LEVELS = 60        # halvings of a quadrature piece
_RTOL = 1e-13       # a piece's quadrature error, relative to the integral of |power| over it
_NOISE = 1e-9       # a disagreement this small (same measure) that halving no longer lowers
_CUBIC_INTEGRAL = np.array([1.0, 1 / 2, 1 / 3, 1 / 4])   # of b0 + b1 u + b2 u^2 + b3 u^3 on [0, 1]
# 4 interior points of [0, 1] (Chebyshev's) and the map from a cubic's values there to its
# coefficients b0..b3: values @ _CHEB4_TO_B
_CHEB4 = 0.5 - 0.5 * np.cos((np.arange(4) + 0.5) * np.pi / 4)
_CHEB4_TO_B = np.linalg.inv(np.vander(_CHEB4, 4, increasing=True)).T
_CHEB5 = np.append(_CHEB4, 0.5)          # and the middle: a check of the cubic through them
_SCALAR = 16       # up to this many cubics with a sign change: one at a time, in floats
_ONE_SIGN = np.array([-1.0, 1.0, 1.0, 1.0])            # |b1| + |b2| + |b3| - |b0| < 0: one sign
# Horner's rounding bound for a cubic at u in [0, 1]: |computed - exact| <= gamma_6 sum |b_i| u^i
# (6 roundings: three products, three sums), gamma_6 = 6 eps / (1 - 6 eps); a margin of 8/6
_HORNER = 8.0 * float(np.finfo(float).eps)


class DenseOutput:
    """The closed-form pieces of an exact run on ``span`` = (t0, t_end) [s].

    Parameters
    ----------
    crawler, gait : what the run simulated.
    segments : the run's ``SegmentList`` (``ExactSolver.segments`` with ``keep_history``).
    span : (t0, t_end) [s], the integrated interval; ``sample`` accepts times inside it.
    tol, max_step : the run's options (a solver is built with them to evaluate the pieces).

    Pickling: the pieces travel with the gait when the gait pickles; otherwise (a ``Custom``
    gait of lambdas) the copy holds only the reason, and its ``sample`` raises RuntimeError.
    """

    __slots__ = ('crawler', 'gait', 'segments', 'span', 'tol', 'max_step')

    def __init__(self, crawler: Crawler, gait: Gait, segments: SegmentList,
                 span: tuple[float, float], *, tol: float = 1e-13,
                 max_step: float | None = None) -> None:
        self.crawler = crawler
        self.gait = gait
        self.segments = segments
        self.span = (float(span[0]), float(span[1]))
        self.tol = float(tol)
        self.max_step = max_step

    def sample(self, times: NDArray[np.float64]) -> dict:
        """The exact states at ``times`` [s] (sorted, shape (N,), inside ``span``): the
        dict of ``ExactSolver.sample`` (x, v, friction, impulse, linkage_force, lengths,
        rates, contact, indeterminate; a leading axis of N)."""
        # a solver of the run's crawler and gait holding the run's pieces: its ``sample`` is
        # the one evaluation of the closed forms (a solver costs ~2 us; keeping one would keep
        # its compiled buffers alive with every Trajectory)
        solver = ExactSolver(self.crawler, self.gait, t0=self.span[0], tol=self.tol,
                             max_step=self.max_step, keep_segments=True)
        solver.segments = self.segments
        return solver.sample(np.ascontiguousarray(times, dtype=float))

    def breaks(self, a: float, b: float) -> NDArray[np.float64]:
        """The times in (a, b) [s] where the closed form changes (events, the gait's
        breakpoints, a sampled gait's piece joins), inside skipped periods too, and a
        ``PiecewiseCubic``'s joins (where l''' jumps): sorted."""
        segs = self.segments
        starts = segs.starts()
        _, row_of = segs.records()
        out = [starts]
        for k in np.flatnonzero(row_of < 0).tolist():
            blk = segs[k]
            # a time t of the block is its template period's t - j T, j = 1..n (``sample``)
            tpl = np.array([sg.t0 for sg in blk.template])
            j0 = max(1, int(math.floor((a - blk.template_t0) / blk.T)) - 1)
            j1 = min(blk.n, int(math.ceil((b - blk.template_t0) / blk.T)) + 1)
            if j1 >= j0:
                out.append(np.add.outer(np.arange(j0, j1 + 1) * blk.T, tpl).ravel())
        # where l''' jumps (a PiecewiseCubic's joins, the node's actuator pieces): the power's
        # slope jumps there, which the quadrature would resolve only by deep splitting
        starts = getattr(self.gait, 'starts', None)
        if isinstance(starts, np.ndarray):
            out.append(starts[(starts > a) & (starts < b)])
        t = np.concatenate(out)
        return np.unique(t[(t > a) & (t < b)])

    def power(self, times: NDArray[np.float64]) -> NDArray[np.float64]:
        """Actuator power sum_j linkage_force_j l_j' [W] at ``times`` (sorted, shape (N,))."""
        out = self.sample(times)
        return np.einsum('ij,ij->i', out['linkage_force'], out['rates'])

    def _blocks(self) -> list:
        """The run's blocks of skipped periods (``PeriodicBlock``), in time order."""
        _, row_of = self.segments.records()
        return [self.segments[k] for k in np.flatnonzero(row_of < 0).tolist()]

    def positive_work(self, a: float, b: float) -> float:
        """Integral of max(power, 0) over [a, b] [J], to ~1e-13 of the integral of |power|.

        The whole skipped periods inside [a, b] are the block's template period repeated (the
        same closed forms at the same template times: ``sample``), so each block counts its
        template period's integral times the periods it has in [a, b] (a period of a block
        the windows do not count whole is moved onto the template: ``_onto_templates``).

        The linkage forces are fitted per segment as affine in l'' (``_Forces``: exact within
        one contact mode, checked on the run's own states), so the power anywhere is one
        compiled gait evaluation. Where the gait is polynomial on a piece (``PiecewiseCubic``:
        the node's actuator; ``PiecewiseParabolic``) the power is a cubic there, integrated in
        closed form between its roots, each one found with a proof (``_cubic_work``,
        ``_cubic_roots01``), also where the fit does not hold (a hold, linkages in lockstep:
        the cubic from the run's own power). Elsewhere (smooth and sampled gaits) the power
        is smooth between the pieces' boundaries (``breaks``); its sign changes there are
        found by probing each piece at 25 interior points and narrowing every change of sign
        (Illinois' regula falsi, to 1e-10 of [a, b]: the integral's error is |power'| times
        the square of that); between boundaries and roots, adaptive 12-point Gauss-Legendre
        quadrature (a piece is accepted when it agrees with the sum over its halves to 1e-13
        of the integral of |power| over it, or over [a, b] in proportion to its length, else
        split). A double root the probes miss is a kink the splitting resolves, a root pair
        closer than the probes is not seen (that path is not proven). A segment the fit does
        not hold for (a hold, linkages moving in lockstep, a run of several gaits) is
        evaluated by ``sample``, as before.
        """
        windows, cuts = [], []         # (start, end, multiplier); the stretches counted
        for blk in self._blocks():
            j0 = max(1, math.ceil((a - blk.template_t0) / blk.T))
            j1 = min(blk.n, math.floor((b - blk.template_t0) / blk.T) - 1)
            if j1 >= j0 + 1:           # two periods or more: worth the template's quadrature
                windows.append((blk.template_t0, blk.template_t0 + blk.T, j1 - j0 + 1))
                cuts.append((blk.template_t0 + j0 * blk.T, blk.template_t0 + (j1 + 1) * blk.T))
        start = a
        for s, e in cuts:
            if s > start:
                windows.append((start, s, 1))
            start = max(start, e)
        if b > start:
            windows.append((start, b, 1))
        lo, hi, mult = [], [], []
        for s, e, m in windows:
            edges = np.concatenate([[s], self.breaks(s, e), [e]])
            lo.append(edges[:-1])
            hi.append(edges[1:])
            mult.append(np.full(edges.size - 1, float(m)))
        lo, hi, mult = map(np.concatenate, (lo, hi, mult))
        keep = hi > lo
        lo, hi, mult = lo[keep], hi[keep], mult[keep]
        if not lo.size:
            return 0.0
        lo, hi, mult = self._shorter(lo, hi, mult, b - a)
        self._onto_templates(lo, hi)
        # constant-jerk pieces (the node's actuator): the power is a cubic on each piece,
        # integrated in closed form; what that path cannot prove goes to the quadrature
        fit = _Forces.fit(self, lo, hi)
        done, work = self._cubic_work(lo, hi, fit)
        total = float(mult[done] @ work)
        rest = np.flatnonzero(~done)
        if not rest.size:
            return total
        lo, hi, mult = lo[rest], hi[rest], mult[rest]
        power = fit.power_of(rest)
        root, owner = self._roots(lo, hi, 1e-10 * (b - a), power)
        # each piece cut at its roots: the points sorted by piece, then time
        pts = np.concatenate([lo, root])
        own = np.concatenate([np.arange(lo.size), owner])
        order = np.lexsort((pts, own))
        pts, own = pts[order], own[order]
        last = np.append(own[1:] != own[:-1], True)       # a piece's last point
        ends = np.where(last, hi[own], np.append(pts[1:], 0.0))
        return total + self._quadrature(pts, ends, mult[own], float(b - a), power, own)

    def _shorter(self, lo: NDArray, hi: NDArray, mult: NDArray, span: float
                 ) -> tuple[NDArray, NDArray, NDArray]:
        """The pieces [lo, hi] [s] (and their ``mult``) of a gait that is not polynomial cut
        into equal parts of at most its period (1/16 of ``span`` [s] without one): the 25
        probes of a piece then see each period, as in a run with events every period (parts
        of 1/16 of a period made a sweep scene's figures 27 % slower). A segment of several
        seconds (a crawler sliding down a slope: no event for 20 s) was one piece: its roots
        were missed, a half of it whose 12 nodes all fell where the power is negative was
        taken as 0 (the positive work of a 20 s run half its true value) and others split
        without end on the power's rounding."""
        from .gaits.cubic import PiecewiseCubic
        from .gaits.piecewise import PiecewiseParabolic

        if isinstance(self.gait, (PiecewiseCubic, PiecewiseParabolic)):
            return lo, hi, mult              # closed form on pieces of any length
        period = getattr(self.gait, 'period', None)
        longest = period if period else span / 16
        k = np.maximum(np.ceil((hi - lo) / longest), 1.0).astype(np.int64)
        if (k == 1).all():
            return lo, hi, mult
        idx = np.repeat(np.arange(lo.size), k)
        j = np.arange(idx.size) - np.repeat(np.cumsum(k) - k, k)
        kk, w = k[idx].astype(float), (hi - lo)[idx]
        new_lo = lo[idx] + w * (j / kk)
        new_hi = np.where(j == k[idx] - 1, hi[idx], lo[idx] + w * ((j + 1) / kk))
        return new_lo, new_hi, mult[idx]

    def _onto_templates(self, lo: NDArray, hi: NDArray) -> None:
        """Pieces inside a block of skipped periods (a period the windows did not count as a
        whole) moved in place onto its template period, t - j T as ``sample`` maps a time:
        the same power, at times of the template's own segments."""
        _, row_of = self.segments.records()
        if (row_of >= 0).all():           # no block of skipped periods
            return
        item = np.clip(np.searchsorted(self.segments.starts(), 0.5 * (lo + hi), side='right')
                       - 1, 0, None)
        for k in np.unique(item[row_of[item] < 0]).tolist():
            blk = self.segments[k]
            sel = np.flatnonzero(item == k)
            j = np.clip(np.floor((0.5 * (lo[sel] + hi[sel]) - blk.t0) / blk.T).astype(int) + 1,
                        1, blk.n)
            lo[sel] -= j * blk.T
            hi[sel] -= j * blk.T

    def _cubic_work(self, lo: NDArray, hi: NDArray, fit: _Forces
                    ) -> tuple[NDArray, NDArray]:
        """Integral of max(power, 0) [J] over the pieces [lo, hi] [s] of a polynomial gait
        (``PiecewiseCubic``, ``PiecewiseParabolic``), in closed form: (which pieces it holds,
        their integrals, in order). The pieces the forces' fit holds for read the gait's
        coefficients (``_fitted_cubic_work``); the others (a hold, linkages in lockstep) are
        cubics all the same, found from the run's own power (``_sampled_cubic_work``): no
        piece of a polynomial gait is left to the probes and the quadrature.
        """
        from .gaits.cubic import PiecewiseCubic
        from .gaits.piecewise import PiecewiseParabolic

        done, work = self._fitted_cubic_work(lo, hi, fit)
        rest = np.flatnonzero(~done)
        if not rest.size or not isinstance(self.gait, (PiecewiseCubic, PiecewiseParabolic)):
            return done, work
        table, _ = self.segments.records()
        if len(table.gaits) != 1 or table.gaits[0] is not self.gait:
            return done, work           # a run of several gaits: the pieces may be others'
        ok, more = self._sampled_cubic_work(lo[rest], hi[rest])
        if not ok.any():
            return done, work
        full = np.zeros(lo.size)
        full[done] = work
        full[rest[ok]] = more[ok]
        done = done.copy()              # (``fit.ok`` itself)
        done[rest[ok]] = True
        return done, full[done]

    def _sampled_cubic_work(self, lo: NDArray, hi: NDArray) -> tuple[NDArray, NDArray]:
        """``_cubic_work`` of pieces [lo, hi] [s] of a polynomial gait that the forces' fit
        does not hold for: (the pieces it holds, their integrals [J]).

        Within one segment (one contact mode) the linkage forces are affine in l'' whatever
        the fit could tell (``_Forces``), and l'' is affine, l' quadratic in t on a piece of
        a constant-jerk gait (between its joins, which are among the pieces' ends): the power
        is a cubic there. Its coefficients come from the run's power at the 4 Chebyshev
        points of [0, 1] (``sample``, the closed form); a fifth value, at the middle, must
        agree with the cubic to 1e-12 of the piece's largest |power| (else the piece is left
        to the quadrature: the assumption did not hold).
        """
        h = hi - lo
        P = self._eval(lo[:, None] + h[:, None] * _CHEB5)
        b = P[:, :4] @ _CHEB4_TO_B
        mid = b[:, 0] + 0.5 * (b[:, 1] + 0.5 * (b[:, 2] + 0.5 * b[:, 3]))
        ok = np.abs(mid - P[:, 4]) <= 1e-12 * np.abs(P).max(axis=1) + 1e-300
        work = np.zeros(lo.size)
        if ok.any():
            work[ok] = h[ok] * _positive_cubic(b[ok])
        return ok, work

    def _fitted_cubic_work(self, lo: NDArray, hi: NDArray, fit: _Forces
                           ) -> tuple[NDArray, NDArray]:
        """``_cubic_work`` of the pieces the forces' fit holds for: (those pieces, their
        integrals [J]).

        With the linkage forces affine in l'' on a piece (``_Forces``), a piece where l' is
        quadratic and l'' affine (``PiecewiseCubic``: its coefficients read directly) or l'
        affine and l'' constant (``PiecewiseParabolic``: four fitted powers) has a cubic power
        G . l'. Its roots in the piece: ``_cubic_roots01`` (each one found, bracketed and
        narrowed to a few ulps of the piece, with the argument why).
        """
        from .gaits.cubic import PiecewiseCubic
        from .gaits.piecewise import PiecewiseParabolic

        none = np.zeros(lo.size, dtype=bool), np.empty(0)
        g = self.gait
        done = fit.ok
        if fit.gait is not g or not done.any():
            return none
        if isinstance(g, PiecewiseParabolic):
            # l'' constant on a piece, l' affine: the power is affine there (a cubic of
            # degree one); its coefficients from the fitted power at 4 interior points
            lo, hi = lo[done], hi[done]
            h = hi - lo
            P = fit.power_of(np.flatnonzero(done))(lo[:, None] + h[:, None] * _CHEB4,
                                                    np.arange(lo.size))
            return done, h * _positive_cubic(P @ _CHEB4_TO_B)
        if not isinstance(g, PiecewiseCubic):
            return none
        starts, anchors, coef = g.as_arrays()   # (the actuator's runs: its own arrays)
        seg = fit.seg
        if not done.all():                # (the node's runs: every piece fitted)
            lo, hi, seg = lo[done], hi[done], seg[done]
        A, c = fit.A[seg], fit.c[seg]     # G = l'' @ A + c
        piece = np.clip(np.searchsorted(starts, 0.5 * (lo + hi), side='right') - 1, 0, None)
        d = (lo - anchors[piece])[:, None]
        v0, a0, jerk = (coef[:, :, col][piece] for col in (1, 2, 3))
        v = v0 + d * (a0 + 0.5 * d * jerk)               # l', l'' at lo; l''' = jerk
        acc = a0 + d * jerk
        g0 = np.einsum('ni,nim->nm', acc, A) + c         # G at lo and its slope [N, N/s]
        g1 = np.einsum('ni,nim->nm', jerk, A)
        h = hi - lo
        # P(lo + u h) = b0 + b1 u + b2 u^2 + b3 u^3, u in [0, 1]
        b = np.empty((lo.size, 4))
        dot = np.einsum
        b[:, 0] = dot('nm,nm->n', g0, v)
        b[:, 1] = h * (dot('nm,nm->n', g0, acc) + dot('nm,nm->n', g1, v))
        b[:, 2] = h * h * (0.5 * dot('nm,nm->n', g0, jerk) + dot('nm,nm->n', g1, acc))
        b[:, 3] = h ** 3 * 0.5 * dot('nm,nm->n', g1, jerk)
        return done, h * _positive_cubic(b)

    def _eval(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``power`` at times in any order and shape."""
        flat = t.ravel()
        order = np.argsort(flat, kind='stable')
        out = np.empty(flat.size)
        out[order] = self.power(flat[order])
        return out.reshape(t.shape)

    def _roots(self, lo: NDArray, hi: NDArray, xtol: float, power: Callable
               ) -> tuple[NDArray, NDArray]:
        """The power's sign changes between 25 interior points of each piece, narrowed to
        ``xtol`` [s]: (times, index of their piece). ``power(t, piece)``: the power at times
        ``t`` (n, k) of the pieces ``piece`` (n,)."""
        u = 0.5 - 0.5 * np.cos((np.arange(_PROBE) + 0.5) * np.pi / _PROBE)
        x = lo[:, None] + (hi - lo)[:, None] * u
        P = power(x, np.arange(lo.size))
        sign = P > 0
        r, c = np.nonzero(sign[:, 1:] != sign[:, :-1])
        x0, x1 = x[r, c], x[r, c + 1]
        f0, f1 = P[r, c], P[r, c + 1]
        for _ in range(_ITERATIONS):
            live = (np.abs(x1 - x0) > xtol) & (f0 != 0) & (f1 != 0)
            if not live.any():
                break
            idx = np.flatnonzero(live)
            a0, a1, g0, g1 = x0[idx], x1[idx], f0[idx], f1[idx]
            xm = a1 - g1 * (a1 - a0) / (g1 - g0)
            bad = ~((xm > np.minimum(a0, a1)) & (xm < np.maximum(a0, a1)))
            xm[bad] = 0.5 * (a0 + a1)[bad]            # the secant left the bracket
            fm = power(xm[:, None], r[idx])[:, 0]
            same = (fm > 0) == (g1 > 0)
            # Illinois: the end kept twice in a row has its value halved
            k, nk = idx[same], idx[~same]
            f0[k] *= 0.5
            x0[nk], f0[nk] = x1[nk], f1[nk]
            x1[idx], f1[idx] = xm, fm
        return np.where(np.abs(f0) < np.abs(f1), x0, x1), r

    def _quadrature(self, lo: NDArray, hi: NDArray, mult: NDArray, span: float,
                    power: Callable, own: NDArray) -> float:
        """Sum of mult * integral of max(power, 0) over the pieces [lo, hi] (adaptive);
        ``power(t, own)`` as in ``_roots``, ``own`` each piece's index there."""
        total, size = 0.0, None
        parent = np.full(lo.size, np.inf)   # each piece's parent's disagreement
        n = _GL_U.size
        w2 = np.concatenate([_GL_W, _GL_W])
        whole = None
        for _ in range(_LEVELS):
            if not lo.size:
                break
            r, c = 0.5 * (hi - lo), 0.5 * (hi + lo)
            halves_at = np.concatenate([(c - 0.5 * r)[:, None] + 0.5 * r[:, None] * _GL_U,
                                        (c + 0.5 * r)[:, None] + 0.5 * r[:, None] * _GL_U],
                                       axis=1)
            if whole is None:          # later levels: the parent's halves are the pieces
                nodes = np.concatenate([c[:, None] + r[:, None] * _GL_U, halves_at], axis=1)
                P = power(nodes, own)
                whole = r * (np.maximum(P[:, :n], 0.0) @ _GL_W)
                P = P[:, n:]
            else:
                P = power(halves_at, own)
            left = 0.5 * r * (np.maximum(P[:, :n], 0.0) @ _GL_W)
            right = 0.5 * r * (np.maximum(P[:, n:], 0.0) @ _GL_W)
            scale = 0.5 * r * (np.abs(P) @ w2)
            if size is None:         # the integral of |power| over [a, b]: the global scale
                size = float((mult * scale).sum())
            # a piece's share of the global tolerance, or its own where it is larger (the
            # values' rounding keeps a piece of tiny power from agreeing to its own 1e-13),
            # and never below the rounding of its values (64 eps of their largest); a piece
            # of a block's template stands for mult periods: its share too
            tol = np.maximum(_RTOL * np.maximum(scale, size * (hi - lo) / span),
                             64 * _EPS * np.abs(P).max(axis=1) * (hi - lo))
            err = np.abs(whole - left - right)
            # the noise of the power's own evaluation (a gait's values at |t| of seconds carry
            # ~1e-12 of rounding, a Scallop's l'' at 8 s): a piece whose disagreement is that
            # small and no longer falls as halving lowers a smooth piece's (by 2^-24) or a
            # kinked one's (by 4) is done; else such pieces split forever (a 12 s slide down
            # a slope: 2^k pieces, no end)
            noise = (err <= _NOISE * scale) & (err >= 0.5 * parent)
            done = (err <= tol) | noise | (hi - lo <= 64 * _EPS * np.abs(hi))
            total += float((mult[done] * (left + right)[done]).sum())
            s = ~done
            lo, hi, c, mult, own = lo[s], hi[s], c[s], mult[s], own[s]
            lo, hi = np.concatenate([lo, c]), np.concatenate([c, hi])
            mult, own = np.concatenate([mult, mult]), np.concatenate([own, own])
            whole = np.concatenate([left[s], right[s]])
            parent = np.concatenate([err[s], err[s]])
        if lo.size:
            raise RuntimeError('positive_work: the quadrature did not converge (report this run)')
        return total

    def __reduce__(self):
        try:
            blob = pickle.dumps((self.gait, self.segments), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:    # a gait of lambdas or closures: not picklable
            reason = (f'its gait ({type(self.gait).__name__}) could not be pickled: '
                      f'{type(exc).__name__}: {exc}')
            return (_Unavailable, (reason,))
        return (_restore, (self.crawler, blob, self.span, self.tol, self.max_step))


def _restore(crawler: Crawler, blob: bytes, span: tuple[float, float], tol: float,
             max_step: float | None) -> DenseOutput:
    gait, segments = pickle.loads(blob)
    return DenseOutput(crawler, gait, segments, span, tol=tol, max_step=max_step)


class _Forces:
    """The linkage forces of each piece of a run as an affine function of l'':
    G = l'' @ A + c [N] (``A`` (m, m) [kg], ``c`` (m,) [N], m = n_links).

    Within one segment (one contact mode) sliding bodies' friction is constant and the stuck
    ones follow the gait, so the forces are affine in l''. A and c are fitted per segment from
    the run's own states (``DenseOutput.sample``) at n_links + 3 interior times, two more than
    they need; a segment counts (``ok``) only when the fit reproduces every one of them to
    1e-13 of the forces and l'' spans its space there (not a hold, not linkages in lockstep):
    otherwise its pieces are evaluated by ``sample``. With the fit, the power anywhere in a
    piece is one compiled gait evaluation (l', l'') and no solver.
    """

    __slots__ = ('dense', 'gait', 'cg', 'ok', 'seg', 'A', 'c')

    @classmethod
    def fit(cls, dense: DenseOutput, lo: NDArray, hi: NDArray) -> _Forces:
        """The fit for the pieces [lo, hi] [s] (each inside one segment: the segments'
        starts are among the pieces' boundaries)."""
        from .gaits.piecewise import PiecewiseParabolic

        self = cls()
        self.dense, self.gait, self.ok = dense, None, np.zeros(lo.size, dtype=bool)
        table, row_of = dense.segments.records()
        if len(table.gaits) != 1:         # a run of several gaits: sample it
            return self
        g = table.gaits[0]
        m = g.n_links
        seg_starts = dense.segments.starts()
        seg = np.clip(np.searchsorted(seg_starts, 0.5 * (lo + hi), side='right') - 1, 0, None)
        first, last = int(seg.min()), int(seg.max())   # the segments of the pieces
        used = np.arange(first, last + 1)
        # a block of skipped periods is no segment of its own (its pieces were moved onto
        # the template): not sampled, which would map every time through the block
        used = used[row_of[used] >= 0]
        if not used.size:
            return self
        s0 = seg_starts[used]
        s1 = np.append(seg_starts, dense.span[1])[used + 1]
        # n_links + 3 interior times of each segment, clustered to neither end
        k = m + 3
        frac = 0.5 - 0.5 * np.cos((np.arange(k) + 0.5) * np.pi / k)
        t = s0[:, None] + (s1 - s0)[:, None] * frac
        good = np.diff(t, axis=1).min(axis=1) > 0      # not a segment of a few floats
        flat = t.ravel()                  # sorted: the segments are disjoint and in order
        G = dense.sample(flat)['linkage_force'].reshape(used.size, k, m)
        cg = g.compiled()
        with cg.lock:
            ldd = cg.values(flat)[2].reshape(used.size, k, m)
        # A rank-deficient l'' is refused, unless the gait's l'' is constant between its
        # breakpoints (bang-bang strokes: a segment does not straddle one), where the fit
        # need only hold at that one l''
        const = isinstance(g, PiecewiseParabolic)
        if const:                         # and no breakpoint inside the segment after all
            bp = np.asarray(g.breakpoints(float(s0[0]), float(s1[-1])), dtype=float)
            const = np.searchsorted(bp, s0, 'right') == np.searchsorted(bp, s1, 'left')
        if m == 1:                        # least squares of a line, in closed form
            x, y = ldd[:, :, 0], G[:, :, 0]
            xm, ym = x.mean(axis=1), y.mean(axis=1)
            dx = x - xm[:, None]
            sxx = np.einsum('sk,sk->s', dx, dx)
            live = sxx > 1e-16 * (k * xm * xm + sxx)
            good &= live | const
            a = np.where(live, np.einsum('sk,sk->s', dx, y) / np.where(live, sxx, 1.0), 0.0)
            A, c = a[:, None, None], (ym - a * xm)[:, None]
        else:                             # through the SVD (batched)
            X = np.concatenate([ldd, np.ones((used.size, k, 1))], axis=2)
            U, S, Vt = np.linalg.svd(X, full_matrices=False)
            live = S > 1e-8 * S[:, :1]
            good &= live[:, -1] | const
            Sinv = np.where(live, 1.0 / np.where(live, S, 1.0), 0.0)
            W = np.einsum('sji,sj,skj,skm->sim', Vt, Sinv, U, G)     # (segments, m + 1, m)
            A, c = W[:, :m, :], W[:, m, :]
        resid = np.abs(np.einsum('ski,sim->skm', ldd, A) + c[:, None, :] - G).max(axis=(1, 2))
        good &= resid <= 1e-13 * np.maximum(np.abs(G).max(axis=(1, 2)), 1e-300)
        self.gait, self.cg, self.A, self.c = g, cg, A, c
        # each piece's row among the fitted segments; a piece in a block matches none
        if used.size == last - first + 1:              # no block among them
            self.seg = seg - first
            self.ok = good[self.seg]
        else:
            self.seg = np.minimum(np.searchsorted(used, seg), used.size - 1)
            self.ok = good[self.seg] & (used[self.seg] == seg)
        return self

    def power_of(self, rows: NDArray) -> Callable:
        """``power(t, piece)`` [W] for the fitted pieces ``rows``: t (n, k) [s] in pieces
        ``rows[piece]`` (n,); fitted pieces from the gait, the others from ``sample``."""
        ok = self.ok[rows]
        seg = self.seg[rows] if self.gait is not None else None

        def power(t: NDArray, piece: NDArray) -> NDArray:
            model = ok[piece]
            if model.all():
                return self._power(t, seg[piece])
            out = np.empty(t.shape)
            if model.any():
                out[model] = self._power(t[model], seg[piece[model]])
            out[~model] = self.dense._eval(t[~model])
            return out
        return power

    def _power(self, t: NDArray, seg: NDArray) -> NDArray:
        """(l'' @ A + c) . l' at times t (n, k) [s] of the segments ``seg`` (n,) [W]."""
        n, k = t.shape
        with self.cg.lock:
            _, ld, ldd = self.cg.values(t.ravel())
        m = ld.shape[1]
        G = np.einsum('nki,nim->nkm', ldd.reshape(n, k, m), self.A[seg]) + self.c[seg][:, None]
        return np.einsum('nkm,nkm->nk', G, ld.reshape(n, k, m))


def _poly(b: NDArray, u: NDArray) -> NDArray:
    """b0 + b1 u + b2 u^2 + b3 u^3 for each row of ``b`` (n, 4) at ``u`` (n, k)."""
    return b[:, :1] + u * (b[:, 1:2] + u * (b[:, 2:3] + u * b[:, 3:4]))


def _poly_integral(b: NDArray, u: NDArray) -> NDArray:
    """The integral of ``_poly`` from 0 to ``u`` (n, k)."""
    return u * (b[:, :1] + u * (b[:, 1:2] / 2 + u * (b[:, 2:3] / 3 + u * b[:, 3:4] / 4)))


def _positive_cubic(b: NDArray) -> NDArray:
    """Integral over [0, 1] of max(0, b0 + b1 u + b2 u^2 + b3 u^3) for each row of ``b``."""
    # |P(u) - b0| <= |b1| + |b2| + |b3| on [0, 1]: most pieces keep b0's sign throughout
    # and their integral is the whole cubic's (or nothing)
    mixed = np.flatnonzero(np.abs(b) @ _ONE_SIGN >= 0.0)
    work = b @ _CUBIC_INTEGRAL
    work[b[:, 0] <= 0] = 0.0
    if 0 < mixed.size <= _SCALAR:         # a few: in floats, without numpy's per-call cost
        for i in mixed.tolist():
            work[i] = _positive_cubic1(*b[i].tolist())
    elif mixed.size:
        bm = b[mixed]
        # cut at the roots and at the knots between which they were sought (a knot within
        # the rounding of a root is where the sign changes)
        pts = np.concatenate([np.zeros((mixed.size, 1)),
                              np.sort(np.concatenate(_cubic_roots01(bm), axis=1), axis=1),
                              np.ones((mixed.size, 1))], axis=1)
        positive = _poly(bm, 0.5 * (pts[:, :-1] + pts[:, 1:])) > 0
        F = _poly_integral(bm, pts)
        work[mixed] = np.where(positive, F[:, 1:] - F[:, :-1], 0.0).sum(axis=1)
    return work


def _positive_cubic1(b0: float, b1: float, b2: float, b3: float) -> float:
    """``_positive_cubic`` of one cubic, in floats: the same steps as ``_cubic_roots01``."""
    def f(u: float) -> float:
        return b0 + u * (b1 + u * (b2 + u * b3))

    def sign(u: float) -> int:
        # the value's sign beyond the rounding of its evaluation, else 0
        v = f(u)
        err = _HORNER * (abs(b0) + u * (abs(b1) + u * (abs(b2) + u * abs(b3))))
        return 1 if v > err else (-1 if v < -err else 0)

    def integral(u: float) -> float:
        return u * (b0 + u * (b1 / 2 + u * (b2 / 3 + u * b3 / 4)))

    qa, qb, qc = 3 * b3, 2 * b2, b1
    disc = qb * qb - 4 * qa * qc
    knots = [0.0, 1.0]
    if disc > 0:
        q = -0.5 * (qb + math.copysign(math.sqrt(disc), qb))
        for r in ((q / qa) if qa else None, (qc / q) if q else None):
            if r is not None and 0 < r < 1:
                knots.append(r)
    if qa and 0 < -qb / (2 * qa) < 1:
        knots.append(-qb / (2 * qa))        # the derivative's vertex
    knots.sort()
    pts = [0.0]
    for x0, x1 in zip(knots, knots[1:]):
        s0, s1 = sign(x0), sign(x1)
        if x1 > x0 and s0 * s1 < 0:
            f0, f1 = f(x0), f(x1)
            lo, hi, up = x0, x1, s1 > 0
            x = (x0 * f1 - x1 * f0) / (f1 - f0)
            if not lo < x < hi:
                x = 0.5 * (lo + hi)
            for _ in range(_ITERATIONS):
                fx = f(x)
                if fx == 0:
                    break
                if (fx < 0) == up:
                    lo = x
                else:
                    hi = x
                dfx = b1 + x * (2 * b2 + 3 * x * b3)
                step = x - fx / dfx if dfx else lo - 1.0
                new = step if lo < step < hi else 0.5 * (lo + hi)
                done = abs(new - x) <= 4 * _EPS or hi - lo <= 4 * _EPS
                x = new
                if done:
                    break
            pts.append(x)
    # cut at the knots too (a knot within the rounding of a root is where the sign changes)
    pts = sorted(pts + knots)
    return sum(integral(e) - integral(s) for s, e in zip(pts, pts[1:])
               if f(0.5 * (s + e)) > 0)


def _cubic_roots01(b: NDArray) -> tuple[NDArray, NDArray]:
    """The sign changes of each cubic b0 + b1 u + b2 u^2 + b3 u^3 (rows of ``b``) in (0, 1),
    shape (n, 4), 1.0 where there is none (an empty interval at the end), and the knots they
    were sought between, (n, 3) (1.0 where none): cut at both, the cubic keeps one sign
    between consecutive cuts.

    Why every sign change is found, once: the derivative 3 b3 u^2 + 2 b2 u + b1 vanishes only
    at its roots (the quadratic formula without cancellation), which with its vertex
    -b2 / (3 b3) (where the two merge, when the discriminant rounds to <= 0; a knot more never
    hurts) cut [0, 1] into at most four stretches. On each the cubic is monotone (to within
    the rounding of those roots: where the discriminant is near 0 the cubic is flat to third
    order there), so it has a root in a stretch if and only if its values at the ends have
    opposite signs, and then exactly one. A value within the rounding of its evaluation
    (Horner's bound, ``_HORNER`` times sum |b_i| u^i) counts as no sign: a root at that
    knot (a root at a piece's end) or a near-double root whose dip below zero is under that
    rounding, worth less than it times the stretch. Each root is bracketed by its stretch and
    narrowed by Newton's method from the secant point, kept inside the bracket (bisection
    where a step leaves it: at most ~52 halvings), until the step or the bracket is a few
    ulps of 1: the integral's error is that squared times |P'|.
    """
    n = b.shape[0]
    # derivative 3 b3 u^2 + 2 b2 u + b1: roots by the cancellation-free quadratic formula
    qa, qb, qc = 3 * b[:, 3], 2 * b[:, 2], b[:, 1]
    disc = qb * qb - 4 * qa * qc
    with np.errstate(divide='ignore', invalid='ignore'):
        q = -0.5 * (qb + np.copysign(np.sqrt(np.maximum(disc, 0.0)), qb))
        crit = np.stack([q / qa, qc / q, -qb / (2 * qa)], axis=1)
    live = np.concatenate([np.repeat((disc > 0)[:, None], 2, axis=1),
                           np.ones((n, 1), dtype=bool)], axis=1)
    crit = np.where(live & (crit > 0) & (crit < 1), crit, 1.0)
    knots = np.concatenate([np.zeros((n, 1)), np.sort(crit, axis=1), np.ones((n, 1))], axis=1)
    f = _poly(b, knots)
    err = _HORNER * _poly(np.abs(b), knots)
    sgn = np.where(f > err, 1, np.where(f < -err, -1, 0))
    x0, x1, f0, f1 = knots[:, :-1], knots[:, 1:], f[:, :-1], f[:, 1:]
    out = np.ones((n, 4))
    r, c = np.nonzero((x1 > x0) & (sgn[:, :-1] * sgn[:, 1:] < 0))
    if not r.size:
        return out, crit
    lo, hi, flo, fhi, br = x0[r, c], x1[r, c], f0[r, c], f1[r, c], b[r]
    x = (lo * fhi - hi * flo) / (fhi - flo)          # the secant point
    x = np.where((x > lo) & (x < hi), x, 0.5 * (lo + hi))
    up = sgn[r, c + 1] > 0                           # P rises through the root
    for _ in range(_ITERATIONS):
        fx = br[:, 0] + x * (br[:, 1] + x * (br[:, 2] + x * br[:, 3]))
        dfx = br[:, 1] + x * (2 * br[:, 2] + 3 * x * br[:, 3])
        right = (fx < 0) == up                       # the root lies right of x
        lo, hi = np.where(right, x, lo), np.where(right, hi, x)
        with np.errstate(divide='ignore', invalid='ignore'):
            step = x - fx / dfx
        new = np.where((step > lo) & (step < hi), step, 0.5 * (lo + hi))
        new[fx == 0] = x[fx == 0]
        moved = (np.abs(new - x) > 4 * _EPS) & (hi - lo > 4 * _EPS)
        x = new
        if not moved.any():
            break
    out[r, c] = x
    return out, crit


class _Unavailable:
    """A pickled ``DenseOutput`` whose gait could not travel: ``sample`` says why."""

    __slots__ = ('reason',)

    def __init__(self, reason: str) -> None:
        self.reason = reason

    @property
    def span(self) -> tuple[float, float]:
        return self.sample(np.empty(0))

    def sample(self, times: NDArray[np.float64]) -> dict:
        raise RuntimeError(f'this Trajectory was unpickled without its dense output: '
                           f'{self.reason}; state_at needs the gait the run used (simulate '
                           'again, or sample the run with simulate(..., t_eval=...))')

    def __reduce__(self):
        return (_Unavailable, (self.reason,))
