"""The plant's engine with stiction (issue 40): the static bounds and the stiction rule reach the
core through the node's parameters, the incumbent (the cluster stuck just before now) is part of
the plant's state across sync cuts, reconfigures and resets, and a journal replays bit for bit.

Expected numbers are physics by hand: a rigid crawler at rest on a slope with
mu_kinetic < tan(alpha) <= mu_static holds (Coulomb's static law); with static = kinetic it slides
down at a = g (sin(alpha) - mu cos(alpha)), so x(t) - x(t1) = -a (t - t1)^2 / 2.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_sim.core.plant import Engine, PlantConfig
from crawler_sim.core.plant.replay import Input, plant_config, replay
from crawler_sim.core.plant.config import LATER_PARAMETERS, PARAMETERS
from crawler_sim.core.solvers.base import capabilities

G = 9.81
TAN = 0.4                        # tan(alpha): between mu_kinetic 0.3 and mu_static 0.5
SLOPE = math.atan(TAN)
#: two 1 kg bodies on the slope; the node's defaults otherwise (0.1 m linkage at rest)
HOLD = dict(masses=[1.0, 1.0], mu=[0.3], mu_backward=[0.3], mu_static=[0.5],
            mu_static_backward=[0.5], slope=SLOPE)
#: the downhill acceleration with kinetic friction only [m/s^2]
A_SLIDE = G * (math.sin(SLOPE) - 0.3 * math.cos(SLOPE))

needs_stiction = pytest.mark.skipif(not capabilities('exact').stiction,
                                    reason='the exact method has no stiction yet (sticky)')


def engine(journal=None, **values) -> Engine:
    return Engine(PlantConfig.defaults(**{**HOLD, **values}).engine_config(), 0,
                  journal=journal)


def run(e: Engine, seconds: float) -> None:
    e.run_to(e.t_ns + round(seconds * 1e9))


# --------------------------------------------------------------------------- parameters

def test_static_bounds_of_the_parameters_reach_the_crawler_as_forces():
    cfg = PlantConfig.defaults(**HOLD)
    normal = np.array([1.0, 1.0]) * G * math.cos(SLOPE)
    np.testing.assert_allclose(cfg.crawler.static_friction, 0.5 * normal, rtol=1e-15)
    np.testing.assert_allclose(cfg.crawler.static_friction_backward, 0.5 * normal, rtol=1e-15)
    np.testing.assert_allclose(cfg.crawler.friction, 0.3 * normal, rtol=1e-15)
    assert cfg.crawler.has_stiction
    assert cfg.engine_config().stiction_rule == 'incumbent'


def test_an_empty_static_parameter_is_the_kinetic_bound_of_its_direction():
    cfg = PlantConfig.defaults(**{**HOLD, 'mu_static_backward': []})
    np.testing.assert_array_equal(cfg.crawler.static_friction_backward,
                                  cfg.crawler.friction_backward)
    cfg = PlantConfig.defaults(masses=[1.0, 1.0], friction=[2.0], static_friction=[],
                               mu_static=[])
    assert not cfg.crawler.has_stiction


def test_forces_replace_coefficients_bound_by_bound():
    # static forward as a force, static backward from its coefficient (0.6 m g cos(alpha))
    cfg = PlantConfig.defaults(**{**HOLD, 'static_friction': [4.0, 5.0],
                                  'mu_static_backward': [0.6]})
    np.testing.assert_array_equal(cfg.crawler.static_friction, [4.0, 5.0])
    np.testing.assert_allclose(cfg.crawler.static_friction_backward,
                               [0.6 * G * math.cos(SLOPE)] * 2, rtol=1e-15)


@pytest.mark.parametrize('values,named', [
    ({'mu_static': [0.2]}, 'mu_static[0] must be >= mu[0]'),
    ({'mu_static_backward': [0.5, 0.1]}, 'mu_static_backward[1] must be >= mu_backward[1]'),
    ({'mu_static': [math.nan]}, 'mu_static[0]'),
    ({'mu_static': [0.5, 0.5, 0.5]}, 'mu_static: must have 1 or 2 entries'),
    ({'static_friction': [-1.0]}, 'static_friction[0]'),
    ({'static_friction': [1.0]}, 'static_friction[0] must be >= friction[0]'),
    ({'friction': [3.0], 'mu_static': [0.3]}, 'mu_static (as forces'),
    ({'friction': [1.0], 'friction_backward': [3.0], 'mu_static': [0.5],
      'mu_static_backward': [0.1]}, 'mu_static_backward (as forces'),
    ({'mu_static': 'high'}, 'mu_static must be a list of numbers'),
    ({'stiction_rule': 'sticky'}, "stiction_rule must be one of 'incumbent', 'margin'"),
    ({'stiction_rule': ['margin']}, 'stiction_rule must be one of'),
])
def test_bad_static_values_give_one_line_naming_the_parameter(values, named):
    with pytest.raises(ValueError) as info:
        PlantConfig.defaults(**{**HOLD, **values})
    assert named in str(info.value)
    assert '\n' not in str(info.value)


def test_a_method_without_stiction_is_refused_naming_the_method():
    able = [m for m in ('exact', 'implicit', 'penalty') if not capabilities(m).stiction]
    for method in able:
        with pytest.raises(ValueError, match=f"method '{method}' cannot simulate static"):
            PlantConfig.defaults(**HOLD, method=method)


def test_values_recorded_before_the_stiction_parameters_still_configure_the_plant():
    """A bag of an older session lacks the stiction parameters: it ran without stiction."""
    old = {name: default for name, (default, _, _) in PARAMETERS.items()
           if name not in LATER_PARAMETERS}
    cfg = plant_config(old)
    assert not cfg.crawler.has_stiction
    assert cfg.engine_config().stiction_rule == 'incumbent'
    with pytest.raises(ValueError, match='lack masses'):        # the others are still needed
        plant_config({k: v for k, v in old.items() if k != 'masses'})


def test_without_stiction_the_stepper_gets_no_stiction_option():
    """Static = kinetic: the core gets exactly the arguments it got before stiction, so the
    runs are what they were (bit for bit)."""
    cfg = PlantConfig.defaults(masses=[1.0, 1.0], mu=[0.3], mu_static=[0.3],
                               stiction_rule='margin').engine_config()
    assert cfg.stepper_options() == {}
    a = Engine(cfg)
    b = Engine(PlantConfig.defaults(masses=[1.0, 1.0], mu=[0.3]).engine_config())
    for e in (a, b):
        e.command([0.15])
        run(e, 0.5)
    np.testing.assert_array_equal(a.state.x, b.state.x)
    np.testing.assert_array_equal(a.state.v, b.state.v)


# --------------------------------------------------------------------------- physics

@needs_stiction
def test_a_crawler_at_rest_on_a_slope_holds_with_stiction_and_slides_without():
    held, sliding = engine(), engine(mu_static=[], mu_static_backward=[])
    x0 = held.state.x.copy()
    run(held, 2.0)
    run(sliding, 2.0)
    np.testing.assert_array_equal(held.state.x, x0)            # not a nanometre of creep
    assert np.all(held.state.contact == 0)
    np.testing.assert_allclose(sliding.state.x - x0, -A_SLIDE * 2.0 ** 2 / 2, rtol=1e-12)


@needs_stiction
def test_lowering_static_to_kinetic_at_run_time_lets_the_held_crawler_slide():
    e = engine()
    run(e, 1.0)
    x1 = e.state.x.copy()
    e.reconfigure(PlantConfig.defaults(**{**HOLD, 'mu_static': [], 'mu_static_backward': []}
                                       ).engine_config())
    run(e, 1.5)
    np.testing.assert_allclose(e.state.x - x1, -A_SLIDE * 1.5 ** 2 / 2, rtol=1e-12)
    # static friction back while it slides: it keeps sliding (kinetic friction acts on a
    # sliding body; the pull exceeds it), accelerating at the same a
    v2, x2 = e.state.v.copy(), e.state.x.copy()
    e.reconfigure(PlantConfig.defaults(**HOLD).engine_config())
    run(e, 0.5)
    np.testing.assert_allclose(e.state.x - x2, v2 * 0.5 - A_SLIDE * 0.5 ** 2 / 2, rtol=1e-12)


@needs_stiction
def test_the_incumbent_is_defined_at_the_start_and_on_reset_and_survives_a_reconfigure():
    e = engine()
    # at rest in the initial configuration: no incumbent at the start instant (Rule S chooses
    # by the margins there, the same choice as with every part incumbent), and after the
    # first interval at rest the whole rigid crawler
    assert e.state.incumbent is not None and not e.state.incumbent.any()
    e.tick_to_grid()
    assert e.state.incumbent.all()
    e.command([0.14])
    run(e, 0.07)                  # the linkage extends: body 1 holds, body 0 slides back
    inc = e.state.incumbent
    np.testing.assert_array_equal(inc, [False, True])
    # a new crawler with stiction (a higher static bound): a new core stepper, same incumbent,
    # and the stuck body exactly at rest in it
    e.reconfigure(PlantConfig.defaults(**{**HOLD, 'mu_static': [0.6]}).engine_config())
    np.testing.assert_array_equal(e.stepper.state.incumbent, inc)
    assert e.stepper.state.v[1] == 0.0
    # the forward static bound is not what holds body 1 (it needs the backward one), so the
    # motion goes on as without the change (to rounding): body 1 holds to its breakaway
    twin = engine()
    twin.command([0.14])
    run(twin, 0.07)
    for _ in range(3):
        run(e, 0.005)
        run(twin, 0.005)
        np.testing.assert_array_equal(e.state.contact, twin.state.contact)
        np.testing.assert_allclose(e.state.x, twin.state.x, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(e.state.contact, [-1, -1])    # broken away by 0.085 s
    e.reset()
    assert not e.state.incumbent.any()
    np.testing.assert_array_equal(e.state.v, 0.0)
    e.tick_to_grid()
    assert e.state.incumbent.all()


@needs_stiction
def test_sync_cuts_off_the_grid_keep_the_held_crawler_exactly_at_rest():
    e = engine()
    x0 = e.state.x.copy()
    for _ in range(37):
        e.tick()
        e.sync()                              # a cut every tick: the state after each
        np.testing.assert_array_equal(e.state.x, x0)
        assert e.state.incumbent.all()


@needs_stiction
def test_a_journal_of_stiction_inputs_replays_bit_for_bit():
    journal: list[Input] = []

    def note(kind, t_ns, payload):
        if kind in ('configure', 'reset'):
            payload = dict(payload.values)
        journal.append(Input(t_ns, kind, payload))
    e = engine(journal=note)
    values0 = dict(e.cfg.values)
    seen: list[tuple[int, np.ndarray, np.ndarray]] = []

    def snap():
        st = e.state
        seen.append((e.t_ns, st.x.copy(), st.v.copy()))
    snap()
    # runs of 0.3705 s and the like end off the 10 ms publish grid: the inputs after them cut
    # the integration there ('sync' in the journal)
    steps = [('command', [0.16]), ('run', 0.3705), ('configure', {'mu_static': [0.7]}),
             ('run', 0.2113), ('command', [0.08]), ('sync', None), ('run', 0.4),
             ('configure', {'stiction_rule': 'margin'}), ('run', 0.3007),
             ('configure', {'mu_static': [], 'mu_static_backward': []}), ('run', 0.25),
             ('reset', None), ('configure', {}), ('command', [0.12]), ('run', 0.5)]
    for kind, arg in steps:
        if kind == 'command':
            e.command(arg)
        elif kind == 'configure':
            e.reconfigure(PlantConfig.defaults(**{**HOLD, **arg}).engine_config())
        elif kind == 'reset':
            e.reset()
            snap()
        elif kind == 'sync':
            e.sync()
        else:
            end = e.t_ns + round(arg * 1e9)
            while e.t_ns < end:
                if e.tick():
                    snap()
    assert any(item.kind == 'sync' for item in journal)
    snaps = replay(values0, journal, e.t_ns)
    x, v = snaps.at([t for t, _, _ in seen], 2)
    np.testing.assert_array_equal(x, np.array([s[1] for s in seen]))
    np.testing.assert_array_equal(v, np.array([s[2] for s in seen]))


@needs_stiction
def test_an_offline_run_as_the_node_runs_it_is_the_engines_with_its_stiction_rule():
    """``streams.simulate_as_node`` (the core in one call) against the engine (integrating at
    every publish tick): the physics does not depend on where the integration is cut, only
    the rounding does, so they agree to 1e-12 m with either rule. The rules differ here (an
    anisotropic pair under a bang-bang stroke from rest, reversing at t = 2 with one body
    stuck: 'incumbent' keeps it, 'margin' takes the other), so a rule lost on one path would
    show."""
    from crawler_sim.core import gaits
    from crawler_sim.core.plant import PreparedTrajectory
    from crawler_sim.core.plant.streams import Stream, simulate_as_node, trajectory_points
    # the reversal at t = 2.00035 s, off the 1 ms tick grid: at a reversal exactly on a tick
    # join (t = 2 with times [0, 1, 3, 4]) the rounding of the event time decides whether
    # the look-ahead reads l'' before or after the join, and the margin rule's choice with it
    t2 = 2.0007
    gait = gaits.PiecewiseParabolic([0, 1, 1 + t2, 2 + t2], [0.5, -1 / t2, 0.5], 0.2)
    final = {}
    for rule in ('incumbent', 'margin'):
        plant = PlantConfig.defaults(masses=[1.5, 0.7], friction=[1.25, 0.9],
                                     friction_backward=[1.8], static_friction=[2.2, 1.25],
                                     static_friction_backward=[3.25, 3.55], stiction_rule=rule,
                                     initial_lengths=[0.2], max_length=1.0)
        tr = simulate_as_node(plant, gait, Stream(rate=50.0, duration=8.0), 8.0, dt=0.01)
        eng = Engine(plant.engine_config())
        eng.trajectory(PreparedTrajectory(0, *trajectory_points(gait, 0.0, 8.0, 50.0, 8.0)))
        for _ in range(800):
            eng.tick_to_grid()
            i = int(np.argmin(np.abs(tr.t - eng.t)))
            np.testing.assert_allclose(tr.x[i], eng.state.x, rtol=0, atol=1e-12)
        final[rule] = float(tr.com[-1])
    assert abs(final['incumbent'] - final['margin']) > 0.5


@needs_stiction
def test_a_command_on_the_reset_tick_moves_the_crawler_as_one_a_tick_later():
    """A crawler at rest has been at rest: a command landing on the start (or reset) tick
    and the same command one tick later give the same motion, shifted by the tick (the plant
    is autonomous at rest), to rounding. Naming body 0 the incumbent at the start instead
    (initial_stuck=0) favoured it: 0.31 mm apart after 0.3 s here (margin picks body 1)."""
    cfg = PlantConfig.defaults(masses=[1.0, 1.0], friction=[1.0], friction_backward=[1.0],
                               static_friction=[2.0, 2.5], static_friction_backward=[2.0, 2.5])
    moves = []
    for delay in (0, 1, 7):
        e = Engine(cfg.engine_config())
        for _ in range(delay):
            e.tick()
        if delay == 7:                      # a reset at rest, the command on its tick
            e.reset()
        x0 = e.state.x.copy()
        e.command([0.15])
        run(e, 0.3)
        moves.append(e.state.x - x0)
    np.testing.assert_allclose(moves[1], moves[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(moves[2], moves[0], rtol=0, atol=1e-12)


@needs_stiction
def test_a_reconfigure_during_a_rest_leaves_every_part_incumbent():
    """The whole crawler stuck goes on with no named incumbent (Rule S by the margins, as
    with every part incumbent): a reconfigure (same physics, another rule name, so a new
    stepper) on the tick a command lands gives the motion of the run without it, to rounding."""
    values = dict(masses=[1.0, 1.0], friction=[1.0], friction_backward=[1.0],
                  static_friction=[2.0, 2.5], static_friction_backward=[2.0, 2.5])
    a = Engine(PlantConfig.defaults(**values).engine_config())
    b = Engine(PlantConfig.defaults(**values).engine_config())
    for e in (a, b):
        run(e, 0.05)
    b.reconfigure(PlantConfig.defaults(**values, gravity=9.81 + 1e-9).engine_config())
    assert b.stepper is not a.stepper
    for e in (a, b):
        e.command([0.15])
        run(e, 0.3)
    np.testing.assert_allclose(b.state.x, a.state.x, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b.state.contact, a.state.contact)


def test_a_journal_recorded_before_the_stiction_parameters_replays_bit_for_bit():
    """An older session: its recorded values and configure/reset entries lack the stiction
    parameters (as sim_node wrote them then); the replay runs them without stiction and
    repeats the recorded states exactly."""
    journal: list[Input] = []

    def strip(values):
        return {k: v for k, v in values.items() if k not in LATER_PARAMETERS}

    def note(kind, t_ns, payload):
        if kind in ('configure', 'reset'):
            payload = strip(payload.values)
        journal.append(Input(t_ns, kind, payload))
    kinetic = dict(masses=[1.0, 2.0], friction=[3.0, 4.0])
    e = Engine(PlantConfig.defaults(**kinetic).engine_config(), 0, journal=note)
    values0 = strip(e.cfg.values)
    seen = [(e.t_ns, e.state.x.copy())]
    e.command([0.15])
    for k in range(60):
        if k == 20:
            e.reconfigure(PlantConfig.defaults(**{**kinetic, 'slope': 0.2}).engine_config())
        if k == 40:
            e.reset()
            seen.append((e.t_ns, e.state.x.copy()))
            e.command([0.05])
        e.tick_to_grid()
        seen.append((e.t_ns, e.state.x.copy()))
    snaps = replay(values0, journal, e.t_ns)
    assert [t for t, _ in seen] == snaps.t_ns
    for (_, x), rx in zip(seen, snaps.x):
        np.testing.assert_array_equal(rx, x)
