"""Actuator model: step-like length commands in, a C2 linkage length l(t) with bounded l', l'' out.

The node receives target lengths (``linkage_cmd``) or timed trajectories (``linkage_trajectory``)
and must hand the core a gait that is at least C2. No ROS here. The node calls
:meth:`Actuator.step` once per integration tick; a run of ticks with no input in between (the
flat-out node between publish ticks, offline runs) is one call of :meth:`Actuator.run`, which
returns the pieces as arrays (:class:`Pieces`, ``PiecewiseCubic.from_arrays``).

Where the code lives: the per-tick work (the jerk law, settling, the piece end values and the
evaluation of a :class:`TrajectoryReference`) is compiled, in ``_actuator.pyx`` (built by
setup.py), its one implementation; this module holds the model's description, the gains, the
inputs and their validation.

Model
-----
Each linkage is a third-order servo with state ``(l, v, a) = (l, l', l'')``. Per tick of length
``dt`` (from ``t0`` to ``t1 = t0 + dt``) the actuator emits ONE constant-jerk piece
``crawler_sim.core.gaits.Cubic(t0, l, v, a, j)``::

    l(t0 + s) = l + v s + a s^2/2 + j s^3/6,   l' = v + a s + j s^2/2,   l'' = a + j s

and the next tick starts from that piece evaluated at ``t1`` (same expression, so the value is
bit-identical). Hence l, l' and l'' are continuous across ticks: **l is C2** (l''' = j is piecewise
constant), which is what the core's exact solver needs (the body accelerations stay finite).

Jerk law (cascaded, saturated; r, r', r'' is the reference, r' = r'' = 0 for a step command)::

    e   = r - l
    v_d = clip(r' + sqrtp(e), -V, V)          sqrtp: kp e near 0, sqrt(2 A_b (|e| - A_b/(2 kp^2)))
                                              beyond |e| = A_b / kp^2 (braking curve, A_b = A/2)
    a_d = clip(r'' + kv (v_d - v), -A, A)
    j   = clip(ka (a_d - a), [j_lo, j_hi])    (feasible interval below)

Gains: the linear, unsaturated loop is j = -ka kv kp (l - r) - ka kv v - ka a. Discrete pole
placement (jerk held constant over dt) gives the sampled closed loop a *triple* pole at
``q = exp(-w dt)``, i.e. exactly the samples of a critically damped continuous loop (s + w)^3,
for every dt (no stability bound on w dt)::

    c = 1 - q,  ka = c (2 q^2 + 5 q + 11) / (6 dt),  kv = 6 c (q + 2) / (dt (2 q^2 + 5 q + 11)),
    kp = c / (dt (q + 2))          (dt -> 0: kp = w/3, kv = w, ka = 3 w, i.e. (s + w)^3)

``w = 2 pi bandwidth / sqrt(2^(1/3) - 1)`` (about 12.3 x bandwidth) so that ``bandwidth`` [Hz] is
the -3 dB frequency of the linear closed loop w^3 / (s + w)^3 from r to l.

Limits, guaranteed at tick ends AND inside ticks (V = max_speed, A = max_acceleration):

- l'' is linear in s, so |a + j dt| <= A at the end (with |a| <= A at the start) bounds it on the
  whole tick: ``j in [(-A - a)/dt, (A - a)/dt]``.
- l' is quadratic in s. The actuator keeps the *viability* invariant ``v + max(a, 0) dt/2 <= V``
  and ``v - max(-a, 0) dt/2 >= -V`` at every tick start (true at rest). Under it, the maximum of
  l' over the tick is at an end (the interior extremum s* = 2 (V - v)/a lies beyond dt), so
  ``|l'| <= V`` on the whole tick reduces to linear bounds on j at s = dt, and requiring the
  invariant again at t1 gives ``j <= (V - v - 1.5 a dt)/dt^2`` and ``j <= 2 (V - v - a dt)/dt^2``
  (and the mirror images). ``j = -a/dt`` (bring l'' to zero) always satisfies every bound, so the
  feasible interval is never empty; the desired jerk is clipped into it.

Settling: the loop converges geometrically. Once |e| <= 1e-12 m, |v| <= 1e-10 m/s and
|a| <= 1e-8 m/s^2 for a linkage, its v and a are set to exactly 0 and it holds its length (l is
not moved, so l stays continuous; the residual offset from the target is <= 1e-12 m). A linkage at
rest emits jerk 0, so a crawler at rest under a constant command gets ``Cubic`` pieces with
``is_constant() == True`` and the core's stepper takes its cheap path.

Determinism: :func:`jerk_law` is a pure function of (state, reference, dt, gains, limits) in IEEE
double arithmetic as written (compiled without fused multiply-add); the same commands at the
same ticks give bit-identical pieces, whether ticked one by one (``step``) or in runs (``run``).
The compiled code gives bit for bit the floats of the pure-Python model it replaced, kept as the
tests' reference in test/core/actuator_oracle.py.

Trajectories
------------
:class:`TrajectoryReference` turns JointTrajectory points (times from a start time, positions and
optional velocities/accelerations) into a reference r(t), r'(t), r''(t), interpolated like
ros2_control's joint_trajectory_controller: quintic per segment when accelerations are given,
cubic Hermite when velocities are given, linear otherwise. The first segment starts at the
actuator's state (l, l', l'') when the trajectory starts (unless the first point is at time 0);
after the last point the reference holds the last position. The reference then goes through the
same actuator (with r' and r'' as feedforward), so the limits above hold for trajectories too and
a feasible, smooth trajectory is tracked with a lag of about one tick.

Units: s, m, m/s, m/s^2, m/s^3; ``run`` takes integer nanoseconds (the engine's time base).
"""
from __future__ import annotations

