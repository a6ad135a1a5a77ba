"""Issue 38, "nothing lost": every command that writes refuses an output that is one of its
inputs (by identity: the same name, a hard link, a symbolic link), lies inside an input bag
folder, or is no file (a directory), with one error line and exit 2, before any work and
without changing a byte anywhere; links planted where outputs and temporaries go are never
written through; a command reruns over its own earlier output."""
from __future__ import annotations

import os
from pathlib import Path
import subprocess

import pytest

from crawler_sim import cli
from crawler_sim.bag import record_arrays
from crawler_sim.sweep.spec import load_spec
from crawler_sim.sweep.tables import write_table
from test.support.synthetic import synthetic_arrays

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / 'config' / 'scenes' / 'scallop_2body.yaml'
PNG_MAGIC = b'\x89PNG\r\n\x1a\n'
SPEC_YAML = '''sweep:
  name: tiny
  periods: 4
  samples_per_period: 8
  chunk_size: 2
  base:
    crawler: {masses: [0.5, 1.0], mu: 0.3}
    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 2.0, asymmetry: 0.2}
  grid:
    gait.asymmetry: [0.2, 0.5, 0.8]
'''


def run(capsys, *args: str | Path) -> subprocess.CompletedProcess:
    code = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)


def error_line(proc: subprocess.CompletedProcess) -> str:
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith('crawler-sim: error: ')]
    assert len(lines) == 1 and 'Traceback' not in proc.stderr, proc.stderr
    return lines[0]


def snapshot(folder: Path) -> dict[str, tuple[str, bytes | str]]:
    """Every entry under ``folder``: links by target, files by content (nothing followed)."""
    out: dict[str, tuple[str, bytes | str]] = {}
    for path in sorted(folder.rglob('*')):
        name = str(path.relative_to(folder))
        if path.is_symlink():
            out[name] = ('link', os.readlink(path))
        elif path.is_dir():
            out[name] = ('dir', b'')
        else:
            out[name] = ('file', path.read_bytes())
    return out


@pytest.fixture
def place(tmp_path, ros_env) -> Path:
    """A bag ``run/`` (run_0.mcap, metadata.yaml), a scene, a sweep spec, sweep results, a
    folder ``dir`` and a user's file ``victim.txt``."""
    a = synthetic_arrays(40, 2, seed=3)
    masses = a.pop('masses')
    writer = record_arrays(tmp_path / 'run', **a, masses=masses)
    assert writer.error is None
    (tmp_path / 'scene.yaml').write_bytes(SCENE.read_bytes())
    (tmp_path / 'best_scene.yaml').write_bytes(SCENE.read_bytes())
    (tmp_path / 'spec.yaml').write_text(SPEC_YAML)
    results = write_table(_results(tmp_path / 'spec.yaml'), tmp_path / 'results.csv')
    assert results.exists()
    (tmp_path / 'dir').mkdir()
    (tmp_path / 'victim.txt').write_bytes(b'years of work')
    return tmp_path


@pytest.fixture
def ros_env(monkeypatch):
    import sys
    if 'AMENT_PREFIX_PATH' not in os.environ:
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)


def _results(spec: Path):
    import pandas as pd
    df = pd.DataFrame({'scene': [0], 'mean_speed': [0.0]}).set_index('scene')
    df.attrs['crawler_sim'] = {'kind': 'sweep', 'spec': load_spec(spec).to_dict()}
    return df


@pytest.fixture
def no_work(monkeypatch):
    """Refusals come before the work: simulating, sweeping or optimising fails the test."""
    from crawler_sim.core.scene import Scene
    import crawler_sim.sweep
    import crawler_sim.sweep.optimize

    def work(*args, **kwargs):
        pytest.fail('the command worked before refusing its output')

    monkeypatch.setattr(Scene, 'simulate', work)
    monkeypatch.setattr(crawler_sim.sweep, 'sweep', work)
    monkeypatch.setattr(crawler_sim.sweep.optimize, 'optimize', work)


