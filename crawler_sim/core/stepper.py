"""Streaming integration (``Stepper``) and whole-run simulation (``simulate``).

The ROS node advances a ``Stepper`` tick by tick with a new gait piece each time; ``simulate``
is the same stepper run over [0, t_end] and sampled into a ``Trajectory``.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .dense import DenseOutput
from .friction import DEFAULT_RULE, check_rule
from .gaits import Gait, _positive as positive
from .gaits.base import BuiltinGait
from .model import Crawler
from .solvers.base import capabilities, solver_class
from .solvers.exact import ExactSolver
from .solvers.implicit import ImplicitSolver
from .solvers.penalty import PenaltySolver
from .trajectory import Event, EventLog, State, Trajectory

__all__ = ['METHODS', 'GaitLengthError', 'Stepper', 'simulate']

#: the methods and their solvers, which keep the contract of ``solvers.base`` (what a solver
#: provides; ``capabilities(method)``: what it can do)
METHODS = {'exact': ExactSolver, 'implicit': ImplicitSolver, 'penalty': PenaltySolver}


def _check_method(method: str) -> str:
    solver_class(method)        # ValueError naming the methods
    return method


def _check_positive(name: str, value, unit: str = 's') -> float:
    return positive(name, value, unit)


def _check_finite(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite number, got {value!r}') from None
    if not math.isfinite(x):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return x


def check_gait(gait: Gait, crawler: Crawler, t: float) -> None:
    """Raise ValueError if the gait's shape does not match p or it is not finite at t."""
    if (isinstance(gait, Gait) and getattr(gait, 'n_links', None) == crawler.p - 1
            and gait.compiled().finite_at(t)):
        return          # a built-in gait of the right shape, finite at t (one compiled call)
    if not isinstance(gait, Gait):
        raise ValueError(f'gait must be a crawler_sim.core.gaits.Gait, got {type(gait).__name__}')
    try:
        vals = gait.at(t)
    except Exception as exc:  # a user's callable failing is a bad gait
        raise ValueError(f'gait failed at t = {t} s: {exc}') from exc
    shape = (crawler.p - 1,)
    if all(isinstance(a, np.ndarray) and a.shape == shape for a in vals) and math.isfinite(
            float(vals[0].sum() + vals[1].sum() + vals[2].sum())):
        return     # the common case, in one test (a sum is finite only if every term is)
    for name, arr in zip(('length', 'velocity', 'acceleration'), vals):
        arr = np.asarray(arr)
        if arr.shape != (crawler.p - 1,):
            raise ValueError(f'gait {name} must have shape ({crawler.p - 1},) for p = '
                             f'{crawler.p} bodies, got {arr.shape}')
        if not np.all(np.isfinite(arr)):
            raise ValueError(f'gait {name} must be finite, got {arr.tolist()} at t = {t} s')


class GaitLengthError(ValueError):
    """A gait whose length reaches <= 0 in the run: l_j = x[j+1] - x[j] <= 0 means bodies j
    and j+1 meet or cross, which no crawler does (the model itself would run on: it uses l'
    and l'' only, so without this check such a run passed silently, issue 43).
    ``linkage``, ``time`` [s] and ``value`` [m] name the first such length found."""

    def __init__(self, linkage: int, time: float, value: float) -> None:
        self.linkage, self.time, self.value = int(linkage), float(time), float(value)
        super().__init__(f'gait length of linkage {self.linkage} reaches {self.value:.6g} m at '
                         f't = {self.time:.6g} s: lengths must stay > 0 (bodies {self.linkage} '
                         f'and {self.linkage + 1} would cross)')


def _first_bad(times: NDArray, values: NDArray) -> None:
    """Raise GaitLengthError for the earliest length <= 0 of ``values`` (per linkage, at
    ``times``), if any."""
    if values.min() > 0:
        return                      # the common case in one reduction
    bad = np.flatnonzero(values <= 0)
    if bad.size:
        j = int(bad[np.argmin(times[bad])])
        raise GaitLengthError(j, times[j], values[j])


def check_lengths(gait: Gait, t0: float, t1: float) -> bool:
    """Refuse (GaitLengthError) a gait whose length reaches <= 0 on [t0, t1], from its closed
    form ``length_minimum`` before any work; returns False when the gait gives none (then
    ``simulate`` checks the run's samples). Only a built-in gait that runs as its own compiled
    kind is asked: a subclass that overrides an evaluation runs through its Python methods, so
    its parent's closed form may not be what the solver sees."""
    if type(gait).length_minimum is Gait.length_minimum:
        return False            # the common streaming case (PiecewiseCubic): one lookup
    native = isinstance(gait, BuiltinGait) and gait.compiled() is gait.__dict__.get('_native_kind')
    if not native:
        return False
    found = gait.length_minimum(t0, t1)
    if found is None:
        return False
    _first_bad(*found)
    return True