import copyreg
from dataclasses import dataclass
import math
from typing import NamedTuple, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crawler_sim.core.gaits import Cubic, PiecewiseCubic, cubic_values

from ._actuator import Reference, Servo, jerk_law

__all__ = ['ActuatorLimits', 'Actuator', 'Pieces', 'TrajectoryReference', 'gains', 'jerk_law',
           'cubic_end', 'BANDWIDTH_TO_POLE']

#: w / (2 pi bandwidth): the triple pole that puts the -3 dB point of w^3/(s+w)^3 at bandwidth.
BANDWIDTH_TO_POLE = 1.0 / math.sqrt(2.0 ** (1.0 / 3.0) - 1.0)


@dataclass(frozen=True)
class ActuatorLimits:
    """Actuator parameters: ``bandwidth`` [Hz] (-3 dB), ``max_speed`` [m/s], ``max_acceleration``
    [m/s^2], all finite and > 0; and the length limits ``min_length`` < ``max_length`` [m]
    (default: none), which the servo brakes for as for a step command to them."""

    bandwidth: float = 5.0
    max_speed: float = 0.5
    max_acceleration: float = 5.0
    min_length: float = -math.inf
    max_length: float = math.inf

    def __post_init__(self) -> None:
        for name in ('bandwidth', 'max_speed', 'max_acceleration'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be finite and > 0, got {value!r}')
        if not self.min_length < self.max_length:      # (NaN fails too)
            raise ValueError(f'`min_length` ({self.min_length!r}) must be < `max_length` '
                             f'({self.max_length!r})')


def gains(bandwidth: float, dt: float) -> tuple[float, float, float]:
    """(kp [1/s], kv [1/s], ka [1/s]) of the cascade for a triple discrete pole at exp(-w dt)
    (see module doc); ``bandwidth`` [Hz], ``dt`` [s]. Once per configuration, not per tick:
    Python floats, handed to the compiled law."""
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f'`dt` must be finite and > 0, got {dt!r}')
    w = 2.0 * math.pi * bandwidth * BANDWIDTH_TO_POLE
    q = math.exp(-w * dt)
    c = -math.expm1(-w * dt)           # 1 - q, accurate for small w dt
    den = 2.0 * q * q + 5.0 * q + 11.0
    return c / (dt * (q + 2.0)), 6.0 * c * (q + 2.0) / (dt * den), c * den / (6.0 * dt)


