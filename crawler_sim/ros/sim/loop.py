"""The real-time loop of sim_node: ticks paced against the wall clock.

One loop drives the ticks in both clock modes. ``real_time_factor`` paces it (1 = real time,
10 = ten times faster, 0 = as fast as possible): the loop sleeps until the wall deadline of the
first tick of each publish period, then runs that period's ticks back to back (nothing is
published in between, so the outputs keep their sim-time grid; they go out up to one publish
period early in wall time). A tick that starts more than one tick period after its wall
deadline is counted as late, and the loop catches up by running the due ticks back to back
(beyond :data:`MAX_LAG` of lag it gives up on the lost time and re-anchors). Flat out, each
iteration runs one whole publish period (``SimNode._tick(to_grid=True)``): the inputs that
arrived are taken at its first tick, as in the paced modes, where a period's ticks run back to
back too.
While paused the loop takes (and counts) the inputs, and republishes the latest state and
/clock every ``PAUSED_REPUBLISH`` wall seconds, unrecorded, so a subscriber that connects while
the crawler is paused sees it (``~/step`` advances one publish period).
Diagnostics go out every ``diagnostics_period`` wall seconds from this loop, so they do not
wait for a message; the bag flushes itself on a wall timer in its own thread (crawler_sim.bag).
"""
from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any, Protocol

from crawler_sim.core.simtime import to_seconds

if TYPE_CHECKING:
    from .clock import SharedClock
    from .params import SimConfig

__all__ = ['run', 'Loopable', 'MAX_LAG', 'PAUSED_REPUBLISH']

MAX_LAG = 0.5            # wall s of lag after which the real-time loop re-anchors
PAUSED_REPUBLISH = 0.5   # wall s between two republications of the state while paused


class Loopable(Protocol):
    """What the loop uses of a node (``SimNode``): the whole interface between the two."""

    counters: dict[str, int]
    clock: SharedClock
    context: Any
    #: wall s of lateness of each paced tick since the last diagnostics report
    lateness: list[float]

    @property
    def lock(self) -> threading.RLock: ...
    @property
    def config(self) -> SimConfig: ...
    @property
    def sim_time_ns(self) -> int: ...
    @property
    def paused(self) -> bool: ...
    @property
    def stopped(self) -> bool: ...
    def take_anchor(self) -> bool:
        """Whether pacing must start again from now (and clear the request)."""
    def reanchor(self) -> None:
        """Ask for pacing to start again from now."""
    def tick_locked(self, to_grid: bool = False) -> None:
        """One tick (``to_grid``: up to the next publish tick), the lock held."""
    def publish_state(self) -> None:
        """Publish the state now (the lock held)."""
    def publish_diagnostics(self, wall_now: float) -> None: ...
    def take_inputs(self) -> int: ...
    def republish(self) -> None: ...


def run(node: Loopable) -> None:
    """Tick ``node`` until it is stopped or its context shuts down."""
    try:
        _loop(node)
    except Exception:
        if node.context.ok():
            raise
        # a signal shut the context down in the middle of a tick (e.g. while publishing)


def _loop(node: Loopable) -> None:
    now = time.perf_counter
    anchor_wall = now()
    anchor_tick = 0
    next_diag = anchor_wall + node.config.diagnostics_period
    ok = node.context.ok
    counters = node.counters
    lateness = node.lateness
    clock = node.clock
    shared = clock.active
    if counters['ticks'] == 0 and not clock.waiting:
        with node.lock:
            node.publish_state()       # the initial state at t = 0 (a bag starts there)
    checks = 0
    next_republish = 0.0
    while not node.stopped:
        # context.ok() costs ~1 us: flat out, ask every 16th iteration
        checks = (checks + 1) & 15
        if checks == 0 and not ok():
            break
        t = now()
        if t >= next_diag:
            node.publish_diagnostics(t)
            next_diag = t + node.config.diagnostics_period
        if shared and clock.due(t):
            with node.lock:
                clock.poll(t)         # follow, keep alive, take over or yield (.clock)
        if node.paused:
            node.take_inputs()        # count (and warn about) commands while paused too
            if t >= next_republish:   # the state stays visible to late subscribers
                node.republish()
                next_republish = t + PAUSED_REPUBLISH
            time.sleep(0.01)
            continue
        if node.take_anchor():
            anchor_wall, anchor_tick = t, counters['ticks']
        cfg = node.config
        target = clock.target_ns
        if target is not None:
            # following another node's /clock: tick up to its time, never past it (the stamps
            # of every robot agree with the one clock)
            with node.lock:
                if not node.paused and node.sim_time_ns + cfg.dt_ns <= target:
                    node.tick_locked()
                    continue
            time.sleep(0.001)
            continue
        rtf = cfg.real_time_factor
        if rtf <= 0.0:
            # Flat out: one publish period per iteration (its ticks back to back, inputs taken
            # at its first tick, as the paced branch does between a period's first tick and
            # the next): the per-tick calls of the loop and of SimNode.tick cost about a third
            # of the engine's own time.
            with node.lock:
                if not node.paused:
                    node.tick_locked(to_grid=True)
            continue
        if rtf > 0.0:
            period = to_seconds(cfg.dt_ns) / rtf
            deadline = anchor_wall + (counters['ticks'] - anchor_tick) * period
            if t < deadline:
                if counters['ticks'] % cfg.publish_every == 0:
                    time.sleep(min(deadline - t, 0.05))
                    continue
                # Within a publish period the ticks run back to back from the deadline of its
                # first one (one wake-up per publish period instead of one per tick: about a
                # third of the CPU at 1 kHz). Nothing is published between two publish ticks,
                # so only this changes: the outputs of a period go out up to one publish period
                # of wall time early, and a command waits up to one period for the next batch.
                # Early ticks are not late: lateness counts the ticks that waited.
            else:
                late = t - deadline
                lateness.append(late)
                if late > period:
                    counters['late_ticks'] += 1
                if late > MAX_LAG:
                    counters['lag_resets'] += 1
                    node.reanchor()
        with node.lock:              # a pause that arrived meanwhile wins
            if not node.paused:
                node.tick_locked()
