"""Simulation output: sampled states, stick/slip events and the locomotion figures."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .model import Crawler

__all__ = ['Event', 'Trajectory', 'State']


class Event(NamedTuple):
    """A change of contact state of one body at ``time`` [s]: +1 forward, 0 stuck, -1 backward."""

    time: float
    body: int
    old: int
    new: int


class State(NamedTuple):
    """The crawler at one instant (all arrays are copies owned by the caller).

    ``x``, ``v``, ``friction``, ``contact`` have shape (p,); ``lengths``, ``rates``,
    ``linkage_force`` shape (p-1,). Units: s, m, m/s, N. ``indeterminate`` is True when several
    bodies stick together and only their total friction is determined (MODEL.md section 2.5).
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
    state : (N, p) int8, +1 sliding forward, 0 stuck, -1 sliding backward
    linkage_force : (N, p-1) force linkage j exerts on body j+1 [N] (positive pushes apart)
    impulse : (N, p) integrated friction force since t[0] [N s] (the seed's k_i with sign flipped)
    lengths, rates : (N, p-1) linkage lengths [m] and rates [m/s]
    events : list of Event, every contact change in (t[0], t[-1]]
    indeterminate : (N,) bool, several bodies stuck together (friction split not unique)
    crawler, method : what produced it; ``info`` holds solver figures (segments, steps, bounds).
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    v: NDArray[np.float64]
    friction: NDArray[np.float64]
    state: NDArray[np.int8]
    linkage_force: NDArray[np.float64]
    impulse: NDArray[np.float64]
    lengths: NDArray[np.float64]
    rates: NDArray[np.float64]
    events: list[Event]
    indeterminate: NDArray[np.bool_]
    crawler: Crawler
    method: str
    info: dict = field(default_factory=dict)

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

    def mean_speed(self, period: float | None = None) -> float:
        """Mean centre-of-mass speed [m/s].

        With ``period`` (e.g. the gait period), the displacement over the last whole period
        divided by it: the steady speed after the initial transient. Without it, over the run.
        The centre of mass at t_end - period is found exactly when that time is a sample, else
        by linear interpolation between samples.
        """
        X = self.com
        if period is None:
            return float((X[-1] - X[0]) / (self.t[-1] - self.t[0]))
        if not period > 0 or period > self.t[-1] - self.t[0]:
            raise ValueError(f'period must be in (0, {self.t[-1] - self.t[0]}] s, got {period!r}')
        t_start = self.t[-1] - period
        return float((X[-1] - np.interp(t_start, self.t, X)) / period)

    @property
    def stick_fraction(self) -> NDArray[np.float64]:
        """Fraction of the run each body spends stuck, shape (p,), from the exact event times."""
        t0, t1 = float(self.t[0]), float(self.t[-1])
        state = self.state[0].astype(int).copy()
        last = np.full(state.size, t0)
        stuck = np.zeros(state.size)
        for ev in self.events:
            if ev.time > t1:
                break
            if state[ev.body] == 0:
                stuck[ev.body] += ev.time - last[ev.body]
            state[ev.body] = ev.new
            last[ev.body] = ev.time
        stuck += np.where(state == 0, t1 - last, 0.0)
        return stuck / (t1 - t0) if t1 > t0 else (state == 0).astype(float)

    @property
    def dissipated_energy(self) -> float:
        """Energy dissipated by friction, integral of -sum_i friction_i v_i dt [J] (>= 0).

        Trapezoidal rule over the samples: exact in stick (zero power) and accurate to the
        sampling step elsewhere.
        """
        return _trapezoid(-np.sum(self.friction * self.v, axis=1), self.t)

    @property
    def actuator_work(self) -> float:
        """Work done by the linkages, integral of sum_j linkage_force_j l_j' dt [J]."""
        return _trapezoid(np.sum(self.linkage_force * self.rates, axis=1), self.t)

    @property
    def positive_actuator_work(self) -> float:
        """Integral of the positive part of the actuator power [J] (motors do not regenerate)."""
        power = np.sum(self.linkage_force * self.rates, axis=1)
        return _trapezoid(np.maximum(power, 0.0), self.t)

    @property
    def cost_of_transport(self) -> float:
        """Positive actuator work / (M g |displacement|), dimensionless (inf if it did not move)."""
        c = self.crawler
        d = abs(self.displacement)
        denom = c.total_mass * c.gravity * d
        return float(self.positive_actuator_work / denom) if denom > 0 else float('inf')

    def __len__(self) -> int:
        return int(self.t.size)