#: (l, l', l'') of a constant-jerk piece after d seconds: the expression of ``gaits.Cubic``
#: itself (the compiled tick computes a piece's end with the same expression, so the next piece
#: starts bit-identically where the previous one ended)
cubic_end = cubic_values


class Pieces(NamedTuple):
    """The constant-jerk pieces of ``n`` consecutive ticks (``Actuator.run``), as arrays: tick k
    is what ``Actuator.step`` returns for it, as (``anchors[k]``, ``coef[k]``), i.e. the piece
    ``Cubic(anchors[k], *coef[k].T)`` valid from ``starts[k]``.

    A settled actuator hands out one constant piece object again and again (the engine hands
    the solver that one object when a whole window is at rest): every tick from ``rest_from``
    on (``n``: none) is ``rest_piece``, whose ``t0`` (its anchor) is the tick it was made at.
    """

    starts: NDArray[np.float64]      # (n,) tick starts [s]
    anchors: NDArray[np.float64]     # (n,) time origin t0 of each tick's piece [s]
    coef: NDArray[np.float64]        # (n, n_links, 4): l0 [m], v0 [m/s], a0 [m/s^2], jerk [m/s^3]
    rest_from: int
    rest_piece: Cubic | None

    def piece(self, k: int) -> Cubic:
        """The piece of tick k as ``step`` returns it (the rest piece: that same object)."""
        if k >= self.rest_from:
            return self.rest_piece
        return Cubic.trusted(float(self.anchors[k]), *self.coef[k].T.tolist())

    def gait(self) -> PiecewiseCubic:
        """The ticks as one ``PiecewiseCubic`` (no Cubic object per tick)."""
        return PiecewiseCubic.from_arrays(self.starts, self.anchors, self.coef)


