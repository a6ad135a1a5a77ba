"""Piecewise gaits with exact breakpoints: `PiecewiseParabolic` strokes and `Spline`."""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import (CLOSURE_RTOL, BuiltinGait, _EMPTY, _finite, _increasing, _n_links,
                   _per_link, _positive)


class PiecewiseParabolic(BuiltinGait):
    """Bang-bang strokes: l'' piecewise constant between breakpoints, l and l' continuous.

    On piece k, t in [t_k, t_{k+1}), l'' = a_k, so l is an exact quadratic in t - t_k.

    Parameters
    ----------
    times : array_like, shape (K + 1,)
        Breakpoints t_0 < t_1 < ... < t_K [s]. When periodic the period is T = t_K - t_0.
    accelerations : array_like, shape (K,) or (K, n_links)
        l'' on each piece [m/s^2]; a 1-D array is shared by every linkage.
    l0, v0 : float or array_like, shape (n_links,)
        l(t_0) [m] and l'(t_0) [m/s].
    periodic : bool
        If True (default) the stroke repeats with period T for all t. It must close: the net
        velocity change sum_k a_k (t_{k+1} - t_k) and the net length change over one period must
        both be zero (relative tolerance `CLOSURE_RTOL`), else ValueError naming
        ``accelerations``. If False, l'' = 0 outside [t_0, t_K): l continues linearly with v0
        before t_0 and with the final velocity after t_K (it holds still when that is zero).

    Notes
    -----
    Pieces are closed on the left: at a breakpoint l'' takes the value of the next piece, also at
    the exact times that `breakpoints` returns for later periods.
    Velocities at breakpoints within `CLOSURE_RTOL` (relative) of zero are set to exactly zero so
    that rests are exact and `is_constant` can see them. `breakpoints` reports only the knots where
    l'' actually changes.
    """

    def __init__(self, times: ArrayLike, accelerations: ArrayLike, l0: ArrayLike,
                 v0: ArrayLike = 0.0, *, periodic: bool = True) -> None:
        tk = _increasing('times', times, min_size=2)
        n_pieces = tk.size - 1
        acc = _finite('accelerations', accelerations)
        if acc.ndim not in (1, 2) or acc.shape[0] != n_pieces:
            raise ValueError(f'accelerations must have shape ({n_pieces},) or ({n_pieces}, '
                             f'n_links) (one row per piece between times), got {acc.shape}')
        n = acc.shape[1] if acc.ndim == 2 else max(np.size(l0), np.size(v0))
        if n < 1:
            raise ValueError(f'accelerations must have at least one column, got {acc.shape}')
        self.n_links = int(n)
        self.times = tk
        self.accelerations = np.broadcast_to(acc.reshape(n_pieces, -1), (n_pieces, n)).copy()
        self.l0 = _per_link('l0', l0, n)
        self.v0 = _per_link('v0', v0, n)
        self.periodic = bool(periodic)
        self.period = float(tk[-1] - tk[0]) if self.periodic else None

        dt = np.diff(tk)[:, None]
        dv = self.accelerations * dt
        vel = self.v0 + np.vstack([np.zeros((1, n)), np.cumsum(dv, axis=0)])  # (K + 1, n)
        v_scale = np.abs(self.v0) + np.sum(np.abs(dv), axis=0)
        tiny = np.abs(vel) <= CLOSURE_RTOL * v_scale
        tiny[0] = False
        vel[tiny] = 0.0
        dl = vel[:-1] * dt + 0.5 * self.accelerations * dt ** 2
        lengths = self.l0 + np.vstack([np.zeros((1, n)), np.cumsum(dl, axis=0)])
        if self.periodic:
            self._check_closed(dv, v_scale, lengths[-1] - self.l0, float(tk[-1] - tk[0]))
        # Extended pieces: index 0 is (-inf, t_0), k + 1 is [t_k, t_k+1), K + 1 is [t_K, inf).
        zeros = np.zeros((1, n))
        self._anchor = np.concatenate([tk[:1], tk])
        self._l = np.vstack([lengths[:1], lengths])
        self._v = np.vstack([vel[:1], vel])
        self._a = np.vstack([zeros, self.accelerations, zeros])

    @staticmethod
    def _check_closed(dv: NDArray[np.float64], v_scale: NDArray[np.float64],
                      net_length: NDArray[np.float64], period: float) -> None:
        net_v = np.sum(dv, axis=0)
        if np.any(np.abs(net_v) > CLOSURE_RTOL * v_scale):
            raise ValueError('accelerations of a periodic stroke must give zero net velocity '
                             'change per period (sum a_k dt_k = 0), got '
                             f'{net_v.tolist()} m/s; a periodic stroke must close')
        if np.any(np.abs(net_length) > CLOSURE_RTOL * v_scale * period):
            raise ValueError('accelerations (with v0) of a periodic stroke must give zero net '
                             f'length change per period, got {net_length.tolist()} m; '
                             'a periodic stroke must close')

    @classmethod
    def stroke(cls, mean: ArrayLike, amplitude: ArrayLike, frequency: float, asymmetry: float,
               phase: ArrayLike = 0.0, *, n_links: int | None = None) -> PiecewiseParabolic:
        """A closed bang-bang stroke between ``mean - amplitude`` and ``mean + amplitude``.

        Extension takes the fraction r = ``asymmetry`` of the period T = 1 / ``frequency``:
        l'' = +a_e for r T / 2, then -a_e for r T / 2, with a_e = 8 amplitude / (r T)^2;
        contraction takes the rest, (1 - r) T, with -a_c then +a_c, a_c = 8 amplitude /
        ((1 - r) T)^2. l' = 0 at the ends of the stroke, where l = mean -/+ amplitude. This is
        the piecewise-parabolic actuation of crawling-robot studies (e.g. Behn et al. 2017).

        Parameters
        ----------
        mean, amplitude : float or array_like, shape (n_links,)
            Mean length and half stroke [m]; ``amplitude >= 0``.
        frequency : float
            Stroke frequency [Hz].
        asymmetry : float
            Fraction of the period spent extending, in the open interval (0, 1).
        phase : float or array_like, shape (n_links,)
            Phase of each linkage [rad], as ``Scallop``'s: linkage j is at its shortest when
            2 pi f t + phase_j = 0 (mod 2 pi), i.e. l_j(t) = stroke(t + phase_j / (2 pi f)).
            The knots of every linkage together are the breakpoints.
        n_links : int, optional
            Number of linkages when ``mean`` and ``amplitude`` are floats (default 1).
        """
        n = _n_links(n_links, max(np.size(mean), np.size(amplitude), np.size(phase)))
        mean_, amp = _per_link('mean', mean, n), _per_link('amplitude', amplitude, n)
        ph = _per_link('phase', phase, n)
        if np.any(amp < 0):
            raise ValueError(f'amplitude must be >= 0 m, got {amp.tolist()}')
        period = 1.0 / _positive('frequency', frequency, 'Hz')
        r = float(asymmetry)
        if not 0.0 < r < 1.0:
            raise ValueError(f'asymmetry must be in the open interval (0, 1), got {asymmetry!r}')
        t_ext, t_con = r * period, (1.0 - r) * period
        times = [0.0, 0.5 * t_ext, t_ext, t_ext + 0.5 * t_con, period]
        a_e, a_c = 8.0 * amp / t_ext ** 2, 8.0 * amp / t_con ** 2
        base = cls(times, np.vstack([a_e, -a_e, -a_c, a_c]), mean_ - amp, 0.0, periodic=True)
        shift = np.mod(ph / (2.0 * math.pi) * period, period)
        if not np.any(shift):
            return base
        return base._shifted(shift)

    def _shifted(self, shift: NDArray[np.float64]) -> PiecewiseParabolic:
        """This periodic stroke with linkage j advanced by ``shift[j]`` in [0, T) [s]:
        l_j(t) = self_j(t + shift_j), on the union of every linkage's knots."""
        T, t0 = self.period, float(self.times[0])
        knots = [np.mod(self.times[:-1] - t0 - s, T) for s in shift]
        times = np.unique(np.concatenate([[0.0, T], *knots]))
        times = times[np.concatenate([[True], np.diff(times) > 1e-12 * T])]   # merge ties
        times[-1] = T
        mid = 0.5 * (times[:-1] + times[1:])
        n = self.n_links
        acc = np.empty((mid.size, n))
        l0, v0 = np.empty(n), np.empty(n)
        for j in range(n):
            tau = np.mod(mid + shift[j], T) + t0
            acc[:, j] = self(tau)[2][:, j]
            at0 = self(np.array([t0 + shift[j]]))
            l0[j], v0[j] = at0[0][0, j], at0[1][0, j]
        return type(self)(times, acc, l0, v0, periodic=True)

    def _kind(self):
        from ..solvers._gait import table
        # one constant-acceleration piece per knot interval (jerk 0); l'' jumps where a does
        n = self.n_links
        if self.periodic:
            K = self.times.size - 1
            coef = np.stack([self._l[1:K + 1], self._v[1:K + 1], self._a[1:K + 1],
                             np.zeros((K, n))], axis=-1)
            a = self.accelerations
            jumps = np.any(a != np.roll(a, 1, axis=0), axis=1)
            return table(coef, knots=self.times, period=self.period, jumps=jumps)
        # extended pieces: (-inf, t_0), [t_k, t_k+1) for each k, [t_K, inf)
        coef = np.stack([self._l, self._v, self._a, np.zeros_like(self._a)], axis=-1)
        starts = np.concatenate([[-math.inf], self.times])
        jumps = np.concatenate([[False], np.any(self._a[1:] != self._a[:-1], axis=1)])
        return table(coef, starts=starts, anchors=self._anchor, jumps=jumps)


