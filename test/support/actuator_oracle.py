"""ORACLE for the compiled actuator: a verbatim copy of the pure-Python actuator model
(``crawler_sim/core/actuator.py`` as of commit c618dbc, before its per-tick work moved to
``crawler_sim/core/_actuator.pyx``).

This is the independent reference the tests and ``benchmarks/actuator.py`` compare the compiled
actuator against, bit for bit: ``jerk_law`` (the servo law with its clamps and the feasible jerk
interval), the settling to rest, the constant-jerk piece ends (``cubic_values``, the expression
of ``gaits.Cubic``) and ``TrajectoryReference`` (linear / cubic Hermite / quintic segments,
holding after the last point). It is test code only: nothing in ``crawler_sim`` imports it, and
it must not be "fixed" to follow later changes of the model; a deliberate change of the model
changes this file in the same commit, with the reason.

Changes of the model since: (issue 25) the feed-forward r', r'' is bounded by max_speed and
max_acceleration, and the length limits [min_length, max_length] bound v_d as targets the
servo brakes for (from where the tick's motion takes the linkage): a reference faster than the
servo drove linkages 0.3 m past max_length.
"""
from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
import math
from typing import Sequence

from crawler_sim.core.gaits import Cubic, cubic_values


#: w / (2 pi bandwidth): the triple pole that puts the -3 dB point of w^3/(s+w)^3 at bandwidth.
BANDWIDTH_TO_POLE = 1.0 / math.sqrt(2.0 ** (1.0 / 3.0) - 1.0)

_SETTLE_L = 1e-12   # m
_SETTLE_V = 1e-10   # m/s
_SETTLE_A = 1e-8    # m/s^2


@dataclass(frozen=True)
class ActuatorLimits:
    """Actuator parameters: ``bandwidth`` [Hz] (-3 dB), ``max_speed`` [m/s], ``max_acceleration``
    [m/s^2]. All must be finite and > 0."""

    bandwidth: float = 5.0
    max_speed: float = 0.5
    max_acceleration: float = 5.0
    min_length: float = -math.inf        # issue 25
    max_length: float = math.inf

    def __post_init__(self) -> None:
        for name in ('bandwidth', 'max_speed', 'max_acceleration'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be finite and > 0, got {value!r}')


def gains(bandwidth: float, dt: float) -> tuple[float, float, float]:
    """(kp, kv, ka) of the cascade for a triple discrete pole at exp(-w dt) (see module doc)."""
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f'`dt` must be finite and > 0, got {dt!r}')
    w = 2.0 * math.pi * bandwidth * BANDWIDTH_TO_POLE
    q = math.exp(-w * dt)
    c = -math.expm1(-w * dt)           # 1 - q, accurate for small w dt
    den = 2.0 * q * q + 5.0 * q + 11.0
    return c / (dt * (q + 2.0)), 6.0 * c * (q + 2.0) / (dt * den), c * den / (6.0 * dt)


def _sqrt_p(e: float, kp: float, a_brake: float) -> float:
    """Position-to-velocity law: linear (kp e) near zero, braking curve sqrt(2 A_b |e|) far away.

    C1 at the junction |e| = A_b / kp^2 (ArduPilot's ``sqrt_controller``).
    """
    linear = a_brake / (kp * kp)
    if e > linear:
        return math.sqrt(2.0 * a_brake * (e - 0.5 * linear))
    if e < -linear:
        return -math.sqrt(2.0 * a_brake * (-e - 0.5 * linear))
    return kp * e