# (command line with {names} of the place, links to make {name: target}, error fragment)
REFUSED = {
    'export over the bag recording': (
        'export {run} --csv {run}/run_0.mcap', {}, 'is an input of this command'),
    'export over the bag metadata': (
        'export {run} --parquet {run}/metadata.yaml', {}, 'is an input of this command'),
    'export of a file over itself': (
        'export {run}/run_0.mcap --csv {run}/run_0.mcap', {}, 'is an input of this command'),
    'export into the bag folder': (
        'export {run} --csv {run}/new.csv', {}, 'lies inside the input bag folder'),
    'export its events into the bag folder': (
        'export {run} --csv {run}/x.csv', {}, 'lies inside the input bag folder'),
    'export over a hard link of the recording': (
        'export {run} --csv {dir}/hard.csv', {'dir/hard.csv': 'hard:run/run_0.mcap'},
        'is an input of this command'),
    'export to a directory': ('export {run} --csv {dir}', {}, 'is a directory'),
    'export with a sidecar that is a directory': (
        'export {run} --csv {tmp}/t.csv', {'t.csv.json': 'mkdir'}, 'is a directory'),
    'plot into the bag folder': ('plot {run} -o {run}/x.png', {}, 'input bag folder'),
    'plot over the recording': ('plot {run} -o {run}/run_0.mcap', {}, 'input'),
    'plot to a directory': ('plot {run} -o {dir}', {}, 'is a directory'),
    'plot in an unknown format': ('plot {run} -o {tmp}/x.xyz', {}, "cannot draw a figure as 'xyz'"),
    'recover into the bag folder': ('recover {run} -o {run}/sub', {}, 'input bag folder'),
    'recover over the bag': ('recover {run} -o {run}', {}, 'is an input of this command'),
    'recover over an existing folder': ('recover {run}/run_0.mcap -o {dir}', {},
                                        'exists already, not overwriting'),
    'simulate plotting over its scene': ('simulate {scene} --plot {scene}', {},
                                         'is an input of this command'),
    'simulate plotting over a link to its scene': (
        'simulate {scene} --plot {tmp}/p.png', {'p.png': 'soft:scene.yaml'},
        'is an input of this command'),
    'simulate recording over its scene': ('simulate {scene} --out {scene}', {},
                                          'is an input of this command'),
    'simulate recording over a folder': ('simulate {scene} --out {dir}', {}, 'exists already'),
    'simulate plotting to a directory': ('simulate {scene} --plot {dir}', {}, 'is a directory'),
    'simulate plotting into its own bag': ('simulate {scene} --out {tmp}/new --plot '
                                           '{tmp}/new/p.png', {}, 'inside the bag folder'),
    'sweep over its spec': ('sweep {spec} -o {spec} --csv', {}, 'is an input of this command'),
    'sweep over a hard link of its spec': ('sweep {spec} -o {tmp}/h.parquet',
                                           {'h.parquet': 'hard:spec.yaml'}, 'is an input'),
    'sweep over the results it reruns': ('sweep {results} -o {results} --csv', {},
                                         'is an input of this command'),
    'sweep with a sidecar that is its spec': ('sweep {spec} -o {tmp}/s.csv --csv',
                                              {'s.csv.json': 'hard:spec.yaml'}, 'is an input'),
    'sweep to a directory': ('sweep {spec} -o {dir}', {}, 'is a directory'),
    'sweep with a planted checkpoint link': (
        'sweep {spec} -o {tmp}/o.parquet', {'o.parquet.chunks': 'soft:dir'},
        'the default checkpoint folder is a link'),
    'optimize over its scene': ('optimize {scene} -o {scene}', {}, 'is an input'),
    'optimize with the scene file over its scene': (
        'optimize {tmp}/best_scene.yaml -o {tmp}/best.yaml', {}, 'is an input'),
    'optimize history over its scene': ('optimize {scene} -o {tmp}/b.yaml --history {scene}',
                                        {}, 'is an input'),
    'optimize history table over a link to its scene': (
        'optimize {scene} -o {tmp}/b.yaml --history-table {tmp}/h.csv',
        {'h.csv': 'hard:scene.yaml'}, 'is an input'),
    'optimize to a directory': ('optimize {scene} -o {dir}', {}, 'is a directory'),
    'optimize history table over its gait file': (
        'optimize {scene} -o {tmp}/b.csv --history-table {tmp}/b.csv', {},
        'named for two outputs of this command'),
    'optimize history over its gait file': (
        'optimize {scene} -o {tmp}/h.png --history {tmp}/./h.png', {},
        'named for two outputs of this command'),
}


