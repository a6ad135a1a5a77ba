"""Command and trajectory intake of sim_node: raw messages to plant inputs, cheap rejection.

The rules an input must meet live with the plant (``crawler_sim.core.plant.inputs``: one home,
shared with ``crawler-sim replay``); this module parses a raw ``linkage_trajectory`` with
:mod:`crawler_sim.bag.trajarrays` (at most ``MAX_TRAJECTORY_POINTS`` points) and counts and
logs rejections in :class:`crawler_sim.ros.rejections.RejectionLog` (the one home
of what every node does with input it cannot use: a count, at most one WARN line per second).
"""
from __future__ import annotations

from crawler_sim.bag import trajarrays
from crawler_sim.bag.trajarrays import TrajectoryFormatError
from crawler_sim.core.plant.inputs import (PreparedTrajectory, check_command, check_trajectory,
                                           linkage_names)
from crawler_sim.ros.rejections import LOG_PERIOD, RejectionLog

__all__ = ['check_command', 'check_trajectory', 'RejectionLog', 'PreparedTrajectory',
           'prepare', 'LOG_PERIOD', 'linkage_names']


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
