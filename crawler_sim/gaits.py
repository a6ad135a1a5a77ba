"""Gaits: the imposed linkage lengths l_j(t) and their first two time derivatives.

Every gait returns ``(l, l', l'')`` in metres, m/s and m/s^2. For a float time each array has
shape ``(n_links,)``; the built-in gaits also take an array of times of shape ``(N,)`` and then
return arrays of shape ``(N, n_links)``. ``l_j = x_{j+1} - x_j`` (see docs/ARCHITECTURE.md).

Gaits in this module:

- `Sinusoid`: one harmonic per linkage, a phase lag makes a travelling wave.
- `Fourier`: a truncated Fourier series per linkage.
- `Scallop`: a smooth (analytic) stroke with a fast and a slow phase, set by ``asymmetry``.
- `PiecewiseParabolic`: bang-bang strokes, piecewise-constant l'' (exact piecewise quadratics).
- `Spline`: a C2 cubic spline through sampled lengths.
- `Cubic`: one constant-jerk piece (the node's actuator model).
- `Custom`: user callables of one float time (not vectorised).
"""
from __future__ import annotations

import math
from bisect import bisect_right
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['Gait', 'Custom', 'Sinusoid', 'Fourier', 'Scallop', 'PiecewiseParabolic', 'Spline',
           'Cubic', 'PiecewiseCubic']

Triple = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]

_EMPTY = np.empty(0)

# Relative tolerance on the closure of a periodic PiecewiseParabolic stroke, and on the velocities
# at breakpoints that are snapped to exactly zero (so rests are exact).
CLOSURE_RTOL = 1e-12


def _per_link(name: str, value: ArrayLike, n: int | None) -> NDArray[np.float64]:
    """Broadcast a scalar or a per-linkage list to shape (n,), checking it is finite."""
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.ndim != 1:
        raise ValueError(f'{name} must be a float or a 1-D list, got shape {arr.shape}')
    if n is not None and arr.size not in (1, n):
        raise ValueError(f'{name} must have 1 or {n} entries (one per linkage), got {arr.size}')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name} must be finite, got {arr.tolist()}')
    return arr if n is None or arr.size == n else np.full(n, arr[0])


def _positive(name: str, value: float, unit: str) -> float:
    """Return ``value`` as a float, checking it is finite and > 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite float > 0 {unit}, got {value!r}') from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f'{name} must be finite and > 0 {unit}, got {value!r}')
    return v


def _n_links(n_links: int | None, inferred: int) -> int:
    """Number of linkages: ``n_links`` when given (an int >= 1), otherwise ``inferred``."""
    if n_links is None:
        return int(inferred)
    if isinstance(n_links, bool) or int(n_links) != n_links or n_links < 1:
        raise ValueError(f'n_links must be an integer >= 1, got {n_links!r}')
    return int(n_links)


def _finite(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """``value`` as a float array, checking every entry is finite."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite numeric array, got {value!r}') from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name} must be finite, got {arr.tolist()}')
    return arr


def _increasing(name: str, value: ArrayLike, min_size: int) -> NDArray[np.float64]:
    """A 1-D, finite, strictly increasing array of at least ``min_size`` times [s]."""
    arr = _finite(name, value)
    if arr.ndim != 1 or arr.size < min_size:
        raise ValueError(f'{name} must be a 1-D array of at least {min_size} times, '
                         f'got shape {arr.shape}')
    if not np.all(np.diff(arr) > 0):
        raise ValueError(f'{name} must be strictly increasing, got {arr.tolist()}')
    return arr


def _interval(t0: float, t1: float) -> tuple[float, float]:
    """Check a query interval [t0, t1] of `breakpoints` or `is_constant`."""
    t0, t1 = float(t0), float(t1)
    if not (math.isfinite(t0) and math.isfinite(t1)):
        raise ValueError(f't0 and t1 must be finite, got {t0!r}, {t1!r}')
    if t1 < t0:
        raise ValueError(f't1 must be >= t0, got t0={t0!r}, t1={t1!r}')
    return t0, t1