def check_stiction(crawler: Crawler, method: str) -> None:
    """Refuse (ValueError naming ``method``) a crawler with stiction for a method that cannot
    simulate it (``capabilities(method).stiction`` False)."""
    if crawler.has_stiction and not capabilities(method).stiction:
        able = [name for name in METHODS if capabilities(name).stiction]
        why = getattr(solver_class(method), 'stiction_refusal', '')   # the method's reason
        raise ValueError(f'method {method!r} cannot simulate static friction above kinetic '
                         f'(the crawler has static_friction > friction'
                         f'{"; " + why if why else ""}): use '
                         f'{" or ".join(map(repr, able)) or "no method yet"}')


def check_initial_stuck(crawler: Crawler, gait: Gait, t0: float, v0: float,
                        initial_stuck: int | None) -> int | None:
    """``initial_stuck`` checked: None, or the index of a body at rest at t0 (body 0 moves at
    v0 [m/s]; body i at v0 + s_i'(t0), s_i its offset from body 0). ValueError naming
    ``initial_stuck`` otherwise."""
    if initial_stuck is None:
        return None
    if isinstance(initial_stuck, bool) or not isinstance(initial_stuck, (int, np.integer)) \
            or not 0 <= initial_stuck < crawler.p:
        raise ValueError(f'initial_stuck must be None or a body index in [0, {crawler.p - 1}], '
                         f'got {initial_stuck!r}')
    i = int(initial_stuck)
    ld = np.asarray(gait.at(t0)[1], dtype=float)
    v_i = v0 + float(np.sum(ld[:i]))        # s_i' = l_0' + ... + l_{i-1}'
    if v_i != 0.0:
        raise ValueError(f'initial_stuck: body {i} must be at rest at t0 = {t0} s to count as '
                         f'stuck before it, but it moves at {v_i!r} m/s (v0 = {v0!r} m/s); '
                         f'give v0 = {v0 - v_i!r} to start it at rest')
    return i


