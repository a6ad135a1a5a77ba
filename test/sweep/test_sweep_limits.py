"""Hostile sweep specs: alias bombs, huge grids and samples, oversize files; each is refused with
one line naming the field and the allowed range, before anything is expanded.

The bombs below expand to about 3e11 values (9 ** 12): a loader or a check that expanded them
would run for hours or run out of memory, so a refusal at all shows it came before expansion.
"""
from __future__ import annotations

import tracemalloc

import pytest

from crawler_sim import cli
from crawler_sim.sweep import SpecError, load_spec, spec_from_dict
from crawler_sim.sweep.spec import LIMITS

BASE_YAML = ('  base:\n'
             '    crawler: {masses: [1.0, 1.0], mu: 0.3}\n'
             '    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 1.0, '
             'asymmetry: 0.5}\n')
BASE = {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
        'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                 'asymmetry': 0.5}}
LEVELS = 12      # 9 ** 12 = 2.8e11 values once expanded


def laughs(levels: int = LEVELS) -> str:
    """A flow sequence whose last entry expands to 9 ** levels strings ("billion laughs")."""
    parts = ['&l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]']
    parts += [f'&l{k} [' + ', '.join([f'*l{k - 1}'] * 9) + ']' for k in range(1, levels)]
    return '[' + ', '.join(parts) + ']'


def merges(levels: int = LEVELS) -> str:
    """Mappings each merging the previous one 9 times (``<<``): merges count like aliases
    (PyYAML releases before 6.0.4 copied merged keys once per use, 9-fold per level, inside
    the constructor itself; the check runs before the constructor)."""
    parts = ['&m0 {a: 1, b: 2, c: 3}']
    parts += [f'&m{k} {{<<: [' + ', '.join([f'*m{k - 1}'] * 9) + f'], k{k}: 0}}'
              for k in range(1, levels)]
    return '[' + ', '.join(parts) + ']'


BOMBS = [   # (where the bomb is, the spec's lines after the base scene)
    ('sweep.description', f'  description: {laughs()}\n  grid: {{gait.asymmetry: [0.3]}}\n'),
    ('sweep.name', f'  name: {laughs()}\n'),
    ('sweep.grid.crawler.masses', f'  grid: {{crawler.masses: [[1.0, 1.0], {laughs()}]}}\n'),
    ('sweep.random.params.gait.type.choice',
     f'  random: {{n: 3, seed: 0, params: {{gait.type: {{choice: {laughs()}}}}}}}\n'),
    ('sweep.base.run.x', '  grid: {gait.asymmetry: [0.3]}\n'),    # the bomb is in the base
    ('sweep.description', f'  description: {merges()}\n'),
]


def write(tmp_path, body: str, name: str = 'spec.yaml'):
    path = tmp_path / name
    path.write_text('sweep:\n' + body)
    return path


def refused(call) -> str:
    with pytest.raises(SpecError) as info:
        call()
    message = str(info.value)
    assert '\n' not in message
    return message


@pytest.mark.parametrize('field, lines', BOMBS, ids=['laughs-description', 'laughs-name',
                                                   'laughs-grid', 'laughs-choice', 'laughs-base',
                                                   'merges-description'])
def test_an_alias_bomb_is_refused_naming_its_field_with_memory_bounded(tmp_path, field, lines):
    base = BASE_YAML
    if field.startswith('sweep.base'):
        base = base.replace('  base:\n', f'  base:\n    run: {{x: {laughs()}}}\n')
    path = write(tmp_path, base + lines)
    tracemalloc.start()
    try:
        message = refused(lambda: load_spec(path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert message.startswith(f'{path}: {field}: expands to more than')
    assert f'allowed 1 to {LIMITS["values"]}' in message
    # expanded, the bomb is some 1e11 objects; refused, a few megabytes at most
    assert peak < 20e6


def test_a_bomb_built_in_python_from_shared_lists_is_refused_too():
    bomb: list = [1.0, 1.0]
    for _ in range(LEVELS):
        bomb = [bomb] * 9         # one list object per level, 9 ** 12 leaves when expanded
    message = refused(lambda: spec_from_dict({'base': BASE,
                                              'grid': {'crawler.masses': [[1.0, 1.0], bomb]}}))
    assert message.startswith('sweep.grid.crawler.masses: expands to more than')


def test_a_spec_that_contains_itself_is_refused(tmp_path):
    path = write(tmp_path, BASE_YAML + '  description: &me [a, *me]\n')
    message = refused(lambda: load_spec(path))
    assert 'sweep.description: contains itself' in message


def test_a_spec_nested_too_deeply_is_refused(tmp_path):
    deep = '[' * 40 + ']' * 40
    path = write(tmp_path, BASE_YAML + f'  description: {deep}\n')
    message = refused(lambda: load_spec(path))
    assert 'sweep.description' in message and f'allowed 1 to {LIMITS["depth"]}' in message


def test_a_spec_file_over_the_size_limit_is_refused_before_it_is_parsed(tmp_path):
    # a valid spec padded with a comment: refused for its size alone
    path = write(tmp_path, BASE_YAML + '# ' + 'x' * LIMITS['file_bytes'] + '\n')
    message = refused(lambda: load_spec(path))
    assert str(path) in message and f'at most {LIMITS["file_bytes"]} bytes' in message
    # a file without an end: read no further than the limit
    message = refused(lambda: load_spec('/dev/zero'))
    assert message.startswith('/dev/zero: a sweep spec file must have at most')


@pytest.mark.parametrize('kw, fragment', [
    # 1e15 scenes from five axes of a thousand values
    ({'grid': {p: {'linspace': [0.1, 0.2, 1000]} for p in
               ('crawler.mu', 'crawler.slope_deg', 'gait.asymmetry', 'gait.amplitude',
                'gait.frequency')}},
     f'sweep.grid: must give 1 to {LIMITS["scenes"]} scenes'),
    # n = 1e15 points: numpy could not even allocate them, so this shows no expansion happens
    ({'grid': {'gait.asymmetry': {'linspace': [0.1, 0.9, 10**15]}}},
     f'sweep.grid.gait.asymmetry.linspace: n must be from 1 to {LIMITS["axis"]}'),
    ({'grid': {'gait.asymmetry': [0.5] * (LIMITS['axis'] + 1)}},
     f'sweep.grid.gait.asymmetry: must have 1 to {LIMITS["axis"]} values'),
    ({'random': {'n': 10**10, 'seed': 0, 'params': {'crawler.mu': {'uniform': [0.1, 0.5]}}}},
     f'sweep.random.n: must be an integer from 1 to {LIMITS["scenes"]}, got 10000000000'),
    ({'random': {'n': 5, 'seed': 0,
                 'params': {'gait.type': {'choice': ['scallop'] * (LIMITS['axis'] + 1)}}}},
     f'sweep.random.params.gait.type.choice: must be a list of 1 to {LIMITS["axis"]} values'),
    ({'random': {'n': 5, 'seed': -1, 'params': {'crawler.mu': {'uniform': [0.1, 0.5]}}}},
     'sweep.random.seed: must be an integer from 0 to'),
    ({'periods': 10**6}, f'sweep.periods: must be an integer from 4 to {LIMITS["periods"]}'),
    ({'periods': 5000, 'samples_per_period': 5000},
     f'sweep.samples_per_period: periods x samples_per_period must be from 16 to '
     f'{LIMITS["samples"]}'),
    ({'chunk_size': 10**9}, f'sweep.chunk_size: must be an integer from 1 to '
                            f'{LIMITS["chunk_size"]}'),
    ({'name': '../../etc/x'}, 'sweep.name: must be a string of 1 to'),
    ({'name': 'n' * 1000}, 'sweep.name: must be a string of 1 to'),
    ({'description': ['not', 'text']}, 'sweep.description: must be a string'),
    ({'description': 'x' * (LIMITS['text'] + 1)}, 'sweep: expands to more than'),
])
def test_a_spec_over_a_size_limit_is_refused_naming_the_field_and_the_range(kw, fragment):
    message = refused(lambda: spec_from_dict({'base': BASE, **kw}))
    assert message.startswith(fragment)
    assert len(message) < 400            # a value in the message is shown shortened


def test_specs_at_the_limits_are_accepted():
    side = {'linspace': [0.1, 0.9, 1000]}
    big = spec_from_dict({'base': BASE, 'grid': {'crawler.mu': side, 'gait.asymmetry': side,
                                                 'gait.amplitude': {'linspace': [0.01, 0.03,
                                                                                 1000]}}})
    assert len(big) == LIMITS['scenes']
    axis = spec_from_dict({'base': BASE, 'grid': {'gait.asymmetry': {
        'linspace': [0.1, 0.9, LIMITS['axis']]}}})
    assert len(axis) == LIMITS['axis']
    sample = spec_from_dict({'base': BASE, 'random': {'n': LIMITS['scenes'], 'seed': 2**64 - 1,
                                                      'params': {'crawler.mu': {
                                                          'uniform': [0.1, 0.5]}}}})
    assert len(sample) == LIMITS['scenes']


def test_aliases_within_the_limits_still_work(tmp_path):
    path = write(tmp_path, BASE_YAML + '  grid:\n    gait.asymmetry: &r [0.2, 0.8]\n'
                                      '    crawler.mu: *r\n')
    assert len(load_spec(path)) == 4


def test_the_sweep_command_refuses_a_bomb_with_one_line_and_exit_2(tmp_path, capsys):
    path = write(tmp_path, BASE_YAML + BOMBS[2][1])
    code = cli.main(['sweep', str(path), '-o', str(tmp_path / 'out.parquet'), '--quiet'])
    err = capsys.readouterr().err
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.startswith('crawler-sim: error:')]
    assert len(lines) == 1 and 'sweep.grid.crawler.masses: expands to more than' in lines[0]
    assert not (tmp_path / 'out.parquet').exists()
