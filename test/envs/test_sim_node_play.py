"""An episode of crawler_sim/Crawl-v0 played into a real sim_node over real DDS (issue 41):
the node, given the env's plant parameters and the same target lengths on ``linkage_cmd`` at
the same ticks, publishes on ``body_states`` the positions the env reported, bit for bit
(max |dx| = 0): what a policy learns in the env is what sim_node does with its commands."""
from __future__ import annotations

import numpy as np
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from crawler_sim.envs import CrawlEnv
from crawler_sim.ros.messages import ns_from_stamp
from test.support.ros import Harness, cmd, ticks


@pytest.fixture
def ros():
    h = Harness()            # its own context and domain id, discovery off (test/support/ros)
    yield h
    h.close()


def test_an_episode_played_into_sim_node_gives_the_env_states(ros):
    env = CrawlEnv({'masses': [0.5, 1.0], 'mu': 0.3, 'mu_backward': 0.45},
                   control_period=0.02, min_length=0.03, max_length=0.17)
    env.reset(seed=0)
    values = dict(env.plant.plant_config.values)
    node = ros.sim(seed=True, publish_clock=False, **values)
    states = ros.listen(JointState, 'body_states')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    actions = np.random.default_rng(3).uniform(-1, 1, (60, 1))
    dx, moved = 0.0, []
    for k, a in enumerate(actions):
        ros.send(pub, cmd(*env.plant.lengths_of(a)), node, 'commands_accepted')
        ticks(node, 20)                       # 1 kHz ticks, one control period of 0.02 s
        _, _, _, _, info = env.step(a)
        t_ns = round(info['t'] * 1e9)
        ros.until(lambda: any(ns_from_stamp(m.header.stamp) == t_ns for m in states),
                  f'body_states at {t_ns} ns')
        msg = next(m for m in states if ns_from_stamp(m.header.stamp) == t_ns)
        dx = max(dx, float(np.max(np.abs(np.array(msg.position) - info['x']))))
        moved.append(info['x'][0])
    assert dx == 0.0
    assert np.ptp(moved) > 0.01               # the crawler moved: the check is not vacuous
