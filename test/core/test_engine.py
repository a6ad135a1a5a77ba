"""The node's engine: batched ticks (flat out) give the same states, bit for bit, as single ones."""
from __future__ import annotations

import numpy as np
import pytest

from crawler_sim.core import gaits
from crawler_sim.core.actuator import ActuatorLimits, TrajectoryReference
from crawler_sim.core.plant import Engine, EngineConfig
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
