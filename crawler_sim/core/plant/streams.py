"""What gait_node sends for a gait, and a run of it "as the node runs it", offline.

gait_node plays a core gait in one of three ways (its parameters ``mode``, ``rate``,
``horizon``, ``preload``, ``duration``), described here by a :class:`Stream`:

- ``command``: every ``1/rate`` s of ROS time the lengths l(t) on ``linkage_cmd`` (step targets
  for the node's servo);
- ``trajectory``: every ``horizon/4`` s a ``linkage_trajectory`` stamped with absolute sim time,
  holding the next ``horizon`` s of the gait sampled at ``rate`` (positions, velocities,
  accelerations: quintic interpolation in the node) plus a final point at rest;
- ``trajectory`` with ``preload``: ONE trajectory of the whole ``duration``, stamped 0 (start at
  the tick it is applied). The same input whatever the timing of DDS and of the node's pacing:
  the deterministic way to play a gait, and what ``crawler-sim optimize`` writes.

:func:`trajectory_points` is the one sampler of a gait into trajectory points (gait_node builds
its messages from it). :func:`actuator_output` runs a stream through the plant's ``Engine`` (the
node's actuator on the node's tick grid, inputs at tick boundaries as the node applies them) and
returns the linkage lengths the servo produced; :func:`simulate_as_node` hands them to the
core's solver. Prediction and robot then see the same l(t): what gait_node and sim_node do,
without ROS.

Units: s, ns, m, m/s, m/s^2, Hz.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any
import math

import numpy as np

from ..gaits import Gait, PiecewiseCubic
from ..stepper import simulate
from ..trajectory import Trajectory
from .config import PlantConfig
from .engine import Engine
from .inputs import MAX_TRAJECTORY_POINTS, PreparedTrajectory
from ..simtime import to_ns, to_seconds

__all__ = ['Stream', 'MODES', 'trajectory_points', 'actuator_output', 'simulate_as_node']

MODES = ('command', 'trajectory')


@dataclass(frozen=True)
class Stream:
    """How gait_node sends a gait (its parameters of the same names).

    ``mode``: 'command' or 'trajectory'; ``rate`` [Hz]: set-points per second, or trajectory
    samples per second; ``horizon`` [s]: gait per streamed trajectory; ``preload``: one
    trajectory of ``duration`` [s] (0: no end, not with preload); ``latency`` [s]: command mode
    only, from the ROS time a set-point is for to the tick it takes effect at (0: the tick
    that starts at that time, an ideal link).
    """

    mode: str = 'trajectory'
    rate: float = 50.0
    horizon: float = 4.0
    preload: bool = True
    duration: float = 0.0
    latency: float = 0.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f'mode must be one of {", ".join(MODES)}, got {self.mode!r}')
        for name, lo, hi in (('rate', 0.1, 10000.0), ('horizon', 0.1, 3600.0),
                             ('duration', 0.0, 1e9), ('latency', 0.0, 10.0)):
            x = getattr(self, name)
            if not (isinstance(x, (int, float)) and math.isfinite(x) and lo <= x <= hi):
                raise ValueError(f'{name} must be in [{lo:g}, {hi:g}], got {x!r}')
        if self.preload and not (self.mode == 'trajectory' and self.duration > 0):
            raise ValueError('preload needs mode trajectory and a duration > 0')
        if self.mode == 'trajectory':
            span, what = ((self.duration, 'duration') if self.preload
                          else (self.horizon, 'horizon'))
            points = round(span * self.rate) + 2
            if points > MAX_TRAJECTORY_POINTS:
                raise ValueError(
                    f'{what} x rate = {span:g} s x {self.rate:g} Hz makes {points} points per '
                    f'trajectory, more than sim_node takes ({MAX_TRAJECTORY_POINTS}): lower '
                    f'{what} or rate' + (' (or stream it: preload false)' if self.preload
                                         else ''))

    @property
    def period_ns(self) -> int:
        """ROS time between two messages [ns] (preload: one message)."""
        every = 1.0 / self.rate if self.mode == 'command' else self.horizon / 4
        return max(1, to_ns(every))


def trajectory_points(gait: Gait, t_gait: float, horizon: float, rate: float,
                      duration: float = 0.0
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The points of one trajectory message: the gait from gait time ``t_gait`` [s] over
    ``horizon`` [s] sampled every ``1/rate`` s (never past ``duration`` when it is > 0), then a
    final point one step later at the last position and at rest (joint_trajectory_controller
    needs zero velocity at the end).

    Returns (time_from_start [ns] int64 (N,), positions, velocities, accelerations (N, n)).
    """
    n = max(2, round(horizon * rate))
    step = 1.0 / rate
    tau = np.arange(n) * step
    gait_t = t_gait + tau
    if duration:
        keep = gait_t <= duration
        tau, gait_t = tau[keep], gait_t[keep]
    if len(gait_t):
        l, ld, ldd = gait(gait_t)
        end = l[-1]
    else:
        l = ld = ldd = np.zeros((0, gait.n_links))
        end = np.asarray(gait.length(t_gait), dtype=float)
    last = float(tau[-1]) if len(tau) else 0.0
    zeros = np.zeros((1, gait.n_links))
    times = np.append(tau, last + step)
    tfs = np.array([to_ns(t) for t in times], dtype=np.int64)
    return (tfs, np.vstack([l, end[None, :]]), np.vstack([ld, zeros]),
            np.vstack([ldd, zeros]))


