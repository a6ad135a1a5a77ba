"""Method "implicit": Moreau-Jean (catching-up) time stepping, MODEL.md section 3.

One step of size h solves exactly, in O(p log p),

    V_{k+1} = argmin_V  M/(2h) (V - V_k)^2 - F_ext V + sum_i phi_i(V + e_i'(t_{k+1})),

then X_{k+1} = X_k + h V_{k+1}. Unconditionally stable, first order in h, and a stuck body has
exactly zero velocity. ``ImplicitBatch`` advances B crawlers with the same p at once.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..gaits import Gait
from ..model import Crawler, kinematics
from ..trajectory import Event
from .contact import solve_inclusion, solve_inclusion_batch, split_friction
from .exact import ExactSolver, check_finite_gait

__all__ = ['ImplicitSolver', 'ImplicitBatch', 'TimeStepper']


class TimeStepper:
    """Shared loop of the fixed-step methods: steps of ``dt`` that land exactly on t1.

    Subclasses implement ``_velocity(h, ep)`` returning (V_new, R) for one step.
    """

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0) -> None:
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f'dt must be a finite step > 0 s, got {dt!r}')
        self.crawler = crawler
        self.gait = gait
        self.dt = float(dt)
        self._m = crawler.masses
        self._M = float(crawler.masses.sum())
        self._fp = crawler.friction
        self._fm = crawler.friction_backward
        self._fext = crawler.external_force
        self.reset(t0=t0, x0=x0, v0=v0)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        l, ld, ldd = self.gait(t0)
        e, ep, epp = kinematics(self._m, l, ld, ldd)
        self.t = float(t0)
        self.X = float(x0 - e[0])
        self.V = float(v0 - ep[0])
        # The state at t0 (contact, friction, acceleration) is the instantaneous mode, the same
        # one the exact method starts from.
        seg = ExactSolver(self.crawler, self.gait, t0=t0, x0=x0, v0=v0).provisional()
        first = seg.evaluate(self.crawler, np.array([float(t0)]))
        self.contact = first['contact'][0].copy()
        self.R = first['friction'][0]
        self.A = float(seg.a) if seg.ref < 0 else float(-epp[seg.ref])
        self.K = np.zeros(self._m.size)
        self._cache = None
        self.events: list[Event] = []
        self.n_steps = 0
        self.rows: list[tuple] = []
        self.record = False

    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Step to t1 with ``gait`` valid on [t, t1]; the last step is shortened to land on t1."""
        if gait is not None:
            self.gait = gait
        t1 = float(t1)
        while self.t < t1:
            n_left = (t1 - self.t) / self.dt
            t_new = t1 if n_left <= 1.0 + 1e-9 else self.t + self.dt
            self._step(t_new)

    def _step(self, t_new: float) -> None:
        h = t_new - self.t
        l, ld, ldd = self.gait.at(t_new)
        check_finite_gait((l, ld, ldd), t_new)
        e, ep, epp = kinematics(self._m, l, ld, ldd)
        V_new, R, contact = self._velocity(h, ep)
        self.A = (V_new - self.V) / h
        self.V = V_new
        self.X += h * V_new
        self.K = self.K + h * R
        self.R = R
        old = self.contact
        for i in np.nonzero(contact != old)[0]:
            self.events.append(Event(float(t_new), int(i), int(old[i]), int(contact[i])))
        self.contact = contact
        self.t = t_new
        self.n_steps += 1
        self._cache = (l, ld, ldd, e, ep, epp)
        if self.record:
            self.rows.append(self._row())

    def current(self) -> dict:
        """The state at self.t as one row of output arrays."""
        return self._row()

    def _row(self) -> dict:
        if getattr(self, '_cache', None) is None or self.n_steps == 0:
            l, ld, ldd = self.gait(self.t)
            e, ep, epp = kinematics(self._m, l, ld, ldd)
        else:
            l, ld, ldd, e, ep, epp = self._cache
        x = self.X + e
        v = self.V + ep
        R = self.R
        body_force = R + self.crawler.gravity_forces - self._m * (self.A + epp)
        return {'t': self.t, 'x': x, 'v': v, 'friction': R.copy(), 'impulse': self.K.copy(),
                'linkage_force': np.cumsum(body_force)[:-1], 'lengths': l, 'rates': ld,
                'contact': self.contact.copy(), 'indeterminate': int(np.sum(self.contact == 0)) > 1}


