"""Command and trajectory intake of sim_node: raw messages to plant inputs, cheap rejection.

The rules an input must meet live with the plant (``crawler_sim.core.plant.inputs``: one home,
shared with ``crawler-sim replay``); this module parses a raw ``linkage_trajectory`` with
:mod:`crawler_sim.bag.trajarrays` (at most ``MAX_TRAJECTORY_POINTS`` points) and counts and
logs rejections.

A rejection is counted and costs microseconds: it is logged at most once per
:data:`LOG_PERIOD` per input with the count since the last message, and the logger is not called
at all in between (rclpy's logger inspects its caller on every call, about 540 us, even when a
throttle then drops the message).
"""
from __future__ import annotations

import time
from typing import Any, Callable

from crawler_sim.bag import trajarrays
from crawler_sim.bag.trajarrays import TrajectoryFormatError
from crawler_sim.core.plant.inputs import (PreparedTrajectory, check_command, check_trajectory,
                                           linkage_names)

__all__ = ['check_command', 'check_trajectory', 'RejectionLog', 'PreparedTrajectory',
           'prepare', 'LOG_PERIOD', 'linkage_names']

LOG_PERIOD = 1.0     # wall s between two log lines about rejected input of one kind


def prepare(data: bytes, n_links: int, lo: float, hi: float, t_ns: int, max_lead_s: float
            ) -> tuple[str | None, PreparedTrajectory | None]:
    """Parse and check a raw ``linkage_trajectory`` message (see :func:`check_trajectory`)."""
    try:
        tr = trajarrays.parse(data, n_links)
    except TrajectoryFormatError as exc:
        return str(exc), None
    reason, prepared = check_trajectory(tr, n_links, lo, hi, t_ns, max_lead_s)
    if prepared is not None:
        prepared.raw = data[:tr.nbytes] if tr.nbytes else data
    return reason, prepared


class RejectionLog:
    """Counts rejected inputs and logs at most once per ``period`` wall seconds per kind.

    ``note`` costs a dict update and one ``time.monotonic()`` call; the logger (about 540 us
    per call in rclpy) is called only when a line is due.
    """

    def __init__(self, counters: dict[str, int], warn: Callable[[str], Any],
                 period: float = LOG_PERIOD, clock: Callable[[], float] = time.monotonic) -> None:
        self.counters = counters
        self._warn = warn
        self._period = period
        self._clock = clock
        self._next: dict[str, float] = {}
        self._since: dict[str, int] = {}
        self.last = ''
        self.lines = 0            # log lines written

    def note(self, kind: str, topic: str, reason: str) -> None:
        key = kind + '_rejected'
        self.counters[key] = self.counters.get(key, 0) + 1
        self.last = f'{kind}: {reason}'
        self._since[kind] = self._since.get(kind, 0) + 1
        now = self._clock()
        if now >= self._next.get(kind, 0.0):
            n, self._since[kind] = self._since[kind], 0
            self._next[kind] = now + self._period
            self.lines += 1
            self._warn(f'{topic} rejected: {reason} ({n} rejected since the last message, '
                       f'{self.counters[key]} in all)')