def _prepared(gait: Gait, t_gait: float, stamp_ns: int, horizon: float, stream: Stream
              ) -> PreparedTrajectory:
    tfs, pos, vel, acc = trajectory_points(gait, t_gait, horizon, stream.rate, stream.duration)
    return PreparedTrajectory(stamp_ns, tfs, pos, vel, acc)


def actuator_output(plant: PlantConfig, gait: Gait, stream: Stream, t_end: float
                    ) -> PiecewiseCubic:
    """The linkage lengths l(t) on [0, ``t_end``] [s] that the node's actuator produces when
    gait_node plays ``gait`` with ``stream`` into a sim_node with parameters ``plant``,
    starting at sim time 0 (gait time 0 = sim time 0). Inputs take effect at the tick that
    starts at (or, with ``latency``, after) the time they are for, as the node applies them."""
    if gait.n_links != plant.n_links:
        raise ValueError(f'the gait drives {gait.n_links} linkages, the plant has '
                         f'{plant.n_links}')
    cfg = plant.engine_config()
    engine = Engine(cfg, 0, integrate=False)
    dt_ns = cfg.dt_ns
    end_ns = max(dt_ns, to_ns(t_end))
    end_ns = -(-end_ns // dt_ns) * dt_ns            # whole ticks
    if stream.preload:
        engine.trajectory(_prepared(gait, 0.0, 0, stream.duration, stream))
        _run_to(engine, end_ns)
        return engine.actuator_output()
    period = stream.period_ns
    delay = to_ns(stream.latency) if stream.mode == 'command' else 0
    k = 0
    while True:
        send_ns = k * period                    # ROS time the message is for
        if stream.duration and to_seconds(send_ns) > stream.duration:
            break
        at_ns = -(-(send_ns + delay) // dt_ns) * dt_ns    # the tick boundary it lands on
        if at_ns >= end_ns:
            break
        _run_to(engine, at_ns)
        t = to_seconds(send_ns)
        if stream.mode == 'command':
            engine.command(np.asarray(gait.length(t), dtype=float).tolist())
        else:
            engine.trajectory(_prepared(gait, t, send_ns, stream.horizon, stream))
        k += 1
    _run_to(engine, end_ns)
    return engine.actuator_output()


def _run_to(engine: Engine, t_ns: int) -> None:
    engine.run_to(t_ns)          # tick() repeated, as one compiled run of the actuator


def simulate_as_node(plant: PlantConfig, gait: Gait, stream: Stream, t_end: float,
                     **kwargs: Any) -> Trajectory:
    """``simulate`` of the plant's crawler driven by :func:`actuator_output` (the plant's
    method and initial position, and with stiction its rule, as the engine starts; ``kwargs``
    go to ``simulate``: ``dt``, ``t_eval``, ...)."""
    out = actuator_output(plant, gait, stream, t_end)
    kwargs.setdefault('x0', float(plant.values['initial_position']))
    for name, value in plant.engine_config().stepper_options().items():
        kwargs.setdefault(name, value)
    if plant.values['method'] == 'penalty':
        kwargs.setdefault('penalty', plant.penalty_n)
    return simulate(plant.crawler, out, t_end, plant.values['method'], **kwargs)
