"""`Custom`: a gait from user callables of one float time."""
from __future__ import annotations

from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import (Gait, Triple)


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
