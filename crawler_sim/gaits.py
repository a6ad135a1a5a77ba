"""Gaits: the imposed linkage lengths l_j(t) and their first two time derivatives.

Every gait returns ``(l, l', l'')`` in metres, m/s and m/s^2. For a float time each array has
shape ``(n_links,)``; the built-in gaits also take an array of times of shape ``(N,)`` and then
return arrays of shape ``(N, n_links)``. ``l_j = x_{j+1} - x_j`` (see docs/ARCHITECTURE.md).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['Gait', 'Custom', 'Sinusoid', 'Cubic']

_EMPTY = np.empty(0)


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


class Gait:
    """Base class of all gaits.

    Subclasses implement ``_eval(t)`` for an array of times ``t`` of shape (N,) returning three
    arrays of shape (N, n_links). Optionally they override ``breakpoints`` (times where l'' may
    jump) and ``is_constant`` (rest intervals the solver can skip).
    """

    n_links: int
    period: float | None = None

    def __call__(self, t: float | ArrayLike):
        if np.ndim(t) == 0:
            l, ld, ldd = self._eval(np.array([float(t)]))
            return l[0], ld[0], ldd[0]
        return self._eval(np.asarray(t, dtype=float))

    def _eval(self, t: NDArray[np.float64]):
        raise NotImplementedError

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


class Custom(Gait):
    """A gait from three user callables of one float time.

    Each callable returns an array of shape (n_links,) (a float is accepted when there is one
    linkage). They are never called with arrays. ``breakpoints`` optionally lists times where the
    acceleration jumps so the exact solver places events there without searching.
    """

    def __init__(self, length: Callable[[float], ArrayLike], velocity: Callable[[float], ArrayLike],
                 acceleration: Callable[[float], ArrayLike], *, period: float | None = None,
                 breakpoints: ArrayLike | None = None) -> None:
        for name, fn in (('length', length), ('velocity', velocity), ('acceleration', acceleration)):
            if not callable(fn):
                raise ValueError(f'Custom gait: {name} must be callable, got {type(fn).__name__}')
        self._fns = (length, velocity, acceleration)
        self.n_links = int(np.atleast_1d(np.asarray(length(0.0), dtype=float)).size)
        self.period = period
        self._breaks = np.sort(np.asarray(breakpoints if breakpoints is not None else [], float))

    def __call__(self, t: float | ArrayLike):
        if np.ndim(t) == 0:
            tf = float(t)
            return tuple(np.atleast_1d(np.asarray(fn(tf), dtype=float)) for fn in self._fns)
        return self._eval(np.asarray(t, dtype=float))

    def _eval(self, t: NDArray[np.float64]):
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
        n = n_links if n_links is not None else max(sizes)
        self.n_links = int(n)
        self.mean = _per_link('mean', mean, n)
        self.amplitude = _per_link('amplitude', amplitude, n)
        self.phase = _per_link('phase', phase, n)
        if not (math.isfinite(frequency) and frequency > 0):
            raise ValueError(f'frequency must be finite and > 0 Hz, got {frequency!r}')
        self.frequency = float(frequency)
        self.period = 1.0 / self.frequency
        self._w = 2.0 * math.pi * self.frequency

    def _eval(self, t: NDArray[np.float64]):
        arg = self._w * t[:, None] + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a = self.amplitude
        return self.mean + a * s, a * self._w * c, -a * self._w ** 2 * s


class Cubic(Gait):
    """One cubic piece per linkage: constant jerk from (l0, v0, a0) at time t0.

    l(t) = l0 + v0 d + a0 d^2 / 2 + jerk d^3 / 6 with d = t - t0. The node's actuator model
    hands the solver one of these per integration tick, so l is C2 across ticks.
    """

    def __init__(self, t0: float, l0: ArrayLike, v0: ArrayLike, a0: ArrayLike,
                 jerk: ArrayLike) -> None:
        self.l0 = np.atleast_1d(np.asarray(l0, dtype=float))
        self.n_links = self.l0.size
        self.t0 = float(t0)
        self.v0 = _per_link('v0', v0, self.n_links)
        self.a0 = _per_link('a0', a0, self.n_links)
        self.jerk = _per_link('jerk', jerk, self.n_links)

    def __call__(self, t: float | ArrayLike):
        if np.ndim(t) == 0:
            d = float(t) - self.t0
            j, a0, v0 = self.jerk, self.a0, self.v0
            return (self.l0 + d * (v0 + d * (0.5 * a0 + d * j / 6.0)),
                    v0 + d * (a0 + 0.5 * d * j), a0 + d * j)
        return self._eval(np.asarray(t, dtype=float))

    def _eval(self, t: NDArray[np.float64]):
        d = (t - self.t0)[:, None]
        j, a0, v0 = self.jerk, self.a0, self.v0
        return (self.l0 + d * (v0 + d * (0.5 * a0 + d * j / 6.0)),
                v0 + d * (a0 + 0.5 * d * j), a0 + d * j)

    def is_constant(self, t0: float, t1: float) -> bool:
        return not (np.any(self.v0) or np.any(self.a0) or np.any(self.jerk))
