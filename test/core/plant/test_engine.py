"""The node's engine: batched ticks (flat out) give the same states, bit for bit, as single ones."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from crawler_sim.core import gaits
from crawler_sim.core.actuator import ActuatorLimits, TrajectoryReference
from crawler_sim.core.plant import Engine, EngineConfig, PlantConfig, PreparedTrajectory, streams
from crawler_sim.core.model import Crawler


def config(p: int, publish_every: int, method: str = 'exact') -> EngineConfig:
    crawler = Crawler.from_coefficients(np.linspace(0.5, 1.0, p), 0.3, 0.3)
    return EngineConfig(crawler=crawler, method=method, dt_ns=1_000_000,
                        publish_every=publish_every, initial_lengths=[0.1] * (p - 1),
                        initial_position=0.0, limits=ActuatorLimits())


def states(engine: Engine, batched: bool, n_periods: int) -> list:
    """(t_ns, x, v, friction, lengths, rates) at every publish tick, targets and a trajectory
    applied at fixed ticks (between periods, as the node does)."""
    out = []
    gait = gaits.Scallop(0.1, 0.02, 2.0, 0.2, [0.0] * (engine.actuator.n_links),
                         n_links=engine.actuator.n_links)
    for k in range(n_periods):
        if k == 3:
            engine.command([0.13] * engine.actuator.n_links)
        if k == 40:
            t = np.arange(1, 200) * 0.02
            l, ld, ldd = gait(t)
            engine.actuator.set_trajectory(TrajectoryReference(
                engine.t, engine.actuator.state(), t, l, ld, ldd))
        if batched:
            n = engine.tick_to_grid()
        else:
            n = 1
            while not engine.tick():
                n += 1
        st = engine.state
        out.append((n, engine.t_ns, st.x.tolist(), st.v.tolist(), st.friction.tolist(),
                    st.lengths.tolist(), st.rates.tolist(), st.contact.tolist()))
    return out


@pytest.mark.parametrize('p,publish_every,method', [(2, 10, 'exact'), (3, 7, 'exact'),
                                                      (2, 1, 'exact'), (2, 10, 'implicit')])
def test_ticks_to_the_grid_equal_single_ticks_bit_for_bit(p, publish_every, method):
    single = states(Engine(config(p, publish_every, method)), False, 120)
    batched = states(Engine(config(p, publish_every, method)), True, 120)
    assert batched == single
    assert all(s[0] == publish_every for s in single)
    assert single[-1][2] != single[0][2]          # the crawler moved


def test_ticks_to_the_grid_start_anywhere_within_a_period():
    a, b = Engine(config(2, 10)), Engine(config(2, 10))
    a.command([0.12])
    b.command([0.12])
    for _ in range(3):
        a.tick()
        b.tick()
    assert b.tick_to_grid() == 7
    while not a.tick():
        pass
    assert a.t_ns == b.t_ns == 10_000_000
    assert a.state.x.tolist() == b.state.x.tolist()


# ---------------------------------------------------------------------------------------------
# Runs of ticks (tick_to_grid, run_to: one compiled run of the actuator, an array-built gait)
# against tick() repeated: the same pieces, states, events and journal, bit for bit.

from test.support import actuator_oracle as oracle  # noqa: E402


def _schedule(rng, n_links: int, dt_ns: int, n_inputs: int) -> list:
    """Random inputs at random tick boundaries: commands (far: saturating), trajectories
    (positions only, with velocities, with accelerations; stamped 0 or absolute), new actuator
    limits, resets, and long quiet spans (the actuator settles and hands out its rest piece)."""
    out, t_ns = [], 0
    for _ in range(n_inputs):
        t_ns += dt_ns * int(rng.choice([1, 3, 10, 37, 400, 2500]))
        u = rng.random()
        if u < 0.4:
            out.append((t_ns, 'command', rng.uniform(0.05, 0.3, n_links).tolist()))
        elif u < 0.75:
            order = int(rng.choice([1, 3, 5]))
            m = int(rng.choice([1, 4, 40]))
            tfs = np.cumsum(rng.integers(1, 60, m)) * dt_ns // 3
            pos = rng.uniform(0.05, 0.3, (m, n_links))
            vel = rng.normal(0, 0.1, (m, n_links)) if order >= 3 else None
            acc = rng.normal(0, 1.0, (m, n_links)) if order == 5 else None
            stamp = 0 if rng.random() < 0.5 else t_ns + int(rng.integers(-2, 3)) * dt_ns
            out.append((t_ns, 'trajectory', PreparedTrajectory(stamp, tfs.astype(np.int64),
                                                               pos, vel, acc)))
        elif u < 0.9:
            out.append((t_ns, 'limits', ActuatorLimits(float(rng.choice([2.0, 5.0, 20.0])),
                                                       float(rng.choice([0.05, 0.5])),
                                                       float(rng.choice([1.0, 5.0, 50.0])))))
        else:
            out.append((t_ns, 'reset', None))
    return out


def _play(engine: Engine, schedule: list, t_end_ns: int, rng=None, read_state=False) -> list:
    """Apply the schedule; between inputs tick() one by one (rng None) or, at random,
    tick(), tick_to_grid() (when the grid comes before the next input) and run_to()."""
    seen = []
    for at_ns, kind, payload in schedule + [(t_end_ns, 'end', None)]:
        while engine.t_ns < at_ns:
            if rng is None:
                engine.tick()
                continue
            cfg = engine.cfg
            grid = (engine.t_ns // (cfg.dt_ns * cfg.publish_every) + 1) * cfg.dt_ns \
                * cfg.publish_every
            u = rng.random()
            if u < 0.2:
                engine.tick()
            elif u < 0.6 and grid <= at_ns:
                engine.tick_to_grid()
            else:
                engine.run_to(int(rng.integers(engine.t_ns + 1, at_ns + 1)))
        if kind == 'command':
            engine.command(payload)
        elif kind == 'trajectory':
            try:
                engine.trajectory(payload)
            except ValueError:          # points already past at this tick: refused
                pass
        elif kind == 'limits':
            engine.reconfigure(dataclasses.replace(engine.cfg, limits=payload))
        elif kind == 'reset':
            engine.reset()
        if read_state and engine.integrate:
            st = engine.state          # the same (off-grid) sync in both runs
            seen.append((engine.t_ns, st.x.tolist(), st.v.tolist(), st.friction.tolist(),
                         st.lengths.tolist(), st.rates.tolist(), st.contact.tolist()))
        seen.append((engine.t_ns, [tuple(map(float.hex, s)) for s in engine.actuator_state()]))
    return seen


def _piece_bits(gait) -> list:
    return [(float.hex(pc.t0), [tuple(map(float.hex, row)) for row in pc._rows])
            for pc in gait.pieces]


@pytest.mark.parametrize('seed', range(8))
def test_runs_of_ticks_emit_the_pieces_of_single_ticks_bit_for_bit(seed):
    """integrate=False (the offline runs): ``actuator_output`` after runs of ticks equals the
    one after tick() repeated, every start time and piece bit for bit, also when read
    mid-way."""
    rng = np.random.default_rng(seed)
    p = int(rng.choice([2, 3, 4]))
    cfg = dataclasses.replace(config(p, int(rng.choice([1, 7, 10]))),
                              dt_ns=int(rng.choice([100_000, 1_000_000, 3_000_000])))
    schedule = _schedule(rng, p - 1, cfg.dt_ns, 25)
    t_end = schedule[-1][0] + 1000 * cfg.dt_ns
    single, runs = Engine(cfg, 0, integrate=False), Engine(cfg, 0, integrate=False)
    half = schedule[:12]
    assert _play(single, half, half[-1][0]) == _play(runs, half, half[-1][0], rng)
    a, b = single.actuator_output(), runs.actuator_output()
    assert a.starts.tobytes() == b.starts.tobytes() and _piece_bits(a) == _piece_bits(b)
    assert _play(single, schedule[12:], t_end) == _play(runs, schedule[12:], t_end, rng)
    a, b = single.actuator_output(), runs.actuator_output()
    assert a.starts.tobytes() == b.starts.tobytes() and _piece_bits(a) == _piece_bits(b)
    # the array-built gait evaluates as the one made of the pieces
    t = np.linspace(-0.01, t_end / 1e9 + 0.01, 997)
    for x, y in zip(b(t), gaits.PiecewiseCubic(a.starts, a.pieces)(t)):
        assert x.tobytes() == y.tobytes()


@pytest.mark.parametrize('seed,method', [(0, 'exact'), (1, 'exact'), (2, 'exact'),
                                         (3, 'implicit'), (4, 'exact')])
def test_runs_of_ticks_give_the_states_of_single_ticks_bit_for_bit(seed, method):
    """integrate=True: the states read at every input, the events and the journal after runs
    of ticks (tick_to_grid, run_to, tick mixed) equal those of tick() repeated."""
    rng = np.random.default_rng(100 + seed)
    p = int(rng.choice([2, 3]))
    cfg = config(p, int(rng.choice([1, 7, 10])), method)
    schedule = _schedule(rng, p - 1, cfg.dt_ns, 14)
    t_end = schedule[-1][0] + 3000 * cfg.dt_ns
    logs = ([], [])
    single = Engine(cfg, 0, lambda *a: logs[0].append(a[:2]))
    runs = Engine(cfg, 0, lambda *a: logs[1].append(a[:2]))
    assert _play(single, schedule, t_end, read_state=True) == \
        _play(runs, schedule, t_end, rng, read_state=True)
    sa, sb = single.state, runs.state
    assert (sa.x.tolist(), sa.v.tolist()) == (sb.x.tolist(), sb.v.tolist())
    events = single.pop_events()
    assert events == runs.pop_events()
    assert logs[0] == logs[1]
    assert single.failures == runs.failures


def test_a_window_at_rest_hands_the_solver_the_one_rest_piece_as_single_ticks_do():
    """A settled actuator's windows go to the exact solver as its rest piece itself (the
    object it already holds: no gait switch), whether ticked one by one or in runs."""
    for batched in (False, True):
        e = Engine(config(2, 10))
        e.command([0.12])
        for _ in range(300):
            if batched:
                e.tick_to_grid()
            else:
                while not e.tick():
                    pass
        rest = e.actuator._rest_piece
        assert rest is not None and e.stepper.gait is rest
        e.run_to(e.t_ns + 25 * e.cfg.dt_ns) if batched else [e.tick() for _ in range(25)]
        e.sync()
        assert e.stepper.gait is rest


@pytest.mark.parametrize('stream', [
    streams.Stream('trajectory', 50.0, 4.0, True, 7.5),
    streams.Stream('trajectory', 20.0, 1.0, False),
    streams.Stream('command', 50.0, preload=False),
    streams.Stream('command', 30.0, preload=False, latency=0.0123),
])
def test_streams_actuator_output_equals_the_engine_as_it_was_bit_for_bit(stream, monkeypatch):
    """``streams.actuator_output`` (one compiled run of the actuator between inputs) against
    the engine and actuator as they were, tick by tick (actuator_oracle.OracleEngine)."""
    plant = PlantConfig.defaults(masses=[0.5, 1.0, 0.7], initial_lengths=[0.1, 0.12],
                                 integration_rate=2000.0)
    gait = gaits.Sinusoid([0.1, 0.12], 0.03, 0.8, [0.0, 1.0])
    got = streams.actuator_output(plant, gait, stream, 9.0)
    monkeypatch.setattr(streams, 'Engine', oracle.OracleEngine)
    want = streams.actuator_output(plant, gait, stream, 9.0)
    assert got.starts.tobytes() == want.starts.tobytes()
    assert _piece_bits(got) == _piece_bits(want)


def test_a_failure_the_fallback_cannot_absorb_leaves_the_plant_at_rest_not_an_exception(
        monkeypatch):
    """Issue 25: tick() must never raise out of the node's loop. When the exact solver and its
    implicit fallback both fail, the engine reports it and starts again at rest (the same
    engine code runs in a replay, so a replay repeats it)."""
    from crawler_sim.core.plant import engine as engine_mod
    eng = Engine(config(2, 10))
    eng.command([0.13])
    eng.tick_to_grid()
    real = engine_mod.Stepper.advance

    def broken(self, t1, gait=None):
        raise ValueError('gait length must be finite')
    monkeypatch.setattr(engine_mod.Stepper, 'advance', broken)
    t_before = eng.t_ns
    eng.tick_to_grid()                              # does not raise
    assert eng.t_ns == t_before + 10 * eng.cfg.dt_ns
    assert any('starts again at rest' in f for f in eng.failures)
    monkeypatch.setattr(engine_mod.Stepper, 'advance', real)
    st = eng.state
    assert st.t == eng.t and list(st.lengths) == list(eng.cfg.initial_lengths)
    assert np.all(st.v == 0.0)


@pytest.mark.parametrize('step_by_step', [False, True])
def test_a_sync_builds_its_table_without_tables_own_classification(monkeypatch, step_by_step):
    """Issues 41/42: the classification of the cubic pieces was half of every sync. The engine's
    gaits hand ``table`` their joins (``cubic.table_jumps``): at most one table per sync, and
    ``table``'s own search of the joins never runs (the states are unchanged: the bit-for-bit
    tests above)."""
    from crawler_sim.core.solvers import _gait
    calls = {'table': 0, 'own': 0}
    real = _gait.table

    def counted(coef, **kw):
        calls['table'] += 1
        calls['own'] += kw.get('jumps') is None
        return real(coef, **kw)

    def counted_run(starts, anchors, coef):     # table + table_jumps in one compiled pass
        calls['table'] += 1
        return real_run(starts, anchors, coef)

    real_run = _gait.table_of_run
    monkeypatch.setattr(_gait, 'table', counted)
    monkeypatch.setattr(_gait, 'table_of_run', counted_run)
    engine = Engine(config(2, 10))
    syncs = 0
    for k in range(300):
        engine.command([0.1 + 0.02 * np.sin(0.05 * k)])
        if step_by_step:
            engine.run_to(engine.t_ns + engine.cfg.dt_ns)
            engine.sync()
        else:
            engine.tick_to_grid()
        syncs += 1
    assert calls['own'] == 0
    assert 0 < calls['table'] <= syncs + 1          # (+ the rest piece the engine starts from)