def jerk_law(l: float, v: float, a: float, r: float, rd: float, rdd: float, dt: float,
             k: tuple[float, float, float], max_speed: float, max_acceleration: float,
             min_length: float = -math.inf, max_length: float = math.inf) -> float:
    """Jerk for one linkage over one tick: a pure function of state, reference and dt.

    Assumes the viability invariant at the start (see module doc); the result keeps
    |l'| <= max_speed and |l''| <= max_acceleration over the whole tick, and the invariant at
    its end.
    """
    kp, kv, ka = k
    vmax, amax = max_speed, max_acceleration
    # One call per linkage per 1 kHz tick: the clamps are written as comparisons instead of
    # builtin min/max calls (about half the cost). Each keeps builtin min/max's choice exactly
    # (the earlier argument on ties, so also the sign of a zero), hence the same bits.
    rd = min(max(rd, -vmax), vmax)          # issue 25: the feed-forward the servo can do
    rdd = min(max(rdd, -amax), amax)
    e = r - l
    linear = 0.5 * amax / (kp * kp)          # _sqrt_p inlined (a_brake = amax / 2)
    if e > linear:
        v_d = rd + math.sqrt(2.0 * (0.5 * amax) * (e - 0.5 * linear))
    elif e < -linear:
        v_d = rd + -math.sqrt(2.0 * (0.5 * amax) * (-e - 0.5 * linear))
    else:
        v_d = rd + kp * e
    # issue 25: the length limits as targets, from where this tick's motion takes the linkage
    v_d = min(v_d, _sqrt_p(max_length - (l + abs(v) * dt), kp, 0.5 * amax))
    v_d = max(v_d, _sqrt_p(min_length - (l - abs(v) * dt), kp, 0.5 * amax))
    if -vmax > v_d:                          # min(max(v_d, -vmax), vmax)
        v_d = -vmax
    if vmax < v_d:
        v_d = vmax
    a_d = rdd + kv * (v_d - v)
    if -amax > a_d:                          # min(max(a_d, -amax), amax)
        a_d = -amax
    if amax < a_d:
        a_d = amax
    j = ka * (a_d - a)
    dt2 = dt * dt
    hi = (amax - a) / dt                     # min of three
    x = 2.0 * (vmax - v - a * dt) / dt2
    if x < hi:
        hi = x
    x = (vmax - v - 1.5 * a * dt) / dt2
    if x < hi:
        hi = x
    lo = (-amax - a) / dt                    # max of three
    x = 2.0 * (-vmax - v - a * dt) / dt2
    if x > lo:
        lo = x
    x = (-vmax - v - 1.5 * a * dt) / dt2
    if x > lo:
        lo = x
    if lo > hi:            # only through rounding at the boundary; -a/dt is always admissible
        return -a / dt
    if lo > j:                               # min(max(j, lo), hi)
        j = lo
    if hi < j:
        j = hi
    return j


#: (l, l', l'') of a constant-jerk piece after d seconds: the expression of ``gaits.Cubic``
#: itself, so the next piece starts bit-identically where the previous one ended
cubic_end = cubic_values


class TrajectoryReference:
    """Reference r(t), r'(t), r''(t) from timed points, interpolated like ros2_control's
    joint_trajectory_controller.

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
        self._t = knots_t
        self._p, self._v, self._a = pos, vel, acc
        self.end_time = self.t_start + knots_t[-1]

    @classmethod
    def from_arrays(cls, t_start: float, state: Sequence[Sequence[float]], times,
                    positions, velocities=None, accelerations=None) -> TrajectoryReference:
        """The same reference as ``cls(...)`` from numpy arrays of any length, without the
        per-element conversions of ``__init__`` (a million points: tens of ms, not seconds).

        ``times`` (N,) and ``positions`` (N, n_links) etc. as in ``__init__``; the times must be
        finite, >= 0 and strictly increasing (checked here with numpy).
        """
        import numpy as np
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
        # rows stay numpy arrays (a list of a million small lists costs seconds to build);
        # __call__ takes the two rows it needs as floats (_row)
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
        self._t = knots_t
        self._p, self._v, self._a = pos, vel, acc
        self.end_time = self.t_start + knots_t[-1]
        return self

    def __call__(self, t: float) -> tuple[list[float], list[float], list[float]]:
        """(r, r', r'') per linkage at sim time t."""
        tau = t - self.t_start
        kt = self._t
        if tau >= kt[-1]:
            return list(_row(self._p, -1)), [0.0] * self.n_links, [0.0] * self.n_links
        if tau <= kt[0]:
            return (list(_row(self._p, 0)), list(_row(self._v, 0)),
                    list(_row(self._a, 0)))
        # A 1 kHz actuator evaluates each segment of a 50 Hz trajectory 20 times in a row: the
        # segment and its per-linkage coefficients are kept until tau leaves it (same floats as
        # computing them every call, so the reference is bit-identical).
        seg = getattr(self, '_seg', None)
        if seg is None or not (seg[0] <= tau < seg[1]):
            seg = self._seg = self._segment(bisect_right(kt, tau) - 1)
        t_k, _t_next, h, coeffs = seg
        s = (tau - t_k) / h
        r, rd, rdd = [], [], []
        if self.order == 1:
            for p0, dp, slope in coeffs:
                r.append(p0 + s * dp)
                rd.append(slope)
                rdd.append(0.0)
            return r, rd, rdd
        h2 = h * h
        for c0, c1, c2, c3, c4, c5 in coeffs:
            x = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
            xd = c1 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))
            xdd = 2 * c2 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5))
            r.append(x)
            rd.append(xd / h)
            rdd.append(xdd / h2)
        return r, rd, rdd

    def _segment(self, k: int) -> tuple[float, float, float, list[tuple[float, ...]]]:
        """(t_k, t_k+1, h, per-linkage coefficients) of segment k [s from ``t_start``]: for
        order 1 (p0, p1 - p0, slope), else the Hermite coefficients on s in [0, 1]."""
        kt = self._t
        h = kt[k + 1] - kt[k]
        P0, P1 = _row(self._p, k), _row(self._p, k + 1)
        if self.order == 1:
            coeffs = [(P0[i], P1[i] - P0[i], (P1[i] - P0[i]) / h) for i in range(self.n_links)]
            return kt[k], kt[k + 1], h, coeffs
        V0, V1 = _row(self._v, k), _row(self._v, k + 1)
        A0, A1 = _row(self._a, k), _row(self._a, k + 1)
        coeffs = [_hermite(P0[i], V0[i] * h, A0[i] * h * h, P1[i], V1[i] * h, A1[i] * h * h,
                           self.order) for i in range(self.n_links)]
        return kt[k], kt[k + 1], h, coeffs