class Spline(BuiltinGait):
    """A C2 cubic spline through sampled lengths (scipy.interpolate.CubicSpline).

    Parameters
    ----------
    times : array_like, shape (N,)
        Strictly increasing sample times [s], N >= 2 (N >= 3 when periodic).
    lengths : array_like, shape (N,) or (N, n_links)
        Lengths at the sample times [m].
    periodic : bool
        If True, the spline uses ``bc_type='periodic'`` (C2 across the wrap), ``period =
        times[-1] - times[0]`` and ``lengths[0]`` must equal ``lengths[-1]``; times outside the
        range wrap. If False (default), the spline is *clamped*: l' = 0 at both ends
        (``bc_type='clamped'``), and outside [times[0], times[-1]) it holds the end lengths with
        l' = l'' = 0 (l'' is right-continuous: 0 at ``times[-1]`` itself). So l and l' are
        continuous everywhere, and l'' can jump only at the two ends, which `breakpoints`
        reports. Inside the range there are no breakpoints (l''' jumps at the knots, l'' does
        not).
    """

    def __init__(self, times: ArrayLike, lengths: ArrayLike, *, periodic: bool = False) -> None:
        self.periodic = bool(periodic)
        tk = _increasing('times', times, min_size=3 if self.periodic else 2)
        y = _finite('lengths', lengths)
        if y.ndim not in (1, 2) or y.shape[0] != tk.size or y.size == 0:
            raise ValueError(f'lengths must have shape ({tk.size},) or ({tk.size}, n_links) '
                             f'(one row per sample time), got {y.shape}')
        y = y.reshape(tk.size, -1).copy()
        if self.periodic:
            if not np.allclose(y[0], y[-1], rtol=1e-15, atol=1e-15):
                raise ValueError('lengths[0] must equal lengths[-1] for a periodic spline, got '
                                 f'{y[0].tolist()} and {y[-1].tolist()}')
            y[-1] = y[0]
        self.n_links = y.shape[1]
        self.times = tk
        self.lengths = y
        self.period = float(tk[-1] - tk[0]) if self.periodic else None
        from scipy.interpolate import CubicSpline   # lazy: keeps `import crawler_sim` light
        self._spline = CubicSpline(tk, y, bc_type='periodic' if self.periodic else 'clamped',
                                   extrapolate='periodic' if self.periodic else True)
        if self.periodic:
            self._jumps = _EMPTY
        else:
            end_acc = self._spline(tk[[0, -1]], 2)
            self._jumps = tk[[0, -1]][np.any(end_acc != 0, axis=1)]

    def _kind(self):
        from ..solvers._gait import table
        # scipy's pieces c[0] d^3 + c[1] d^2 + c[2] d + c[3] as (l0, v0, a0, jerk); l'' is
        # continuous at the interior knots (C2), so only the clamped ends can be breakpoints
        c = self._spline.c                                  # (4, N - 1, n_links)
        coef = np.stack([c[3], c[2], 2.0 * c[1], 6.0 * c[0]], axis=-1)
        tk = self.times
        if self.periodic:
            return table(coef, knots=tk, period=self.period,
                         jumps=np.zeros(tk.size - 1, dtype=bool))
        d = tk[-1] - tk[-2]
        last = coef[-1]
        end = last[:, 0] + d * (last[:, 1] + d * (0.5 * last[:, 2] + d * last[:, 3] / 6.0))
        hold = np.zeros((2, self.n_links, 4))
        hold[0, :, 0] = self.lengths[0]
        hold[1, :, 0] = end
        coef = np.concatenate([hold[:1], coef, hold[1:]])
        starts = np.concatenate([[-math.inf], tk])
        anchors = np.concatenate([[tk[0]], tk])
        jumps = np.zeros(starts.size, dtype=bool)
        jumps[1] = tk[0] in self._jumps
        jumps[-1] = tk[-1] in self._jumps
        return table(coef, starts=starts, anchors=anchors, jumps=jumps)

