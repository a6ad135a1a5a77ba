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

import numpy as np
from numpy.typing import NDArray

from .gaits import Gait
from .model import Crawler
from .solvers.exact import ExactSolver
from .solvers.segments import SegmentList

__all__ = ['DenseOutput']

_EPS = float(np.finfo(float).eps)
_GL_U, _GL_W = np.polynomial.legendre.leggauss(12)
_PROBE = 9          # interior points of each piece where a sign change of the power is sought
_ITERATIONS = 80    # Illinois steps (each at most halves the bracket, about every third)
_LEVELS = 60        # halvings of a quadrature piece
_RTOL = 1e-13       # a piece's quadrature error, relative to the integral of |power| over it


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
        template period's integral times the periods it has in [a, b]. The power is smooth
        between the pieces' boundaries (``breaks``); its sign changes there are found by
        probing each piece at 9 interior points and narrowing every change of sign (Illinois'
        regula falsi, to 1e-10 of [a, b]: the integral's error is |power'| times the square of
        that); between boundaries and roots, adaptive 12-point Gauss-Legendre quadrature (a
        piece is accepted when it agrees with the sum over its halves to 1e-13 of the integral
        of |power| over it, or over [a, b] in proportion to its length, else split). A double
        root the probes miss is a kink the splitting resolves.
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
        root, owner = self._roots(lo, hi, 1e-10 * (b - a))
        # each piece cut at its roots: the points sorted by piece, then time
        pts = np.concatenate([lo, root])
        own = np.concatenate([np.arange(lo.size), owner])
        order = np.lexsort((pts, own))
        pts, own = pts[order], own[order]
        last = np.append(own[1:] != own[:-1], True)       # a piece's last point
        ends = np.where(last, hi[own], np.append(pts[1:], 0.0))
        return self._quadrature(pts, ends, mult[own], float(b - a))

    def _eval(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """``power`` at times in any order and shape."""
        flat = t.ravel()
        order = np.argsort(flat, kind='stable')
        out = np.empty(flat.size)
        out[order] = self.power(flat[order])
        return out.reshape(t.shape)

    def _roots(self, lo: NDArray, hi: NDArray, xtol: float) -> tuple[NDArray, NDArray]:
        """The power's sign changes between 9 interior points of each piece, narrowed to
        ``xtol`` [s]: (times, index of their piece)."""
        u = 0.5 - 0.5 * np.cos((np.arange(_PROBE) + 0.5) * np.pi / _PROBE)
        x = lo[:, None] + (hi - lo)[:, None] * u
        P = self._eval(x)
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
            fm = self._eval(xm)
            same = (fm > 0) == (g1 > 0)
            # Illinois: the end kept twice in a row has its value halved
            k, nk = idx[same], idx[~same]
            f0[k] *= 0.5
            x0[nk], f0[nk] = x1[nk], f1[nk]
            x1[idx], f1[idx] = xm, fm
        return np.where(np.abs(f0) < np.abs(f1), x0, x1), r

    def _quadrature(self, lo: NDArray, hi: NDArray, mult: NDArray, span: float) -> float:
        """Sum of mult * integral of max(power, 0) over the pieces [lo, hi] (adaptive)."""
        total, size = 0.0, None
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
                P = self._eval(nodes)
                whole = r * (np.maximum(P[:, :n], 0.0) @ _GL_W)
                P = P[:, n:]
            else:
                P = self._eval(halves_at)
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
            done = (np.abs(whole - left - right) <= tol) | (hi - lo <= 64 * _EPS * np.abs(hi))
            total += float((mult[done] * (left + right)[done]).sum())
            s = ~done
            lo, hi, c, mult = lo[s], hi[s], c[s], mult[s]
            lo, hi = np.concatenate([lo, c]), np.concatenate([c, hi])
            mult = np.concatenate([mult, mult])
            whole = np.concatenate([left[s], right[s]])
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
