"""Simulation output: sampled states, stick/slip events and the locomotion figures."""
from __future__ import annotations

import bisect
import warnings
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from itertools import islice
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .friction import bounds
from .model import Crawler
from .solvers.base import Capabilities, capabilities

if TYPE_CHECKING:      # dense imports the solvers, which import this module
    from .dense import DenseOutput

__all__ = ['Event', 'EventLog', 'Trajectory', 'State', 'sample_frame']


class Event(NamedTuple):
    """A change of contact state of one body at ``time`` [s]: +1 forward, 0 stuck, -1 backward."""

    time: float
    body: int
    old: int
    new: int


class EventLog(Sequence):
    """Events in time order, with repeated gait periods stored once (a read-only sequence).

    The exact method's periodic skip adds ``n`` repetitions of one period's events as one
    block (its events, the period T and n); element k of the block is generated on access. So
    a long periodic run keeps memory independent of its length, while ``len``, indexing,
    slicing and iteration behave as on the list of every event.
    """

    def __init__(self) -> None:
        self._parts: list = []        # list[Event] runs, or (template, n, T) blocks
        self._ends: list[int] = []    # cumulative lengths

    def __len__(self) -> int:
        return self._ends[-1] if self._ends else 0

    def _tail(self) -> list:
        if not self._parts or not isinstance(self._parts[-1], list):
            self._parts.append([])
            self._ends.append(len(self))
        return self._parts[-1]

    def append(self, ev: Event) -> None:
        self._tail().append(ev)
        self._ends[-1] += 1

    def extend(self, evs: Iterable[Event]) -> None:
        evs = list(evs)
        self._tail().extend(evs)
        self._ends[-1] += len(evs)

    def add_periodic(self, template: list, n: int, T: float) -> None:
        """The events ``template`` (one period) repeated n times, shifted by T, 2 T, ... n T."""
        if template and n > 0:
            self._parts.append((list(template), int(n), float(T)))
            self._ends.append(len(self) + len(template) * int(n))

    def clear(self) -> None:
        self._parts.clear()
        self._ends.clear()

    def _get(self, k: int) -> Event:
        j = bisect.bisect_right(self._ends, k)
        part = self._parts[j]
        local = k - (self._ends[j - 1] if j else 0)
        if isinstance(part, list):
            return part[local]
        tpl, _, T = part
        rep, i = divmod(local, len(tpl))
        ev = tpl[i]
        return Event(ev.time + (rep + 1) * T, ev.body, ev.old, ev.new)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self._get(i) for i in range(*k.indices(len(self)))]
        n = len(self)
        k = int(k)
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError('event index out of range')
        return self._get(k)

    def __iter__(self):
        for part in self._parts:
            if isinstance(part, list):
                yield from part
            else:
                yield from _repeated(*part)

    def compact(self, limit: int = 1_000_000) -> list[Event] | EventLog:
        """A plain list when it holds at most ``limit`` events, else this log itself."""
        if len(self) > limit:
            return self
        if len(self._parts) == 1 and isinstance(self._parts[0], list):
            return list(self._parts[0])          # no repeated period: the list as it is
        return list(self)


#: an Event from a (time, body, old, new) tuple at C speed
new_event = partial(tuple.__new__, Event)
_REPS = 4096       # periods of a repeated block generated at once (bounded memory)
_CHUNK = 1 << 16   # events read at once by Trajectory.sliding_distance (bounded memory)


def _repeated(template: list, n: int, T: float) -> Iterator[Event]:
    """The events of one period (``template``) repeated n times, shifted by T, 2 T, ... n T
    (the times ``EventLog._get`` gives), built a few thousand periods at a time in numpy."""
    times = [ev.time for ev in template]
    rest = list(zip(*(ev[1:] for ev in template)))
    for r0 in range(1, n + 1, _REPS):
        k = min(_REPS, n + 1 - r0)
        # (rep T) + time, rep from r0: the float operations of ``_get``, in one array op
        shifted = np.add.outer(np.arange(r0, r0 + k) * T, times).ravel().tolist()
        yield from map(new_event, zip(shifted, *(col * k for col in rest)))


