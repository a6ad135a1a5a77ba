"""``ExactSolver.current`` (plain floats, called at every publish tick of sim_node) against
``Segment.evaluate`` (the array closed form used for sampled trajectories), written apart.

Random crawlers (p = 2..5, direction-dependent friction, slopes, a frictionless body) under a
Scallop gait and at rest under a constant command, so both slide segments and stick segments
with groups of several bodies are met; after every advance the two must agree to rounding.
"""
import numpy as np
import pytest

from crawler_sim import Crawler
from crawler_sim.core import gaits
from crawler_sim.core.solvers.exact import ExactSolver

KEYS = ('x', 'v', 'friction', 'impulse', 'linkage_force', 'lengths', 'rates', 'contact')


def _scene(seed: int):
    rng = np.random.default_rng(seed)
    p = int(rng.integers(2, 6))
    m = 10.0 ** rng.uniform(-1, 1, p)
    f = m * rng.uniform(0.5, 5.0, p)
    fb = f * 10.0 ** rng.uniform(-0.3, 0.3, p)
    if seed % 3 == 0:
        f[-1] = fb[-1] = 0.0          # a frictionless body: contact = sign of its velocity
    slope = float(rng.uniform(-0.2, 0.2)) if seed % 2 else 0.0
    crawler = Crawler(m, f, fb, slope=slope)
    if seed % 4 == 3:                 # at rest under a constant command: one stuck group
        gait = gaits.Fourier(0.1, (np.zeros((p - 1, 1)), np.zeros((p - 1, 1))), 1.0)
    else:
        gait = gaits.Scallop(0.1, float(rng.uniform(0.01, 0.03)), float(rng.uniform(0.5, 3)),
                             float(rng.uniform(0.0, 0.4)), list(rng.uniform(0, 6, p - 1)),
                             n_links=p - 1)
    return crawler, gait


@pytest.mark.parametrize('seed', range(16))
def test_current_equals_the_segment_closed_form(seed):
    crawler, gait = _scene(seed)
    solver = ExactSolver(crawler, gait, periodic_skip=False)
    seen_stick = seen_slide = False
    for k in range(1, 400):
        solver.advance(k * 0.0037)
        seg = solver.last
        assert seg is not None and seg.t1 == solver.t
        now = solver.current()
        ref = seg.evaluate(crawler, np.array([solver.t]))
        for key in KEYS:
            scale = max(1.0, float(np.max(np.abs(ref[key]))))
            np.testing.assert_allclose(now[key], ref[key][0], rtol=0, atol=1e-12 * scale,
                                       err_msg=f'{key} at t = {solver.t}')
        assert now['indeterminate'] == bool(seg.group.sum() > 1)
        seen_stick |= seg.ref >= 0
        seen_slide |= seg.ref < 0
    assert seen_stick or seen_slide
