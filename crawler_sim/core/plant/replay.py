"""A recorded journal of plant inputs run again through an engine: the node's run, bit for bit.

sim_node hands every input its ``Engine`` takes to a journal (``Engine.journal``: command,
trajectory, configure, reset, pause, resume, and integration cuts off the publish grid), and
records it with the sim time it took effect at. :func:`replay` starts an engine from the
recorded initial parameters and applies the same inputs at the same tick boundaries, in the same
order; the engine's arithmetic is then the node's, so the states it publishes are the recorded
ones exactly (same version, same method). No ROS: the bag side (``crawler_sim.bag.inputs``)
decodes the messages into :class:`Input`.

Snapshots are taken where the node publishes: at the start, at every publish tick and after
every reset (the node publishes the state it resets to, at the same sim time as the tick
before: two samples may share a time, and are told apart by their order).

A recorded input is checked before it is used (a bag is a file anyone can write): a command's
lengths (as many as the plant has linkages then, finite, within the range any ``min_length`` /
``max_length`` allows), a trajectory's points, the parameter values of a configure or reset
(``PlantConfig.from_values``). One that fails raises :class:`JournalError`, one line naming the
input (its index in the journal and its sim time) and the field.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import numpy as np

from .config import LATER_PARAMETERS, PARAMETERS, PlantConfig, _short
from .engine import Engine
from .inputs import TrajectoryArrays, check_command, check_trajectory
from ..simtime import to_seconds

__all__ = ['Input', 'JournalError', 'Snapshots', 'replay', 'KINDS', 'input_name']

KINDS = ('command', 'trajectory', 'configure', 'reset', 'pause', 'resume', 'sync')
#: the lengths [m] a recorded command may hold: what any min_length / max_length allows
LENGTH_RANGE = (PARAMETERS['min_length'][2][0], PARAMETERS['max_length'][2][1])


class JournalError(ValueError):
    """A recorded plant input that cannot be used (malformed, or not an input the node could
    have applied). The message is one line naming the input (its index in the journal and
    its sim time) and the field: the bag is refused, as bad input, not a failure of the work."""


def input_name(index: int, t_ns: int) -> str:
    """How an error names the journal's message ``index`` (0-based, in log-time order) at
    sim time ``t_ns`` [ns]."""
    return f'plant_inputs message #{index} (t = {to_seconds(t_ns):.9f} s)'


class Input(NamedTuple):
    """One plant input as recorded: at sim time ``t_ns`` [ns] (a tick boundary), ``kind``
    (one of :data:`KINDS`) and its payload: target lengths [m] (command), the points
    (trajectory, as received: :class:`TrajectoryArrays`, or None for "stop"), the plant's
    parameter values (configure, reset), None otherwise. ``index``: its message's index in
    the recorded journal (-1: not from a journal; errors then count the inputs given)."""

    t_ns: int
    kind: str
    payload: Any = None
    index: int = -1


@dataclass
class Snapshots:
    """States where the node publishes: ``t_ns`` [ns] and, per snapshot, body positions [m]
    and velocities [m/s] (as many as the crawler had bodies then)."""

    t_ns: list[int] = field(default_factory=list)
    x: list[np.ndarray] = field(default_factory=list)
    v: list[np.ndarray] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    def take(self, engine: Engine) -> None:
        st = engine.state
        self.t_ns.append(engine.t_ns)
        self.x.append(np.array(st.x, dtype=float))
        self.v.append(np.array(st.v, dtype=float))

    def at(self, t_ns: Sequence[int], p: int) -> tuple[np.ndarray, np.ndarray]:
        """(x, v) of shape (len(t_ns), p) at the recorded sample times: the samples at a time
        are the last snapshots at that time, in order (the last one when there are fewer); NaN
        where a body did not exist or no snapshot has that time."""
        by_time: dict[int, list[int]] = {}
        for i, t in enumerate(self.t_ns):
            by_time.setdefault(t, []).append(i)
        x = np.full((len(t_ns), p), np.nan)
        v = np.full((len(t_ns), p), np.nan)
        seen: dict[int, int] = {}
        counts: dict[int, int] = {}
        for t in t_ns:
            counts[int(t)] = counts.get(int(t), 0) + 1
        for row, t in enumerate(int(t) for t in t_ns):
            hits = by_time.get(t)
            if not hits:
                continue
            k = seen.get(t, 0)
            seen[t] = k + 1
            # more snapshots than samples at t (a cut off the grid that nothing published, e.g.
            # a state read, then a reset): the samples are the last ones
            i = hits[min(k + max(len(hits) - counts[t], 0), len(hits) - 1)]
            n = min(p, len(self.x[i]))
            x[row, :n] = self.x[i][:n]
            v[row, :n] = self.v[i][:n]
        return x, v


def plant_config(values: Mapping[str, Any], method: str | None = None) -> PlantConfig:
    """The plant configuration of recorded parameter values (``method`` overrides theirs);
    values recorded before the ``LATER_PARAMETERS`` existed take their defaults."""
    v = {name: values[name] for name in PARAMETERS if name in values}
    for name in LATER_PARAMETERS:     # a bag recorded before they existed ran without them
        v.setdefault(name, PARAMETERS[name][0])
    missing = [name for name in PARAMETERS if name not in v]
    if missing:
        raise ValueError(f'the recorded parameters lack {", ".join(missing)}')
    if method is not None:
        v['method'] = method
    return PlantConfig.from_values(v)


def replay(values: Mapping[str, Any], inputs: Sequence[Input], until_ns: int, *,
           method: str | None = None, t0_ns: int = 0, from_ns: int | None = None,
           on_failure: Callable[[str], Any] | None = None) -> Snapshots:
    """Run the plant from rest in the configuration of ``values`` (sim_node's parameter
    values) at ``t0_ns``, applying ``inputs`` (in order, each before the tick that starts at
    its time) up to ``until_ns``; the snapshots the node would publish. ``method`` replaces the
    recorded method everywhere (then the states are close, not identical). Solver failures,
    which the engine survives as the node does, are reported through ``on_failure``.

    ``from_ns``: the first recorded sample. When the first input is a reset at or before it
    (a node that follows another's /clock starts its time there), the run starts at that reset
    instead of ticking up to it."""
    pending = sorted(range(len(inputs)), key=lambda k: (inputs[k].t_ns, k))   # stable in time
    first = inputs[pending[0]] if pending else None
    if (first is not None and first.kind == 'reset' and from_ns is not None
            and t0_ns < first.t_ns <= from_ns):
        values = _values(first, pending[0], method).values
        t0_ns = first.t_ns
        pending = pending[1:]
    engine = Engine(plant_config(values, method).engine_config(), t0_ns)
    snaps = Snapshots()
    snaps.take(engine)
    i, n = 0, len(pending)
    reported = 0
    while True:
        while i < n and inputs[pending[i]].t_ns <= engine.t_ns:
            _apply(engine, inputs[pending[i]], pending[i], method, snaps)
            i += 1
        if engine.t_ns >= until_ns:
            break
        next_ns = inputs[pending[i]].t_ns if i < n else math.inf
        cfg = engine.cfg
        grid_ns = (engine.t_ns // (cfg.dt_ns * cfg.publish_every) + 1) * cfg.dt_ns \
            * cfg.publish_every
        if next_ns >= grid_ns and grid_ns <= until_ns:
            engine.tick_to_grid()
            snaps.take(engine)
        elif engine.tick():
            snaps.take(engine)
        if len(engine.failures) > reported:
            reported = len(engine.failures)
            snaps.failures.append(engine.failures[-1])
            if on_failure is not None:
                on_failure(engine.failures[-1])
    return snaps


def _name(item: Input, k: int) -> str:
    """The input's name in an error: its journal message, else its place among the inputs."""
    if item.index >= 0:
        return input_name(item.index, item.t_ns)
    return f'input #{k} (t = {to_seconds(item.t_ns):.9f} s)'


def _apply(engine: Engine, item: Input, k: int, method: str | None, snaps: Snapshots) -> None:
    """Apply ``item`` (the ``k``-th input given) once it has been checked."""
    kind, payload = item.kind, item.payload
    if kind == 'command':
        engine.command(_lengths(engine, item, k))
    elif kind == 'trajectory':
        engine.trajectory(None if payload is None else _prepared(engine, item, k))
    elif kind == 'configure':
        engine.reconfigure(_values(item, k, method).engine_config())
    elif kind == 'reset':
        engine.reset(_values(item, k, method).engine_config())
        snaps.take(engine)
    elif kind == 'pause':
        engine.pause()
    elif kind == 'resume':
        engine.resume()
    elif kind == 'sync':
        engine.sync()
        snaps.take(engine)      # what the node may have published there (steps off the grid)
    else:
        raise JournalError(f'{_name(item, k)}: kind must be one of {", ".join(KINDS)}, got '
                           f'{_short(kind)}')


def _lengths(engine: Engine, item: Input, k: int) -> list[float]:
    """A recorded command's lengths [m], checked: one number per linkage of the plant now,
    finite, within :data:`LENGTH_RANGE` (the node checked them against the limits of the
    moment it took them, which a parameter change in the same tick may have moved since)."""
    data = item.payload
    if (not isinstance(data, (list, tuple))
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in data)):
        raise JournalError(f'{_name(item, k)}: command lengths must be a list of numbers [m], '
                           f'got {_short(data)}')
    lengths = [float(x) for x in data]
    n_links = engine.cfg.crawler.p - 1
    reason = check_command(lengths, n_links, *LENGTH_RANGE)
    if reason is None and not all(math.isfinite(x) for x in lengths):
        reason = 'the lengths are not finite (all NaN: "no command", never applied)'
    if reason is not None:
        raise JournalError(f'{_name(item, k)}: command lengths: {reason}')
    return lengths


