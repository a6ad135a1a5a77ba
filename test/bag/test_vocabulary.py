"""One run-data vocabulary (issue 27: ``Trajectory.state``, ``Run.contact`` and
``State.contact`` were one array under three names): an offline run, the bag it is recorded
to and the streaming state name each quantity alike, and the arrays agree."""
from __future__ import annotations

import numpy as np
import pytest

from crawler_sim import Crawler, Stepper, gaits, simulate
from crawler_sim.bag import load, record_trajectory
from crawler_sim.core.simtime import to_ns

SHARED = ('x', 'v', 'friction', 'contact', 'lengths', 'rates', 'linkage_force')


def test_a_run_and_its_bag_name_the_same_arrays_alike(tmp_path):
    crawler = Crawler(masses=[0.5, 1.0], mu=0.3)
    gait = gaits.Scallop(mean=0.1, amplitude=0.02, frequency=2.0, asymmetry=0.2)
    run = simulate(crawler, gait, 1.0, t_eval=np.linspace(0.0, 1.0, 101))
    record_trajectory(tmp_path / 'bag', run).close()
    bag = load(tmp_path / 'bag')
    # times are stamps: whole nanoseconds
    assert bag.t_ns.tolist() == [to_ns(t) for t in run.t]
    for name in SHARED:
        # the bag stores float64 and int8 as they are: the same numbers, not close ones
        np.testing.assert_array_equal(getattr(bag, name), getattr(run, name), err_msg=name)
    assert set(np.unique(run.contact)) <= {-1, 0, 1} and (run.contact == 0).any()
    state = Stepper(crawler, gait).state
    for name in ('x', 'v', 'friction', 'contact', 'lengths', 'rates', 'linkage_force'):
        assert np.shape(getattr(state, name))[-1] == np.shape(getattr(run, name))[-1], name


def test_the_old_name_still_reads_but_warns():
    run = simulate(Crawler(masses=[1.0, 1.0], mu=0.3), gaits.Sinusoid(0.1, 0.02, 1.0), 0.5)
    with pytest.warns(DeprecationWarning, match='Trajectory.contact'):
        assert run.state is run.contact
