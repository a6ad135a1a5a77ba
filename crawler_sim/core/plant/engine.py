"""The plant: the actuator and the crawler on a fixed tick grid, and every input that changes it.

``Engine`` is the one owner of the simulated plant. sim_node, ``crawler-sim replay``, the
offline runs "as the node runs them" (``streams``) and the optimiser drive it through its input
methods only: ``command`` (target lengths), ``trajectory`` (timed points), ``reconfigure`` (new
parameters: masses and p, friction, method, actuator limits), ``reset``, ``pause`` and
``resume``. Each input takes effect at the current tick boundary and is handed, with its time,
to the ``journal`` callback: a node records them, and replaying the journal through another
engine repeats the run bit for bit (``replay``).

Each tick the actuator model emits one constant-jerk piece of l(t) (``actuator.py``); the pieces
are queued and the core ``Stepper`` integrates them exactly in one call at each publish tick
(``sync``). The physics does not depend on where the integration is cut, only the rounding does,
so sync points are part of the determinism contract: the publish grid (every ``publish_every``
ticks) and explicit ``sync()`` calls. Times are integer nanoseconds.

With stiction (static friction above kinetic, STICTION.md) the state has one more part: the
cluster stuck just before now (the incumbent, ``State.incumbent``), which Rule S needs at a
coincident rest. It lives in the core ``Stepper`` across sync cuts; where the engine starts a
new stepper it is handed on: a reconfigure (new crawler, method, step or ``stiction_rule``)
starts the new stepper with the old one's incumbent (``initial_stuck``), and a start, a reset
or a contained failure begins at rest with no incumbent: Rule S chooses at that instant by the
static margins, which for a crawler at rest (every body stuck before, so every rigid part
incumbent) is the same choice. (Naming one body, ``initial_stuck=0``, would favour it when a
command lands on the reset tick, unlike the same command a tick later.) Without stiction
nothing of this is passed, so such runs are bit for bit what they were before stiction.

Runs of ticks with no input in between (``tick_to_grid``, ``run_to``) are one compiled run of
the actuator (``Actuator.run``, the pieces as arrays) and reach the exact solver as one
array-built ``PiecewiseCubic``: the same pieces, gaits and states, bit for bit, as ``tick()``
repeated. With nothing queued and the exact method, a run up to the publish grid and its sync
are the plant's compiled step (``_batch.PlantStep``, issue 41): the actuator writes its pieces
into the table the exact core integrates, with no Python call in between, and hands back to
the methods here (``_gait``, ``_integrate``) whatever it does not handle; the
vector environment steps N engines through the same function (``_batch.step_plants``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, Sequence

import numpy as np

from ..actuator import Actuator, ActuatorLimits, Pieces, TrajectoryReference
from ..friction import DEFAULT_RULE
from ..gaits import Cubic, Gait, PiecewiseCubic
from ..model import Crawler
from ..solvers.base import SolverError, capabilities
from ..stepper import Stepper
from ..solvers._exact import event_records as _event_records
from ..trajectory import Event, State, new_event
from .inputs import PreparedTrajectory
from ._batch import plant_step as _plant_step
from ..simtime import to_seconds

#: what a tick's integration may raise without stopping the plant: a failed step
#: (``SolverError``), a command the solver cannot take (ValueError: a gait of the wrong shape or
#: not finite), a runaway state overflowing a float conversion (ArithmeticError)
_FAILURES = (SolverError, ValueError, ArithmeticError)

__all__ = ['Engine', 'EngineConfig', 'Journal']

#: journal(kind, t_ns, payload): kind is 'command' (lengths), 'trajectory'
#: (PreparedTrajectory or None), 'configure' and 'reset' (EngineConfig), 'pause', 'resume' and
#: 'sync' (an integration cut off the publish grid) (None)
Journal = Callable[[str, int, Any], None]


@dataclass(frozen=True)
class EngineConfig:
    """What the engine needs (units: s, m, ns); ``values``: the parameter values it was made
    from (``PlantConfig``), kept for the journal."""

    crawler: Crawler
    method: str
    dt_ns: int                           # tick length [ns]
    publish_every: int                   # sync every this many ticks
    initial_lengths: Sequence[float]     # [m]
    initial_position: float              # body 0 [m]
    limits: ActuatorLimits
    penalty: Sequence[float] | None = None
    values: dict | None = field(default=None, compare=False, repr=False)
    stiction_rule: str = DEFAULT_RULE    # Rule S at a coincident rest (core.friction.RULES)

    def stepper_options(self) -> dict[str, Any]:
        """The stiction options of a core ``Stepper`` of this plant: none without stiction
        (the stepper's defaults; runs stay what they were before stiction)."""
        if not self.crawler.has_stiction:
            return {}
        return {'stiction_rule': self.stiction_rule}


class _NoEvents(list):
    """The event list of an engine with ``keep_events=False``: whatever is added is dropped
    (the compiled step and the Python paths add to it alike)."""

    def append(self, item: Any) -> None:
        pass

    def extend(self, items: Any) -> None:
        pass


class Engine:
    """Actuator + core stepper on a fixed tick grid in integer nanoseconds."""

    def __init__(self, cfg: EngineConfig, t_ns: int = 0, journal: Journal | None = None, *,
                 integrate: bool = True, keep_events: bool = True) -> None:
        """``integrate=False``: the actuator only; the pieces it emits are kept for
        :meth:`actuator_output` instead of being integrated (an offline run hands them to the
        core in one call, ``streams``). ``keep_events=False``: contact events are dropped
        (:meth:`pop_events` returns none), so a plant that never pops them (a Gymnasium
        env, an episode without end) does not grow."""
        self.failures: list[str] = []
        self.keep_events = keep_events
        self.journal = journal
        self.paused = False
        self.integrate = integrate
        # integrate=False: what the actuator emitted, the queue's runs (``_drain``) in order
        self._log: list = []
        self._step: Any = None
        self._build(cfg, t_ns)

    # ------------------------------------------------------------------ inputs
    def command(self, lengths: Sequence[float]) -> None:
        """Step targets [m], one per linkage, from the current tick boundary (cancels a
        trajectory)."""
        lengths = [float(x) for x in lengths]
        if len(lengths) != self.actuator.n_links:
            self.actuator.set_target(lengths)     # raises its ValueError
        self.actuator._set_target(lengths)
        self._note('command', lengths)

    def trajectory(self, prepared: PreparedTrajectory | None) -> None:
        """Follow timed points from the current tick boundary (None or no point: hold the
        current length). Raises ValueError, changing nothing, when the point times cannot be
        used at this sim time or the interpolation leaves [min_length, max_length]
        (``PreparedTrajectory.reference``)."""
        if prepared is None or not len(prepared.tfs_ns):
            self.actuator.set_trajectory(None)
        else:
            self.actuator.set_trajectory(self.check_trajectory(prepared))
        self._note('trajectory', prepared)

    def check_trajectory(self, prepared: PreparedTrajectory) -> TrajectoryReference:
        """The reference ``trajectory(prepared)`` would follow from the current tick boundary
        (ValueError as there, nothing changed); kept with ``prepared``, so applying it in the
        same tick builds it once (a node checks a trajectory when it arrives)."""
        v = self.cfg.values or {}
        lo, hi = v.get('min_length', -math.inf), v.get('max_length', math.inf)
        return prepared.reference(self.t_ns, self.actuator.state(), lo, hi)

    def reconfigure(self, cfg: EngineConfig) -> bool:
        """New parameters from the current tick boundary. A change of p starts again at rest
        in the initial configuration (returns True); a new crawler, method, step or stiction
        rule keeps the bodies' positions and velocities, and with stiction the cluster stuck
        before (``_handover``); new actuator limits keep its state."""
        old = self.cfg
        if cfg.crawler.p != old.crawler.p:
            self._build(cfg, self.t_ns)
            self._note('configure', cfg)
            return True
        if (cfg.crawler.to_dict() != old.crawler.to_dict() or cfg.method != old.method
                or cfg.dt_ns != old.dt_ns or cfg.penalty != old.penalty
                or cfg.stepper_options() != old.stepper_options()):
            self._restart_stepper(cfg)
        else:
            self.sync()
            self.cfg = cfg
            self._step = None           # the publish grid may have changed
            if cfg.limits != old.limits:
                self.actuator.configure(limits=cfg.limits)
        self._note('configure', cfg)
        return False

    def reset(self, cfg: EngineConfig | None = None, t_ns: int | None = None) -> None:
        """Back to rest in the initial configuration (of ``cfg``, default the current one) at
        the current sim time (or at ``t_ns``, a tick boundary at or after it: a node that
        follows another's clock starts at that clock's time); events not popped yet are
        dropped."""
        cfg = cfg or self.cfg
        if t_ns is None:
            t_ns = self.t_ns
        elif t_ns % cfg.dt_ns:
            t_ns += cfg.dt_ns - t_ns % cfg.dt_ns
        self._build(cfg, t_ns)
        self._note('reset', self.cfg)

    def pause(self) -> None:
        """Stop ticking (the caller does not tick a paused engine; sim time stands still)."""
        self.paused = True
        self._note('pause', None)

    def resume(self) -> None:
        self.paused = False
        self._note('resume', None)

    def _note(self, kind: str, payload: Any) -> None:
        if self.journal is not None:
            self.journal(kind, self.t_ns, payload)

    # ------------------------------------------------------------------ building
    def _build(self, cfg: EngineConfig, t_ns: int) -> None:
        """(Re)start at rest in the initial configuration at sim time ``t_ns``."""
        self.cfg = cfg
        self.t_ns = t_ns
        dt = to_seconds(cfg.dt_ns)
        self.actuator = Actuator(list(cfg.initial_lengths), dt, cfg.limits)
        t = to_seconds(t_ns)
        rest = Cubic(t, list(cfg.initial_lengths), 0.0, 0.0, 0.0)
        self.stepper = Stepper(cfg.crawler, rest, cfg.method, t0=t, x0=cfg.initial_position,
                               v0=0.0, dt=dt, penalty=cfg.penalty, **cfg.stepper_options())
        self.stepper.pop_events()
        self._step = None               # the compiled step of these objects, made when needed
        # the queue of ticks not integrated yet: single ticks (tick()) as start times and Cubic
        # pieces, and runs of ticks as (number of single ticks queued before it, Pieces)
        self._starts: list[float] = []
        self._pieces: list[Cubic] = []
        self._blocks: list[tuple[int, Pieces]] = []
        # the events not popped yet, in order: Event tuples, and from the compiled step the
        # events of a call as one bytes of records (``_packed``: some are; made Events when
        # popped, so a run that does not pop them keeps no object per event)
        self._events: list = [] if self.keep_events else _NoEvents()
        self._packed = False

    def _restart_stepper(self, cfg: EngineConfig) -> None:
        """New crawler, method or step from the current state on (bodies keep x and v)."""
        self.sync()
        st = self.stepper.state
        t = to_seconds(self.t_ns)
        self.actuator.configure(dt=to_seconds(cfg.dt_ns), limits=cfg.limits)
        ls, vs, as_ = zip(*self.actuator.state())
        here = Cubic(t, list(ls), list(vs), list(as_), 0.0)
        self._events.extend(self.stepper.pop_events())
        v0, opts = _handover(st, here, cfg)
        self.stepper = Stepper(cfg.crawler, here, cfg.method, t0=t, x0=float(st.x[0]),
                               v0=v0, dt=to_seconds(cfg.dt_ns), penalty=cfg.penalty, **opts)
        self.stepper.pop_events()
        self.cfg = cfg
        self._step = None

    # ------------------------------------------------------------------ time
    @property
    def t(self) -> float:
        """Sim time [s] at the current tick boundary."""
        return to_seconds(self.t_ns)

    def tick(self) -> bool:
        """One tick of the actuator; integrates (syncs) on the publish grid.

        Returns True when this tick ended on the publish grid (the state is then current).
        """
        t0_ns = self.t_ns
        t1_ns = t0_ns + self.cfg.dt_ns
        t0 = to_seconds(t0_ns)
        self._starts.append(t0)
        self._pieces.append(self.actuator.step(t0, to_seconds(t1_ns)))
        self.t_ns = t1_ns
        if (t1_ns // self.cfg.dt_ns) % self.cfg.publish_every == 0:
            self.sync()
            return True
        return False

    def _ticks_to_grid(self) -> int:
        """How many ticks from now up to and including the next one that ends on the publish
        grid (tick k ends on it when (t1_ns // dt_ns) % publish_every == 0)."""
        every = self.cfg.publish_every
        return every - (self.t_ns // self.cfg.dt_ns) % every

    def _run(self, n: int) -> None:
        """``n`` ticks with no input in between, as one run of the actuator (queued)."""
        dt_ns = self.cfg.dt_ns
        self._blocks.append((len(self._pieces), self.actuator.run(self.t_ns, dt_ns, n)))
        self.t_ns += n * dt_ns

    def _fast(self) -> Any:
        """The compiled step of this engine (``_batch.PlantStep``: the actuator's run, its
        table and the exact integration in one pass), or False where only the Python path
        runs (``_batch.plant_step``); made once per stepper, actuator and configuration."""
        step = self._step
        if step is None:
            step = self._step = _plant_step(self) or False
        return step

    def _compiled(self) -> Any:
        """The compiled step when it may run the ticks up to the grid now (nothing queued,
        one made for these objects, ``_fast``, and still theirs), else None."""
        if self._pieces or self._blocks:
            return None
        step = self._step if self._step is not None else self._fast()
        return step if step and step.current() else None

    def tick_to_grid(self) -> int:
        """``tick()`` repeated up to and including the next tick that ends on the publish grid
        (which syncs); returns how many ticks ran. The same pieces, bit for bit, as calling
        ``tick()`` that many times: a caller that has nothing to apply between those ticks
        (the flat-out node between two publish ticks) saves the per-tick calls (one compiled
        run of the actuator, ``Actuator.run``; with nothing queued, the plant's compiled
        step, ``_batch``)."""
        step = self._compiled()
        if step is not None:
            return step.run()
        n = self._ticks_to_grid()
        self._run(n)
        self.sync()
        return n

    def run_to(self, t_ns: int) -> int:
        """``tick()`` repeated while the sim time is before ``t_ns`` [ns] (no input in between;
        syncs on the publish grid as ``tick()`` does); returns how many ticks ran. The same
        pieces and states, bit for bit, as those ticks one by one; an offline run
        (``integrate=False``, ``streams``) runs them as one compiled run of the actuator."""
        total = 0
        dt_ns, every = self.cfg.dt_ns, self.cfg.publish_every
        while self.t_ns < t_ns:
            n = -(-(t_ns - self.t_ns) // dt_ns)
            k = self._ticks_to_grid()
            if n < k:
                self._run(n)             # ends off the grid: queued, as single ticks are
            elif (step := self._compiled()) is not None:
                n = step.run()           # tick_to_grid() with nothing queued: compiled
            elif self.integrate:
                n = k                    # tick_to_grid(), k known
                self._run(n)
                self.sync()
            else:
                # without integration a sync only moves the queue to the log: one run up to
                # the last grid tick of the span (what is after it stays queued, as with tick())
                n = k + (n - k) // every * every
                self._run(n)
                self.sync()
            total += n
        return total

    def _drain(self) -> list[tuple[list[float], list[Cubic]] | Pieces]:
        """Empty the queue: the queued ticks in order, runs of single ticks as (starts, pieces)
        and runs of the actuator as ``Pieces``."""
        starts, pieces, blocks = self._starts, self._pieces, self._blocks
        self._starts, self._pieces, self._blocks = [], [], []
        out: list = []
        k = 0
        for at, block in blocks:
            if at > k:
                out.append((starts[k:at], pieces[k:at]))
                k = at
            out.append(block)
        if k < len(pieces):
            out.append((starts[k:], pieces[k:]))
        return out

    @staticmethod
    def _arrays(runs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(starts, anchors, coef) of the queued ticks (``_drain``) as arrays."""
        parts = [(r.starts, r.anchors, r.coef) if isinstance(r, Pieces)
                 else (np.array(r[0]), np.array([pc.t0 for pc in r[1]]),
                       np.array([pc._rows for pc in r[1]], dtype=float)) for r in runs]
        if len(parts) == 1:
            return parts[0]
        return tuple(np.concatenate(x) for x in zip(*parts))

    @staticmethod
    def _ticks(runs: list) -> tuple[list[float], list[Cubic]]:
        """The queued ticks (``_drain``) as start times and one Cubic each (the rest piece of
        a run is that same object, as ``step`` hands it out)."""
        if len(runs) == 1 and not isinstance(runs[0], Pieces):
            return runs[0]
        starts, pieces = [], []
        for r in runs:
            if isinstance(r, Pieces):
                starts += r.starts.tolist()
                pieces += [r.piece(k) for k in range(len(r.starts))]
            else:
                starts += r[0]
                pieces += r[1]
        return starts, pieces

    @staticmethod
    def _gait(runs: list) -> Gait:
        """The queued ticks (``_drain``) as the exact solver's gait: the piece itself when
        there is one, or when every tick is the same rest piece (the object the solver may
        already hold, so it continues without a gait switch), else one PiecewiseCubic (from
        arrays when the actuator ran in blocks, without a Cubic per tick)."""
        first = runs[0]
        if len(runs) == 1 and type(first) is Pieces and first.rest_from != 0 \
                and len(first.starts) > 1:
            # one run of the actuator that is not a rest window (a control period): what the
            # general path below returns, without its checks
            return PiecewiseCubic.from_arrays(first.starts, first.anchors, first.coef)
        if len(runs) == 1 and not isinstance(first, Pieces):
            starts, pieces = first
            return pieces[0] if len(pieces) == 1 or all(pc is pieces[0] for pc in pieces) \
                else PiecewiseCubic.trusted(starts, pieces)
        if isinstance(first, Pieces):
            if len(runs) == 1 and len(first.starts) == 1:
                return first.piece(0)
            obj = first.rest_piece if first.rest_from == 0 else None
        else:
            obj = first[1][0]
        if obj is not None and all(
                (r.rest_from == 0 and r.rest_piece is obj) if isinstance(r, Pieces)
                else all(pc is obj for pc in r[1]) for r in runs):
            return obj
        return PiecewiseCubic.from_arrays(*Engine._arrays(runs))

    def sync(self) -> None:
        """Integrate the queued pieces up to the current tick boundary."""
        if not (self._pieces or self._blocks):
            return
        if not self.integrate:
            for run in self._drain():
                last = self._log[-1] if self._log else None
                if isinstance(run, Pieces) or last is None or isinstance(last, Pieces):
                    self._log.append(run)
                else:                   # single ticks after single ticks: one run
                    last[0].extend(run[0])
                    last[1].extend(run[1])
            return
        if (self.t_ns // self.cfg.dt_ns) % self.cfg.publish_every:
            # off the publish grid: where the integration is cut changes the rounding, so a
            # replay must cut here too
            self._note('sync', None)
        blocks = self._blocks
        if len(blocks) == 1 and not self._pieces:
            # one run of the actuator and no single ticks (a control period): ``_drain``'s
            # result without its loop and new lists
            self._blocks = []
            runs = [blocks[0][1]]
        else:
            runs = self._drain()
        t1 = to_seconds(self.t_ns)
        if not _fixed_step(self.stepper.method):
            self._integrate(t1, self._gait(runs))
            return
        try:
            # time stepping: one call per tick keeps its steps on the tick grid
            starts, pieces = self._ticks(runs)
            ends = starts[1:] + [t1]
            for end, piece in zip(ends, pieces):
                self.stepper.advance(end, piece)
        except _FAILURES as exc:
            self._contain(exc)
            return
        self._events.extend(self.stepper.pop_events())

    def _integrate(self, t1: float, gait: Gait, failed: int | None = None) -> None:
        """The queued ticks' ``gait`` integrated up to t1 [s] by an event-driven method
        (``sync``'s work once the queue is drained; the compiled step's path for what it does
        not handle itself): a failure falls back to the implicit method, then is contained;
        the events are kept. ``failed``: the status with which the compiled step's
        integration stopped (its core restored, as ``ExactSolver.advance`` leaves it): that
        failure is raised as the solver raises it, and goes the same way."""
        try:
            try:
                if failed is None:
                    self.stepper.advance(t1, gait)
                else:
                    self.stepper._solver._fail(failed, t1)
            except _FAILURES as exc:
                self._fallback(t1, gait, exc)
        except _FAILURES as exc:
            self._contain(exc)
            return
        self._events.extend(self.stepper.pop_events())

    def _fallback(self, t1: float, gait, exc: Exception) -> None:
        """Redo the interval with the implicit method from its start, so one failure never
        stops the node; the failure is kept in ``failures``."""
        self.failures.append(f'{self.stepper.method} solver failed before t = {t1} s: {exc}')
        st = self.stepper.state
        v0, opts = _handover(st, gait, self.cfg)
        self.stepper = Stepper(self.cfg.crawler, gait, 'implicit', t0=float(st.t),
                               x0=float(st.x[0]), v0=v0, dt=to_seconds(self.cfg.dt_ns), **opts)
        self._step = None
        self.stepper.advance(t1, gait)

    def _contain(self, exc: Exception) -> None:
        """The last line of defence (inputs are checked before they get here): a failure the
        fallback could not absorb leaves the plant at rest in its initial configuration at the
        current sim time, reported in ``failures``; the engine never raises out of a tick.
        Deterministic, so a replay of the journal repeats it."""
        self.failures.append(f'integration failed before t = {to_seconds(self.t_ns)} s '
                             f'({type(exc).__name__}: {exc}); the crawler starts again at rest')
        self._build(self.cfg, self.t_ns)

    @property
    def state(self) -> State:
        """The crawler now (integrates what is queued first)."""
        if not self.integrate:
            raise RuntimeError('an Engine(..., integrate=False) has no crawler state')
        self.sync()
        return self.stepper.state

    def read_state(self, x: np.ndarray, v: np.ndarray, contact: np.ndarray) -> None:
        """``state``'s x [m], v [m/s] and contact written into (p,) float64, float64 and int8
        arrays (integrates what is queued first): the environments' per-step read, without a
        State (``Stepper.read_state``; the same values, bit for bit)."""
        if not self.integrate:
            raise RuntimeError('an Engine(..., integrate=False) has no crawler state')
        if self._blocks or self._pieces:
            self.sync()
        self.stepper.read_state(x, v, contact)

    def actuator_output(self) -> PiecewiseCubic:
        """l(t) the actuator emitted so far (``integrate=False``): one constant-jerk piece per
        tick."""
        if self.integrate:
            raise RuntimeError('actuator_output() needs an Engine(..., integrate=False)')
        self.sync()
        if not self._log:
            raise ValueError('no tick has run yet')
        # one run of arrays from now on (a later call adds to it)
        starts, anchors, coef = self._arrays(self._log)
        self._log = [Pieces(starts, anchors, coef, len(starts), None)]
        return PiecewiseCubic.from_arrays(starts, anchors, coef)

    def actuator_state(self) -> list[tuple[float, float, float]]:
        """(l [m], l' [m/s], l'' [m/s^2]) per linkage at the current tick boundary."""
        return self.actuator.state()

    def pop_events(self) -> list[Event]:
        """Contact events integrated so far and not yet popped, in time order."""
        out, self._events = self._events, [] if self.keep_events else self._events
        if self._packed:
            self._packed = False
            events: list[Event] = []
            for item in out:
                if type(item) is bytes:
                    events += _event_records(item, new_event)
                else:
                    events.append(item)
            return events
        return out


#: fixed_step of each method asked so far (a method's capabilities do not change)
_FIXED_STEP: dict[str, bool] = {}


def _fixed_step(method: str) -> bool:
    """``capabilities(method).fixed_step``, looked up once per method."""
    fixed = _FIXED_STEP.get(method)
    if fixed is None:
        fixed = _FIXED_STEP[method] = capabilities(method).fixed_step
    return fixed


def _handover(st: State, gait: Gait, cfg: EngineConfig) -> tuple[float, dict[str, Any]]:
    """(v0 [m/s] of body 0, stiction options) of a new ``Stepper`` that continues from the
    state ``st`` under ``gait`` with ``cfg``: body 0's velocity, and with stiction the cluster
    stuck just before now (``st.incumbent``; a stepper that does not know it: the bodies at
    rest, ``contact == 0``, which describes the interval before ``st.t``). A part of the
    crawler goes on as ``initial_stuck``, its first body, whose velocity is set to exactly 0
    (v0 = -(l_0' + ... + l_{i-1}'), as ``Stepper`` computes it), which it is up to rounding.
    The whole crawler stuck goes on with no incumbent: where a dwell ends at this instant Rule
    S then chooses by the margins, as it does with every part incumbent (naming body 0 would
    favour it). (``initial_stuck`` names one body: a stuck cluster of several bodies that
    splits at this very instant keeps only the part holding that body as incumbent.)"""
    opts = cfg.stepper_options()
    v0 = float(st.v[0])
    if not opts:
        return v0, opts
    stuck = st.incumbent if st.incumbent is not None else np.asarray(st.contact) == 0
    if np.any(stuck):
        i = int(np.argmax(stuck))
        rates = np.asarray(gait.at(float(st.t))[1], dtype=float)
        v0 = 0.0 - float(np.sum(rates[:i]))
        if not np.all(stuck):
            opts['initial_stuck'] = i
    return v0, opts