@pytest.mark.parametrize('case', list(REFUSED))
def test_an_output_that_is_an_input_or_no_file_is_refused_with_exit_2_and_nothing_changed(
        case, place, capsys, no_work):
    line, links, fragment = REFUSED[case]
    for name, how in links.items():
        if how == 'mkdir':
            (place / name).mkdir()
        elif how.startswith('hard:'):
            os.link(place / how[5:], place / name)
        else:
            (place / name).symlink_to(place / how[5:])
    names = {'tmp': place, 'run': place / 'run', 'dir': place / 'dir',
             'scene': place / 'scene.yaml', 'spec': place / 'spec.yaml',
             'results': place / 'results.csv'}
    before = snapshot(place)
    proc = run(capsys, *line.format(**names).split())
    assert proc.returncode == 2, proc.stderr
    assert fragment in error_line(proc)
    assert snapshot(place) == before


def test_export_writes_nothing_through_a_link_planted_at_the_old_temporary(place, capsys):
    # the temporaries had fixed names (out.csv.tmp): a link there overwrote the user's file
    for name in ('out.csv.tmp', 'out.csv.json.tmp', 'out_events.csv.tmp'):
        (place / name).symlink_to(place / 'victim.txt')
    (place / 'out.csv').symlink_to(place / 'victim.txt')        # the output itself a link
    proc = run(capsys, 'export', place / 'run', '--csv', place / 'out.csv')
    assert proc.returncode == 0, proc.stderr
    assert (place / 'victim.txt').read_bytes() == b'years of work'
    for name in ('out.csv', 'out.csv.json', 'out_events.csv', 'out_events.csv.json'):
        assert (place / name).is_file() and not (place / name).is_symlink()


def test_plot_writes_the_file_it_names_and_prints(place, capsys):
    # a name without a suffix got '.png' appended by matplotlib while 'out' was printed
    proc = run(capsys, 'plot', place / 'run', '-o', place / 'out')
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(place / 'out')
    assert (place / 'out').read_bytes()[:8] == PNG_MAGIC
    assert not (place / 'out.png').exists()


def test_plot_replaces_an_output_link_without_writing_its_target(place, capsys):
    (place / 'p.png').symlink_to(place / 'victim.txt')
    proc = run(capsys, 'plot', place / 'run', '-o', place / 'p.png')
    assert proc.returncode == 0, proc.stderr
    assert (place / 'victim.txt').read_bytes() == b'years of work'
    assert (place / 'p.png').read_bytes()[:8] == PNG_MAGIC


def test_the_sweep_reruns_over_its_own_output_and_never_writes_through_links(place, capsys):
    out = place / 'o.csv'
    for name in ('o.csv.tmp', 'o.csv.json.tmp'):
        (place / name).symlink_to(place / 'victim.txt')
    for _ in range(2):                               # the README's commands rerun
        proc = run(capsys, 'sweep', place / 'spec.yaml', '-o', out, '--csv', '--workers', '1',
                   '--quiet')
        assert proc.returncode == 0, proc.stderr
    assert (place / 'victim.txt').read_bytes() == b'years of work'
    assert out.is_file() and '3 scenes' in proc.stdout


def test_recover_refuses_an_existing_output_with_exit_2(place, capsys):
    proc = run(capsys, 'recover', place / 'run', '-o', place / 'dir')
    assert proc.returncode == 2
    assert 'exists already, not overwriting' in error_line(proc)


def test_the_inputs_are_released_after_a_command(place, capsys, no_work):
    from crawler_sim.bag.files import check_output

    run(capsys, 'sweep', place / 'spec.yaml', '-o', place / 'spec.yaml')
    check_output(place / 'spec.yaml')                # no longer an input of anything
