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
    rd, rdd = min(max(rd, -vmax), vmax), min(max(rdd, -amax), amax)   # issue 25: feasible
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


# ---------------------------------------------------------------------------------------------
# The compiled actuator against the pure-Python model it replaced (test/core/actuator_oracle.py),
# bit for bit: every float compared with == and by the sign of zeros.

from test.support import actuator_oracle as oracle  # noqa: E402


def _bits(x: float) -> tuple[float, float]:
    return x, math.copysign(1.0, x)


def assert_same_floats(got, want, where=''):
    got, want = list(got), list(want)
    assert len(got) == len(want), where
    for x, y in zip(got, want):
        assert type(x) is float and type(y) is float, where
        assert x == y and math.copysign(1.0, x) == math.copysign(1.0, y), (where, x, y)


def assert_same_piece(got: Cubic, want: Cubic, where=''):
    assert type(got) is Cubic and got.n_links == want.n_links, where
    assert_same_floats([got.t0], [want.t0], where)
    assert len(got._rows) == len(want._rows), where
    for rg, rw in zip(got._rows, want._rows):
        assert_same_floats(rg, rw, where)
    assert got.is_constant(0.0, 1.0) == want.is_constant(0.0, 1.0), where


def assert_same_state(act: Actuator, orc, where=''):
    for name in ('l', 'v', 'a', 'target'):
        assert_same_floats(getattr(act, name), getattr(orc, name), f'{where} {name}')
    assert (act.trajectory is None) == (orc.trajectory is None), where
    assert act._settled == orc._settled, where
    assert (act._rest_piece is None) == (orc._rest_piece is None), where


def _limits(rng) -> tuple[float, float, float]:
    """Bandwidth [Hz], max speed, max acceleration: mostly saturating, sometimes linear."""
    return (float(rng.choice([0.5, 2.0, 5.0, 20.0, 80.0])),
            float(rng.choice([0.01, 0.05, 0.5, 3.0])),
            float(rng.choice([0.1, 1.0, 5.0, 100.0])))


def _signed(rng, shape, scale):
    """Random values with exact zeros of both signs mixed in."""
    x = rng.normal(0.0, scale, shape)
    mask = rng.random(shape)
    x[mask < 0.15] = 0.0
    x[(mask >= 0.15) & (mask < 0.3)] = -0.0
    return x


def _reference_inputs(rng, n_links: int, dt: float, state):
    """Random trajectory points: positions only, with velocities or with accelerations; the
    first point at 0 or later; few or many points, spaced from under a tick to many ticks."""
    order = int(rng.choice([1, 3, 5]))
    m = int(rng.choice([1, 2, 3, 8, 30]))
    gaps = rng.uniform(0.3, 40.0, m) * dt
    times = np.cumsum(gaps) - (gaps[0] if rng.random() < 0.3 else 0.0)
    pos = rng.uniform(0.02, 0.5, (m, n_links))
    if rng.random() < 0.2:
        pos[0] = [s[0] for s in state]          # dp = 0 on the first segment
    vel = _signed(rng, (m, n_links), 0.3) if order >= 3 else None
    acc = _signed(rng, (m, n_links), 3.0) if order == 5 else None
    return times, pos, vel, acc


def _make_references(rng, t_start, act, orc, inputs):
    times, pos, vel, acc = inputs
    if rng.random() < 0.5:
        return (TrajectoryReference.from_arrays(t_start, act.state(), times, pos, vel, acc),
                oracle.TrajectoryReference.from_arrays(t_start, orc.state(), times, pos, vel,
                                                       acc))
    lists = [None if x is None else x.tolist() for x in (pos, vel, acc)]
    return (TrajectoryReference(t_start, act.state(), times.tolist(), *lists),
            oracle.TrajectoryReference(t_start, orc.state(), times.tolist(), *lists))


def _inputs(rng, act, orc, t, dt):
    """Apply one random input to both actuators (or none)."""
    u = rng.random()
    n = act.n_links
    if u < 0.04:                    # a step command, often far (saturating), sometimes here
        tgt = (rng.uniform(0.0, 0.6, n) if rng.random() < 0.8 else np.array(act.l)).tolist()
        act.set_target(tgt)
        orc.set_target(tgt)
    elif u < 0.055:
        t_start = t + float(rng.choice([0.0, -0.5 * dt, 0.7 * dt, 3 * dt]))
        ra, ro = _make_references(rng, t_start, act, orc,
                                  _reference_inputs(rng, n, dt, act.state()))
        act.set_trajectory(ra)
        orc.set_trajectory(ro)
    elif u < 0.06:
        act.set_trajectory(None)
        orc.set_trajectory(None)
    elif u < 0.068:                 # new limits (the state is clipped into tighter ones)
        lim = _limits(rng)
        act.configure(limits=ActuatorLimits(*lim))
        orc.configure(limits=oracle.ActuatorLimits(*lim))
    elif u < 0.07:                  # a new tick length for the law (the engine's dt change)
        new_dt = dt * float(rng.choice([0.5, 1.0, 3.0]))
        act.configure(dt=new_dt)
        orc.configure(dt=new_dt)
    elif u < 0.072:
        lengths = rng.uniform(0.05, 0.4, n).tolist()
        act.reset(lengths)
        orc.reset(lengths)


