"""``info`` text and ``plot`` figure of a bag."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crawler_sim.bag import BagWarning, info, plot, record_arrays
from crawler_sim.bag.plot import stick_intervals
from test.support.synthetic import synthetic_arrays

N = 120


@pytest.fixture(scope='module')
def bag(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('info') / 'run'
    a = synthetic_arrays(N, 3, dt=0.01, t0=2.0, seed=9)
    masses = a.pop('masses')
    record_arrays(path, **a, masses=masses, scene={'p': 3, 'gait': 'sinusoid'})
    return path


def test_info_lists_topics_types_counts_duration_and_start(bag):
    text = info(bag)
    lines = text.splitlines()
    assert 'status:    complete' in lines
    assert f'messages:  {4 * N + 1}' in lines
    assert 'start:     2.000000000 s' in lines
    assert 'duration:  1.190000000 s' in lines
    assert 'metadata:  metadata.yaml' in lines
    body = next(line for line in lines if '/body_states' in line)
    assert 'sensor_msgs/msg/JointState' in body and f'{N} msgs' in body
    assert any('/odom' in line and 'nav_msgs/msg/Odometry' in line for line in lines)
    assert any(line.startswith('scene:') and 'gait=sinusoid' in line for line in lines)


def test_info_marks_an_incomplete_file(bag, tmp_path):
    data = (bag / 'run_0.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:len(data) // 2])
    text = info(tmp_path / 'cut.mcap')
    assert 'status:    INCOMPLETE' in text and 'recover' in text


def test_plot_writes_a_png(bag, tmp_path):
    out = plot(bag, tmp_path / 'run.png')
    assert out == tmp_path / 'run.png'
    data = out.read_bytes()
    assert data[:8] == b'\x89PNG\r\n\x1a\n' and len(data) > 20_000


def test_plot_of_a_truncated_bag_warns_and_still_plots(bag, tmp_path):
    data = (bag / 'run_0.mcap').read_bytes()
    (tmp_path / 'cut.mcap').write_bytes(data[:len(data) * 3 // 4])
    with pytest.warns(BagWarning):
        out = plot(tmp_path / 'cut.mcap', tmp_path / 'cut.png')
    assert out.stat().st_size > 10_000


def test_stick_intervals_cover_each_run_of_zero_contact_until_the_next_sample():
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    stuck = np.array([True, True, False, True, False, True])
    assert stick_intervals(t, stuck) == [(0.0, 2.0), (3.0, 1.0), (5.0, 0.0)]
    assert stick_intervals(t, np.zeros(6, bool)) == []
    assert stick_intervals(t[:0], stuck[:0]) == []


def _drawn(fig) -> list[tuple[str, int, int]]:
    """(y label, lines, shaded bands) of each panel."""
    return [(ax.get_ylabel(), len(ax.lines), len(ax.collections)) for ax in fig.axes]


def test_one_figure_for_an_offline_run_and_its_recording(tmp_path):
    """issue 27: `simulate --plot` and `plot` of the recorded run drew different figures. Now
    both draw bag.plot.figure: the same panels with the same curves and stick bands."""
    from crawler_sim import Crawler, gaits, simulate
    from crawler_sim.bag import load, record_trajectory
    from crawler_sim.bag.plot import PANELS, figure

    run = simulate(Crawler(masses=[0.5, 1.0, 0.8], mu=0.3),
                   gaits.Sinusoid(mean=[0.1, 0.1], amplitude=[0.02, 0.02], frequency=2.0), 2.0,
                   t_eval=np.linspace(0.0, 2.0, 201))
    record_trajectory(tmp_path / 'bag', run).close()
    offline, recorded = _drawn(figure(run, 'offline')), _drawn(figure(load(tmp_path / 'bag')))
    assert offline == recorded
    assert [label for label, _, _ in offline] == list(PANELS)
    # three bodies on x, v, friction; two linkages; one band collection per body
    assert [n for _, n, _ in offline] == [3, 3, 3, 2, 0] and offline[4][2] == 3
