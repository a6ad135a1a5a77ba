"""A bag whose number of bodies changed during the run (issue 25).

sim_node resets and records on when ``p`` is changed, so one bag holds states of 3 bodies and
then states of 2. The missing third body must never read as contact 0 ("stuck"), and loading
must not cast NaN to an integer (numpy's "invalid value encountered in cast").
"""
from __future__ import annotations

import warnings

import numpy as np
from numpy.testing import assert_array_equal
import pytest

from crawler_sim.bag import NO_BODY, BagWarning, Recorder, load

# state rows as recorded: (t, x, v, friction, contact, lengths, rates, linkage_force)
THREE = [(0.01 * i, [0.0, 0.1, 0.2], [1.0, 2.0, 3.0], [0.5, 0.0, -0.5], [1, 0, -1],
          [0.1, 0.1], [0.0, 0.0], [2.0, 3.0]) for i in range(5)]
TWO = [(0.05 + 0.01 * i, [0.3, 0.4], [4.0, 5.0], [0.0, 0.25], [0, 1], [0.1], [0.01], [4.0])
       for i in range(5)]


@pytest.fixture
def changed_bag(tmp_path):
    with Recorder(tmp_path / 'run', masses=[1.0, 1.0, 1.0], flush_interval=None) as rec:
        for row in THREE:
            rec.record_state(*row)
        rec.masses = np.array([1.0, 1.0])          # the node reset with p = 2
        for row in TWO:
            rec.record_state(*row)
    return tmp_path / 'run'


def test_bodies_missing_after_p_changed_are_marked_not_stuck(changed_bag):
    with warnings.catch_warnings():
        warnings.simplefilter('error', RuntimeWarning)     # no NaN cast to int8
        warnings.simplefilter('error', BagWarning)
        run = load(changed_bag)
    assert len(run) == 10 and run.p == 3
    assert NO_BODY not in (-1, 0, 1)
    # the first five states had three bodies, the last five two
    assert run.present[:5].all()
    assert run.present[5:, :2].all() and not run.present[5:, 2].any()
    assert_array_equal(run.contact[:5], [[1, 0, -1]] * 5)
    assert_array_equal(run.contact[5:], [[0, 1, NO_BODY]] * 5)   # a real 0 stays stuck
    assert_array_equal(run.x[5:, :2], [[0.3, 0.4]] * 5)
    for name in ('x', 'v', 'friction'):
        assert np.isnan(getattr(run, name)[5:, 2]).all(), name
    assert_array_equal(run.lengths[5:, 0], [0.1] * 5)
    assert np.isnan(run.lengths[5:, 1]).all() and np.isnan(run.linkage_force[5:, 1]).all()


def test_a_bag_with_a_constant_p_has_every_body_present(tmp_path):
    with Recorder(tmp_path / 'run', masses=[1.0, 1.0, 1.0], flush_interval=None) as rec:
        for row in THREE:
            rec.record_state(*row)
    run = load(tmp_path / 'run')
    assert run.present.shape == (5, 3) and run.present.all()
    assert NO_BODY not in run.contact
