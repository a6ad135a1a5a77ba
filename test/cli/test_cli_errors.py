"""Issue 38's audit of the command line's "internal error" paths: every error a user's input can
cause is one line naming the file and the field, with exit 2 for a refused input (the catch-all
in `crawler_sim.cli.main` keeps "internal error" for the package's own bugs)."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest

from crawler_sim import cli
from crawler_sim.bag import record_arrays
from crawler_sim.core.scene import load_scene, scene_to_dict
from test.support.synthetic import synthetic_arrays

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / 'config' / 'scenes' / 'scallop_2body.yaml'


def run(capsys, *args: str | Path) -> subprocess.CompletedProcess:
    code = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)


def error_line(proc: subprocess.CompletedProcess) -> str:
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith('crawler-sim: error: ')]
    assert len(lines) == 1 and 'Traceback' not in proc.stderr, proc.stderr
    assert 'internal error' not in lines[0]
    return lines[0]


@pytest.fixture(autouse=True)
def ros_env(monkeypatch):
    if 'AMENT_PREFIX_PATH' not in os.environ:
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)


def offline_bag(path: Path, **scene_changes) -> Path:
    """An offline bag of synthetic states whose recorded scene is SCENE's with changes."""
    a = synthetic_arrays(30, 2, seed=1)
    masses = a.pop('masses')
    scene = {**scene_to_dict(load_scene(SCENE)), **scene_changes}
    assert record_arrays(path, **a, masses=masses, scene=scene).error is None
    return path


@pytest.mark.parametrize('as_node, fragment', [
    (5, 'scene.as_node: must be a mapping with mode and rate, got int'),
    ({'rate': 50}, 'scene.as_node.mode: must be one of preload, trajectory, command, got None'),
    ({'mode': 'zz', 'rate': 50}, "scene.as_node.mode: must be one of preload, trajectory, "
                                 "command, got 'zz'"),
    ({'mode': 'preload', 'rate': 'x'}, "scene.as_node.rate: must be a finite number > 0 [Hz], "
                                       "got 'x'"),
    ({'mode': 'preload', 'rate': -5}, 'scene.as_node.rate: must be a finite number > 0'),
])
def test_replay_of_a_bag_whose_recorded_as_node_is_malformed_names_the_field(
        tmp_path, capsys, as_node, fragment):
    # was: internal error (TypeError / KeyError / AttributeError) or a bare float() message
    bag = offline_bag(tmp_path / 'run', as_node=as_node)
    proc = run(capsys, 'replay', bag)
    assert proc.returncode == 2
    line = error_line(proc)
    assert str(bag) in line and fragment in line


def test_replay_as_the_node_ran_it_at_stamps_off_its_grid_reports_the_difference(tmp_path,
                                                                                 capsys):
    # the states are sampled at the recorded times (interpolated): it used Trajectory.p,
    # which does not exist (internal error AttributeError)
    bag = offline_bag(tmp_path / 'run', as_node={'mode': 'command', 'rate': 50})
    proc = run(capsys, 'replay', bag)
    assert proc.returncode == 1
    assert 'replay differs from the recording' in error_line(proc)


def test_a_scene_whose_method_is_a_list_is_refused_naming_the_field(tmp_path, capsys):
    # was: internal error (TypeError: unhashable type: 'list')
    path = tmp_path / 'scene.yaml'
    path.write_text(SCENE.read_text().replace('method: exact', 'method: [exact]'))
    assert '[exact]' in path.read_text()
    proc = run(capsys, 'simulate', path)
    assert proc.returncode == 2
    assert "scene.run.method: unknown method ['exact']" in error_line(proc)


