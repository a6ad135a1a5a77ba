"""`Custom`: a gait from user callables of one float time (or, ``vectorized=True``, of an
array of times)."""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import Gait, Triple, _finite, _positive


class Custom(Gait):
    """A gait from three user callables of one float time.

    Each callable returns an array of shape (n_links,) (a float is accepted when there is one
    linkage). They are never called with arrays, unless ``vectorized=True``: each callable
    then takes an array of times of shape (n,) and returns an array of shape (n, n_links)
    (checked: a wrong shape or a non-finite value is a ValueError naming the function and
    the shape expected). The sampling then evaluates every node of a round (all the pieces
    of a window) in one call of each function, the fastest path (a 2-period run, sampling
    included, 2.2-2.6x its built-in twin side by side, a 20-period run 3.1-3.4x;
    ``benchmarks.custom_cost``); scalar callables are called once a node (l'' about 1026
    times for the one period a ``period=`` gait samples; 264 times for a 2-period run
    without a period, 1,284 for 20 periods: a window whose pieces are far from resolved is
    cut in four at once; l and l' at the pieces' ends).

    Optional hints for the exact solver (the more it knows, the less it must assume):

    - ``breakpoints`` [s]: times where l'' jumps, so events there are placed without
      searching (times where only l''' jumps may be listed too: each side is then sampled
      apart). A listed time is that of a jump within ``BREAK_ULPS`` (16) float spacings of it
      (times computed as k T + t_k, or printed to 15 significant digits, are that close); a
      jump at the run's start or end needs none. An unlisted jump is refused, naming its time
      (to the float) and the nearest listed one;
    - ``period`` [s]: the gait repeats with this period (enables the periodic skip; the gait
      is sampled over one period);
    - ``jerk_bound`` [m/s^3]: an upper bound of |l'''| (float, one per linkage, or a callable
      ``(t0, t1) -> bounds`` on [t0, t1]): every sampled piece is checked against it, and a
      gait whose l''' exceeds it is refused, naming it;
    - ``max_step`` [s]: the largest step between two event checks (and the sampling: 8
      cells per step).

    The functions are sampled into Chebyshev pieces to the rounding of their values
    (``solvers.proxy``: l'' at about one point per cell, l and l' at each join, checked to be
    its integrals) and the solver reads the pieces, in the compiled segment loop; the
    callables are called at times inside the span being integrated only.
    """

    def __init__(self, length: Callable[[float], ArrayLike],
                 velocity: Callable[[float], ArrayLike],
                 acceleration: Callable[[float], ArrayLike], *, period: float | None = None,
                 breakpoints: ArrayLike | None = None,
                 jerk_bound: ArrayLike | Callable | None = None,
                 max_step: float | None = None, vectorized: bool = False) -> None:
        for name, fn in (('length', length), ('velocity', velocity),
                         ('acceleration', acceleration)):
            if not callable(fn):
                raise ValueError(f'Custom gait: {name} must be callable, got {type(fn).__name__}')
        self.vectorized = bool(vectorized)
        if self.vectorized:
            probe = np.asarray(length(np.zeros(1)), dtype=float)
            if probe.ndim != 2 or probe.shape[0] != 1:
                raise ValueError(f'Custom gait (vectorized=True): length(t) for t of shape (1,) '
                                 f'must return an array of shape (1, n_links), got shape '
                                 f'{probe.shape}')
            self.n_links = int(probe.shape[1])
            # checked array callables (closures over the functions, not over the gait: the
            # table that keeps them must not keep the gait alive, see ``_weak_method``)
            self._vfns = tuple(_Checked(fn, name, self.n_links) for name, fn in
                               (('length', length), ('velocity', velocity),
                                ('acceleration', acceleration)))
            # the scalar view (one float -> (n_links,)), where Python reads one time
            self._fns = tuple(_AtOne(fn) for fn in self._vfns)
        else:
            self._vfns = None
            self._fns = (length, velocity, acceleration)
            self.n_links = int(np.atleast_1d(np.asarray(length(0.0), dtype=float)).size)
        self.period = None if period is None else _positive('period', period, 's')
        self.max_step = None if max_step is None else _positive('max_step', max_step, 's')
        breaks = _finite('breakpoints', [] if breakpoints is None else breakpoints)
        if breaks.ndim > 1:
            raise ValueError(f'breakpoints must be a 1-D list of finite times [s], got shape '
                             f'{breaks.shape}')
        self._breaks = np.sort(breaks.reshape(-1))
        if jerk_bound is None or callable(jerk_bound):
            self._jerk = jerk_bound
        else:
            jb = np.broadcast_to(np.asarray(jerk_bound, dtype=float), (self.n_links,)).copy()
            if not np.all(np.isfinite(jb)) or np.any(jb < 0):
                raise ValueError(f'jerk_bound must be finite and >= 0 m/s^3, got {jb.tolist()}')
            self._jerk = jb

    def _compile(self):
        fl, fv, fa = self._fns
        breaks = self._weak_method('breakpoints') if self._breaks.size else None
        jerk = self._weak_method('jerk_bound') if self._jerk is not None else None
        if self._vfns is None:
            # (the scalar path as it was: a bound read through ``jerk_bound`` piece by piece)
            return self._sampled(fa, lambda t: (fl(t), fv(t)), breaks, jerk, fns=self._fns)
        # ``Gait._sampled`` with the array functions handed to the table as well
        from ..solvers._gait import proxy
        from ..solvers.proxy import ChebTable
        vl, vv, va = self._vfns
        if self._jerk is not None and not callable(self._jerk):
            jerk = self._jerk               # one bound for all times: handed over as it is
        table = ChebTable(fa, lambda t: (fl(t), fv(t)), self.n_links, self.period,
                          self.max_step, breaks, jerk, batch=(va, lambda ts: (vl(ts), vv(ts))))
        return proxy(self, self.n_links, table, fns=self._fns)

    def __call__(self, t: float | ArrayLike) -> Triple:
        if np.ndim(t) == 0:
            tf = float(t)
            return tuple(np.atleast_1d(np.asarray(fn(tf), dtype=float)) for fn in self._fns)
        return super().__call__(t)

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        if self._vfns is not None:
            return tuple(fn(t) for fn in self._vfns)
        ts = t.tolist()
        # one conversion per derivative (floats or arrays alike), not one per time
        return tuple(np.array([fn(tk) for tk in ts], dtype=float).reshape(t.size, self.n_links)
                     for fn in self._fns)

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        b = self._breaks
        return b[(b > t0) & (b < t1)]

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64] | None:
        if self._jerk is None or not callable(self._jerk):
            return self._jerk
        jb = np.broadcast_to(np.asarray(self._jerk(t0, t1), dtype=float), (self.n_links,))
        if not np.all(np.isfinite(jb) | (jb == math.inf)) or np.any(jb < 0):
            raise ValueError(f'jerk_bound({t0}, {t1}) must return values >= 0 m/s^3, '
                             f'got {jb.tolist()}')
        return jb



