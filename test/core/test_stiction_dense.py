"""Dense output carries the incumbent (issue 40: the cluster stuck just before t is state
"everywhere a state lives"): ``Trajectory.state_at`` gives, at each time, what
``Stepper.state.incumbent`` is after advancing to that time, inside skipped periods too.

The expected values: STICTION.md T5 by hand, and the Stepper's own state at the same times (an
independent path: the compiled loop's state, not the kept segment records).
"""
from __future__ import annotations

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core.gaits import PiecewiseParabolic
from test.support.stiction_reference import GRAVITY, random_scene

# T5 (STICTION.md s. 4.2, test_stiction_exact): body 0 stuck on [0, 1) (initial_stuck=0); at the
# reversal t = 1 'incumbent' keeps body 0, 'margin' anchors body 1 from then on
T5_GAIT = PiecewiseParabolic([0.0, 2.0, 4.0], [0.5, -0.5], 1.0, -0.5)
T5_CRAWLER = cs.Crawler([1.0, 1.0], 1.0, static_friction=[2.0, 2.5])


@pytest.mark.parametrize('rule, after', [('incumbent', [True, False]), ('margin', [False, True])])
def test_t5_the_incumbent_before_at_and_after_the_reversal(rule, after):
    tr = cs.simulate(T5_CRAWLER, T5_GAIT, 8.0, stiction_rule=rule, initial_stuck=0)
    # at t = 0 the initial one; at t = 1 exactly the segment that ends there (body 0 stuck)
    times = np.array([1.5, 0.0, 0.5, 1.0, 7.9])           # in any order
    inc = tr.state_at(times).incumbent
    assert inc.tolist() == [after, [True, False], [True, False], [True, False], after]
    assert tr.state_at(1.0).incumbent.tolist() == [True, False]
    assert tr.state_at(2.5).incumbent.tolist() == after


def stepper_incumbents(crawler, gait, times, **kw):
    st = cs.Stepper(crawler, gait, **kw)
    out = []
    for t in times:
        st.advance(float(t))
        out.append(st.state.incumbent.tolist())
    return out


@pytest.mark.parametrize('skip', [True, False])
@pytest.mark.parametrize('rule', ['incumbent', 'margin'])
@pytest.mark.parametrize('seed', [4, 6, 7, 10, 28, 38, 46])
def test_state_at_gives_the_steppers_incumbent_between_events_and_the_left_one_at_them(
        seed, rule, skip):
    # random stiction scenes (stroke reversals, bang-bang dwells of a 3-body cluster), 6
    # periods, times in the skipped periods too. Between events: the Stepper streamed to the
    # same times. At an event time itself the Stepper is no reference: a streamed run's events
    # agree with the whole run's to a float or two, not to the bit, and a float decides the
    # side; there the incumbent is the one just before (1e-9 s earlier, the same segment)
    sc = random_scene(seed)
    crawler = cs.Crawler(sc['masses'], sc['friction'], sc['friction_backward'],
                         slope=sc['slope'], gravity=GRAVITY,
                         static_friction=sc['static_friction'],
                         static_friction_backward=sc['static_friction_backward'])
    t_end = 6.0 * sc['period']
    tr = cs.simulate(crawler, sc['gait'], t_end, stiction_rule=rule, periodic_skip=skip)
    if skip:
        assert tr.info['skipped_periods'] > 0
    ev = np.array(sorted({e.time for e in tr.events if 0.0 < e.time < t_end}))
    rng = np.random.default_rng(seed)
    times = np.unique(np.concatenate([[0.0, t_end], 0.5 * (ev[1:] + ev[:-1]),
                                      rng.uniform(0.0, t_end, 20)]))
    want = stepper_incumbents(crawler, sc['gait'], times, stiction_rule=rule,
                              periodic_skip=skip)
    assert tr.state_at(times).incumbent.tolist() == want
    assert any(any(w) for w in want)            # a stuck cluster somewhere: it tests something
    before = tr.state_at(ev - 1e-9).incumbent
    at = tr.state_at(ev).incumbent
    assert at.tolist() == before.tolist()