class Gait:
    """Base class of all gaits.

    Contract for subclasses:

    1. Set ``n_links`` (int, p - 1) and ``period`` [s] (None unless the gait is periodic).
    2. Implement ``_eval(t)`` for an array of times ``t`` of shape (N,) [s], returning the three
       arrays (l [m], l' [m/s], l'' [m/s^2]) of shape (N, n_links), without a Python loop over t.
    3. l and l' must be continuous in t. If l'' jumps, override ``breakpoints`` so that it
       returns every jump time in the open interval (t0, t1), sorted; the exact solver relies
       on it.
    4. Optionally override ``is_constant`` (rest intervals the solver can skip). It must return
       True only when l' == 0 and l'' == 0 on all of [t0, t1].
    """

    n_links: int
    period: float | None = None

    def __call__(self, t: float | ArrayLike) -> Triple:
        """Evaluate (l [m], l' [m/s], l'' [m/s^2]) at a time or an array of times [s].

        For a float ``t`` each array has shape (n_links,); for ``t`` of shape (N,) each has
        shape (N, n_links).
        """
        if np.ndim(t) == 0:
            l, ld, ldd = self._eval(np.array([float(t)]))
            return l[0], ld[0], ldd[0]
        ta = np.asarray(t, dtype=float)
        if ta.ndim != 1:
            raise ValueError(f't must be a float or a 1-D array of times, got shape {ta.shape}')
        return self._eval(ta)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        raise NotImplementedError

    def at(self, t: float) -> Triple:
        """(l, l', l'') at one float time, each of shape (n_links,): the solver's hot path.

        Same values as ``self(t)`` to rounding; subclasses override it with scalar math.
        """
        return self(t)

    def at1(self, t: float) -> tuple[float, float, float]:
        """(l, l', l'') of linkage 0 at one float time, as floats: the root finders' hot path
        for one-linkage (two-body) crawlers. Subclasses may override it with scalar math."""
        l, ld, ldd = self.at(t)
        return float(l[0]), float(ld[0]), float(ldd[0])

    def length(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Linkage lengths l(t) [m]."""
        return self(t)[0]

    def velocity(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Linkage rates l'(t) [m/s]."""
        return self(t)[1]

    def acceleration(self, t: float | ArrayLike) -> NDArray[np.float64]:
        """Linkage accelerations l''(t) [m/s^2]."""
        return self(t)[2]

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        """Sorted times in the open interval (t0, t1) where l'' may jump; none by default."""
        return _EMPTY

    def is_constant(self, t0: float, t1: float) -> bool:
        """True only when l' and l'' are exactly zero on all of [t0, t1]."""
        return False

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64] | None:
        """Upper bounds of the jerk |d l''/dt| [m/s^3] per linkage on [t0, t1] between
        breakpoints (where l'' is continuous), or None if unknown (the default). The exact
        solver uses them to rule out, without a root search, a velocity that dips to zero
        between two grid points; a bound that is too small makes it miss such dips."""
        return None


class Custom(Gait):
    """A gait from three user callables of one float time.

    Each callable returns an array of shape (n_links,) (a float is accepted when there is one
    linkage). They are never called with arrays. ``breakpoints`` optionally lists times where the
    acceleration jumps so the exact solver places events there without searching.
    """

    def __init__(self, length: Callable[[float], ArrayLike],
                 velocity: Callable[[float], ArrayLike],
                 acceleration: Callable[[float], ArrayLike], *, period: float | None = None,
                 breakpoints: ArrayLike | None = None) -> None:
        for name, fn in (('length', length), ('velocity', velocity),
                         ('acceleration', acceleration)):
            if not callable(fn):
                raise ValueError(f'Custom gait: {name} must be callable, got {type(fn).__name__}')
        self._fns = (length, velocity, acceleration)
        self.n_links = int(np.atleast_1d(np.asarray(length(0.0), dtype=float)).size)
        self.period = period
        self._breaks = np.sort(np.asarray(breakpoints if breakpoints is not None else [], float))

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            tf = float(t)
            return tuple(np.atleast_1d(np.asarray(fn(tf), dtype=float)) for fn in self._fns)
        return super().__call__(t)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        out = [np.empty((t.size, self.n_links)) for _ in range(3)]
        for k, tk in enumerate(t.tolist()):
            for arr, fn in zip(out, self._fns):
                arr[k] = np.asarray(fn(tk), dtype=float)
        return tuple(out)

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        b = self._breaks
        return b[(b > t0) & (b < t1)]


