"""The actuator model: limits inside ticks, C2 joins, critical damping, bandwidth, trajectories."""
from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_sim.core.actuator import (Actuator, ActuatorLimits, BANDWIDTH_TO_POLE, TrajectoryReference,
                                  gains, jerk_law)
from crawler_sim.core.gaits import Cubic

CASES = [  # bandwidth [Hz], max_speed, max_acceleration, dt
    (5.0, 0.5, 5.0, 1e-3),
    (5.0, 0.05, 5.0, 1e-3),      # speed-limited
    (2.0, 0.5, 0.5, 1e-2),       # acceleration-limited, coarse ticks
    (20.0, 1.0, 100.0, 1e-3),    # fast, mostly linear
    (5.0, 0.5, 5.0, 0.1),        # w dt = 3.1: far beyond a continuous-time design
]


def run(act: Actuator, commands: dict[int, list[float]], n_ticks: int, samples: int = 9):
    """Step the actuator; return the pieces, tick times and densely sampled (l, l', l'')."""
    pieces, dense = [], []
    for k in range(n_ticks):
        if k in commands:
            act.set_target(commands[k])
        t0, t1 = k * act.dt, (k + 1) * act.dt
        piece = act.step(t0, t1)
        pieces.append((t0, t1, piece))
        dense.append(piece(np.linspace(t0, t1, samples)))
    l, v, a = (np.concatenate([d[i] for d in dense]) for i in range(3))
    return pieces, l, v, a


