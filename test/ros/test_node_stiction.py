"""sim_node with stiction (issue 40), over real DDS: the static bounds are parameters set at run
time through the node's SetParameters service, bad values are refused with a reason naming the
parameter (the node runs on), and a recorded session with stiction replays with max |dx| = 0.

Expected numbers are physics by hand: two 1 kg bodies at rest on a slope with
mu_kinetic = 0.3 < tan(alpha) = 0.4 <= mu_static = 0.5 hold exactly (Coulomb's static law: the
pull M g sin(alpha) is within the static capacity); with the static bounds lowered to the kinetic
ones the rigid crawler slides down at a = g (sin(alpha) - 0.3 cos(alpha)), so
x(t) - x(t1) = -a (t - t1)^2 / 2 from the tick t1 the change took effect at.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from crawler_sim import bag
from crawler_sim.cli import _replay
from crawler_sim.core.solvers.base import capabilities
from test.support.ros import cmd, ticks

pytestmark = pytest.mark.skipif(not capabilities('exact').stiction,
                                reason='the exact method has no stiction yet (sticky)')

G = 9.81
SLOPE = math.atan(0.4)
HOLD = {'masses': [1.0, 1.0], 'mu': [0.3], 'mu_backward': [0.3], 'mu_static': [0.5],
        'mu_static_backward': [0.5], 'slope': SLOPE, 'publish_clock': False}
A_SLIDE = G * (math.sin(SLOPE) - 0.3 * math.cos(SLOPE))      # downhill, kinetic only [m/s^2]


def set_over_dds(ros, **values):
    """Set parameters through the node's SetParameters service (one result per parameter)."""
    req = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                            for k, v in values.items()])
    return ros.call(SetParameters, '/crawler_sim/set_parameters', req).results


def test_a_crawler_held_by_stiction_slides_when_static_is_lowered_at_run_time(ros):
    sim = ros.sim(seed=True, **HOLD)
    states = ros.listen(JointState, 'body_states')
    x0 = sim.state.x.copy()
    ticks(sim, 1000)                                     # 1 s on the slope
    np.testing.assert_array_equal(sim.state.x, x0)      # held: not a nanometre of creep
    ros.until(lambda: states and states[-1].header.stamp.sec == 1, 'the state at 1 s')
    np.testing.assert_array_equal(states[-1].position, x0)
    assert list(states[-1].velocity) == [0.0, 0.0]
    # empty lists: the static bounds back to their defaults, the kinetic ones
    results = set_over_dds(ros, mu_static=[], mu_static_backward=[])
    assert all(r.successful for r in results), [r.reason for r in results]
    t1, x1 = sim.sim_time_ns, sim.state.x.copy()
    ticks(sim, 500)
    assert not sim.config.crawler.has_stiction
    assert (sim.sim_time_ns - t1) == 500_000_000
    np.testing.assert_allclose(sim.state.x - x1, -A_SLIDE * 0.5 ** 2 / 2, rtol=1e-12)
    assert np.all(sim.state.contact == -1)


@pytest.mark.parametrize('values,named', [
    ({'mu_static_backward': [0.2]}, 'mu_static_backward[0] must be >= mu_backward[0]'),
    ({'mu_static': [math.nan]}, 'mu_static[0]'),
    ({'mu_static': [0.5, 0.5, 0.5]}, 'mu_static: must have 1 or 2 entries'),
    ({'static_friction': [1.0, 1.0]}, 'static_friction[0] must be >= friction[0]'),
    ({'stiction_rule': 'sticky'}, 'stiction_rule must be one of'),
    ({'method': 'penalty'}, "method 'penalty' cannot simulate static friction"),
])
def test_a_bad_static_value_is_refused_naming_it_and_the_node_runs_on(ros, values, named):
    sim = ros.sim(seed=True, **HOLD)
    ticks(sim, 100)
    before = dict(sim.config.values)
    results = set_over_dds(ros, **values)
    assert not results[0].successful
    assert named in results[0].reason and '\n' not in results[0].reason
    ticks(sim, 200)
    assert sim.config.values == before
    np.testing.assert_array_equal(sim.state.v, 0.0)     # still held


def test_a_recorded_session_with_stiction_replays_with_zero_difference(ros, tmp_path):
    sim = ros.sim(seed=True, record=True, record_dir=str(tmp_path), record_name='stiction',
                  **{**HOLD, 'slope': 0.1})
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    for step, (target, change) in enumerate([
            (0.16, {}), (0.06, {'mu_static': [0.9, 0.5]}), (0.2, {'stiction_rule': 'margin'}),
            (0.1, {'mu_static_backward': []}), (0.14, {'static_friction': [6.0, 4.0]})]):
        ros.send(pub, cmd(target), sim, 'commands_accepted')
        ticks(sim, 137 + 50 * step)             # commands land off and on the publish grid
        if change:
            results = set_over_dds(ros, **change)
            assert all(r.successful for r in results), [r.reason for r in results]
        ticks(sim, 211)
        if step == 2:
            ros.call(Trigger, '/crawler_sim/reset', Trigger.Request())
            ticks(sim, 3)
    sim.close()
    run = bag.load(tmp_path / 'stiction')
    assert len(run.t) > 100
    assert run.scene['mu_static'] == [0.5] and run.scene['stiction_rule'] == 'incumbent'
    contact = np.asarray(run.contact)
    assert (contact == 0).any() and (contact != 0).any()          # it stuck and it slid
    res = _replay(run, None, 0.0)
    assert res['max_position_error'] == 0.0, res
    assert res['max_velocity_error'] == 0.0, res
    assert 'parameter change' in res['inputs'] and 'reset' in res['inputs']
    # the command itself: exit 0 at a tolerance below any rounding
    from crawler_sim import cli
    assert cli.main(['replay', str(tmp_path / 'stiction'), '--tol', '1e-300']) == 0


def test_the_incumbent_read_back_from_the_bag_is_the_engines(ros, tmp_path):
    sim = ros.sim(seed=True, record=True, record_dir=str(tmp_path), record_name='incumbent',
                  **HOLD)
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    seen = {0: sim.state.incumbent.copy()}
    for target in (None, 0.16, 0.05, 0.2):
        if target is not None:
            ros.send(pub, cmd(target), sim, 'commands_accepted')
        for _ in range(40):
            ticks(sim, 10)                       # one publish period (100 Hz of 1 kHz ticks)
            seen[sim.sim_time_ns] = sim.state.incumbent.copy()
    sim.close()
    run = bag.load(tmp_path / 'incumbent')
    rows = {int(t): i for i, t in enumerate(run.t_ns)}
    kinds = set()
    for t_ns, inc in seen.items():
        if t_ns == 0:
            continue                 # at the start: counted stuck before it, not yet recorded
        np.testing.assert_array_equal(run.incumbent[rows[t_ns]], inc, err_msg=str(t_ns))
        kinds.add(tuple(inc))
    assert len(kinds) >= 3, kinds              # held, one body held, none held were all seen
