"""Sizes checked before the work that depends on them (issue 38, item 5): bodies, entries and
file sizes of scenes (simulate, optimize, a sweep's base), the numbers of bodies a sweep spec
can give, and optimize's settings. Each is refused in one line naming the field and its range,
exit 2, before anything is allocated by it (the work that would follow is made to fail the
test if it is reached)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from crawler_sim import cli
from crawler_sim.core.scene import (MAX_ENTRIES, MAX_SCENE_BODIES, MAX_SCENE_BYTES, SceneError,
                                    scene_from_dict)
from crawler_sim.sweep import optimize as opt
from crawler_sim.sweep import spec_from_dict

GAIT = {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0, 'asymmetry': 0.3}


def scene_file(tmp_path: Path, bodies: int, gait: dict | None = None) -> Path:
    path = tmp_path / f'b{bodies}.yaml'
    masses = '[' + ','.join(['1'] * bodies) + ']'
    path.write_text(f'scene:\n  crawler:\n    masses: {masses}\n    mu: 0.3\n'
                    f'  gait: {json.dumps(gait or GAIT)}\n')
    return path


def errors(capsys) -> list[str]:
    return [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith('crawler-sim:')
            and 'error' in ln]


@pytest.fixture
def no_work(monkeypatch):
    """The optimiser's allocations (the plant, the search's population) fail the test if they
    are reached."""
    import scipy.optimize

    def reached(*args, **kw):
        raise AssertionError('work started before the sizes were checked')
    monkeypatch.setattr(opt, 'plant_for', reached)
    monkeypatch.setattr(scipy.optimize, 'differential_evolution', reached)


def test_a_scene_file_of_a_million_bodies_is_refused_by_its_size_before_parsing(tmp_path,
                                                                                 capsys):
    path = scene_file(tmp_path, 1_000_000)               # 2 MB: 51 s and 790 MB to parse
    before = path.read_bytes()
    assert cli.main(['optimize', str(path), '-o', str(tmp_path / 'best.yaml')]) == 2
    assert errors(capsys) == [f'crawler-sim: error: {path}: a scene file must have at most '
                              f'{MAX_SCENE_BYTES} bytes, got more']
    assert path.read_bytes() == before and not (tmp_path / 'best.yaml').exists()


@pytest.mark.parametrize('command', ['simulate', 'optimize'])
def test_more_bodies_than_a_scene_may_have_are_refused_naming_the_limit(tmp_path, capsys,
                                                                         no_work, command):
    path = scene_file(tmp_path, 50_000)                  # 100 kB: within the file size
    args = [command, str(path)] + (['-o', str(tmp_path / 'best.yaml')]
                                   if command == 'optimize' else [])
    assert cli.main(args) == 2
    assert errors(capsys) == [f'crawler-sim: error: {path}: scene.crawler.masses: must list 2 '
                              f'to {MAX_SCENE_BODIES} bodies, got 50000']


def test_optimize_scored_as_the_node_refuses_more_bodies_than_sim_node_takes_before_work(
        tmp_path, capsys, no_work):
    path = scene_file(tmp_path, 1000)
    assert cli.main(['optimize', str(path), '-o', str(tmp_path / 'best.yaml')]) == 2
    [line] = errors(capsys)
    assert 'scene.crawler.masses: scored as the node runs it, the crawler must have 2 to 64 ' \
           'bodies' in line and 'got 1000' in line


@pytest.mark.parametrize('settings, message', [
    (dict(family_name='fourier', harmonics=3), 'fourier family: 234 parameters for 40 bodies '
                                               'and 3 harmonics; allowed 1 to 200'),
    (dict(popsize=10**9), 'popsize: must be an integer from 1 to 1000, got 1000000000'),
    (dict(family_name='fourier', harmonics=1, popsize=1000),
     'popsize: popsize x parameters must be from 1 to 10000 (strokes per generation), got '
     '1000 x 78 = 78000'),
    (dict(maxiter=-1), 'maxiter: must be an integer from 0 to 10000, got -1'),
    (dict(periods=10**12), 'periods: must be an integer from 4 to 10000'),
    (dict(harmonics=10**6), 'harmonics: must be an integer from 1 to 32'),
    (dict(workers=0), 'workers: must be an integer from 1 to 1024, got 0'),
])
def test_optimize_settings_out_of_range_are_refused_before_anything_is_built(no_work,
                                                                              settings,
                                                                              message):
    base = scene_from_dict({'crawler': {'masses': [1.0] * 40, 'mu': 0.3}, 'gait': GAIT})
    with pytest.raises(opt.OptimizeError, match='^' + message.replace('(', r'\(')
                       .replace(')', r'\)')):
        opt.optimize(base, **{'score': 'ideal', **settings})


def test_optimize_settings_on_the_command_line_are_exit_2(tmp_path, capsys, no_work):
    path = scene_file(tmp_path, 2)
    assert cli.main(['optimize', str(path), '--popsize', '100000', '-o',
                     str(tmp_path / 'best.yaml')]) == 2
    assert errors(capsys) == ['crawler-sim: error: popsize: must be an integer from 1 to 1000, '
                              'got 100000']


def test_a_gait_table_of_nested_aliases_is_refused_at_the_entry_limit_not_walked():
    table: list = [0.01] * 10
    for _ in range(9):                    # 10^10 numbers if walked: a YAML alias bomb's shape
        table = [table] * 10
    with pytest.raises(SceneError, match=f'scene.gait.coefficients: must have at most '
                       f'{MAX_ENTRIES} entries'):
        scene_from_dict({'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
                         'gait': {'type': 'fourier', 'mean': 0.1, 'frequency': 1.0,
                                  'coefficients': table}})


SWEEP = {'base': {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3}, 'gait': GAIT}}


@pytest.mark.parametrize('params, message', [
    ({'grid': {'bodies': [2, 1_000_000_000]}},
     'sweep.grid.bodies: numbers of bodies must be integers from 2 to 1000, got 1000000000'),
    ({'grid': {'bodies': [2, 2.5]}},
     'sweep.grid.bodies: numbers of bodies must be integers from 2 to 1000, got 2.5'),
    ({'random': {'n': 3, 'params': {'bodies': {'integers': [2, 10**9]}}}},
     'sweep.random.params.bodies.integers: numbers of bodies must be integers from 2 to 1000'),
    ({'random': {'n': 3, 'params': {'bodies': {'choice': [3, 5000]}}}},
     'sweep.random.params.bodies.choice: numbers of bodies must be integers from 2 to 1000'),
    ({'random': {'n': 3, 'params': {'bodies': {'uniform': [2, 5]}}}},
     r'sweep.random.params.bodies: must be \{integers: \[a, b\]\} or \{choice: \[...\]\}'),
])
def test_a_sweep_that_could_give_too_many_bodies_is_refused_when_read(params, message):
    with pytest.raises(ValueError, match='^' + message):
        spec_from_dict({**SWEEP, **params})



@pytest.mark.parametrize('extra, refused', [(0, False), (1, True)])
def test_the_entry_limit_counts_each_number_and_row_once(monkeypatch, extra, refused):
    from crawler_sim.core import scene as scene_module
    monkeypatch.setattr(scene_module, 'MAX_ENTRIES', 100)
    # coefficients [cos, sin] of one linkage and k harmonics: 2 + 2 + 2 k entries
    k = (100 - 4) // 2 + extra
    gait = {'type': 'fourier', 'mean': 0.1, 'frequency': 1.0,
            'coefficients': [[[0.001] * k], [[0.0] * k]]}
    try:
        scene_from_dict({'crawler': {'masses': [1.0, 1.0], 'mu': 0.3}, 'gait': gait})
        message = ''
    except SceneError as exc:
        message = str(exc)
    assert message == ('scene.gait.coefficients: must have at most 100 entries (its numbers '
                       'and rows, each use of a YAML alias counted)' if refused else ''), message
