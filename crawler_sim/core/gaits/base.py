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
import weakref

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['Gait', 'BuiltinGait', 'CLOSURE_RTOL', 'BREAK_ULPS']

Triple = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]

_EMPTY = np.empty(0)

# A jump of l'' within this many float spacings of a listed breakpoint's time (or of a run's
# start or end) is at that time: the rounding of a time computed as k T + t_k, or printed to
# 15 significant digits, is a few. The sampler of a Python gait (``solvers.proxy``) and
# ``verify`` read l'' this far inside a piece that starts or ends there; l'' moves by at most
# |l'''| times it, half the rounding the sampler's fit allows on each coefficient for a time of
# size |t| (eps |t| |l'''|, a node's error spread over N = 32 coefficients).
BREAK_ULPS = 16

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
       on it. A returned time is that of a jump within ``BREAK_ULPS`` float spacings of it (the
       rounding of a time computed as k T + t_k); a jump at a run's start or end needs none.
    4. Optionally override ``is_constant`` (rest intervals the solver can skip). It must return
       True only when l' == 0 and l'' == 0 on all of [t0, t1].
    5. Optionally override ``jerk_bound``: the pieces the gait is sampled into are checked
       against it (a piece whose l''' exceeds it is refused, naming ``jerk_bound``).

    Every gait runs in the compiled solvers through ``compiled()``: the built-in gaits
    (``BuiltinGait``) as their own compiled kind, which their Python methods call too (one
    arithmetic); any other gait, such as a user's subclass, through its Python methods,
    sampled into Chebyshev pieces to the rounding of its values (``solvers.proxy``, the kind
    PROXY) that the solvers read.
    """

    n_links: int
    period: float | None = None

    def compiled(self) -> object:
        """The gait's compiled form (``solvers._gait.CompiledGait``), built once per gait."""
        cg = self.__dict__.get('_compiled')
        if cg is None:
            cg = self.__dict__['_compiled'] = self._compile()
        return cg

    def _compile(self):
        """A gait that is not built in: its Python ``at`` sampled into Chebyshev pieces
        (split at its ``breakpoints``, checked against its ``jerk_bound`` if it has one)."""
        at = self._weak_method('at')
        jerk = (self._weak_method('jerk_bound')
                if type(self).jerk_bound is not Gait.jerk_bound else None)
        return self._sampled(lambda t: at(t)[2], lambda t: at(t)[:2],
                             self._weak_method('breakpoints'), jerk)

    def _weak_method(self, name: str):
        """``self.<name>`` called through a weak reference. The compiled form keeps it (in its
        table of pieces) without keeping the gait alive: the gait and its compiled form are
        freed when the last reference to the gait goes, not left as a cycle for the cyclic
        collector, which a new gait per run then runs often (a fresh Custom gait's run 280 ->
        440 us in a process of 50,000 objects)."""
        ref = weakref.ref(self)
        return lambda *args: getattr(ref(), name)(*args)

    def _sampled(self, accel, state, breaks, jerk, fns=None):
        """The compiled form (kind PROXY) of a gait of Python functions: ``accel(t)`` its l'',
        ``state(t)`` its (l, l'), ``breaks`` / ``jerk`` its breakpoints and |l'''| bounds
        (callables of (t0, t1), or None), ``fns`` the (l, l', l'') callables Python reads
        outside the pieces (else ``at``)."""
        from ..solvers._gait import proxy
        from ..solvers.proxy import ChebTable
        table = ChebTable(accel, state, self.n_links, self.period,
                          getattr(self, 'max_step', None), breaks, jerk)
        return proxy(self, self.n_links, table, fns=fns)

    def __getstate__(self) -> dict:
        # the compiled form is rebuilt where the gait is used (a sweep sends gaits to workers)
        state = self.__dict__.copy()
        state.pop('_compiled', None)
        return state

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
        """(l, l', l'') at one float time, each of shape (n_links,)."""
        return self(t)

    def at1(self, t: float) -> tuple[float, float, float]:
        """(l, l', l'') of linkage 0 at one float time, as floats."""
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
        """Upper bounds of |l'''| [m/s^3] per linkage on [t0, t1], or None if unknown (default).

        Between the breakpoints l'' must be Lipschitz with this constant (l''' may jump, as at
        the joins of a `PiecewiseCubic`). A built-in gait's bound is the one its event search
        is proven with; a user's gait is sampled into pieces that are checked against it."""
        return None

    def length_minimum(self, t0: float, t1: float
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The smallest length of each linkage on [t0, t1] and the first time it is reached,
        as (times [s], lengths [m]) of shape (n_links,), or None when not known in closed
        form (default). ``simulate`` and ``Stepper`` refuse a gait whose length reaches <= 0
        from it before any work; without it ``simulate`` checks the run's samples after."""
        return None

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64] | None:
        """Upper bounds of |l''''| [m/s^4] per linkage on [t0, t1] between breakpoints, or None
        when unknown or when l''' jumps inside (a built-in gait's search then bounds the
        stuck-force rows with `jerk_bound` alone; a user's gait is sampled, its own series'
        bounds used)."""
        return None


def _runs_native(cls: type, evaluation: tuple[str, ...]) -> bool:
    """True if no class of ``cls``'s hierarchy below the one defining ``_kind`` overrides an
    evaluation method (else its gaits are sampled through their Python methods). Found once
    per class, not per gait compiled (the engine compiles a new gait per sync): kept in the
    class's own ``_runs_native_`` (a plain class attribute lookup; a parent's is not read)."""
    for c in cls.__mro__:
        if '_kind' in c.__dict__:
            return True             # nothing overridden below the built-in class
        if any(name in c.__dict__ for name in evaluation):
            return False
    return True


class BuiltinGait(Gait):
    """A gait with a compiled kind of its own (``_kind``): every evaluation, from Python and
    from the solvers, goes through it. A subclass that overrides an evaluation method (``at``,
    ``_eval``, ``breakpoints``, ...) runs in the solvers through its Python methods instead
    (sampled, as any user's gait), so what it says is what the solvers see."""

    _EVALUATION = ('__call__', '_eval', 'at', 'at1', 'breakpoints', 'is_constant',
                   'jerk_bound', 'snap_bound')

    def _kind(self):
        raise NotImplementedError

    def _native(self):
        """The compiled kind of this gait's class (built once)."""
        cg = self.__dict__.get('_native_kind')
        if cg is None:
            cg = self.__dict__['_native_kind'] = self._kind()
        return cg

    def _compile(self):
        cls = type(self)
        native = cls.__dict__.get('_runs_native_')     # this class's own, not a parent's
        if native is None:
            native = _runs_native(cls, self._EVALUATION)
            type.__setattr__(cls, '_runs_native_', native)
        return self._native() if native else Gait._compile(self)

    def __getstate__(self) -> dict:
        state = super().__getstate__()
        state.pop('_native_kind', None)
        return state

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        return self._native().values(t)

    def at(self, t: float) -> Triple:
        return self._native().at(float(t))

    def at1(self, t: float) -> tuple[float, float, float]:
        return self._native().at1(float(t))

    def breakpoints(self, t0: float, t1: float) -> NDArray[np.float64]:
        t0, t1 = _interval(t0, t1)
        return self._native().breakpoints(t0, t1)

    def is_constant(self, t0: float, t1: float) -> bool:
        t0, t1 = _interval(t0, t1)
        return self._native().is_constant(t0, t1)

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return self._native().bounds(float(t0), float(t1))[0]

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64] | None:
        return self._native().bounds(float(t0), float(t1))[1]
