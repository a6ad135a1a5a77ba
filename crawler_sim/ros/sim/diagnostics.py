"""sim_node diagnostics: figures since the previous report, as one DiagnosticStatus.

The status is named ``<node fully qualified name>: simulation`` (so two namespaced crawlers
publish distinct names on the shared ``/diagnostics``) and carries the hardware id
``crawler_sim``. Level WARN names what went wrong since the previous report (late ticks,
rejected inputs, a recording or solver failure), else OK.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray

from crawler_sim.ros import messages as M
from crawler_sim.core.simtime import to_seconds

__all__ = ['Diagnostics', 'COUNTERS', 'graph_count']

COUNTERS = ('ticks', 'late_ticks', 'commands_accepted', 'commands_rejected',
            'commands_no_value', 'trajectories_accepted', 'trajectories_rejected',
            'solver_events', 'resets', 'lag_resets', 'solver_failures', 'nonfinite_outputs',
            'tick_failures')


#: WARN when a paced run keeps less than this fraction of its real-time factor target
RTF_WARN = 0.9
#: ... or when ticks were late in this many reports in a row, or in more than LATE_SHARE of a
#: report's ticks (a couple of late ticks on a loaded machine is not trouble)
LATE_STREAK = 3
LATE_SHARE = 0.01


class Diagnostics:
    """Tick lateness and counter deltas between two reports."""

    def __init__(self, counters: dict[str, int], name: str) -> None:
        self.counters = counters
        self.name = name
        self.lateness: list[float] = []       # wall s, one entry per real-time tick
        self._prev = (0, time.perf_counter(), dict(counters))
        self._rtf = 0.0
        self._late_streak = 0

    def message(self, t_ns: int, values: dict[str, Any], wall_now: float | None = None,
                extra_warnings: list[str] | None = None, final: bool = False
                ) -> DiagnosticArray:
        """The report at sim time ``t_ns`` [ns]; ``values`` are the node's own figures
        (``paused``, ``real_time_factor_target``). ``final``: the report at shutdown, whose
        period was cut short: it repeats the last real-time factor instead of measuring one."""
        wall_now = time.perf_counter() if wall_now is None else wall_now
        t_prev, wall_prev, c_prev = self._prev
        c = dict(self.counters)
        if not final:
            self._rtf = to_seconds(t_ns - t_prev) / max(wall_now - wall_prev, 1e-9)
        rtf = self._rtf
        late = sorted(self.lateness)
        self.lateness.clear()        # in place: the loop holds this list
        self._prev = (t_ns, wall_now, c)
        p99 = late[min(len(late) - 1, int(0.99 * len(late)))] * 1e3 if late else 0.0
        out = {'sim_time': to_seconds(t_ns), 'real_time_factor': rtf,
               'tick_lateness_p99_ms': p99,
               'tick_lateness_max_ms': late[-1] * 1e3 if late else 0.0}
        out.update(values)
        out.update(c)
        warn = []
        n_late = c['late_ticks'] - c_prev['late_ticks']
        n_ticks = max(c['ticks'] - c_prev['ticks'], 1)
        self._late_streak = self._late_streak + 1 if n_late else 0
        if n_late and (self._late_streak >= LATE_STREAK or n_late > LATE_SHARE * n_ticks):
            warn.append(f'{n_late} late ticks of {n_ticks}'
                        + (f' ({self._late_streak} reports in a row)'
                           if self._late_streak >= LATE_STREAK else ''))
        target = float(values.get('real_time_factor_target', 0.0) or 0.0)
        if (target > 0 and not values.get('paused') and not final
                and c['ticks'] > c_prev['ticks'] and rtf < RTF_WARN * target):
            warn.append(f'real-time factor {rtf:.3g} below {RTF_WARN:g} x the target '
                        f'{target:g}')
        for kind in ('commands', 'trajectories'):
            k = kind + '_rejected'
            if c[k] > c_prev[k]:
                warn.append(f'{c[k] - c_prev[k]} {kind} rejected')
        # what the simulation got wrong is an ERROR (the node goes on, but the run is not what
        # was asked for); what was refused or late is a WARN
        error = []
        if c['solver_failures'] > c_prev['solver_failures']:
            error.append('solver failed, fell back to implicit')
        if c['nonfinite_outputs'] > c_prev['nonfinite_outputs']:
            error.append('non-finite state: outputs withheld, reset')
        if c['tick_failures'] > c_prev['tick_failures']:
            error.append('a tick failed: reset to rest')
        warn += extra_warnings or []
        return M.diagnostics_msg(t_ns, out, warn=warn, name=self.name, error=error)


def graph_count(query: Callable[[], int]) -> int:
    """A graph count, or -1 once the context is shut down (e.g. in the final diagnostics)."""
    try:
        return int(query())
    except Exception:  # rclpy raises RCLError for an invalid context
        return -1