class _Checked:
    """``fn`` of an array of times (n,) whose values are checked: an array of shape
    (n, n_links), finite, else a one-line ValueError naming ``name`` and the shape. A class,
    not a closure: a gait of module-level functions stays picklable (a sweep sends gaits to
    its workers)."""

    def __init__(self, fn: Callable[[NDArray[np.float64]], ArrayLike], name: str,
                 n_links: int) -> None:
        self.fn, self.name, self.n_links = fn, name, n_links

    def __call__(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.asarray(self.fn(t), dtype=float)
        if v.shape != (t.size, self.n_links):
            raise ValueError(f'Custom gait (vectorized=True): {self.name}(t) for t of shape '
                             f'({t.size},) must return shape ({t.size}, {self.n_links}), got '
                             f'shape {v.shape}')
        if not np.isfinite(v).all():
            k = int(np.argwhere(~np.isfinite(v))[0, 0])
            raise ValueError(f'Custom gait (vectorized=True): {self.name}(t) must be finite, '
                             f'got {v[k].tolist()} at t = {float(t[k])!r} s')
        return v


class _AtOne:
    """A checked array function (``_Checked``) at one float time: shape (n_links,)."""

    def __init__(self, fn: _Checked) -> None:
        self.fn = fn

    def __call__(self, t: float) -> NDArray[np.float64]:
        return self.fn(np.array([float(t)]))[0]