RESULTS = {  # file name -> (contents, sidecar contents or None, error fragment)
    'bad_sidecar.csv': ('scene,x\n0,0\n', '{not json', 'bad_sidecar.csv.json: not the JSON '
                        'metadata of a table'),
    'list_sidecar.csv': ('scene,x\n0,0\n', '[1, 2]', 'list_sidecar.csv.json: the metadata '
                         'must be a JSON object, got list'),
    'old_prefix.csv': ('# crawler_sim: {bad\nscene\n0\n', None, 'old_prefix.csv: its first '
                       'line: not the JSON metadata of a table'),
    'binary.csv': (b'\xff\xfe\x00garbage', None, 'binary.csv: not a csv table'),
    'garbage.parquet': (b'PAR1 garbage', None, 'garbage.parquet: not a parquet table'),
    'no_spec.csv': ('scene,x\n0,0\n', '{"kind": "bag"}', 'no_spec.csv: holds no sweep spec'),
    'spec_5.csv': ('scene,x\n0,0\n', '{"kind": "sweep", "spec": 5}',
                   'spec_5.csv: sweep: must be a mapping'),
}


@pytest.mark.parametrize('name', list(RESULTS))
def test_sweep_of_results_it_cannot_read_is_a_refused_input_naming_the_file(tmp_path, capsys,
                                                                            name):
    # was: exit 1 with pyarrow's, json's or the codec's message naming no file, or
    # internal error (AttributeError: 'list' object has no attribute 'get')
    text, sidecar, fragment = RESULTS[name]
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    if sidecar is not None:
        (tmp_path / f'{name}.json').write_text(sidecar)
    proc = run(capsys, 'sweep', path, '-o', tmp_path / 'out.parquet')
    assert proc.returncode == 2
    assert fragment in error_line(proc)
    assert not (tmp_path / 'out.parquet').exists()


@pytest.mark.parametrize('option, value, bound', [
    ('--harmonics', '-1', '>= 1'), ('--periods', '0', '>= 1'), ('--popsize', '0', '>= 1'),
    ('--workers', '0', '>= 1'), ('--maxiter', '-1', '>= 0'), ('--periods', 'x', '>= 1'),
])
def test_optimize_refuses_counts_out_of_range_before_optimising(tmp_path, capsys, option,
                                                                value, bound):
    # --harmonics -1 failed inside the optimiser with exit 1; 0 periods or popsize exited 0
    proc = run(capsys, 'optimize', SCENE, '-o', tmp_path / 'b.yaml', option, value)
    assert proc.returncode == 2
    assert f'argument {option}: must be an integer {bound}, got {value!r}' in error_line(proc)
    assert list(tmp_path.iterdir()) == []


def test_an_oserror_without_a_reason_is_not_an_internal_error(monkeypatch, capsys):
    from crawler_sim.core.scene import Scene

    def fail(self, **kwargs):
        raise OSError('the device went away')

    monkeypatch.setattr(Scene, 'simulate', fail)
    proc = run(capsys, 'simulate', SCENE)
    assert proc.returncode == 1
    assert 'the device went away' in error_line(proc)


def body_states_only(path: Path) -> Path:
    """A bag of body_states alone (an outputs switched off, a foreign recorder): no joint_states
    or contact_states, no scene."""
    from sensor_msgs.msg import JointState

    from crawler_sim.bag import BagWriter

    with BagWriter(path, flush_interval=None) as writer:
        for k in range(5):
            msg = JointState(name=['body_0', 'body_1'], position=[0.1 * k, 0.2 + 0.1 * k],
                             velocity=[0.1, 0.1], effort=[-1.0, -2.0])
            writer.write('/body_states', 'sensor_msgs/msg/JointState', msg, k * 10_000_000)
    return path


def test_export_of_a_bag_without_contact_states_writes_what_was_recorded(tmp_path, capsys):
    # was: internal error (IndexError: index 0 is out of bounds for axis 1 with size 0)
    from crawler_sim.sweep.tables import read_table

    bag = body_states_only(tmp_path / 'run')
    proc = run(capsys, 'export', bag, '--csv', tmp_path / 'run.csv')
    assert proc.returncode == 0, proc.stderr
    samples = read_table(tmp_path / 'run.csv')
    assert not [c for c in samples.columns if c.startswith('contact_')]   # none recorded
    assert samples['x_1'].tolist() == pytest.approx([0.2, 0.3, 0.4, 0.5, 0.6])


def test_replay_of_a_bag_without_a_scene_names_the_bag(tmp_path, capsys):
    bag = body_states_only(tmp_path / 'run')
    proc = run(capsys, 'replay', bag)
    assert proc.returncode == 2
    assert f'{bag}: the bag holds no scene' in error_line(proc)