@pytest.mark.parametrize('seed', range(12))
def test_the_compiled_actuator_gives_the_oracles_pieces_bit_for_bit(seed):
    """Random command streams, trajectories (positions only, with velocities, with
    accelerations), saturating strokes, limit changes and resets, dt from 1e-5 to 1e-1 s: every
    piece, state, target and flag equal to the pure-Python model's, bit for bit."""
    rng = np.random.default_rng(1000 + seed)
    for stream in range(25):
        n = int(rng.integers(1, 4))
        dt = float(10.0 ** rng.uniform(-5, -1))
        lim = _limits(rng)
        l0 = rng.uniform(0.05, 0.3, n).tolist()
        act = Actuator(l0, dt, ActuatorLimits(*lim))
        orc = oracle.Actuator(l0, dt, oracle.ActuatorLimits(*lim))
        t = float(rng.choice([0.0, 12.5, 1e4]))
        prev_a = prev_o = None
        for k in range(400):
            where = f'seed {seed} stream {stream} tick {k}'
            _inputs(rng, act, orc, t, dt)
            if rng.random() < 0.2:          # t1 defaults to t0 + dt
                pa, po, t1 = act.step(t), orc.step(t), t + dt
            else:
                t1 = t + dt * float(rng.choice([1.0, 1.0, 1.0 + 1e-9, 0.999]))
                pa, po = act.step(t, t1), orc.step(t, t1)
            assert_same_piece(pa, po, where)
            # the same object again exactly when the model hands out its rest piece again
            assert (pa is prev_a) == (po is prev_o), where
            assert_same_state(act, orc, where)
            prev_a, prev_o, t = pa, po, t1


@pytest.mark.parametrize('seed', range(6))
def test_a_run_of_ticks_gives_the_oracles_steps_bit_for_bit(seed):
    """``Actuator.run`` (runs of ticks between inputs, integer ns) against the model stepped
    tick by tick at the engine's times t_ns / 1e9, rest piece and its reuse included."""
    rng = np.random.default_rng(2000 + seed)
    for stream in range(20):
        n = int(rng.integers(1, 4))
        dt_ns = int(rng.choice([10_000, 100_000, 1_000_000, 3_333_333, 20_000_000,
                                100_000_000]))
        dt = dt_ns * 1e-9
        lim = _limits(rng)
        l0 = rng.uniform(0.05, 0.3, n).tolist()
        act = Actuator(l0, dt, ActuatorLimits(*lim))
        orc = oracle.Actuator(l0, dt, oracle.ActuatorLimits(*lim))
        t_ns = int(rng.choice([0, 7 * dt_ns, 10**13]))
        prev_o = None
        for block in range(40):
            _inputs(rng, act, orc, t_ns / 1e9, dt)
            m = int(rng.choice([0, 1, 2, 7, 50, 300]))
            got = act.run(t_ns, dt_ns, m)
            assert got.coef.shape == (m, n, 4) and got.starts.shape == got.anchors.shape == (m,)
            for k in range(m):
                where = f'seed {seed} stream {stream} block {block} tick {k}'
                t1_ns = t_ns + dt_ns
                po = orc.step(t_ns / 1e9, t1_ns / 1e9)
                assert_same_floats([float(got.starts[k])], [t_ns / 1e9], where)
                assert_same_floats([float(got.anchors[k])], [po.t0], where)
                for row, want in zip(got.coef[k].tolist(), po._rows):
                    assert_same_floats(row, want, where)
                assert_same_piece(got.piece(k), po, where)
                # ticks from rest_from on are the rest piece, one object (as step hands it out)
                assert (k >= got.rest_from) == (po is orc._rest_piece), where
                if k > 0:
                    assert (got.piece(k) is got.piece(k - 1)) == (po is prev_o), where
                prev_o, t_ns = po, t1_ns
            if got.rest_from < m:
                assert got.rest_piece is act._rest_piece is act.step(t_ns / 1e9)
                prev_o = orc.step(t_ns / 1e9)
                t_ns += dt_ns
            assert_same_state(act, orc, f'seed {seed} stream {stream} block {block}')