class ImplicitSolver(TimeStepper):
    """Moreau-Jean stepping for one crawler."""

    def _velocity(self, h: float, ep: NDArray):
        fp, fm = self._fp, self._fm
        kinks = -ep
        V_new, s = solve_inclusion(self._M / h, self.V, self._fext, kinks, fp, fm)
        at = kinks == V_new
        v = V_new + ep
        v[at] = 0.0
        contact = np.sign(v).astype(np.int8)
        R = np.where(contact > 0, -fp, np.where(contact < 0, fm, 0.0))
        if at.any():
            R[at] = -split_friction(s, fp[at], fm[at])
        return V_new, R, contact


class ImplicitBatch:
    """Moreau-Jean stepping of B crawlers with the same number of bodies p, vectorised.

    Parameters
    ----------
    masses, friction : array_like, shape (B, p) (or (p,), broadcast)
        Masses [kg] (> 0) and forward friction forces [N] (>= 0).
    friction_backward : array_like, shape (B, p), optional
        Backward friction [N]; default equal to ``friction``.
    slope : float or array_like (B,)
        Inclination [rad]; gravity [m/s^2].

    State: ``X`` (B,) centre of mass [m], ``V`` (B,) its velocity [m/s], ``t`` [s].
    ``step(h, rates)`` takes the linkage rates l'(t + h), shape (p-1,) shared or (B, p-1).
    Body velocities are ``V + e'``; ``body_velocities(rates)`` returns them.
    """

    def __init__(self, masses: ArrayLike, friction: ArrayLike,
                 friction_backward: ArrayLike | None = None, slope: ArrayLike = 0.0,
                 gravity: float = 9.81, *, batch: int | None = None) -> None:
        m = np.asarray(masses, dtype=float)
        f = np.asarray(friction, dtype=float)
        if m.ndim == 1:
            m = np.broadcast_to(m, (batch or 1, m.size))
        B, p = m.shape
        if p < 2:
            raise ValueError(f'masses must have p >= 2 columns, got {p}')
        if not np.all(np.isfinite(m) & (m > 0)):
            raise ValueError('masses must be finite and > 0')
        f = np.broadcast_to(f, (B, p)).astype(float)
        fb = f if friction_backward is None else np.broadcast_to(
            np.asarray(friction_backward, dtype=float), (B, p)).astype(float)
        for name, arr in (('friction', f), ('friction_backward', fb)):
            if not np.all(np.isfinite(arr) & (arr >= 0)):
                raise ValueError(f'{name} must be finite and >= 0')
        slope = np.broadcast_to(np.asarray(slope, dtype=float), (B,))
        self.masses = np.ascontiguousarray(m)
        self.M = self.masses.sum(axis=1)
        self._w = self.masses / self.M[:, None]
        self.f_plus = np.ascontiguousarray(f)
        self.f_minus = np.ascontiguousarray(fb)
        self.F_ext = -self.M * gravity * np.sin(slope)
        self.B, self.p = B, p
        self.X = np.zeros(B)
        self.V = np.zeros(B)
        self.t = 0.0

    def _ep(self, rates: NDArray) -> NDArray:
        rates = np.asarray(rates, dtype=float)
        s = np.zeros((self.B, self.p)) if rates.ndim == 2 else np.zeros(self.p)
        np.cumsum(rates, axis=-1, out=s[..., 1:])
        if s.ndim == 1:
            return s[None, :] - (self._w @ s)[:, None]
        return s - np.einsum('bp,bp->b', self._w, s)[:, None]

    def body_velocities(self, rates: ArrayLike) -> NDArray:
        """Velocities of the bodies (B, p) [m/s] given the linkage rates at the current time."""
        return self.V[:, None] + self._ep(rates)

    def step(self, h: float, rates: ArrayLike) -> None:
        """Advance every crawler by h [s]; ``rates`` are l'(t + h)."""
        ep = self._ep(rates)
        c = self.M / h
        V, _ = solve_inclusion_batch(c, self.V, self.F_ext, -ep, self.f_plus, self.f_minus)
        self.V = V
        self.X = self.X + h * V
        self.t += h
