"""A truncated offline bag replays without a false MISMATCH (issue 11 point 9, bag side).

The bag stores stamps in integer ns. Re-simulating at ``stamp / 1e9`` moves every sample by up
to 0.5 ns, a velocity difference of 0.5 ns times the acceleration; the comparison therefore
happens in the recorded ns base (``Run.t_ns`` and ``clock.rows_at_ns``).
"""
from __future__ import annotations

from pathlib import Path
import warnings

import numpy as np

from crawler_sim.bag import BagWarning, load
from crawler_sim.bag.clock import rows_at_ns, to_ns

REPO = Path(__file__).resolve().parents[2]


def test_rows_at_ns_finds_each_recorded_stamp_and_marks_the_others():
    t = np.array([0.0, 0.1, 0.2, 0.30000000000000004, 1 / 3])
    # stamps written by a recorder (rounded to ns), one unknown, in any order
    stamps = np.array([333_333_333, 100_000_000, 300_000_000, 150_000_000], dtype=np.int64)
    assert rows_at_ns(t, stamps).tolist() == [4, 1, 3, -1]
    assert rows_at_ns(t, np.array([2_000_000_000])).tolist() == [-1]        # past the end


def test_run_t_ns_holds_the_recorded_stamps(tmp_path):
    from crawler_sim.bag import record_arrays
    from test.support.synthetic import synthetic_arrays
    a = synthetic_arrays(50, 2, dt=1 / 3)
    a.pop('masses')
    record_arrays(tmp_path / 'r', **a)
    run = load(tmp_path / 'r')
    # 1/3 s steps are not whole ns: the stamps are the rounded times, t is their float
    assert run.t_ns.dtype == np.int64
    assert run.t_ns.tolist() == [round(x * 1e9) for x in a['t']]
    assert np.array_equal(run.t, run.t_ns / 1e9)


def test_a_truncated_offline_bag_replays_as_a_match(tmp_path):
    from crawler_sim.cli import _record, _replay
    from crawler_sim.core.scene import load_scene
    scene = load_scene(REPO / 'config' / 'scenes' / 'scallop_2body.yaml').with_run(t_end=3.0)
    tr = scene.simulate()
    _record(tmp_path / 'full', scene, tr)
    data = (tmp_path / 'full' / 'full_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) * 2 // 3])          # as a killed recording
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', BagWarning)
        run = load(cut)
    assert run.truncated and 0 < len(run) < len(tr.t)
    assert run.t_ns.tolist() == to_ns(tr.t[:len(run)]).tolist()
    res = _replay(run, None, 1e-9)
    assert res['match'], res
    assert res['max_velocity_error'] == 0.0 and res['max_position_error'] == 0.0


def test_samples_sharing_a_ns_stamp_are_matched_in_order():
    # an event 0.3 ns after a regular sample: both record as 1_250_000_000 ns; the second
    # recorded row must map to the second sample, not again to the first
    from crawler_sim.bag.clock import rows_at_ns
    t = np.array([1.0, 1.25, 1.25 + 3e-10, 1.5])
    stamps = np.array([1_000_000_000, 1_250_000_000, 1_250_000_000, 1_500_000_000])
    assert rows_at_ns(t, stamps).tolist() == [0, 1, 2, 3]
    assert rows_at_ns(t, stamps[:3]).tolist() == [0, 1, 2]          # a truncated bag
    assert rows_at_ns(t, np.array([1_250_000_001])).tolist() == [-1]