@pytest.mark.parametrize('order', [1, 3, 5])
def test_the_compiled_reference_equals_the_oracles_at_any_time_bit_for_bit(order):
    rng = np.random.default_rng(30 + order)
    for case in range(40):
        n = int(rng.integers(1, 4))
        m = int(rng.choice([1, 2, 5, 40]))
        times = np.cumsum(rng.uniform(1e-4, 0.05, m)) - (0.0 if rng.random() < 0.5 else 1e-4)
        times[0] = max(times[0], 0.0)
        pos = _signed(rng, (m, n), 0.1)
        vel = _signed(rng, (m, n), 1.0) if order >= 3 else None
        acc = _signed(rng, (m, n), 10.0) if order == 5 else None
        state = [tuple(float(x) for x in _signed(rng, 3, 0.2)) for _ in range(n)]
        t_start = float(rng.choice([0.0, 2.0, 1e5]))
        if rng.random() < 0.5:
            got = TrajectoryReference.from_arrays(t_start, state, times, pos, vel, acc)
            want = oracle.TrajectoryReference.from_arrays(t_start, state, times, pos, vel, acc)
        else:
            lists = [None if x is None else x.tolist() for x in (pos, vel, acc)]
            got = TrajectoryReference(t_start, state, times.tolist(), *lists)
            want = oracle.TrajectoryReference(t_start, state, times.tolist(), *lists)
        assert got.end_time == want.end_time and got.order == want.order
        knots = t_start + np.array(want._t)
        ts = np.concatenate([knots, np.nextafter(knots, -np.inf), np.nextafter(knots, np.inf),
                             rng.uniform(t_start - 0.01, want.end_time + 0.01, 200),
                             [t_start, want.end_time]])
        for t in ts.tolist():
            for a, b in zip(got(t), want(t)):
                assert_same_floats(a, b, f'order {order} case {case} t {t!r}')


def test_jerk_law_equals_the_oracles_bit_for_bit_at_the_clamps_and_ties():
    rng = np.random.default_rng(11)
    for _ in range(20000):
        vmax, amax = float(rng.choice([0.01, 0.5, 3.0])), float(rng.choice([0.1, 5.0, 100.0]))
        dt = float(10.0 ** rng.uniform(-5, -1))
        k = gains(float(rng.choice([0.5, 5.0, 80.0])), dt)
        l = float(rng.choice([0.0, -0.0, 0.1]))
        r = l + float(rng.choice([0.0, -0.0, 1e-13, -1e-6, 1e-3, -0.05, 0.3]))
        v = float(rng.choice([0.0, -0.0, vmax, -vmax, rng.uniform(-vmax, vmax)]))
        a = float(rng.choice([0.0, -0.0, amax, -amax, rng.uniform(-amax, amax)]))
        rd = float(rng.choice([0.0, -0.0, vmax, rng.normal(0, vmax)]))
        rdd = float(rng.choice([0.0, -0.0, -amax, rng.normal(0, amax)]))
        args = (l, v, a, r, rd, rdd, dt, k, vmax, amax)
        assert_same_floats([jerk_law(*args)], [oracle.jerk_law(*args)], args)


@pytest.mark.parametrize('offset,v,a', [(1e-12, 0.0, 0.0), (-1e-12, 0.0, 0.0),
                                        (0.0, 1e-10, 0.0), (0.0, -1e-10, 1e-8),
                                        (0.0, 0.0, -1e-8), (1e-12, 1e-10, 1e-8),
                                        (2e-12, 0.0, 0.0), (0.0, 2e-10, 0.0),
                                        (0.0, 0.0, 2e-8)])
def test_settling_thresholds_are_inclusive_as_in_the_oracle(offset, v, a):
    """At exactly |e| = 1e-12 m, |l'| = 1e-10 m/s, |l''| = 1e-8 m/s^2 a linkage settles (and
    a hair beyond it does not), as in the model (from l = 0, so e is exactly the offset)."""
    act = Actuator([0.0], 1e-3, ActuatorLimits())
    orc = oracle.Actuator([0.0], 1e-3, oracle.ActuatorLimits())
    for x in (act, orc):
        x.set_target([offset])
        x.v, x.a = [v], [a]
    for k in range(3):
        assert_same_piece(act.step(k * 1e-3), orc.step(k * 1e-3), k)
        assert_same_state(act, orc, k)


