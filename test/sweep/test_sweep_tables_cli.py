"""Tables of runs and bags, Parquet/CSV with metadata, and the sweep, export and optimize
commands."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml

import crawler_sim as cs
from crawler_sim import cli
from crawler_sim.core.scene import load_scene, scene_to_dict

from crawler_sim.sweep.tables import read_table, trajectory_frames, write_table

REPO = Path(__file__).resolve().parents[2]
SPEC_YAML = '''sweep:
  name: tiny
  periods: 6
  samples_per_period: 20
  chunk_size: 2
  base:
    crawler: {masses: [0.5, 1.0], mu: 0.3}
    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 2.0, asymmetry: 0.2}
  grid:
    gait.asymmetry: [0.2, 0.5, 0.8]
'''


def run(capsys, *args: str) -> subprocess.CompletedProcess:
    code = cli.main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)


@pytest.fixture(scope='module')
def traj():
    return cs.simulate(cs.Crawler([0.5, 1.0], [1.5, 3.0]), cs.gaits.Scallop(0.1, 0.02, 2.0, 0.2),
                       3.0)


def test_a_trajectory_is_one_row_per_sample_and_one_row_per_event(traj):
    samples, events = trajectory_frames(traj)
    assert len(samples) == len(traj) and len(events) == len(traj.events) > 0
    assert list(samples.columns[:2]) == ['x_0', 'x_1'] and 'linkage_force_0' in samples
    assert samples.shape[1] == 4 * 2 + 3 * 1 + 1       # x v friction contact; 3 per link; com
    np.testing.assert_array_equal(samples['v_1'], traj.v[:, 1])
    # centre of mass by hand: (0.5 x_0 + 1.0 x_1) / 1.5
    np.testing.assert_allclose(samples['com'], (0.5 * traj.x[:, 0] + traj.x[:, 1]) / 1.5,
                               rtol=0, atol=1e-15)
    assert events['t'].is_monotonic_increasing and set(events['body']) <= {0, 1}


@pytest.mark.parametrize('suffix', ['parquet', 'csv'])
def test_tables_keep_every_float_bit_and_the_metadata(traj, tmp_path, suffix):
    samples, _ = trajectory_frames(traj)
    path = write_table(samples, tmp_path / f'run.{suffix}')
    back = read_table(path)
    np.testing.assert_array_equal(back.index.to_numpy(), samples.index.to_numpy())
    np.testing.assert_array_equal(back.to_numpy(dtype=float), samples.to_numpy(dtype=float))
    assert back.attrs['crawler_sim']['crawler']['masses'] == [0.5, 1.0]
    with pytest.raises(ValueError, match='format must be one of parquet, csv'):
        write_table(samples, tmp_path / 'run.xlsx')


def test_export_writes_a_bags_samples_and_events_that_match_the_run(traj, tmp_path, capsys,
                                                                    monkeypatch):
    if 'AMENT_PREFIX_PATH' not in os.environ:
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)
    from crawler_sim.bag import record_trajectory
    scene = load_scene(REPO / 'config' / 'scenes' / 'scallop_2body.yaml')
    writer = record_trajectory(tmp_path / 'bag', traj, scene=scene_to_dict(scene))
    assert not getattr(writer, 'error', None)
    proc = run(capsys, 'export', str(tmp_path / 'bag'), '--csv', str(tmp_path / 'run.csv'))
    assert proc.returncode == 0, proc.stderr
    samples = read_table(tmp_path / 'run.csv')
    events = read_table(tmp_path / 'run_events.csv')
    assert len(samples) == len(traj) and len(events) == len(traj.events)
    np.testing.assert_allclose(samples.index.to_numpy(), traj.t, rtol=0, atol=1e-9)  # ns stamps
    np.testing.assert_array_equal(samples['x_1'].to_numpy(), traj.x[:, 1])
    np.testing.assert_array_equal(samples['contact_0'].to_numpy(), traj.contact[:, 0])


def test_export_of_a_missing_bag_is_a_usage_error(tmp_path, capsys):
    proc = run(capsys, 'export', str(tmp_path / 'nope'), '--parquet', str(tmp_path / 'x.parquet'))
    assert proc.returncode == 2 and 'no such bag' in proc.stderr


def test_the_sweep_command_writes_parquet_that_reruns_to_the_same_frame(tmp_path, capsys):
    spec = tmp_path / 'tiny.yaml'
    spec.write_text(SPEC_YAML)
    out = tmp_path / 'tiny.parquet'
    proc = run(capsys, 'sweep', str(spec), '-o', str(out), '--workers', '1', '--quiet')
    assert proc.returncode == 0, proc.stderr
    assert '3 scenes x 6 periods' in proc.stdout and not (tmp_path / 'tiny.parquet.chunks').exists()
    first = read_table(out)
    assert first.attrs['crawler_sim']['spec']['grid'] == {'gait.asymmetry': [0.2, 0.5, 0.8]}
    again = tmp_path / 'again.parquet'
    proc = run(capsys, 'sweep', str(out), '-o', str(again), '--workers', '1', '--quiet')
    assert proc.returncode == 0, proc.stderr
    pd.testing.assert_frame_equal(read_table(again), first, check_exact=True)
    # the time-antisymmetric stroke (r = 0.5) is the zero of the row, the others move
    speeds = first['mean_speed'].to_numpy()
    assert abs(speeds[1]) < 1e-12 and abs(speeds[0]) > 1e-4


def test_a_bad_spec_is_one_error_line_and_exit_2(tmp_path, capsys):
    spec = tmp_path / 'bad.yaml'
    spec.write_text(SPEC_YAML.replace('[0.2, 0.5, 0.8]', '{linspace: [0.2, 0.8]}'))
    proc = run(capsys, 'sweep', str(spec), '-o', str(tmp_path / 'x.parquet'))
    assert proc.returncode == 2
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith('crawler-sim: error:')]
    assert len(errors) == 1 and 'sweep.grid.gait.asymmetry.linspace' in errors[0]


def gait_node_gait(params_file: Path):
    """Start a gait_node with ``--params-file`` in its own context and return its gait."""
    import rclpy
    from rclpy.context import Context

    from crawler_sim.ros.gait_node import GaitNode
    from test.support.ros import next_domain_id

    ctx = Context()
    rclpy.init(args=['--ros-args', '--params-file', str(params_file)], context=ctx,
               domain_id=next_domain_id())
    try:
        node = GaitNode(context=ctx)
        gait = node.gait
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    return gait


def test_optimize_writes_a_gait_node_parameter_file_whose_stroke_keeps_the_limits(tmp_path,
                                                                                  capsys):
    out = tmp_path / 'best.yaml'
    proc = run(capsys, 'optimize', str(REPO / 'config' / 'scenes' / 'scallop_2body.yaml'), '--maxiter', '3',
               '--popsize', '4', '--max-acceleration', '1.5', '--max-speed', '0.1',
               '--score', 'ideal',
               '-o', str(out), '--history', str(tmp_path / 'hist.png'), '--history-table',
               str(tmp_path / 'hist.csv'))
    assert proc.returncode == 0, proc.stderr
    g = gait_node_gait(out)           # the gait a real gait_node builds from the file
    assert isinstance(g, cs.gaits.Scallop) and g.n_links == 1
    params = yaml.safe_load(out.read_text())['gait_node']['ros__parameters']
    assert g.asymmetry == params['asymmetry'] and g.frequency == params['frequency']
    # check the limits independently on a fine grid of that gait
    t = np.linspace(0.0, g.period, 200_001)
    _, ld, ldd = g(t)
    assert np.abs(ld).max() <= 0.1 * (1 + 1e-3) and np.abs(ldd).max() <= 1.5 * (1 + 1e-3)
    scene = load_scene(tmp_path / 'best_scene.yaml')
    assert scene.gait_spec['amplitude'] == pytest.approx(params['amplitude'], rel=1e-12)
    assert (tmp_path / 'hist.png').read_bytes()[:4] == b'\x89PNG'
    hist = read_table(tmp_path / 'hist.csv')
    assert set(hist['stage']) == {'global', 'local'}
    best = hist['score'].min()
    assert best < 0                            # it found a stroke that moves forward


def test_optimize_on_dask_finds_the_same_stroke_as_locally(dask_client):
    from crawler_sim.sweep.optimize import optimize
    scene = load_scene(REPO / 'config' / 'scenes' / 'scallop_2body.yaml')
    kw = dict(maxiter=2, popsize=4, local_maxiter=10, periods=8)
    local = optimize(scene, **kw)
    remote = optimize(scene, client=dask_client, **kw)
    np.testing.assert_array_equal(remote.x, local.x)
    assert [h['score'] for h in remote.history] == [h['score'] for h in local.history]


def test_the_help_lists_the_new_commands(capsys):
    proc = run(capsys, '--help')
    for name in ('sweep', 'optimize', 'export'):
        assert name in proc.stdout


def test_the_sweep_command_runs_on_a_scheduler_address_with_the_same_result(dask_client,
                                                                            tmp_path, capsys):
    spec = tmp_path / 'tiny.yaml'
    spec.write_text(SPEC_YAML)
    local, remote = tmp_path / 'local.parquet', tmp_path / 'remote.parquet'
    assert run(capsys, 'sweep', str(spec), '-o', str(local), '--workers', '1',
               '--quiet').returncode == 0
    proc = run(capsys, 'sweep', str(spec), '-o', str(remote), '--quiet', '--scheduler',
               dask_client.scheduler.address)
    assert proc.returncode == 0, proc.stderr
    assert dask_client.scheduler.address in proc.stdout
    pd.testing.assert_frame_equal(read_table(remote), read_table(local), check_exact=True)


@pytest.mark.parametrize('family', ['stroke', 'fourier'])
def test_optimize_writes_a_file_gait_node_plays_for_every_family(tmp_path, capsys, family):
    """Families gait_node has no parameters for go through ``gait_file``: the gait a real
    gait_node builds from OUT must be the best scene's gait (compared on a grid of a period)."""
    out = tmp_path / 'best.yaml'
    proc = run(capsys, 'optimize', str(REPO / 'config' / 'scenes' / 'scallop_2body.yaml'),
               '--family', family, '--maxiter', '2', '--popsize', '3', '-o', str(out))
    assert proc.returncode == 0, proc.stderr
    played = gait_node_gait(out)
    best = load_scene(tmp_path / 'best_scene.yaml').gait
    assert type(played) is type(best)
    t = np.linspace(0.0, 2.0 * best.period, 1001)
    for a, b in zip(played(t), best(t)):
        np.testing.assert_array_equal(a, b)


def test_a_csv_table_is_plain_for_pandas_and_numpy_and_keeps_its_metadata_beside_it(tmp_path):
    """Issue 27: the first line ``# crawler_sim: {json}`` broke ``pd.read_csv`` and
    ``np.genfromtxt``. The metadata now lives in ``<name>.csv.json``."""
    from crawler_sim.sweep.tables import read_table, write_table
    df = pd.DataFrame({'a': [1.0, 0.1 + 0.2], 'b': [3.0, 4.0]}, index=pd.Index([0, 1], name='t'))
    df.attrs['crawler_sim'] = {'kind': 'sweep', 'spec': {'n': 2}}
    path = write_table(df, tmp_path / 'out.csv')
    plain = pd.read_csv(path, index_col=0)
    assert plain['a'].tolist() == [1.0, 0.1 + 0.2]            # 17 digits: exact
    arr = np.genfromtxt(path, delimiter=',', names=True)
    assert arr['b'].tolist() == [3.0, 4.0]
    back = read_table(path)
    assert back.attrs['crawler_sim'] == {'kind': 'sweep', 'spec': {'n': 2}}
    assert (tmp_path / 'out.csv.json').is_file()
