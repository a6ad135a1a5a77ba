"""The figures of one periodic run: steady speed after a detected transient, stick fractions,
dissipated energy, cost of transport, actuator peak force and the verify() figure.

Transient detection
-------------------
The centre of mass X is read exactly at the period boundaries t_k = k T (an exact run's dense
output, ``Trajectory.state_at``; another method's samples there), giving the displacement of
every period d_k = X(t_k) - X(t_{k-1}), k = 1..N. The run is steady from period k0 on when
every later d_k agrees with the last one, d_N, to ``STEADY_RTOL`` times the stroke's scale (the
largest linkage excursion or |d|). The transient is then k0 periods long; the figures below are
taken over the steady window [t_k0, t_N]. When fewer than ``MIN_STEADY`` periods agree (no
steady state yet, or a steady state that repeats only every few periods) ``steady`` is False
and the window is the last half of the run.

Energy
------
Between two consecutive events each body slides one way or sticks, and its friction force is
constant while it slides, so the energy it dissipates is exactly f_i^+ (forward travel) + f_i^-
(backward travel), f^+ and f^- its kinetic bounds (``core.friction``: a sliding body gets its
kinetic force, with or without stiction; a stuck one dissipates nothing)
(``Trajectory.sliding_distance``: exact for the exact method, every event
read from its dense output). The actuator's positive work, the integral of max(G l', 0), is
``Trajectory.positive_work``: quadrature between the power's roots to ~1e-13 for the exact
method, the trapezoid over the samples for the others.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core import friction
from ..core.scene import Scene
from ..core.solvers.base import capabilities
from ..core.stepper import simulate
from ..core.trajectory import Trajectory
from ..core.verify import verify

__all__ = ['FIGURES', 'STEADY_RTOL', 'MIN_STEADY', 'steady_window', 'run_figures',
           'scene_figures', 'window_speed']

STEADY_RTOL = 1e-8   # agreement of the per-period displacements, relative to the stroke scale
MIN_STEADY = 2       # periods that must agree before a run counts as steady

#: The figure columns of a sweep row, in order (stick_fraction_<i> per body follow them).
FIGURES = ('bodies', 'period', 'mean_speed', 'displacement_per_period', 'transient_periods',
           'steady', 'dissipated_energy', 'positive_actuator_work', 'cost_of_transport',
           'actuator_peak_force', 'events_per_period', 'verify_worst', 'verify_ok')


def steady_window(boundary_x: np.ndarray, scale: float) -> tuple[int, bool]:
    """(k0, steady) from the centre of mass at the period boundaries, shape (N + 1,).

    k0 is the first period boundary from which every period's displacement equals the last
    one's to ``STEADY_RTOL * scale`` [m]. If fewer than ``MIN_STEADY`` periods agree, returns
    (N // 2, False).
    """
    d = np.diff(boundary_x)
    n = d.size
    tol = STEADY_RTOL * max(scale, float(np.abs(d).max(initial=0.0)), 1e-300)
    off = np.abs(d - d[-1]) > tol
    k0 = int(np.flatnonzero(off)[-1]) + 1 if off.any() else 0
    if n - k0 < MIN_STEADY:
        return n // 2, False
    return k0, True


def window_speed(t: np.ndarray, com: np.ndarray, start: float, end: float) -> float:
    """Mean speed [m/s] of the centre of mass ``com`` [m] sampled at times ``t`` [s] over
    [start, end], its values at the ends interpolated linearly between samples (a recorded
    run's states are on the publish grid, not on the period boundaries)."""
    if not (t[0] <= start < end <= t[-1]):
        raise ValueError(f'the window [{start}, {end}] s is not inside the run '
                         f'[{t[0]}, {t[-1]}] s')
    a, b = np.interp([start, end], t, com)
    return float((b - a) / (end - start))


def _stuck_time(tr: Trajectory, a: float, b: float) -> np.ndarray:
    """Time each body spends stuck in [a, b] [s], shape (p,), from the exact event times."""
    state = tr.contact[0].astype(int).copy()
    last = np.full(state.size, float(tr.t[0]))
    stuck = np.zeros(state.size)
    for ev in tr.events:
        if ev.time > b:
            break
        if state[ev.body] == 0:
            stuck[ev.body] += max(0.0, ev.time - max(last[ev.body], a))
        state[ev.body] = ev.new
        last[ev.body] = ev.time
    stuck += np.where(state == 0, np.maximum(0.0, b - np.maximum(last, a)), 0.0)
    return stuck


def _boundaries(tr: Trajectory, bounds: np.ndarray, idx: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """(X, t) at the period boundaries k T, shape (N + 1,) each [m, s]. An exact run's X is
    exact at the boundaries themselves (``Trajectory.state_at``: its samples sit on them only
    to the rounding of the sample grid, or of the node's tick grid); another run's X is its
    samples' (``idx``) at their own times."""
    if tr.dense is None:
        return tr.com[idx], tr.t[idx]
    t_b = np.clip(bounds, tr.t[0], tr.t[-1])     # the run's ends, where they round apart
    m = tr.crawler.masses
    return tr.state_at(t_b).x @ (m / m.sum()), t_b


def run_figures(tr: Trajectory, period: float, periods: int) -> dict[str, Any]:
    """The sweep figures of a run of ``periods`` whole periods [s] sampled at the boundaries."""
    c = tr.crawler
    bounds = np.arange(periods + 1) * period
    idx = np.searchsorted(tr.t, bounds - 1e-9 * period)
    idx[-1] = tr.t.size - 1
    if np.any(np.abs(tr.t[idx] - bounds) > 1e-9 * period):
        raise ValueError('the run is not sampled at the period boundaries')
    X_b, t_b = _boundaries(tr, bounds, idx)
    scale = float(np.ptp(tr.lengths)) if tr.lengths.size else 0.0
    k0, steady = steady_window(X_b, scale)
    t0, t1 = float(t_b[k0]), float(t_b[-1])
    window = t1 - t0
    n_win = periods - k0
    dx = float(X_b[-1] - X_b[k0])
    speed = dx / window
    fwd, back = tr.sliding_distance(t0, t1)
    law = friction.bounds(c)
    dissipated = float(law.kinetic_forward @ fwd + law.kinetic_backward @ back)
    pos_work = tr.positive_work(t0, t1)
    denom = c.total_mass * c.gravity * abs(dx)
    report = verify(tr)
    out: dict[str, Any] = {
        'bodies': c.p, 'period': period, 'mean_speed': speed,
        'displacement_per_period': speed * period, 'transient_periods': k0, 'steady': steady,
        'dissipated_energy': dissipated / n_win, 'positive_actuator_work': pos_work / n_win,
        'cost_of_transport': pos_work / denom if denom > 0 else math.inf,
        'actuator_peak_force': float(np.abs(tr.linkage_force).max(initial=0.0)),
        'events_per_period': sum(1 for e in tr.events if t0 < e.time <= t1) / n_win,
        'verify_worst': report.worst, 'verify_ok': report.ok(1e-9),
    }
    frac = _stuck_time(tr, t0, t1) / window
    for i, f in enumerate(frac):
        out[f'stick_fraction_{i}'] = float(f)
    return out


def scene_figures(scene: Scene, periods: int, samples_per_period: int) -> dict[str, Any]:
    """Simulate ``scene`` for ``periods`` gait periods and return its sweep figures.

    The samples are ``samples_per_period`` per period on a uniform grid through every period
    boundary, plus (method "exact") every event time.
    """
    period = scene.gait.period
    if not period:
        raise ValueError(f'the gait {scene.gait_spec["type"]!r} is not periodic')
    r = scene.run
    t_end = periods * period
    n = periods * samples_per_period
    if not capabilities(r.method).fixed_step:
        # dt only sets the sample grid of an event-driven method: linspace(0, t_end, n + 1)
        # plus the events
        tr = simulate(scene.crawler, scene.gait, t_end, r.method, dt=t_end / n, v0=r.v0, x0=r.x0,
                      tol=r.tol, max_step=r.max_step, stiction_rule=r.stiction_rule,
                      initial_stuck=r.initial_stuck)
    else:
        tr = simulate(scene.crawler, scene.gait, t_end, r.method, dt=r.dt, v0=r.v0, x0=r.x0,
                      penalty=r.penalty, t_eval=np.linspace(0.0, t_end, n + 1),
                      stiction_rule=r.stiction_rule, initial_stuck=r.initial_stuck)
    return run_figures(tr, period, periods)