class State(NamedTuple):
    """The crawler at one instant (all arrays are copies owned by the caller).

    ``x``, ``v``, ``friction``, ``contact`` have shape (p,); ``lengths``, ``rates``,
    ``linkage_force`` shape (p-1,). Units: s, m, m/s, N. ``indeterminate`` is True when several
    bodies stick together and only their total friction is determined (MODEL.md section 2.5).
    ``incumbent`` (p,) bool marks the bodies of the cluster stuck just before t (all False:
    none), the one bit of state a crawler with stiction needs beyond (t, x, v) (STICTION.md
    s. 7); None where it is not known (a state built by hand, a method without stiction).
    ``Trajectory.state_at`` of N times returns the same fields with a leading time axis:
    ``t`` (N,), ``x`` (N, p), ..., ``indeterminate`` (N,) bool.
    """

    t: float
    x: NDArray[np.float64]
    v: NDArray[np.float64]
    friction: NDArray[np.float64]
    contact: NDArray[np.int8]
    linkage_force: NDArray[np.float64]
    lengths: NDArray[np.float64]
    rates: NDArray[np.float64]
    indeterminate: bool = False
    incumbent: NDArray[np.bool_] | None = None


def _caps(method: str) -> Capabilities:
    """What the run's method can do (none for a label no solver has: a hand-built run)."""
    return capabilities(method, strict=False)