def _row(rows, k: int) -> list[float]:
    """Row k of a list of rows, or of a 2-D array as floats (same values)."""
    return rows[k] if isinstance(rows, list) else rows[k].tolist()


def _hermite(p0: float, v0: float, a0: float, p1: float, v1: float, a1: float,
             order: int) -> tuple[float, ...]:
    """Coefficients c0..c5 on s in [0, 1] of the cubic (order 3) or quintic (order 5) Hermite
    polynomial with the given end values and (scaled) derivatives."""
    dp = p1 - p0
    if order == 3:
        return (p0, v0, 3 * dp - 2 * v0 - v1, -2 * dp + v0 + v1, 0.0, 0.0)
    return (p0, v0, 0.5 * a0,
            10 * dp - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1,
            -15 * dp + 8 * v0 + 7 * v1 + 1.5 * a0 - a1,
            6 * dp - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1)


class Actuator:
    """The per-linkage servo of the module doc, stepping one tick at a time.

    Parameters
    ----------
    lengths : sequence of float, shape (n_links,)
        Initial lengths [m]; the actuator starts at rest with these as its target.
    dt : float
        Tick length [s].
    limits : ActuatorLimits
    """

    def __init__(self, lengths: Sequence[float], dt: float, limits: ActuatorLimits) -> None:
        self.n_links = len(lengths)
        if self.n_links < 1:
            raise ValueError('the actuator needs at least one linkage')
        self.limits = limits
        self.dt = float(dt)
        self._k = gains(limits.bandwidth, self.dt)
        self.reset(lengths)

    def reset(self, lengths: Sequence[float]) -> None:
        """Back to rest at ``lengths`` with them as target (no trajectory)."""
        if len(lengths) != self.n_links:
            raise ValueError(f'expected {self.n_links} lengths, got {len(lengths)}')
        self.l = [float(x) for x in lengths]
        self.v = [0.0] * self.n_links
        self.a = [0.0] * self.n_links
        self.target = list(self.l)
        self.trajectory: TrajectoryReference | None = None
        self._settled = [True] * self.n_links
        self._rest_piece: Cubic | None = None

    def configure(self, dt: float | None = None, limits: ActuatorLimits | None = None) -> None:
        """Change the tick length and/or limits from the next tick; the state is kept.

        If new limits are tighter than the current state, the state is clipped into them
        (a discontinuity only when limits are lowered while moving, by the caller's choice).
        """
        if limits is not None:
            self.limits = limits
        if dt is not None:
            self.dt = float(dt)
        self._k = gains(self.limits.bandwidth, self.dt)
        vmax, amax, h = self.limits.max_speed, self.limits.max_acceleration, self.dt
        for i in range(self.n_links):
            a = min(max(self.a[i], -amax), amax)
            v = self.v[i]
            v = min(v, vmax - max(a, 0.0) * 0.5 * h)
            v = max(v, -vmax + max(-a, 0.0) * 0.5 * h)
            self.v[i], self.a[i] = v, a

    def set_target(self, lengths: Sequence[float]) -> None:
        """A step command: target lengths [m] held until the next command; cancels a trajectory."""
        if len(lengths) != self.n_links:
            raise ValueError(f'expected {self.n_links} lengths, got {len(lengths)}')
        new = [float(x) for x in lengths]
        self.trajectory = None
        self._rest_piece = None
        for i in range(self.n_links):
            if new[i] != self.target[i]:
                self._settled[i] = False
        self.target = new

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
        """(l, l', l'') per linkage at the current tick start."""
        return list(zip(self.l, self.v, self.a))

    def step(self, t0: float, t1: float | None = None) -> Cubic:
        """The constant-jerk piece on [t0, t1] (t1 defaults to t0 + dt); advances the state to t1.

        The jerk uses the nominal ``dt``; pass ``t1`` so that the end state is computed with the
        exact float ``t1 - t0`` the solver will use.
        """
        if t1 is None:
            t1 = t0 + self.dt
        d = t1 - t0
        lim = self.limits
        traj = self.trajectory
        if traj is not None:
            ref = traj(t0)
            if t0 >= traj.end_time:
                self.trajectory = None          # hold the last point as a plain target
                self.target = list(ref[0])
        elif self._rest_piece is not None:
            return self._rest_piece
        l0, v0, a0 = list(self.l), list(self.v), list(self.a)
        jerk = [0.0] * self.n_links
        for i in range(self.n_links):
            if traj is None:
                if self._settled[i]:
                    continue
                r, rd, rdd = self.target[i], 0.0, 0.0
                if (abs(r - l0[i]) <= _SETTLE_L and abs(v0[i]) <= _SETTLE_V
                        and abs(a0[i]) <= _SETTLE_A):
                    self._settled[i] = True
                    v0[i] = a0[i] = 0.0
                    self.v[i] = self.a[i] = 0.0
                    continue
            else:
                r, rd, rdd = ref[0][i], ref[1][i], ref[2][i]
            j = jerk_law(l0[i], v0[i], a0[i], r, rd, rdd, self.dt, self._k,
                         lim.max_speed, lim.max_acceleration, lim.min_length, lim.max_length)
            jerk[i] = j
            self.l[i], self.v[i], self.a[i] = cubic_end(l0[i], v0[i], a0[i], j, d)
        piece = Cubic.trusted(t0, l0, v0, a0, jerk)
        if traj is None and all(self._settled):
            self._rest_piece = piece      # constant: valid at any time, reused until a command
        return piece