class TrajectoryReference:
    """Reference r(t), r'(t), r''(t) from timed points, interpolated like ros2_control's
    joint_trajectory_controller (evaluated by the compiled ``_actuator.Reference``).

    Parameters
    ----------
    t_start : float
        Sim time [s] the point times are measured from.
    state : sequence of (l, v, a) per linkage
        The actuator state at ``t_start`` (start knot of the first segment).
    times : sequence of float, shape (N,)
        Strictly increasing times from ``t_start`` [s], ``times[0] >= 0``.
    positions : shape (N, n_links)
        Lengths [m].
    velocities, accelerations : shape (N, n_links) or None
        Optional rates [m/s] and accelerations [m/s^2] (accelerations need velocities).
    """

    def __init__(self, t_start: float, state: Sequence[Sequence[float]], times: Sequence[float],
                 positions: Sequence[Sequence[float]],
                 velocities: Sequence[Sequence[float]] | None = None,
                 accelerations: Sequence[Sequence[float]] | None = None) -> None:
        n_pts = len(times)
        if n_pts == 0 or len(positions) != n_pts:
            raise ValueError('a trajectory needs at least one point and one position row per time')
        if accelerations is not None and velocities is None:
            raise ValueError('accelerations need velocities')
        self.n_links = len(state)
        self.t_start = float(t_start)
        self.order = 5 if accelerations is not None else 3 if velocities is not None else 1
        ts = [float(t) for t in times]
        if ts[0] < 0 or any(b <= a for a, b in zip(ts, ts[1:])):
            raise ValueError('trajectory times must be >= 0 and strictly increasing')
        knots_t = ([] if ts[0] == 0.0 else [0.0]) + ts
        zero = [0.0] * self.n_links
        pos = [[float(x) for x in row] for row in positions]
        vel = ([[float(x) for x in row] for row in velocities] if velocities is not None
               else [zero] * n_pts)
        acc = ([[float(x) for x in row] for row in accelerations] if accelerations is not None
               else [zero] * n_pts)
        if ts[0] != 0.0:
            pos.insert(0, [s[0] for s in state])
            vel.insert(0, [s[1] for s in state] if self.order >= 3 else zero)
            acc.insert(0, [s[2] for s in state] if self.order >= 5 else zero)
        self._knots(knots_t, *(np.array(x, dtype=float).reshape(len(knots_t), self.n_links)
                               for x in (pos, vel, acc)))

    @classmethod
    def from_arrays(cls, t_start: float, state: Sequence[Sequence[float]], times: ArrayLike,
                    positions: ArrayLike, velocities: ArrayLike | None = None,
                    accelerations: ArrayLike | None = None) -> TrajectoryReference:
        """The same reference as ``cls(...)`` from numpy arrays of any length, without the
        per-element conversions of ``__init__`` (a million points: tens of ms, not seconds).

        ``times`` (N,) and ``positions`` (N, n_links) etc. as in ``__init__``; the times must be
        finite, >= 0 and strictly increasing (checked here with numpy).
        """
        ts = np.asarray(times, dtype=float)
        if ts.ndim != 1 or len(ts) == 0 or len(positions) != len(ts):
            raise ValueError('a trajectory needs at least one point and one position row per time')
        if accelerations is not None and velocities is None:
            raise ValueError('accelerations need velocities')
        if not (np.isfinite(ts).all() and ts[0] >= 0 and np.all(np.diff(ts) > 0)):
            raise ValueError('trajectory times must be >= 0 and strictly increasing')
        self = cls.__new__(cls)
        self.n_links = len(state)
        self.t_start = float(t_start)
        self.order = 5 if accelerations is not None else 3 if velocities is not None else 1
        n_pts = len(ts)
        pos = np.asarray(positions, dtype=float).reshape(n_pts, self.n_links)
        zeros = np.zeros((n_pts, self.n_links))
        vel = (np.asarray(velocities, dtype=float).reshape(n_pts, self.n_links)
               if velocities is not None else zeros)
        acc = (np.asarray(accelerations, dtype=float).reshape(n_pts, self.n_links)
               if accelerations is not None else zeros)
        knots_t = ts.tolist()
        if knots_t[0] != 0.0:            # the first segment starts at the actuator's state
            knots_t.insert(0, 0.0)
            st = np.array([[float(x) for x in row] for row in state])
            zero = np.zeros((1, self.n_links))
            pos = np.vstack([st[:, 0][None, :], pos])
            vel = np.vstack([st[:, 1][None, :] if self.order >= 3 else zero, vel])
            acc = np.vstack([st[:, 2][None, :] if self.order >= 5 else zero, acc])
        self._knots(knots_t, pos, vel, acc)
        return self

    def _knots(self, knots_t: list[float], pos: NDArray[np.float64], vel: NDArray[np.float64],
               acc: NDArray[np.float64]) -> None:
        """Keep the knots (times [s] from ``t_start``, rows (m, n_links)) and compile them."""
        self._t = knots_t
        self._p, self._v, self._a = pos, vel, acc
        self._c = Reference(self.t_start, knots_t, pos, vel, acc, self.order)
        self.end_time = self._c.end_time       # t_start + the last knot time [s]

    def __getstate__(self) -> dict:
        # the compiled evaluator is rebuilt from the knots (it does not pickle)
        state = self.__dict__.copy()
        del state['_c']
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._knots(self._t, self._p, self._v, self._a)

    def __call__(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """(r [m], r' [m/s], r'' [m/s^2]) per linkage at sim time t [s]: quintic, cubic Hermite
        or linear per segment; before the first knot its row, after the last the last position
        at rest."""
        return self._c(t)

    def outside(self, lo: float, hi: float) -> tuple[int, int, float] | None:
        """Where the interpolant leaves [lo, hi] [m] between its knots, or None when it stays
        inside everywhere (and is finite): (segment k, linkage j, a value [m] beyond the
        bound, NaN when not finite). The knots themselves are the caller's to check.

        Exact up to ``_RANGE_TOL``: each segment's polynomial is bounded by the hull of its
        Bernstein coefficients, split in halves (de Casteljau) where the hull crosses a bound,
        up to ``_RANGE_DEPTH`` times; a piece still crossing then holds a value beyond it."""
        coef = self._c.coefficients()                    # (segments, n_links, 6)
        if not coef.size:
            return None
        with np.errstate(over='ignore', invalid='ignore'):
            b = coef @ _TO_BERNSTEIN.T                    # Bernstein coefficients on [0, 1]
            bad = ~np.isfinite(b).all(axis=2)
            if bad.any():
                k, j = (int(x) for x in np.argwhere(bad)[0])
                return k, j, math.nan
            where = np.argwhere(b.max(axis=2) > hi + _RANGE_TOL)
            if len(where):
                found = _beyond(b, where, lambda x: x.max(axis=-1) > hi + _RANGE_TOL, max)
                if found:
                    return found
            where = np.argwhere(b.min(axis=2) < lo - _RANGE_TOL)
            if len(where):
                found = _beyond(b, where, lambda x: x.min(axis=-1) < lo - _RANGE_TOL, min)
                if found:
                    return found
        return None


#: power basis -> Bernstein basis of degree 5 on [0, 1]: b_i = sum_{k <= i} C(i,k)/C(5,k) c_k
_TO_BERNSTEIN = np.array([[math.comb(i, k) / math.comb(5, k) if k <= i else 0.0
                           for k in range(6)] for i in range(6)])
_RANGE_DEPTH = 16        # halvings of a segment whose hull crosses a bound (2^-16 of it)
_RANGE_TOL = 1e-12       # m: a hull within this of a bound is inside (a knot at the bound)


def _beyond(b: NDArray[np.float64], where: NDArray[np.int64], crosses,
            pick) -> tuple[int, int, float] | None:
    """The first (segment, linkage, value) among ``where`` whose polynomial really crosses:
    halve the Bernstein coefficients ``b[k, j]`` while their hull ``crosses``; a value of the
    curve beyond the bound is an end coefficient of a piece that still crosses."""
    for k, j in where:
        pieces = [b[k, j]]
        for _ in range(_RANGE_DEPTH):
            nxt = []
            for c in pieces:
                for half in _halves(c):
                    if crosses(half):
                        end = pick(half[0], half[-1])       # values of the curve itself
                        if crosses(np.array([end])):
                            return int(k), int(j), float(end)
                        nxt.append(half)
            if not nxt:
                break
            pieces = nxt[:64]          # a bounded search: the crossing pieces nearest first
        else:
            return int(k), int(j), float(pick(*(c for p in pieces for c in p)))
    return None


def _halves(c: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """de Casteljau at s = 1/2: the Bernstein coefficients of the two halves."""
    left, right = [c[0]], [c[-1]]
    row = c
    while len(row) > 1:
        row = 0.5 * (row[:-1] + row[1:])
        left.append(row[0])
        right.append(row[-1])
    return np.array(left), np.array(right[::-1])


class Actuator(Servo):
    """The per-linkage servo of the module doc, stepping one tick at a time (``step``) or a run
    of ticks (``run``); the tick itself is compiled (``_actuator.Servo``).

    Parameters
    ----------
    lengths : sequence of float, shape (n_links,)
        Initial lengths [m]; the actuator starts at rest with these as its target.
    dt : float
        Tick length [s].
    limits : ActuatorLimits

    Attributes read by the node and the tests: ``n_links``, ``dt`` [s], ``limits``, ``l``,
    ``v``, ``a`` (lists per linkage at the current tick start [m, m/s, m/s^2], copies),
    ``target`` [m] and ``trajectory`` (the ``TrajectoryReference`` followed, or None).
    ``step(t0, t1=None) -> Cubic``: the piece on [t0, t1] [s] (see ``Servo.step``).
    """

    def __init__(self, lengths: Sequence[float], dt: float, limits: ActuatorLimits) -> None:
        self._alloc(len(lengths))
        self.limits = limits
        self.dt = float(dt)
        self._k = gains(limits.bandwidth, self.dt)
        self.reset(lengths)

    def reset(self, lengths: Sequence[float]) -> None:
        """Back to rest at ``lengths`` [m] with them as target (no trajectory)."""
        if len(lengths) != self.n_links:
            raise ValueError(f'expected {self.n_links} lengths, got {len(lengths)}')
        self.l = [float(x) for x in lengths]
        self.v = [0.0] * self.n_links
        self.a = [0.0] * self.n_links
        self.target = self.l
        self.trajectory = None
        self._settled = [True] * self.n_links
        self._rest_piece = None

    def configure(self, dt: float | None = None, limits: ActuatorLimits | None = None) -> None:
        """Change the tick length [s] and/or limits from the next tick; the state is kept.

        If new limits are tighter than the current state, the state is clipped into them
        (a discontinuity only when limits are lowered while moving, by the caller's choice).
        """
        if limits is not None:
            self.limits = limits
        if dt is not None:
            self.dt = float(dt)
        self._k = gains(self.limits.bandwidth, self.dt)
        vmax, amax, h = self.limits.max_speed, self.limits.max_acceleration, self.dt
        vs, as_ = self.v, self.a
        for i in range(self.n_links):
            a = min(max(as_[i], -amax), amax)
            v = vs[i]
            v = min(v, vmax - max(a, 0.0) * 0.5 * h)
            v = max(v, -vmax + max(-a, 0.0) * 0.5 * h)
            vs[i], as_[i] = v, a
        self.v, self.a = vs, as_

    def set_target(self, lengths: Sequence[float]) -> None:
        """A step command: target lengths [m] held until the next command; cancels a trajectory."""
        if len(lengths) != self.n_links:
            raise ValueError(f'expected {self.n_links} lengths, got {len(lengths)}')
        self._set_target([float(x) for x in lengths])

    def _set_target(self, new: list[float]) -> None:
        """``set_target`` of a list of n_links Python floats, unchecked (the engine's command,
        which has converted them already)."""
        self.trajectory = None
        self._rest_piece = None
        self._command(new)          # a changed target unsettles its linkage (compiled)

    def set_trajectory(self, trajectory: TrajectoryReference | None) -> None:
        """Follow ``trajectory`` (None: hold the current length)."""
        if trajectory is None:
            self.trajectory = None
            self.set_target(self.l)
            return
        if trajectory.n_links != self.n_links:
            raise ValueError(f'expected {self.n_links} linkages, got {trajectory.n_links}')
        self.trajectory = trajectory
        self._rest_piece = None
        self.target = [float(x) for x in trajectory._p[-1]]
        self._settled = [False] * self.n_links

    def state(self) -> list[tuple[float, float, float]]:
        """(l [m], l' [m/s], l'' [m/s^2]) per linkage at the current tick start."""
        return list(zip(self.l, self.v, self.a))

    _STATE = ('dt', 'limits', '_k', 'l', 'v', 'a', 'target', 'trajectory', '_settled',
              '_rest_piece')

    def __reduce__(self):
        # the compiled state does not pickle by itself: the object from its Python-visible
        # state (copy and pickle as before the tick was compiled)
        state = {name: getattr(self, name) for name in self._STATE}
        return copyreg.__newobj__, (type(self),), (self.n_links, state, self.__dict__)

    def __setstate__(self, state: tuple) -> None:
        n_links, values, extra = state
        self._alloc(n_links)
        for name in self._STATE:
            setattr(self, name, values[name])
        self.__dict__.update(extra)

    def run(self, t0_ns: int, dt_ns: int, n: int) -> Pieces:
        """``n`` ticks of ``dt_ns`` [ns] from sim time ``t0_ns`` [ns] with no input in between:
        the pieces, bit for bit, of ``step(to_seconds(t0_ns), to_seconds(t1_ns))`` for each tick
        (t1_ns =
        t0_ns + dt_ns, the engine's time base), as arrays; the state advances to the end."""
        return Pieces(*self._run(t0_ns, dt_ns, n))