class Stepper:
    """Incremental integration of one crawler for streaming use.

    Parameters
    ----------
    crawler, gait : the crawler and the gait valid from t0 on (it can change at each advance).
    method : "exact" (default), "implicit" or "penalty".
    t0, x0, v0 : start time [s], position [m] and velocity [m/s] of body 0.
    dt : step [s] of "implicit" and "penalty" (default 1e-3).
    penalty : the seed's n [N s/m] for "penalty", one float or one per body.
    tol : event time tolerance of "exact" [s]; max_step : largest step between event checks [s].
    keep_history : keep every segment / event for later sampling (``simulate`` does); streaming
        use leaves it off and drains events with ``pop_events``.
    periodic_skip : let a method that can (``capabilities(method).periodic_skip``) skip gait
        periods that repeat; None (default): decided from the scene (see ``ExactSolver``).
    stiction_rule : the rule at a coincident rest of a crawler with stiction
        (``core.friction.RULES``): 'incumbent' (Rule S, default: the cluster stuck just before
        holds first, then the largest static margin) or 'margin' (largest margin alone).
        STICTION.md T5 is where they differ. Without stiction it changes nothing.
    initial_stuck : None (default: no body counts as stuck before t0, so Rule S chooses the
        mode at t0 from the margins), or the index of a body at rest at t0 whose cluster counts
        as stuck just before t0 (the incumbent; ValueError naming ``initial_stuck`` if that body
        is not at rest: v0 plus its offset rate from body 0 must be 0). To start with body i
        stuck, give the v0 that puts it at rest and ``initial_stuck=i``.

    A crawler with stiction (``crawler.has_stiction``) needs a method whose
    ``capabilities(method).stiction`` is True; the others are refused (ValueError naming
    ``method``).

    A failed step raises ``solvers.base.SolverError`` (the solver's ``status`` and ``message``)
    or, for a gait value or state that is not finite, ValueError. ``advance`` refuses a gait
    whose closed-form minimum length (``Gait.length_minimum``: Sinusoid, Scallop) is <= 0 on
    [t, t1] with ``GaitLengthError`` (a ValueError) before any work; other gaits are not
    checked while streaming (the node bounds its lengths by ``min_length`` itself).
    """

    def __init__(self, crawler: Crawler, gait: Gait, method: str = 'exact', *, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0, dt: float | None = None,
                 penalty: ArrayLike | None = None, tol: float = 1e-13,
                 max_step: float | None = None, keep_history: bool = False,
                 periodic_skip: bool | None = None, stiction_rule: str = DEFAULT_RULE,
                 initial_stuck: int | None = None) -> None:
        self.method = _check_method(method)
        t0, x0, v0 = _check_finite('t0', t0), _check_finite('x0', x0), _check_finite('v0', v0)
        check_gait(gait, crawler, t0)
        check_stiction(crawler, method)
        check_rule(stiction_rule)
        initial_stuck = check_initial_stuck(crawler, gait, t0, v0, initial_stuck)
        self.crawler = crawler
        cls = solver_class(method)
        self._options = cls.options(dt=dt, penalty=penalty, tol=tol, max_step=max_step,
                                    keep_history=keep_history, periodic_skip=periodic_skip,
                                    stiction_rule=stiction_rule, initial_stuck=initial_stuck)
        self._solver = cls(crawler, gait, t0=t0, x0=x0, v0=v0, **self._options)
        self._keep = keep_history
        self._n_events_read = 0

    @property
    def t(self) -> float:
        """Current time [s]."""
        return self._solver.t

    @property
    def gait(self) -> Gait:
        return self._solver.gait

    @property
    def solver(self) -> object:
        """The method's solver object (segments, steps, counters)."""
        return self._solver

    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Integrate to t1 [s] (>= t) with ``gait`` (or the previous one) valid on [t, t1]."""
        t1 = _check_finite('t1', t1)
        t = self._solver.t
        if t1 < t:
            raise ValueError(f't1 must be >= the current time {t} s, got {t1}')
        if gait is not None:
            check_gait(gait, self.crawler, t)
        check_lengths(self.gait if gait is None else gait, t, t1)
        self._solver.advance(t1, gait)

    def _row(self) -> dict:
        return self._solver.current()

    @property
    def state(self) -> State:
        """The crawler at the current time (left limit at an event)."""
        r = self._row()
        inc = r.get('incumbent')
        return State(self.t, r['x'], r['v'], r['friction'], r['contact'].astype(np.int8),
                     r['linkage_force'], r['lengths'], r['rates'], bool(r['indeterminate']),
                     None if inc is None else np.asarray(inc, dtype=bool).copy())

    def read_state(self, x: NDArray[np.float64], v: NDArray[np.float64],
                   contact: NDArray[np.int8]) -> None:
        """``state``'s x [m], v [m/s] and contact written into (p,) float64, float64 and int8
        arrays: the exact method's core writes them from the last segment without a State
        (bit for bit the same values; the environments' step reads only these, issue 41);
        otherwise they are copied from ``state``."""
        core = self._solver._core if type(self._solver) is ExactSolver else None
        if core is None or not core.read_state(x, v, contact):
            st = self.state
            x[:], v[:], contact[:] = st.x, st.v, st.contact

    def pop_events(self) -> list[Event]:
        """Contact events since the last call, in time order."""
        ev = self._solver.events
        n = len(ev)
        start = self._n_events_read
        if n <= start:
            out = ()             # none new (most calls of a stream): no slice of the log
        elif start == 0 and type(ev) is EventLog:
            out = ev.compact()   # all of it (a stream's events): its list, not n index reads
        else:
            out = ev[start:]
        if self._keep:
            self._n_events_read = n
        else:
            # streaming: drop what was read so a long run does not accumulate events
            ev.clear()
            if hasattr(self._solver, 'forget_history'):
                self._solver.forget_history()
        return list(out)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0,
              initial_stuck: int | None = None) -> None:
        """Back to an initial state (events are cleared); ``initial_stuck`` as in the
        constructor (None: no incumbent; it is not carried over from before the reset)."""
        initial_stuck = check_initial_stuck(self.crawler, self.gait, t0, v0, initial_stuck)
        if initial_stuck is None:
            self._solver.reset(t0=t0, x0=x0, v0=v0)
        else:       # (a method without stiction has no incumbent to set)
            self._solver.reset(t0=t0, x0=x0, v0=v0, initial_stuck=initial_stuck)
        self._n_events_read = 0


def _check_times(t_eval: ArrayLike, t_end: float) -> NDArray:
    t = np.asarray(t_eval, dtype=float).ravel()
    first, last = (float(t[0]), float(t[-1])) if t.size else (math.nan, math.nan)
    # sorted with finite ends means finite throughout (a NaN breaks the order): one pass
    ordered = bool((t[1:] >= t[:-1]).all())
    if not (math.isfinite(first) and math.isfinite(last)) or not (ordered or np.isfinite(t).all()):
        raise ValueError('t_eval must be a non-empty list of finite times in [0, t_end] s')
    if first < 0 or last > t_end or not ordered:
        raise ValueError(f't_eval must be sorted and within [0, {t_end}] s')
    return t


def _events(events):
    """Every event as a list, or the exact method's ``EventLog`` (repeated periods stored
    once) beyond a million events, so memory stays independent of t_end."""
    return events.compact() if hasattr(events, 'compact') else list(events)


def _check_samples(times: NDArray, lengths: NDArray, lengths_check: str) -> None:
    """The first sampled length <= 0 of a gait without a closed-form minimum (the run's own
    samples, no extra evaluation of the gait): a UserWarning, or GaitLengthError when
    ``lengths_check`` is 'raise'. A warning, not a refusal, by default: it is found only after
    the work, and the model itself needs l' and l'' alone (gaits of any lengths are in use as
    offsets, e.g. random constant-jerk pieces in the tests)."""
    lengths = np.asarray(lengths)
    if lengths.size and not lengths.min() > 0:       # (a NaN is the solver's to report)
        bad = lengths <= 0
        if bad.any():
            k = int(np.argmax(bad.any(axis=1)))      # the first sample with one
            j = int(np.argmax(bad[k]))
            err = GaitLengthError(j, float(times[k]), float(lengths[k, j]))
            if lengths_check == 'raise':
                raise err
            warnings.warn(str(err), UserWarning, stacklevel=3)


def simulate(crawler: Crawler, gait: Gait, t_end: float, method: str = 'exact', *,
             dt: float | None = None, t_eval: ArrayLike | None = None, v0: float = 0.0,
             x0: float = 0.0, penalty: ArrayLike | None = None, tol: float = 1e-13,
             max_step: float | None = None, include_events: bool = True,
             periodic_skip: bool | None = None, lengths_check: str = 'warn',
             stiction_rule: str = DEFAULT_RULE, initial_stuck: int | None = None
             ) -> Trajectory:
    """Simulate the crawler under ``gait`` on [0, t_end] and return the sampled ``Trajectory``.

    With method "exact" the values at ``t_eval`` are exact (closed form, not interpolated) and,
    unless ``t_eval`` is given or ``include_events`` is False, the event times are added to the
    default uniform samples. "implicit" and "penalty" step with ``dt`` (default 1e-3 s) and land
    a step on every requested time. v0 / x0: initial velocity / position of body 0.
    ``tol`` / ``max_step`` / ``periodic_skip`` / ``stiction_rule`` / ``initial_stuck``: see
    ``Stepper`` (a crawler with static friction above kinetic needs a method whose
    ``capabilities(method).stiction`` is True).

    A gait length l_j(t) <= 0 within the run (bodies j and j+1 would cross) raises
    ``GaitLengthError`` (a ValueError naming the linkage, the time and the value) before any
    work when the gait knows its minimum in closed form (``Gait.length_minimum``: Sinusoid,
    Scallop); for other gaits the run's samples are checked after it (the first sampled length
    <= 0; a dip between two samples is not seen): a UserWarning with the same facts, or with
    ``lengths_check='raise'`` the GaitLengthError (scenes ask for it).
    """
    if not isinstance(crawler, Crawler):
        raise ValueError(f'crawler must be a crawler_sim.Crawler, got {type(crawler).__name__}')
    _check_method(method)
    if lengths_check not in ('warn', 'raise'):
        raise ValueError(f"lengths_check must be 'warn' or 'raise', got {lengths_check!r}")
    t_end = _check_positive('t_end', t_end)
    if dt is not None:
        dt = _check_positive('dt', dt)
    st = Stepper(crawler, gait, method, x0=x0, v0=v0, dt=dt, penalty=penalty, tol=tol,
                 max_step=max_step, keep_history=True, periodic_skip=periodic_skip,
                 stiction_rule=stiction_rule, initial_stuck=initial_stuck)
    solver = st.solver
    solver.check_span(gait, t_end, st._options)
    times = None if t_eval is None else _check_times(t_eval, t_end)
    known = check_lengths(gait, 0.0, t_end)
    times, out, info = solver.simulate(t_end, times, include_events, dt)
    if not known:
        _check_samples(times, out['lengths'], lengths_check)
    # a closed-form run's pieces stay with its Trajectory: state_at evaluates them
    dense = (DenseOutput(crawler, solver.gait, solver.segments, (0.0, solver.t),
                         tol=solver.tol, max_step=solver.max_step)
             if capabilities(method).dense_output else None)
    return Trajectory(t=times, x=out['x'], v=out['v'], friction=out['friction'],
                      contact=np.asarray(out['contact'], dtype=np.int8),
                      linkage_force=out['linkage_force'], impulse=out['impulse'],
                      lengths=out['lengths'], rates=out['rates'],
                      events=_events(solver.events), indeterminate=out['indeterminate'],
                      crawler=crawler, method=method, info=info, dense=dense)