def _trapezoid(y: NDArray, t: NDArray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulated run sampled at times ``t``.

    Attributes
    ----------
    t : (N,) s
    x, v : (N, p) body positions [m] and velocities [m/s]
    friction : (N, p) force the ground exerts on each body [N] (opposes its sliding)
    contact : (N, p) int8, +1 sliding forward, 0 stuck, -1 sliding backward (the names are
        those of a loaded bag, :class:`crawler_sim.bag.Run`, and of :class:`State`)
    linkage_force : (N, p-1) force linkage j exerts on body j+1 [N] (positive pushes apart)
    impulse : (N, p) integrated friction force since t[0] [N s] (the seed's k_i with sign flipped)
    lengths, rates : (N, p-1) linkage lengths [m] and rates [m/s]
    events : every contact change (Event) in (t[0], t[-1]]: a list, or for a long periodic run
        of the exact method (over a million events) an ``EventLog`` sequence that stores the
        repeated periods once (memory independent of t_end)
    indeterminate : (N,) bool, several bodies stuck together (friction split not unique)
    crawler, method : what produced it; ``info`` holds solver figures (segments, steps, bounds).
    dense : what :meth:`state_at` evaluates: the closed-form pieces of an exact run and the
        gait they read (``crawler_sim.core.dense.DenseOutput``, set by ``simulate``); None for
        "implicit" and "penalty" runs.
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    v: NDArray[np.float64]
    friction: NDArray[np.float64]
    contact: NDArray[np.int8]
    linkage_force: NDArray[np.float64]
    impulse: NDArray[np.float64]
    lengths: NDArray[np.float64]
    rates: NDArray[np.float64]
    events: list[Event]
    indeterminate: NDArray[np.bool_]
    crawler: Crawler
    method: str
    info: dict = field(default_factory=dict)
    dense: DenseOutput | None = field(default=None, repr=False)

    @property
    def state(self) -> NDArray[np.int8]:
        """Deprecated name of :attr:`contact` (before 0.4)."""
        warnings.warn('Trajectory.state is now Trajectory.contact (the name a loaded bag and '
                      'State use)', DeprecationWarning, stacklevel=2)
        return self.contact

    @property
    def com(self) -> NDArray[np.float64]:
        """Centre-of-mass position X(t) [m], shape (N,)."""
        m = self.crawler.masses
        return self.x @ (m / m.sum())

    @property
    def com_velocity(self) -> NDArray[np.float64]:
        """Centre-of-mass velocity V(t) [m/s], shape (N,)."""
        m = self.crawler.masses
        return self.v @ (m / m.sum())

    @property
    def displacement(self) -> float:
        """Net centre-of-mass displacement over the run [m] (positive forward)."""
        X = self.com
        return float(X[-1] - X[0])

    def state_at(self, t: float | ArrayLike) -> State:
        """The exact state at time(s) ``t`` [s] of an exact run (dense output).

        Parameters
        ----------
        t : float, or array of shape (N,), in any order, inside the integrated span [0, t_end]
            (the run's, even where ``t_eval`` sampled less of it).

        Returns
        -------
        State
            For a float, the state at t (arrays of shape (p,) and (p-1,)). For an array, the
            same fields with a leading axis of N: ``t`` (N,), ``x``, ``v``, ``friction``,
            ``contact`` (N, p), ``linkage_force``, ``lengths``, ``rates`` (N, p-1),
            ``indeterminate`` (N,), ``incumbent`` (N, p): the cluster stuck just before t
            (at an event, on the segment that ends there), as ``Stepper.state`` gives it.

        The closed form between events, inside periodically skipped periods too: the values a
        run sampled at t gives (``simulate(..., t_eval=[t])``), bit for bit, with no
        interpolation and no new integration (``crawler_sim.core.dense``). At an event time,
        the state a sample at that time holds. It reads the gait the run used, which the
        Trajectory keeps; a gait of Python functions through the pieces it was sampled into
        during the run (its functions are not called again).

        Raises
        ------
        RuntimeError
            For "implicit" and "penalty" runs: they keep no interpolant of their steps (sample
            them with ``simulate(..., t_eval=...)``, which lands a step on every time), and for
            a Trajectory without dense output (built by hand, or unpickled when its gait could
            not be pickled).
        ValueError
            If a time is not finite or lies outside [0, t_end].
        """
        if self.dense is None:
            why = (f'method {self.method!r} keeps no interpolant of its steps'
                   if not _caps(self.method).dense_output
                   else 'this Trajectory holds no dense output (only simulate sets it)')
            raise RuntimeError(f"state_at is the exact method's dense output: {why}; sample "
                               'the run at the times you need with simulate(..., t_eval=...)')
        times = np.asarray(t, dtype=float)
        if times.ndim > 1:
            raise ValueError(f't must be a float or a 1-d array of times [s], got shape '
                             f'{times.shape}')
        flat = times.reshape(-1)
        lo, hi = self.dense.span
        if flat.size and not (np.isfinite(flat).all() and lo <= flat.min()
                              and flat.max() <= hi):
            bad = flat[~(np.isfinite(flat) & (flat >= lo) & (flat <= hi))][0]
            raise ValueError(f't must be finite and within the run [{lo!r}, {hi!r}] s, got '
                             f'{float(bad)!r}')
        order = np.argsort(flat, kind='stable')
        out = self.dense.sample(flat[order])
        back = np.empty_like(order)
        back[order] = np.arange(order.size)
        f = {k: np.asarray(v)[back] for k, v in out.items()}
        contact = f['contact'].astype(np.int8)
        ind = f['indeterminate'].astype(bool)
        # the incumbent (N, p) bool: the cluster stuck on the piece before each time
        from .solvers.exact import incumbent_at      # (the solvers import this module)
        inc = incumbent_at(self.dense.segments, flat, self.crawler.p)
        if times.ndim == 0:
            return State(float(times), f['x'][0], f['v'][0], f['friction'][0], contact[0],
                         f['linkage_force'][0], f['lengths'][0], f['rates'][0], bool(ind[0]),
                         None if inc is None else inc[0])
        return State(flat.copy(), f['x'], f['v'], f['friction'], contact, f['linkage_force'],
                     f['lengths'], f['rates'], ind, inc)

    def _com_at(self, t: float) -> float:
        """Centre of mass X(t) [m]: a sample's when t is one, else the exact dense output; for
        an "implicit" or "penalty" run, linear between samples (the O(dt) schemes' own
        interpolant when the samples are their steps)."""
        k = int(np.searchsorted(self.t, t))
        if k < self.t.size and self.t[k] == t:
            return float(self.com[k])
        if self.dense is not None or _caps(self.method).dense_output:
            m = self.crawler.masses
            return float(self.state_at(t).x @ (m / m.sum()))
        return float(np.interp(t, self.t, self.com))

    def mean_speed(self, period: float | None = None) -> float:
        """Mean centre-of-mass speed [m/s] (positive forward).

        With ``period`` [s] (e.g. the gait period), the displacement over the last whole
        period [t_end - period, t_end] divided by it: the steady speed after the initial
        transient. Without it, over the run. For an exact run the centre of mass at
        t_end - period is exact (a sample, or :meth:`state_at`); for "implicit" and "penalty"
        it is interpolated linearly between samples (first order, as the schemes are).
        """
        X = self.com
        if period is None:
            return float((X[-1] - X[0]) / (self.t[-1] - self.t[0]))
        if not period > 0 or period > self.t[-1] - self.t[0]:
            raise ValueError(f'period must be in (0, {self.t[-1] - self.t[0]}] s, got {period!r}')
        t_start = float(self.t[-1] - period)
        return float((X[-1] - self._com_at(t_start)) / period)

    @property
    def stick_fraction(self) -> NDArray[np.float64]:
        """Fraction of the run each body spends stuck, shape (p,), from the exact event times."""
        t0, t1 = float(self.t[0]), float(self.t[-1])
        state = self.contact[0].astype(int).copy()
        last = np.full(state.size, t0)
        stuck = np.zeros(state.size)

        def run(events, shift=0.0) -> bool:
            for ev in events:
                time = ev.time + shift
                if time > t1:
                    return False
                if state[ev.body] == 0:
                    stuck[ev.body] += time - last[ev.body]
                state[ev.body] = ev.new
                last[ev.body] = time
            return True
        parts = self.events._parts if isinstance(self.events, EventLog) else [self.events]
        for part in parts:
            if isinstance(part, list):
                if not run(part):
                    break
                continue
            # a periodic block: every repetition adds the same stuck time per body
            tpl, n, T = part
            k_full = min(n, int((t1 - tpl[-1].time) // T))   # repetitions inside [.., t1]
            start = 1
            if k_full >= 2:
                before = stuck.copy()
                run(tpl, T)
                moved = np.zeros(state.size, bool)
                moved[[ev.body for ev in tpl]] = True
                stuck += (k_full - 1) * (stuck - before)
                last[moved] += (k_full - 1) * T
                start = k_full + 1
            done = False
            for rep in range(start, n + 1):
                if not run(tpl, rep * T):
                    done = True
                    break
            if done:
                break
        stuck += np.where(state == 0, t1 - last, 0.0)
        return stuck / (t1 - t0) if t1 > t0 else (state == 0).astype(float)

    def sliding_distance(self, start: float | None = None, end: float | None = None
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Distance each body slides forward and backward over [start, end] [m] (default: the
        run), two arrays of shape (p,), each >= 0.

        Between two consecutive event times a body keeps its direction or stays stuck (a
        reversal is an event), so over each interval between nodes its travel is the positive
        or the negative part of its displacement. For an exact run the nodes are the samples,
        every event and the window's ends (read with :meth:`state_at`): exact. Otherwise (no
        dense output) they are the samples in [start, end]: exact when every event time is a
        sample (the default samples of "exact"), else a lower bound to the sampling step.
        """
        t = self.t
        a = float(t[0]) if start is None else float(start)
        b = float(t[-1]) if end is None else float(end)
        if not t[0] <= a <= b <= t[-1]:
            raise ValueError(f'the window [{start}, {end}] s must lie inside the run '
                             f'[{t[0]}, {t[-1]}] s')
        p = self.x.shape[1]
        fwd, back = np.zeros(p), np.zeros(p)
        i0, i1 = int(np.searchsorted(t, a, 'left')), int(np.searchsorted(t, b, 'right'))
        exact = self.dense is not None
        prev = self.state_at(a).x if exact and t[i0] != a else self.x[i0]

        def add(xs: NDArray) -> None:
            nonlocal prev
            if len(xs):
                d = np.diff(xs, axis=0, prepend=prev[None])
                fwd[:] += np.maximum(d, 0.0).sum(axis=0)
                back[:] += np.maximum(-d, 0.0).sum(axis=0)
                prev = xs[-1]
        k = i0
        if exact:
            # the events in (a, b), a chunk at a time (a long periodic run holds millions),
            # merged with the samples up to the chunk's last event
            it = iter(self.events)
            while True:
                ev = np.fromiter((e.time for e in islice(it, _CHUNK)), float)
                inside = ev[(ev > a) & (ev < b)]
                if inside.size:
                    j = max(k, int(np.searchsorted(t, inside[-1], 'right')))
                    times = np.concatenate([inside, t[k:j]])
                    xs = np.concatenate([self.state_at(inside).x, self.x[k:j]])
                    add(xs[np.argsort(times, kind='stable')])
                    k = j
                if ev.size < _CHUNK or ev[-1] >= b:
                    break
        add(self.x[k:i1])
        if exact and t[i1 - 1] != b:
            add(self.state_at(b).x[None])
        return fwd, back

    @property
    def dissipated_energy(self) -> float:
        """Energy dissipated by friction, integral of -sum_i friction_i v_i dt [J] (>= 0).

        Each body's friction is constant while it slides one way (its kinetic bound: a stuck
        body dissipates nothing, whatever its static bound), so this is
        sum_i friction_i * forward_i + friction_backward_i * backward_i over the distances
        of :meth:`sliding_distance`: exact for an exact run. For "implicit" and "penalty",
        the trapezoidal rule over the samples (exact in stick, accurate to the step
        elsewhere).
        """
        if not _caps(self.method).closed_form:
            return _trapezoid(-np.sum(self.friction * self.v, axis=1), self.t)
        fwd, back = self.sliding_distance()
        b = bounds(self.crawler)
        return float(b.kinetic_forward @ fwd + b.kinetic_backward @ back)

    @property
    def actuator_work(self) -> float:
        """Work done by the linkages, integral of sum_j linkage_force_j l_j' dt [J].

        For an exact run from the energy balance, which holds exactly (the linkage forces'
        power on the bodies is sum_j linkage_force_j l_j'): the kinetic energy gained plus
        :attr:`dissipated_energy` minus the work of gravity along the slope, all exact. For
        "implicit" and "penalty", the trapezoidal rule over the samples.
        """
        if not _caps(self.method).closed_form:
            return _trapezoid(np.sum(self.linkage_force * self.rates, axis=1), self.t)
        c = self.crawler
        kinetic = 0.5 * c.masses @ (self.v[-1] ** 2 - self.v[0] ** 2)
        gravity = c.gravity_forces @ (self.x[-1] - self.x[0])
        return float(kinetic + self.dissipated_energy - gravity)

    def positive_work(self, start: float | None = None, end: float | None = None) -> float:
        """Integral of the positive part of the actuator power sum_j linkage_force_j l_j'
        over [start, end] [J] (default: the run; motors do not regenerate).

        For an exact run, from its dense output: the power's sign changes found and each
        stretch between them and the pieces' boundaries integrated in closed form where the
        gait is polynomial (the node's constant-jerk pieces, bang-bang strokes), else by
        adaptive Gauss-Legendre quadrature to ~1e-13 of the integral of |power|
        (``DenseOutput.positive_work``; whole skipped periods counted as their template
        period). Otherwise the trapezoidal rule over the samples in [start, end].
        """
        t = self.t
        a = float(t[0]) if start is None else float(start)
        b = float(t[-1]) if end is None else float(end)
        if not t[0] <= a <= b <= t[-1]:
            raise ValueError(f'the window [{start}, {end}] s must lie inside the run '
                             f'[{t[0]}, {t[-1]}] s')
        if self.dense is not None:
            return self.dense.positive_work(a, b)
        i0, i1 = int(np.searchsorted(t, a, 'left')), int(np.searchsorted(t, b, 'right'))
        power = np.sum(self.linkage_force[i0:i1] * self.rates[i0:i1], axis=1)
        return _trapezoid(np.maximum(power, 0.0), t[i0:i1])

    @property
    def positive_actuator_work(self) -> float:
        """Integral of the positive part of the actuator power over the run [J]
        (:meth:`positive_work`: exact for an exact run)."""
        return self.positive_work()

    @property
    def cost_of_transport(self) -> float:
        """Positive actuator work / (M g |displacement|), dimensionless (inf if it did not
        move); exact for an exact run."""
        c = self.crawler
        d = abs(self.displacement)
        denom = c.total_mass * c.gravity * d
        return float(self.positive_actuator_work / denom) if denom > 0 else float('inf')

    def __len__(self) -> int:
        return int(self.t.size)

    def __repr__(self) -> str:
        """One line for a notebook: bodies, method, span, samples, events, mean speed (the
        dataclass's own repr printed every array in full)."""
        t = self.t
        if not t.size:
            return f'Trajectory(p={self.x.shape[-1]}, method={self.method!r}, no samples)'
        span = float(t[-1] - t[0])
        speed = f'{self.mean_speed():.6g} m/s' if span > 0 else 'n/a'
        return (f'Trajectory(p={self.x.shape[1]}, method={self.method!r}, '
                f't=[{t[0]:g}, {t[-1]:g}] s, {t.size} samples, {len(self.events)} events, '
                f'mean speed {speed})')

    def to_pandas(self) -> 'pandas.DataFrame':  # noqa: F821 - pandas is optional
        """The samples as a pandas DataFrame (:func:`sample_frame`: index ``t`` [s]; per body
        ``x_i``, ``v_i``, ``friction_i``, ``contact_i``; per linkage ``length_j``, ``rate_j``,
        ``linkage_force_j``; ``com``). The events: ``pandas.DataFrame(trajectory.events)``.
        Needs pandas (``pip install pandas``)."""
        return sample_frame(self.t, self.x, self.v, self.friction, self.contact, self.lengths,
                            self.rates, self.linkage_force, self.crawler.masses)


def sample_frame(t: ArrayLike, x: ArrayLike, v: ArrayLike, friction: ArrayLike,
                 contact: ArrayLike, lengths: ArrayLike, rates: ArrayLike,
                 linkage_force: ArrayLike, masses: ArrayLike | None = None
                 ) -> 'pandas.DataFrame':  # noqa: F821 - pandas is optional
    """The one table layout of a run's samples (a Trajectory, a loaded bag, an export): index
    ``t`` [s]; per body i ``x_i`` [m], ``v_i`` [m/s], ``friction_i`` [N], ``contact_i`` (int8,
    when recorded); per linkage j ``length_j`` [m], ``rate_j`` [m/s], ``linkage_force_j`` [N];
    and ``com`` [m] when the masses are given. ImportError naming the pip command without
    pandas."""
    try:
        import pandas as pd
    except ImportError as exc:
        raise ImportError('a table of a run needs pandas, which is not installed: '
                          'pip install pandas', name='pandas') from exc
    x = np.asarray(x, dtype=np.float64)
    lengths = np.asarray(lengths, dtype=np.float64)
    cols: dict[str, NDArray] = {}
    p, n = x.shape[1], lengths.shape[1]
    for name, arr in (('x', x), ('v', v), ('friction', friction)):
        arr = np.asarray(arr)
        for i in range(p):
            cols[f'{name}_{i}'] = np.asarray(arr[:, i], dtype=np.float64)
    contact = np.asarray(contact)
    for i in range(contact.shape[1]):       # none from a bag recorded without contact_states
        cols[f'contact_{i}'] = np.asarray(contact[:, i], dtype=np.int8)
    for name, arr in (('length', lengths), ('rate', rates), ('linkage_force', linkage_force)):
        arr = np.asarray(arr)
        for j in range(n):
            cols[f'{name}_{j}'] = np.asarray(arr[:, j], dtype=np.float64)
    if masses is not None:
        m = np.asarray(masses, dtype=np.float64)
        cols['com'] = x @ (m / m.sum())
    return pd.DataFrame(cols, index=pd.Index(np.asarray(t, dtype=np.float64), name='t'))