class Sinusoid(Gait):
    """l_j(t) = mean_j + amplitude_j sin(2 pi frequency t + phase_j).

    ``mean``, ``amplitude`` [m] and ``phase`` [rad] are per linkage (or one float for all);
    ``frequency`` [Hz] is shared so the gait is periodic. A phase lag between neighbouring
    linkages makes a travelling wave.
    """

    def __init__(self, mean: ArrayLike, amplitude: ArrayLike, frequency: float,
                 phase: ArrayLike = 0.0, *, n_links: int | None = None) -> None:
        sizes = [np.size(a) for a in (mean, amplitude, phase)]
        n = _n_links(n_links, max(sizes))
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.amplitude = _per_link('amplitude', amplitude, n)
        self.phase = _per_link('phase', phase, n)
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency
        self._w = 2.0 * math.pi * self.frequency

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        arg = self._w * t[:, None] + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a = self.amplitude
        return self.mean + a * s, a * self._w * c, -a * self._w ** 2 * s

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.abs(self.amplitude) * self._w ** 3

    def at(self, t: float) -> Triple:
        if self.n_links == 1:
            l, ld, ldd = self.at1(t)
            return np.array([l]), np.array([ld]), np.array([ldd])
        arg = self._w * t + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a = self.amplitude
        return self.mean + a * s, a * self._w * c, -a * self._w ** 2 * s

    def at1(self, t: float) -> tuple[float, float, float]:
        arg = self._w * t + float(self.phase[0])
        s, c = math.sin(arg), math.cos(arg)
        a = float(self.amplitude[0])
        return float(self.mean[0]) + a * s, a * self._w * c, -a * self._w ** 2 * s


class Fourier(Gait):
    """A truncated Fourier series per linkage.

    l_j(t) = mean_j + sum_{k=1..K} (a_jk cos(2 pi k f t) + b_jk sin(2 pi k f t))

    Parameters
    ----------
    mean : float or array_like, shape (n_links,)
        Mean lengths [m].
    coefficients : pair (cos, sin) of array_like
        ``cos`` holds a_jk and ``sin`` holds b_jk [m], both of shape (K,) (the same series for
        every linkage) or (n_links, K). Column ``k - 1`` is harmonic k (k = 1..K); there is no
        constant term (that is ``mean``). An array of shape (2, K) or (2, n_links, K) also works.
    frequency : float
        Fundamental frequency f [Hz]; ``period = 1 / f``.
    n_links : int, optional
        Number of linkages when it cannot be read from the shapes of ``mean`` and the
        coefficients.
    """

    def __init__(self, mean: ArrayLike, coefficients: tuple[ArrayLike, ArrayLike] | ArrayLike,
                 frequency: float, *, n_links: int | None = None) -> None:
        try:
            cos, sin = coefficients
        except (TypeError, ValueError):
            raise ValueError('coefficients must be a pair (cos, sin) of arrays of shape (K,) '
                             'or (n_links, K)') from None
        a = _finite('coefficients', cos)
        b = _finite('coefficients', sin)
        if a.shape != b.shape or a.ndim not in (1, 2) or a.shape[-1] < 1:
            raise ValueError('coefficients (cos, sin) must both have shape (K,) or (n_links, K) '
                             f'with K >= 1, got {a.shape} and {b.shape}')
        rows = a.shape[0] if a.ndim == 2 else 1
        n = _n_links(n_links, max(rows, np.size(mean)))
        if a.ndim == 2 and rows != n:
            raise ValueError(f'coefficients must have {n} rows (one per linkage), got {rows}')
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.cos = np.broadcast_to(a, (n, a.shape[-1])).copy()
        self.sin = np.broadcast_to(b, (n, b.shape[-1])).copy()
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency
        w = 2.0 * math.pi * self.frequency
        k = np.arange(1, a.shape[-1] + 1, dtype=float)
        self._k = k
        # [cos(k th) | sin(k th)] @ matrix gives l - mean, l', l'' (th = 2 pi f t).
        a_t, b_t = self.cos.T, self.sin.T                       # (K, n)
        wk = (w * k)[:, None]
        self._m0 = np.vstack([a_t, b_t])
        self._m1 = np.vstack([wk * b_t, -wk * a_t])
        self._m2 = np.vstack([-wk ** 2 * a_t, -wk ** 2 * b_t])

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        # Reduce to the phase in cycles first so that large t keeps full accuracy.
        th = 2.0 * math.pi * np.mod(self.frequency * t, 1.0)
        arg = th[:, None] * self._k
        cs = np.hstack([np.cos(arg), np.sin(arg)])
        return self.mean + cs @ self._m0, cs @ self._m1, cs @ self._m2

    def is_constant(self, t0: float, t1: float) -> bool:
        return not (np.any(self.cos) or np.any(self.sin))

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        wk3 = (2.0 * math.pi * self.frequency * self._k) ** 3
        return (np.abs(self.cos) + np.abs(self.sin)) @ wk3