def _values(item: Input, k: int, method: str | None) -> PlantConfig:
    """The plant configuration of a recorded configure or reset, checked as the node checks a
    parameter change (``PlantConfig.from_values``: the message names the parameter)."""
    if not isinstance(item.payload, Mapping):
        raise JournalError(f'{_name(item, k)}: {item.kind} values must be a mapping of the '
                           f'parameters, got {_short(item.payload)}')
    try:
        return plant_config(item.payload, method)
    except (ValueError, TypeError) as exc:
        raise JournalError(f'{_name(item, k)}: {item.kind} values: {exc}') from None


def _prepared(engine: Engine, item: Input, k: int):
    """A recorded trajectory as the node applied it: it passed the node's checks when it
    arrived, so only its structure is checked again (the limits may have changed since)."""
    tr = item.payload
    if not isinstance(tr, TrajectoryArrays):
        raise JournalError(f'{_name(item, k)}: trajectory points must be trajectory arrays, '
                           f'got {_short(tr)}')
    n_links = engine.cfg.crawler.p - 1
    reason, prepared = check_trajectory(tr, n_links, -math.inf, math.inf, engine.t_ns,
                                        math.inf)
    if reason is None and len(prepared.tfs_ns):      # (no point: hold, nothing to check)
        try:
            engine.check_trajectory(prepared)
        except ValueError as exc:
            reason = str(exc)
    if reason is not None:
        raise JournalError(f'{_name(item, k)}: the trajectory cannot be applied: {reason}')
    return prepared