class OracleEngine:
    """The actuator side of ``plant.Engine(cfg, t_ns, integrate=False)`` as it was (c618dbc),
    with the actuator above: one ``step`` per ``tick()``, a sync (moving the queue to the log)
    on the publish grid, ``actuator_output`` from Cubic objects. Drop-in for
    ``plant.streams.actuator_output`` (``command``, ``trajectory``, ``run_to``, ``t_ns``)."""

    def __init__(self, cfg, t_ns: int = 0, journal=None, *, integrate: bool = False) -> None:
        if integrate:
            raise ValueError('the oracle engine has no crawler (integrate=False only)')
        self.cfg = cfg
        self.t_ns = t_ns
        self.actuator = Actuator(list(cfg.initial_lengths), cfg.dt_ns / 1e9, cfg.limits)
        self._starts: list[float] = []
        self._pieces: list[Cubic] = []
        self._log_starts: list[float] = []
        self._log_pieces: list[Cubic] = []

    def command(self, lengths) -> None:
        self.actuator.set_target([float(x) for x in lengths])

    def trajectory(self, prepared) -> None:
        if prepared is None or not len(prepared.tfs_ns):
            self.actuator.set_trajectory(None)
            return
        keep, times = prepared.times(self.t_ns)
        vel = prepared.velocities[keep] if prepared.velocities is not None else None
        acc = prepared.accelerations[keep] if prepared.accelerations is not None else None
        self.actuator.set_trajectory(TrajectoryReference.from_arrays(
            self.t_ns / 1e9, self.actuator.state(), times, prepared.positions[keep], vel, acc))

    def tick(self) -> bool:
        t0_ns = self.t_ns
        t1_ns = t0_ns + self.cfg.dt_ns
        t0 = t0_ns / 1e9
        self._starts.append(t0)
        self._pieces.append(self.actuator.step(t0, t1_ns / 1e9))
        self.t_ns = t1_ns
        if (t1_ns // self.cfg.dt_ns) % self.cfg.publish_every == 0:
            self.sync()
            return True
        return False

    def run_to(self, t_ns: int) -> None:
        while self.t_ns < t_ns:
            self.tick()

    def sync(self) -> None:
        self._log_starts.extend(self._starts)
        self._log_pieces.extend(self._pieces)
        self._pieces, self._starts = [], []

    def actuator_output(self):
        from crawler_sim.core.gaits import PiecewiseCubic
        self.sync()
        return PiecewiseCubic.trusted(list(self._log_starts), list(self._log_pieces))
