"""With stiction the physics must not depend on where the integration is cut (issue 40; the
plant's determinism contract, issue 37's "streamed equal to one-shot").

Rule S is not continuous in its data: at a coincident rest (STICTION.md s. 3, U3) the answer
jumps between candidates, so a call that ends near an event must leave the decision to the
same data the uninterrupted run uses. The expected answer is the run made in one call (an
invariant, not a number of the code under test): a Stepper advanced to the same end through a
cut at every event time, exactly at it, one float either side and a few tolerances after (an
event within 4 tol of a call's end was moved onto it; the look-ahead of the decision stopped
at the call's end), must give the same state to 1e-12 m, with either rule.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits
from crawler_sim.core.plant import PlantConfig
from crawler_sim.core.plant.streams import Stream, actuator_output
from test.support.stiction_reference import GRAVITY, random_scene

TOL_X = 1e-12
RULES = ('incumbent', 'margin')


def crawler_of(scene: dict) -> cs.Crawler:
    return cs.Crawler(scene['masses'], scene['friction'], scene['friction_backward'],
                      slope=scene['slope'], gravity=GRAVITY,
                      static_friction=scene['static_friction'],
                      static_friction_backward=scene['static_friction_backward'])


def cuts_around(te: float) -> list[float]:
    """The cuts tried at an event time te [s]: te, one float either side, 10 and 100 floats
    and 2e-13 s (2 tol) after it (there a call used to end on a moved event)."""
    u = math.ulp(te)
    return [te - u, te, te + u, te + 10 * u, te + 100 * u, te + 2e-13]


def assert_same_state(a: cs.Stepper, b: cs.Stepper, what: str) -> None:
    sa, sb = a.state, b.state
    assert np.max(np.abs(sa.x - sb.x)) <= TOL_X, what
    assert sa.contact.tolist() == sb.contact.tolist(), what
    assert sa.incumbent.tolist() == sb.incumbent.tolist(), what


@pytest.mark.parametrize('rule', RULES)
@pytest.mark.parametrize('seed', range(40))
def test_a_run_cut_at_any_event_gives_the_one_call_answer(seed, rule):
    # random 2- and 3-body scenes (static 1-2x kinetic; sinusoid, Fourier, bang-bang and
    # stroke-reversal gaits), two periods; before the fix 25 of these 80 runs differed, by
    # 4e-5 to 3e-2 m, for a cut within 4 tol after an event
    scene = random_scene(seed)
    crawler, gait = crawler_of(scene), scene['gait']
    t_end = 2.0 * scene['period']
    whole = cs.Stepper(crawler, gait, stiction_rule=rule)
    whole.advance(t_end)
    times = sorted({e.time for e in whole.pop_events() if 0.0 < e.time < t_end})
    assert times, 'a scene without events tests nothing'
    for te in times:
        for cut in cuts_around(te):
            cut_run = cs.Stepper(crawler, gait, stiction_rule=rule)
            cut_run.advance(cut)
            cut_run.advance(t_end)
            assert_same_state(cut_run, whole, f'cut at {cut!r} (event at {te!r})')


@pytest.mark.parametrize('rule', RULES)
def test_a_run_streamed_in_many_calls_with_the_periodic_skip_gives_the_one_call_answer(rule):
    # the stroke-reversal scenes where the two rules differ, 4 periods with the periodic skip,
    # cut at every event, and streamed at a 1 ms grid
    for seed in (6, 7, 38, 46):
        scene = random_scene(seed)
        crawler, gait = crawler_of(scene), scene['gait']
        t_end = 4.0 * scene['period']
        whole = cs.Stepper(crawler, gait, stiction_rule=rule, periodic_skip=True)
        whole.advance(t_end)
        times = [e.time for e in whole.pop_events() if 0.0 < e.time < t_end]
        streamed = cs.Stepper(crawler, gait, stiction_rule=rule, periodic_skip=True)
        for t in sorted(set(times) | set(np.arange(1e-3, t_end, 1e-3).tolist())):
            streamed.advance(t)
        streamed.advance(t_end)
        assert_same_state(streamed, whole, f'seed {seed}')


def reversal_plant(rule: str) -> tuple:
    """The plumbing engineer's scene: a parabolic stroke whose reversal (l' = 0) falls on
    t = 2 s, body 0 stuck there, the servo between the command and the crawler."""
    gait = gaits.PiecewiseParabolic([0, 1, 3, 4], [0.5, -0.5, 0.5], 0.2)
    plant = PlantConfig.defaults(
        masses=[1.5, 0.7], friction=[1.25, 0.9], friction_backward=[1.8],
        static_friction=[2.2, 1.25], static_friction_backward=[3.25, 3.55],
        stiction_rule=rule, initial_lengths=[0.2], max_length=1.0)
    return gait, plant


@pytest.mark.parametrize('rule', RULES)
def test_a_stroke_reversal_rounded_just_before_a_cut_is_decided_as_in_one_call(rule):
    # the plumbing engineer's scene: the servo's output of a parabolic stroke, body 1 reverses
    # (l' = 0) at t = 2 s, rounded to 2 - 2.2e-15, while body 0 is stuck (a U3). Cut at 2.0 the
    # event was moved onto the cut, where body 1's velocity (-1.2e-15 m/s) had passed zero: it
    # was taken as sliding backward and never decided ('margin' kept body 0 instead of body 1:
    # x = [0, 0.6375] m instead of [0.0625, 0.7] m at 2.5 s)
    gait, plant = reversal_plant(rule)
    out = actuator_output(plant, gait, Stream(rate=50.0, duration=8.0), 3.0)
    runs = []
    for cuts in ([2.5], [2.0, 2.5], [1.5, 2.0, 2.0 + 1e-13, 2.5]):
        st = cs.Stepper(plant.crawler, out, stiction_rule=rule)
        for t in cuts:
            st.advance(t, out)
        runs.append(st)
    for st in runs[1:]:
        assert_same_state(st, runs[0], rule)


@pytest.mark.parametrize('rule', RULES)
def test_the_engine_cut_at_its_sync_grid_gives_the_offline_runs_answer(rule):
    # the same reversal through the plant's engine (cut at every tick of its grid, one of them
    # at 2 s) against the node's offline run of the same command stream
    from crawler_sim.core.plant import Engine, PreparedTrajectory
    from crawler_sim.core.plant.streams import simulate_as_node, trajectory_points
    gait, plant = reversal_plant(rule)
    tr = simulate_as_node(plant, gait, Stream(rate=50.0, duration=8.0), 8.0, dt=0.01)
    eng = Engine(plant.engine_config())
    eng.trajectory(PreparedTrajectory(0, *trajectory_points(gait, 0.0, 8.0, 50.0, 8.0)))
    while eng.t < 2.5:
        eng.tick_to_grid()
    near = [(e.time, e.body, e.old, e.new) for e in tr.events if 1.9 < e.time < 2.2]
    assert [(e.time, e.body, e.old, e.new) for e in eng.pop_events()
            if 1.9 < e.time < 2.2] == near
    k = int(np.argmin(np.abs(tr.t - eng.t)))
    assert tr.t[k] == eng.t
    assert np.max(np.abs(eng.state.x - tr.x[k])) <= TOL_X
