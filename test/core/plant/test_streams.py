"""Offline runs "as the node runs them" (crawler_sim.core.plant.streams, issue 24): the stream
gait_node sends, through the plant's engine, then the core in one call."""
from __future__ import annotations

import numpy as np
import pytest

from crawler_sim.core import gaits
from crawler_sim.core.plant import Engine, PlantConfig, PreparedTrajectory
from crawler_sim.core.plant.streams import (Stream, actuator_output, simulate_as_node,
                                            trajectory_points)

GAIT = gaits.Scallop(0.1, 0.02, 2.0, 0.2, [0.0], n_links=1)


def test_a_preloaded_run_equals_the_nodes_engine_tick_by_tick():
    """The engine of sim_node (integrating its pieces at every publish tick) against the
    offline path (the same pieces handed to ``simulate`` at once): the physics does not depend
    on where the integration is cut, only the rounding does."""
    plant = PlantConfig.defaults()
    stream = Stream(rate=50.0, duration=4.0)
    tr = simulate_as_node(plant, GAIT, stream, 4.0, dt=0.01)
    eng = Engine(plant.engine_config())
    tfs, pos, vel, acc = trajectory_points(GAIT, 0.0, 4.0, 50.0, 4.0)
    eng.trajectory(PreparedTrajectory(0, tfs, pos, vel, acc))
    worst = 0.0
    for k in range(400):
        eng.tick_to_grid()
        i = int(np.argmin(np.abs(tr.t - eng.t)))
        assert tr.t[i] == pytest.approx(eng.t, abs=1e-12)
        worst = max(worst, float(np.abs(tr.x[i] - eng.state.x).max()))
    assert worst < 1e-12
    assert np.ptp(tr.com) > 5e-3                      # it crawled


def test_the_trajectory_points_sample_the_gait_and_end_at_rest():
    tfs, pos, vel, acc = trajectory_points(GAIT, 0.3, 1.0, 50.0)
    assert tfs.tolist() == [k * 20_000_000 for k in range(51)]     # 50 samples + the rest point
    t = 0.3 + np.arange(50) / 50.0
    l, ld, ldd = GAIT(t)
    for got, want in ((pos, l), (vel, ld), (acc, ldd)):     # times k / 50 within rounding
        np.testing.assert_allclose(got[:-1], want, rtol=1e-12, atol=1e-12)
    assert pos[-1].tolist() == pos[-2].tolist() and vel[-1].tolist() == acc[-1].tolist() == [0.0]
    cut = trajectory_points(GAIT, 0.0, 10.0, 50.0, duration=1.0)[0]
    assert cut[-2] == 1_000_000_000 and len(cut) == 52              # never past the duration


def test_a_command_lands_at_the_first_tick_after_its_time_plus_the_latency():
    """Command mode: set-point k is for ROS time k / rate and takes effect at the tick boundary
    at or after k / rate + latency: before it the actuator holds (constant pieces)."""
    plant = PlantConfig.defaults()
    far = gaits.Sinusoid(0.2, 0.0, 1.0, n_links=1)          # a constant 0.2 m target
    out = actuator_output(plant, far, Stream('command', rate=10.0, preload=False,
                                             latency=0.0025), 0.01)
    moving = [p.t0 for p in out.pieces if not p.is_constant(p.t0, p.t0 + 1e-3)]
    assert moving[0] == pytest.approx(0.003, abs=1e-12)          # 2.5 ms -> the 3 ms tick


@pytest.mark.parametrize('kw,message', [
    ({'mode': 'topic'}, 'mode must be one of command, trajectory'),
    ({'rate': 0.0}, 'rate must be in [0.1, 10000]'),
    ({'preload': True, 'duration': 0.0}, 'preload needs mode trajectory and a duration > 0'),
])
def test_a_stream_names_the_bad_field(kw, message):
    with pytest.raises(ValueError, match=message.replace('[', r'\[')):
        Stream(**{'duration': 1.0, **kw})


@pytest.mark.parametrize('velocity', [1e3, 1e200, 1e308])
def test_a_trajectory_whose_interpolation_leaves_the_range_is_refused_naming_where(velocity):
    """Issue 25: a middle point's velocity of 1e3 m/s with every position in [0.02, 0.5] m drove
    the linkage to -0.0675 m, and 1e308 made the next tick raise. The interpolation between the
    points is checked (its Bernstein hull, refined), not only the points."""
    plant = PlantConfig.defaults()
    eng = Engine(plant.engine_config())
    tfs = np.arange(1, 6) * 100_000_000
    vel = np.zeros((5, 1))
    vel[2, 0] = velocity
    prepared = PreparedTrajectory(0, tfs, np.full((5, 1), 0.1), vel, None)
    with pytest.raises(ValueError, match=r'interpolation of linkage_0 between point #\d and '
                                         r'point #\d reaches .* outside \[min_length'):
        eng.trajectory(prepared)
    assert eng.actuator.trajectory is None            # nothing changed
    vel[2, 0] = 0.3                                   # a moderate one: accepted
    eng.trajectory(PreparedTrajectory(0, tfs, np.full((5, 1), 0.1), vel, None))
    assert eng.actuator.trajectory is not None