@pytest.mark.parametrize('bw,vmax,amax,dt', CASES)
def test_speed_and_acceleration_stay_within_limits_inside_every_tick(bw, vmax, amax, dt):
    rng = np.random.default_rng(1)
    act = Actuator([0.1, 0.2], dt, ActuatorLimits(bw, vmax, amax))
    n = int(round(6.0 / dt))
    # random steps, some large enough to saturate speed, at random ticks (also mid-motion)
    commands = {int(k): rng.uniform(0.0, 0.6, 2).tolist()
                for k in rng.choice(n // 2, size=12, replace=False)}
    _, _, v, a = run(act, commands, n)
    assert np.max(np.abs(v)) <= vmax * (1 + 1e-12)
    assert np.max(np.abs(a)) <= amax * (1 + 1e-12)
    assert np.max(np.abs(v)) > 0.3 * vmax      # the test did drive it hard


@pytest.mark.parametrize('bw,vmax,amax,dt', CASES)
def test_pieces_join_bit_for_bit_so_the_length_is_C2(bw, vmax, amax, dt):
    act = Actuator([0.1], dt, ActuatorLimits(bw, vmax, amax))
    pieces, *_ = run(act, {0: [0.3], 40: [0.05]}, 200)
    snaps = 0
    for (_, t1, prev), (t0, _, nxt) in zip(pieces, pieces[1:]):
        assert t1 == t0
        (l1, v1, a1), (l0, v0, a0) = prev(t1), nxt(t0)
        np.testing.assert_array_equal(l1, l0)
        if v1[0] != v0[0] or a1[0] != a0[0]:
            # the one documented exception: settling sets |l'| <= 1e-10, |l''| <= 1e-8 to 0
            assert v0[0] == 0.0 and a0[0] == 0.0
            assert abs(v1[0]) <= 1e-10 and abs(a1[0]) <= 1e-8
            snaps += 1
    assert snaps <= 2


@pytest.mark.parametrize('bw,vmax,amax,dt', CASES)
def test_a_step_settles_without_overshoot_and_then_emits_constant_pieces(bw, vmax, amax, dt):
    act = Actuator([0.1], dt, ActuatorLimits(bw, vmax, amax))
    n = int(round(8.0 / dt))
    pieces, l, _, _ = run(act, {0: [0.25]}, n)
    assert np.max(l) <= 0.25 + 1e-9                     # no overshoot
    assert abs(act.l[0] - 0.25) <= 1e-12
    assert act.v == [0.0] and act.a == [0.0]
    last = pieces[-1][2]
    assert last.is_constant(pieces[-1][0], pieces[-1][1])


def test_gains_place_a_triple_pole_at_the_sampled_continuous_pole():
    # the sampled loop x+ = (A + B K) x must have char. poly (z - q)^3, q = exp(-w dt)
    for bw, dt in [(5.0, 1e-3), (5.0, 1e-2), (1.0, 0.2)]:
        kp, kv, ka = gains(bw, dt)
        w = 2 * math.pi * bw * BANDWIDTH_TO_POLE
        q = math.exp(-w * dt)
        a_mat = np.array([[1, dt, dt ** 2 / 2], [0, 1, dt], [0, 0, 1]])
        b = np.array([dt ** 3 / 6, dt ** 2 / 2, dt])
        k = np.array([-ka * kv * kp, -ka * kv, -ka])
        poly = np.poly(a_mat + np.outer(b, k))
        np.testing.assert_allclose(poly, np.poly([q, q, q]), atol=1e-12)
    kp, kv, ka = gains(5.0, 1e-6)        # continuous limit: (s + w)^3
    w = 2 * math.pi * 5.0 * BANDWIDTH_TO_POLE
    np.testing.assert_allclose([kp, kv, ka], [w / 3, w, 3 * w], rtol=1e-4)


def test_bandwidth_is_the_minus_3_dB_frequency_of_small_signal_tracking():
    bw, dt = 2.0, 1e-3
    act = Actuator([0.1], dt, ActuatorLimits(bw, 10.0, 1000.0))   # limits never active
    n = int(round(6.0 / dt))
    out = []
    for k in range(n):
        t0 = k * dt
        act.set_target([0.1 + 1e-4 * math.sin(2 * math.pi * bw * t0)])
        act.step(t0, t0 + dt)
        out.append(act.l[0] - 0.1)
    tail = np.array(out[n // 2:])
    gain = (tail.max() - tail.min()) / 2e-4
    assert gain == pytest.approx(1 / math.sqrt(2), rel=0.02)


def test_the_same_commands_give_bit_identical_pieces():
    def go():
        act = Actuator([0.1, 0.1], 1e-3, ActuatorLimits())
        pieces, l, v, a = run(act, {0: [0.2, 0.05], 300: [0.12, 0.3]}, 900, samples=2)
        return l, v, a, [p.jerk.tobytes() for *_, p in pieces]
    first, second = go(), go()
    for x, y in zip(first[:3], second[:3]):
        np.testing.assert_array_equal(x, y)
    assert first[3] == second[3]


def test_jerk_law_keeps_random_viable_states_viable():
    rng = np.random.default_rng(7)
    k = gains(5.0, 1e-3)
    vmax, amax, dt = 0.5, 5.0, 1e-3
    for _ in range(5000):
        a = rng.uniform(-amax, amax)
        # a viable state: v + max(a, 0) dt/2 <= V and v - max(-a, 0) dt/2 >= -V
        v = rng.uniform(-vmax + max(-a, 0) * dt / 2, vmax - max(a, 0) * dt / 2)
        r, rd, rdd = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-50, 50)
        j = jerk_law(0.0, v, a, r, rd, rdd, dt, k, vmax, amax)
        s = np.linspace(0, dt, 21)
        vs = v + a * s + j * s ** 2 / 2
        a1, v1 = a + j * dt, vs[-1]
        assert np.all(np.abs(vs) <= vmax * (1 + 1e-12))
        assert abs(a1) <= amax * (1 + 1e-12)
        assert v1 + max(a1, 0) * dt / 2 <= vmax * (1 + 1e-12)
        assert v1 - max(-a1, 0) * dt / 2 >= -vmax * (1 + 1e-12)


@pytest.mark.parametrize('bad', [dict(bandwidth=0.0), dict(max_speed=-1.0),
                                 dict(max_acceleration=math.inf)])
def test_invalid_limits_are_rejected(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        ActuatorLimits(**bad)


def test_quintic_trajectory_reference_passes_through_its_points_with_their_derivatives():
    state = [(0.1, 0.0, 0.0)]
    ref = TrajectoryReference(2.0, state, [0.5, 1.5], [[0.2], [0.15]], [[0.1], [0.0]],
                              [[0.3], [0.0]])
    for t, (p, v, a) in [(2.0, (0.1, 0.0, 0.0)), (2.5, (0.2, 0.1, 0.3)),
                         (3.5, (0.15, 0.0, 0.0)), (9.0, (0.15, 0.0, 0.0))]:
        r, rd, rdd = ref(t)
        assert r[0] == pytest.approx(p, abs=1e-12)
        assert rd[0] == pytest.approx(v, abs=1e-12)
        assert rdd[0] == pytest.approx(a, abs=1e-9)
    # derivatives are consistent with the positions (finite differences mid-segment)
    h = 1e-6
    r_m, r_p, (r, rd, rdd) = ref(3.0 - h)[0][0], ref(3.0 + h)[0][0], ref(3.0)
    assert (r_p - r_m) / (2 * h) == pytest.approx(rd[0], rel=1e-6)


def test_linear_and_cubic_references_interpolate_like_joint_trajectory_controller():
    state = [(0.1, 0.05, 0.0)]
    lin = TrajectoryReference(0.0, state, [1.0, 2.0], [[0.2], [0.4]])
    assert lin(0.5)[0][0] == pytest.approx(0.15)          # straight from the current length
    assert lin(1.5)[1][0] == pytest.approx(0.2)           # slope of the second segment
    cub = TrajectoryReference(0.0, state, [1.0], [[0.2]], [[0.0]])
    r, rd, _ = cub(0.0)
    assert rd[0] == pytest.approx(0.05)                   # starts with the current rate
    assert cub(1.0)[0][0] == pytest.approx(0.2)
    with pytest.raises(ValueError, match='strictly increasing'):
        TrajectoryReference(0.0, state, [1.0, 1.0], [[0.2], [0.3]])


def test_the_actuator_tracks_a_feasible_trajectory_closely_and_ends_at_rest():
    dt = 1e-3
    act = Actuator([0.1], dt, ActuatorLimits(5.0, 0.5, 5.0))
    times = np.linspace(0.5, 3.0, 11)
    pos = 0.1 + 0.05 * np.sin(np.pi * (times - 0.5) / 2.5) ** 2
    act.set_trajectory(TrajectoryReference(0.0, act.state(), times.tolist(),
                                           pos[:, None].tolist(),
                                           np.zeros((11, 1)).tolist()))
    ref = act.trajectory
    worst = 0.0
    for k in range(int(5.0 / dt)):
        t0 = k * dt
        act.step(t0, t0 + dt)
        if t0 < 3.0:
            worst = max(worst, abs(act.l[0] - ref(t0 + dt)[0][0]))
    assert worst < 2e-3
    assert act.trajectory is None and act.v == [0.0] and act.l[0] == pytest.approx(pos[-1])


def test_a_settled_actuator_hands_the_solver_constant_pieces():
    act = Actuator([0.1, 0.1], 1e-3, ActuatorLimits())
    piece = act.step(0.0, 1e-3)
    assert isinstance(piece, Cubic) and piece.is_constant(0.0, 1e-3)


def _jerk_law_spec(l, v, a, r, rd, rdd, dt, k, vmax, amax):
    """jerk_law as first written, with builtin min/max (the spec the fast version must match
    bit for bit)."""
    kp, kv, ka = k
    e, ab = r - l, 0.5 * amax
    lin = ab / (kp * kp)
    s = (math.sqrt(2.0 * ab * (e - 0.5 * lin)) if e > lin
         else -math.sqrt(2.0 * ab * (-e - 0.5 * lin)) if e < -lin else kp * e)
    v_d = min(max(rd + s, -vmax), vmax)
    a_d = min(max(rdd + kv * (v_d - v), -amax), amax)
    j = ka * (a_d - a)
    dt2 = dt * dt
    hi = min((amax - a) / dt, 2.0 * (vmax - v - a * dt) / dt2, (vmax - v - 1.5 * a * dt) / dt2)
    lo = max((-amax - a) / dt, 2.0 * (-vmax - v - a * dt) / dt2, (-vmax - v - 1.5 * a * dt) / dt2)
    return -a / dt if lo > hi else min(max(j, lo), hi)


def test_jerk_law_equals_its_min_max_spec_bit_for_bit_including_clamps_and_ties():
    rng = np.random.default_rng(7)
    for _ in range(20000):
        vmax, amax = rng.choice([0.05, 0.5, 2.0]), rng.choice([0.5, 5.0, 50.0])
        dt = rng.choice([1e-3, 1e-2, 0.1])
        k = gains(rng.choice([2.0, 5.0, 20.0]), dt)
        l = 0.1
        r = l + rng.choice([0.0, 1e-9, -1e-6, 1e-3, -0.05, 0.3])
        v = float(rng.choice([0.0, -0.0, vmax, -vmax, rng.uniform(-vmax, vmax)]))
        a = float(rng.choice([0.0, amax, -amax, rng.uniform(-amax, amax)]))
        rd, rdd = float(rng.choice([0.0, rng.normal(0, vmax)])), float(rng.normal(0, amax))
        args = (l, v, a, r, rd, rdd, dt, k, vmax, amax)
        got, want = jerk_law(*args), _jerk_law_spec(*args)
        assert got == want and math.copysign(1.0, got) == math.copysign(1.0, want), args


@pytest.mark.parametrize('order', [1, 3, 5])
def test_a_reference_evaluated_in_any_time_order_equals_a_fresh_one_at_each_time(order):
    # the reference keeps its current segment between calls; jumping back, forward, to the ends
    # and between segments must give what a reference that never cached anything gives
    rng = np.random.default_rng(order)
    times = np.cumsum(rng.uniform(0.005, 0.05, 30))
    pos = rng.uniform(0.05, 0.15, (30, 2))
    vel = rng.normal(size=(30, 2)) if order >= 3 else None
    acc = rng.normal(size=(30, 2)) if order == 5 else None
    state = [(0.1, 0.01, 0.2), (0.12, -0.02, 0.0)]
    ref = TrajectoryReference.from_arrays(2.0, state, times, pos, vel, acc)
    ts = np.concatenate([2.0 + np.arange(0.0, times[-1] + 0.01, 1e-3),
                         rng.uniform(1.9, 2.1 + times[-1], 300), 2.0 + times[::-1]])
    for t in ts.tolist():
        fresh = TrajectoryReference.from_arrays(2.0, state, times, pos, vel, acc)
        assert ref(t) == fresh(t), t