class Scallop(Gait):
    """A smooth periodic stroke with a fast and a slow phase.

    A cosine stroke between ``mean - amplitude`` and ``mean + amplitude`` is run through an
    analytic, strictly monotone time warp so that the extension (l' > 0) lasts the fraction
    ``asymmetry`` = r of the period and the contraction the rest. With x = 2 pi f t + phase_j -
    pi r, c = cos(pi r), s = sin(pi r) and D = 1 - c cos x > 0, the warped phase phi(x) has

        sin phi = s sin x / D,   cos phi = (cos x - c) / D,
        phi' = s / D,            phi'' = -s c sin x / D^2

    (the circle map tan(phi/2) = cot(pi r / 2) tan(x/2); phi' > 0 for every r in (0, 1)), and

        l = mean + amplitude sin phi,
        l' = amplitude w cos(phi) phi',
        l'' = amplitude w^2 (cos(phi) phi'' - sin(phi) phi'^2),   w = 2 pi f,

    all in closed form, so the gait is C-infinity. r = 0.5 gives mean - amplitude cos(w t +
    phase). l is at its minimum when w t + phase = 0 (mod 2 pi), extends while w t + phase is in
    (0, 2 pi r), then contracts.

    Parameters
    ----------
    mean, amplitude : float or array_like, shape (n_links,)
        Mean length and half stroke [m]; ``amplitude >= 0``.
    frequency : float
        Stroke frequency [Hz]; ``period = 1 / frequency``.
    asymmetry : float
        Fraction r of the period spent extending, in the open interval (0, 1). r = 0.2 is a fast
        extension and a slow contraction.
    phase : float or array_like, shape (n_links,)
        Phase lead of each linkage [rad] (a lag between neighbours makes a travelling wave).
    n_links : int, optional
        Number of linkages when the per-linkage arguments are all floats.
    """

    def __init__(self, mean: ArrayLike, amplitude: ArrayLike, frequency: float,
                 asymmetry: float, phase: ArrayLike = 0.0, *, n_links: int | None = None) -> None:
        n = _n_links(n_links, max(np.size(a) for a in (mean, amplitude, phase)))
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.amplitude = _per_link('amplitude', amplitude, n)
        if np.any(self.amplitude < 0):
            raise ValueError(f'amplitude must be >= 0 m, got {self.amplitude.tolist()}')
        self.phase = _per_link('phase', phase, n)
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency
        try:
            r = float(asymmetry)
        except (TypeError, ValueError):
            raise ValueError(f'asymmetry must be a float in (0, 1), got {asymmetry!r}') from None
        if not 0.0 < r < 1.0:
            raise ValueError(f'asymmetry must be in the open interval (0, 1), got {asymmetry!r}')
        self.asymmetry = r
        self._c, self._s = math.cos(math.pi * r), math.sin(math.pi * r)
        self._w = 2.0 * math.pi * self.frequency

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        c, s, w, amp = self._c, self._s, self._w, self.amplitude
        x = 2.0 * math.pi * np.mod(self.frequency * t, 1.0)[:, None] + (
            self.phase - math.pi * self.asymmetry)
        cx, sx = np.cos(x), np.sin(x)
        inv_d = 1.0 / (1.0 - c * cx)
        sin_phi, cos_phi = s * sx * inv_d, (cx - c) * inv_d
        dphi = s * inv_d
        ddphi = -s * c * sx * inv_d ** 2
        return (self.mean + amp * sin_phi, amp * w * cos_phi * dphi,
                amp * w ** 2 * (cos_phi * ddphi - sin_phi * dphi ** 2))

    def at(self, t: float) -> Triple:
        if self.n_links != 1:
            return self(t)
        l, ld, ldd = self.at1(t)
        return np.array([l]), np.array([ld]), np.array([ldd])

    def at1(self, t: float) -> tuple[float, float, float]:
        # the formulas of _eval in scalar math: about 15 times faster than the array path
        c, s, w = self._c, self._s, self._w
        amp = float(self.amplitude[0])
        x = 2.0 * math.pi * ((self.frequency * t) % 1.0) + (
            float(self.phase[0]) - math.pi * self.asymmetry)
        cx, sx = math.cos(x), math.sin(x)
        inv_d = 1.0 / (1.0 - c * cx)
        sin_phi, cos_phi = s * sx * inv_d, (cx - c) * inv_d
        dphi = s * inv_d
        ddphi = -s * c * sx * inv_d ** 2
        return (float(self.mean[0]) + amp * sin_phi, amp * w * cos_phi * dphi,
                amp * w ** 2 * (cos_phi * ddphi - sin_phi * dphi ** 2))

    def is_constant(self, t0: float, t1: float) -> bool:
        return not np.any(self.amplitude)


