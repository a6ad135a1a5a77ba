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
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import numpy as np

from .config import PARAMETERS, PlantConfig
from .engine import Engine
from .inputs import TrajectoryArrays, check_trajectory
from ..simtime import to_seconds

__all__ = ['Input', 'Snapshots', 'replay', 'KINDS']

KINDS = ('command', 'trajectory', 'configure', 'reset', 'pause', 'resume', 'sync')


class Input(NamedTuple):
    """One plant input as recorded: at sim time ``t_ns`` [ns] (a tick boundary), ``kind``
    (one of :data:`KINDS`) and its payload: target lengths [m] (command), the points
    (trajectory, as received: :class:`TrajectoryArrays`, or None for "stop"), the plant's
    parameter values (configure, reset), None otherwise."""

    t_ns: int
    kind: str
    payload: Any = None


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
        """(x, v) of shape (len(t_ns), p) at the recorded sample times: the k-th sample at a
        time is the k-th snapshot at that time (the last one when there are fewer); NaN where a
        body did not exist or no snapshot has that time."""
        by_time: dict[int, list[int]] = {}
        for i, t in enumerate(self.t_ns):
            by_time.setdefault(t, []).append(i)
        x = np.full((len(t_ns), p), np.nan)
        v = np.full((len(t_ns), p), np.nan)
        seen: dict[int, int] = {}
        for row, t in enumerate(int(t) for t in t_ns):
            hits = by_time.get(t)
            if not hits:
                continue
            k = seen.get(t, 0)
            seen[t] = k + 1
            i = hits[min(k, len(hits) - 1)]
            n = min(p, len(self.x[i]))
            x[row, :n] = self.x[i][:n]
            v[row, :n] = self.v[i][:n]
        return x, v


def plant_config(values: Mapping[str, Any], method: str | None = None) -> PlantConfig:
    """The plant configuration of recorded parameter values (``method`` overrides theirs)."""
    v = {name: values[name] for name in PARAMETERS if name in values}
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
        values, t0_ns = first.payload, first.t_ns
        pending = pending[1:]
    engine = Engine(plant_config(values, method).engine_config(), t0_ns)
    snaps = Snapshots()
    snaps.take(engine)
    i, n = 0, len(pending)
    reported = 0
    while True:
        while i < n and inputs[pending[i]].t_ns <= engine.t_ns:
            _apply(engine, inputs[pending[i]], method, snaps)
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


def _apply(engine: Engine, item: Input, method: str | None, snaps: Snapshots) -> None:
    kind, payload = item.kind, item.payload
    if kind == 'command':
        engine.command(payload)
    elif kind == 'trajectory':
        engine.trajectory(None if payload is None else _prepared(engine, payload))
    elif kind == 'configure':
        engine.reconfigure(plant_config(payload, method).engine_config())
    elif kind == 'reset':
        engine.reset(plant_config(payload, method).engine_config())
        snaps.take(engine)
    elif kind == 'pause':
        engine.pause()
    elif kind == 'resume':
        engine.resume()
    elif kind == 'sync':
        engine.sync()
    else:
        raise ValueError(f'unknown plant input {kind!r} at t = {to_seconds(item.t_ns)} s '
                         f'(expected one of {", ".join(KINDS)})')


def _prepared(engine: Engine, tr: TrajectoryArrays):
    """A recorded trajectory as the node applied it: it passed the node's checks when it
    arrived, so only its structure is checked again (the limits may have changed since)."""
    n_links = engine.cfg.crawler.p - 1
    reason, prepared = check_trajectory(tr, n_links, -math.inf, math.inf, engine.t_ns,
                                        math.inf)
    if reason is not None:
        raise ValueError(f'recorded trajectory at t = {to_seconds(engine.t_ns)} s cannot be '
                         'applied: '
                         f'{reason}')
    return prepared