def test_an_actuator_and_its_reference_copy_and_pickle_and_go_on_bit_for_bit():
    import copy
    import pickle
    act = Actuator([0.1, 0.2], 1e-3, ActuatorLimits())
    ref = TrajectoryReference(0.0, act.state(), [0.1, 0.3], [[0.2, 0.1], [0.25, 0.3]],
                              [[0.0, 0.0], [0.1, 0.1]])
    act.set_trajectory(ref)
    for k in range(150):
        act.step(k * 1e-3)
    copies = [pickle.loads(pickle.dumps(act)), copy.deepcopy(act)]
    for k in range(150, 4000):          # following, the end of the trajectory, settling
        want = act.step(k * 1e-3)
        for cp in copies:
            assert_same_piece(cp.step(k * 1e-3), want, k)
            assert_same_state(cp, act, k)
    assert act._rest_piece is not None
    for cp in (pickle.loads(pickle.dumps(act)), copy.deepcopy(act)):
        assert_same_state(cp, act)
        assert cp.step(9.0) is cp._rest_piece
        assert_same_piece(cp._rest_piece, act._rest_piece)
    assert pickle.loads(pickle.dumps(ref))(0.2) == ref(0.2)


def _worst_outside(out, t_end: float, lo: float, hi: float) -> float:
    """How far l(t) of the actuator's output goes beyond [lo, hi] [m] on a fine grid."""
    ts = np.linspace(float(out.starts[0]), t_end, 200_001)
    l = out(ts)[0]
    return float(max(l.max() - hi, lo - l.min()))


def test_an_infeasible_reference_no_longer_drives_the_linkage_past_its_limits():
    """Issue 25: points alternating between min_length and max_length every 10 ms (linear
    interpolation: 48 m/s of feed-forward against a 0.5 m/s servo) drove the linkage 0.3 m past
    max_length. The feed-forward is now bounded by what the servo can do, and the length limits
    bound the servo's speed towards them."""
    from crawler_sim.core.plant import Engine, PlantConfig, PreparedTrajectory
    cfg = PlantConfig.defaults()
    eng = Engine(cfg.engine_config(), integrate=False)
    t = np.arange(1, 201) * 0.01
    pos = np.where(np.arange(200) % 2, 0.5, 0.02)[:, None]
    eng.trajectory(PreparedTrajectory(0, np.rint(t * 1e9).astype(np.int64), pos, None, None))
    eng.run_to(2_500_000_000)
    assert _worst_outside(eng.actuator_output(), 2.5, 0.02, 0.5) <= 1e-12


def test_at_the_nodes_defaults_random_commands_and_trajectories_keep_the_length_in_range():
    """Random sessions at sim_node's defaults and tick rates from 100 Hz to 5 kHz: steps to
    the limits, trajectories of positions only / with velocities / with accelerations between
    them (those whose interpolation leaves the range are refused). The length stays in
    [min_length, max_length] (to 1e-12 m, the settling threshold)."""
    from crawler_sim.core.plant import Engine, PlantConfig, PreparedTrajectory
    rng = np.random.default_rng(25)
    worst, refused = -1.0, 0
    for _ in range(40):
        rate = float(rng.choice([100.0, 1000.0, 5000.0]))
        cfg = PlantConfig.defaults(integration_rate=rate, publish_rate=min(100.0, rate))
        eng = Engine(cfg.engine_config(), integrate=False)
        for _ in range(20):
            if rng.random() < 0.5:
                eng.command([float(rng.choice([0.02, 0.5, rng.uniform(0.02, 0.5)]))])
            else:
                n = int(rng.integers(2, 20))
                t = np.cumsum(rng.uniform(0.01, 0.3, n))
                pos = rng.choice([0.02, 0.5, 0.3], n)[:, None] * 1.0
                order = int(rng.choice([1, 3, 5]))
                vel = rng.uniform(-2, 2, (n, 1)) if order >= 3 else None
                if vel is not None:
                    vel[-1] = 0.0
                acc = rng.uniform(-20, 20, (n, 1)) if order == 5 else None
                try:
                    eng.trajectory(PreparedTrajectory(0, np.rint(t * 1e9).astype(np.int64),
                                                      pos, vel, acc))
                except ValueError:
                    refused += 1
            eng.run_to(eng.t_ns + int(rng.integers(1, 800)) * cfg.dt_ns)
        worst = max(worst, _worst_outside(eng.actuator_output(), eng.t, 0.02, 0.5))
    assert worst <= 1e-12, worst
    assert refused > 10                 # the search met trajectories that leave the range