class PiecewiseParabolic(Gait):
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
        self._rest = np.all((self._a == 0) & (self._v == 0), axis=1)
        if self.periodic:
            a = self.accelerations
            jumps = np.any(a != np.roll(a, 1, axis=0), axis=1)
            self._jumps = tk[:-1][jumps]
        else:
            self._jumps = tk[np.any(self._a[1:] != self._a[:-1], axis=1)]

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
               *, n_links: int | None = None) -> PiecewiseParabolic:
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
        n_links : int, optional
            Number of linkages when ``mean`` and ``amplitude`` are floats (default 1).
        """
        n = _n_links(n_links, max(np.size(mean), np.size(amplitude)))
        mean_, amp = _per_link('mean', mean, n), _per_link('amplitude', amplitude, n)
        if np.any(amp < 0):
            raise ValueError(f'amplitude must be >= 0 m, got {amp.tolist()}')
        period = 1.0 / _positive('frequency', frequency, 'Hz')
        r = float(asymmetry)
        if not 0.0 < r < 1.0:
            raise ValueError(f'asymmetry must be in the open interval (0, 1), got {asymmetry!r}')
        t_ext, t_con = r * period, (1.0 - r) * period
        times = [0.0, 0.5 * t_ext, t_ext, t_ext + 0.5 * t_con, period]
        a_e, a_c = 8.0 * amp / t_ext ** 2, 8.0 * amp / t_con ** 2
        return cls(times, np.vstack([a_e, -a_e, -a_c, a_c]), mean_ - amp, 0.0, periodic=True)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        tk = self.times
        if not self.periodic:
            j = np.searchsorted(tk, t, side='right')
            d = (t - self._anchor[j])[:, None]
        else:
            # Knot k of period m sits at tk[k] + m T (period m ends at tk[0] + (m + 1) T),
            # computed exactly as in `breakpoints`, so at a reported breakpoint the gait takes
            # the next piece, as it does at tk[k].
            period, last = self.period, tk.size - 1
            m = np.floor((t - tk[0]) / period)
            knots = np.concatenate([tk[None, :-1] + (m * period)[:, None],
                                    (tk[0] + (m + 1) * period)[:, None]], axis=1)
            j = np.sum(knots <= t[:, None], axis=1)
            m = np.where(j == 0, m - 1, np.where(j > last, m + 1, m))
            j = np.where(j == 0, last, np.where(j > last, 1, j))
            d = (t - (tk[j - 1] + m * period))[:, None]
        a, v = self._a[j], self._v[j]
        return self._l[j] + d * (v + 0.5 * a * d), v + a * d, a

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        t0, t1 = _interval(t0, t1)
        jumps = self._jumps
        if jumps.size == 0 or t1 <= t0:
            return _EMPTY
        if self.periodic:
            start, period = self.times[0], self.period
            m = np.arange(math.floor((t0 - start) / period) - 1,
                          math.floor((t1 - start) / period) + 2, dtype=float)
            jumps = np.sort((jumps[None, :] + m[:, None] * period).ravel())
        return jumps[(jumps > t0) & (jumps < t1)]

    def is_constant(self, t0: float, t1: float) -> bool:
        """True when l' and l'' are zero on [t0, t1].

        Pieces are judged on their interiors: a rest piece [t_k, t_k+1) queried exactly is
        constant even though l'' jumps at its ends.
        """
        t0, t1 = _interval(t0, t1)
        rest = self._rest
        if not self.periodic:
            j0 = np.searchsorted(self.times, t0, side='right')
            j1 = j0 if t1 == t0 else np.searchsorted(self.times, t1, side='left')
            return bool(np.all(rest[j0:j1 + 1]))
        pieces = rest[1:-1]
        if np.all(pieces):
            return True
        if t1 - t0 >= self.period:
            return False
        tk = self.times
        s0 = tk[0] + np.mod(t0 - tk[0], self.period)
        s1 = s0 + (t1 - t0)
        knots = np.concatenate([tk, tk[1:] + self.period])
        twice = np.concatenate([pieces, pieces])
        j0 = min(int(np.searchsorted(knots, s0, side='right')) - 1, twice.size - 1)
        j1 = j0 if t1 == t0 else int(np.searchsorted(knots, s1, side='left')) - 1
        return bool(np.all(twice[j0:max(j0, j1) + 1]))

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.zeros(self.n_links)      # l'' is constant between breakpoints


class Spline(Gait):
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
        self._flat = bool(np.all(y == y[0]))
        if self.periodic:
            self._jumps = _EMPTY
        else:
            end_acc = self._spline(tk[[0, -1]], 2)
            self._jumps = tk[[0, -1]][np.any(end_acc != 0, axis=1)]

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        sp = self._spline
        if self.periodic:
            return sp(t), sp(t, 1), sp(t, 2)
        s = np.clip(t, self.times[0], self.times[-1])
        outside = ((t < self.times[0]) | (t >= self.times[-1]))[:, None]
        return sp(s), np.where(outside, 0.0, sp(s, 1)), np.where(outside, 0.0, sp(s, 2))

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        t0, t1 = _interval(t0, t1)
        b = self._jumps
        return b[(b > t0) & (b < t1)]

    def is_constant(self, t0: float, t1: float) -> bool:
        t0, t1 = _interval(t0, t1)
        if self._flat:
            return True
        if self.periodic:
            return False
        return t1 <= self.times[0] or t0 >= self.times[-1]


def cubic_values(l0, v0, a0, jerk, d):
    """(l, l', l'') of a constant-jerk piece d [s] after its start, for floats or arrays.

    The one expression used by ``Cubic``, ``PiecewiseCubic`` and the node's actuator, so that a
    piece evaluated at its end gives bit-identically the next piece's start."""
    return (l0 + d * (v0 + d * (0.5 * a0 + d * jerk / 6.0)), v0 + d * (a0 + 0.5 * d * jerk),
            a0 + d * jerk)


class Cubic(Gait):
    """One cubic piece per linkage: constant jerk from (l0, v0, a0) at time t0.

    l(t) = l0 + v0 d + a0 d^2 / 2 + jerk d^3 / 6 with d = t - t0. The node's actuator model
    hands the solver one of these per integration tick, so l is C2 across ticks.
    """

    def __init__(self, t0: float, l0: ArrayLike, v0: ArrayLike, a0: ArrayLike,
                 jerk: ArrayLike) -> None:
        l0 = _per_link('l0', l0, None)
        self.n_links = l0.size
        self.t0 = float(t0)
        self._arrays = (l0, _per_link('v0', v0, self.n_links), _per_link('a0', a0, self.n_links),
                        _per_link('jerk', jerk, self.n_links))
        self._constant = not any(np.any(x) for x in self._arrays[1:])
        self._rows = list(zip(*(x.tolist() for x in self._arrays)))

    # the coefficients as arrays [m, m/s, m/s^2, m/s^3], shape (n_links,); a trusted piece
    # (one per node tick) makes them only if asked
    l0 = property(lambda self: self._coefficients()[0])
    v0 = property(lambda self: self._coefficients()[1])
    a0 = property(lambda self: self._coefficients()[2])
    jerk = property(lambda self: self._coefficients()[3])

    def _coefficients(self) -> tuple[NDArray[np.float64], ...]:
        if self._arrays is None:
            self._arrays = tuple(np.array(x) for x in zip(*self._rows))
        return self._arrays

    @classmethod
    def trusted(cls, t0: float, l0: list[float], v0: list[float], a0: list[float],
                jerk: list[float]) -> Cubic:
        """Build from lists of finite floats of equal length without validation (the
        actuator's hot path, one piece per tick; it produces only finite values)."""
        self = cls.__new__(cls)
        self.t0 = float(t0)
        self.n_links = len(l0)
        self._arrays = None
        self._constant = not (any(v0) or any(a0) or any(jerk))
        self._rows = list(zip(l0, v0, a0, jerk))
        return self

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            return self.at(float(t))
        return super().__call__(t)

    def at(self, t: float) -> Triple:
        # cubic_values in Python floats (IEEE, same operation order: the array path's bits)
        d = t - self.t0
        l, v, a = zip(*(cubic_values(*row, d) for row in self._rows))
        return np.array(l), np.array(v), np.array(a)

    def at1(self, t: float) -> tuple[float, float, float]:
        return cubic_values(*self._rows[0], t - self.t0)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        return cubic_values(*self._coefficients(), (t - self.t0)[:, None])

    def is_constant(self, t0: float, t1: float) -> bool:
        return self._constant

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.array([abs(r[3]) for r in self._rows])


class PiecewiseCubic(Gait):
    """Consecutive ``Cubic`` pieces, piece k valid on [starts[k], starts[k+1]) (the last one
    from its start on), as the node's actuator hands them out tick by tick.

    The node integrates many ticks in one exact solve with this gait. Joins where l'' does not
    continue exactly (a cubic's end value differs from the next piece's a0) are reported as
    breakpoints, so the exact solver places events there precisely.
    """

    def __init__(self, starts: ArrayLike, pieces: list[Cubic]) -> None:
        # built once per publish tick by the node: checks and joins in plain Python floats
        starts = np.asarray(starts, dtype=float)
        if starts.ndim != 1 or starts.size != len(pieces) or starts.size == 0:
            raise ValueError('starts must list one start time [s] per piece')
        sl = starts.tolist()
        if any(b <= a for a, b in zip(sl, sl[1:])) or not all(map(math.isfinite, sl)):
            raise ValueError('starts must be finite and strictly increasing')
        self.n_links = pieces[0].n_links
        if any(pc.n_links != self.n_links for pc in pieces):
            raise ValueError('every piece must have the same number of linkages')
        self.starts = starts
        self._starts = sl
        self.pieces = list(pieces)
        self._arrays = None       # stacked coefficients for array evaluation, made on demand
        # l'' at the end of piece k (the Cubic's own expression a0 + d j) against a0 of k+1
        jumps = []
        for k in range(len(pieces) - 1):
            d = sl[k + 1] - pieces[k].t0
            if any(r[2] + d * r[3] != n[2] for r, n in zip(pieces[k]._rows, pieces[k + 1]._rows)):
                jumps.append(sl[k + 1])
        self._jumps = np.array(jumps)
        self._constant = [pc._constant for pc in pieces]

    def _index(self, t: float) -> int:
        return max(bisect_right(self._starts, t) - 1, 0)

    def at(self, t: float) -> Triple:
        return self.pieces[self._index(t)].at(t)

    def at1(self, t: float) -> tuple[float, float, float]:
        return self.pieces[self._index(t)].at1(t)

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            return self.at(float(t))
        return super().__call__(t)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        if t.size * self.n_links <= 64:
            return self._eval_small(t)
        if self._arrays is None:
            rows = np.array([pc._rows for pc in self.pieces])     # (K, n_links, 4)
            self._arrays = (np.array([pc.t0 for pc in self.pieces]),
                            [rows[:, :, i] for i in range(4)])
        t0s, c = self._arrays
        k = np.clip(np.searchsorted(self.starts, t, side='right') - 1, 0, len(self.pieces) - 1)
        return cubic_values(*(x[k] for x in c), (t - t0s[k])[:, None])

    def _eval_small(self, t: NDArray[np.float64]) -> Triple:
        # The node's event grid (a few points per publish window): Python floats beat numpy's
        # per-call overhead here; same expressions, so the same bits as the array path.
        starts, pieces = self._starts, self.pieces
        rows = []
        for tt in t.tolist():
            pc = pieces[max(bisect_right(starts, tt) - 1, 0)]
            rows.append([cubic_values(*row, tt - pc.t0) for row in pc._rows])
        out = np.array(rows)                      # (N, n_links, 3)
        return out[:, :, 0], out[:, :, 1], out[:, :, 2]

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        b = self._jumps
        return b[(b > t0) & (b < t1)] if b.size else b

    def is_constant(self, t0: float, t1: float) -> bool:
        k0, k1 = self._index(t0), self._index(t1)
        return all(self._constant[k0:k1 + 1])

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        k0, k1 = self._index(t0), self._index(t1)
        return np.array([max(abs(pc._rows[i][3]) for pc in self.pieces[k0:k1 + 1])
                         for i in range(self.n_links)])
