"""Sweep specs: grids, random samples, parameter paths, and one-line errors naming the field."""
from __future__ import annotations

import numpy as np
import pytest

from crawler_sim.sweep import SpecError, load_spec, spec_from_dict
from crawler_sim.sweep.spec import apply_params

BASE = {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
        'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                 'asymmetry': 0.5}}


def spec(**kw):
    return spec_from_dict({'base': BASE, **kw})


def test_a_grid_is_every_combination_in_order_with_linspace_ends_included():
    s = spec(grid={'crawler.mu': [0.2, 0.4], 'gait.asymmetry': {'linspace': [0.1, 0.9, 5]}})
    sets = list(s.param_sets())
    assert len(s) == len(sets) == 10
    # the last axis varies fastest (itertools.product order); linspace steps of 0.2 by hand
    assert [p['gait.asymmetry'] for p in sets[:5]] == pytest.approx([0.1, 0.3, 0.5, 0.7, 0.9])
    assert [p['crawler.mu'] for p in sets[::5]] == [0.2, 0.4]


def test_a_logspace_axis_has_constant_ratios_between_its_given_ends():
    s = spec(grid={'gait.frequency': {'logspace': [0.5, 8.0, 5]}})
    f = np.array([p['gait.frequency'] for p in s.param_sets()])
    assert f == pytest.approx([0.5, 1.0, 2.0, 4.0, 8.0])


def test_random_draws_repeat_with_the_seed_stay_in_range_and_change_with_another_seed():
    params = {'crawler.mu': {'uniform': [0.1, 0.5]}, 'gait.frequency': {'loguniform': [1, 4]},
              'bodies': {'integers': [2, 4]}, 'gait.type': {'choice': ['scallop', 'stroke']}}
    a = list(spec(random={'n': 200, 'seed': 3, 'params': params}).param_sets())
    b = list(spec(random={'n': 200, 'seed': 3, 'params': params}).param_sets())
    c = list(spec(random={'n': 200, 'seed': 4, 'params': params}).param_sets())
    assert a == b and a != c and len(a) == 200
    assert all(0.1 <= p['crawler.mu'] <= 0.5 and 1 <= p['gait.frequency'] <= 4 for p in a)
    assert {p['bodies'] for p in a} == {2, 3, 4}       # both ends included
    assert {p['gait.type'] for p in a} == {'scallop', 'stroke'}


def test_bodies_repeats_the_first_mass_and_an_indexed_path_sets_one_entry():
    scene = apply_params({'crawler': {'masses': [2.0, 1.0], 'mu': [0.3, 0.4]}, 'gait': {}},
                         {'bodies': 4, 'crawler.mu[2]': 0.9})
    assert scene['crawler']['masses'] == [2.0] * 4
    assert scene['crawler']['mu'] == [0.3, 0.3, 0.9, 0.3]


def test_the_spec_round_trips_through_plain_data():
    s = spec(grid={'gait.asymmetry': {'linspace': [0.2, 0.8, 4]}}, periods=10)
    again = spec_from_dict(s.to_dict())
    assert again == s and list(again.param_sets()) == list(s.param_sets())


@pytest.mark.parametrize('bad, fragment', [
    ({'grid': {'gait.asymmetry': {'linspace': [0.1, 0.9]}}}, 'sweep.grid.gait.asymmetry.linspace'),
    ({'grid': {'gait.frequency': {'logspace': [0.0, 1.0, 3]}}}, '0 < a <= b'),
    ({'grid': {'mass': [1, 2]}}, 'dotted path'),
    ({'grid': {'gait.asymmetry': []}}, 'non-empty list'),
    ({'random': {'n': 0, 'seed': 0, 'params': {'crawler.mu': {'uniform': [0, 1]}}}},
     'sweep.random.n: must be an integer from 1 to'),
    ({'random': {'n': 5, 'seed': 0, 'params': {'crawler.mu': {'normal': [0, 1]}}}},
     'sweep.random.params.crawler.mu'),
    ({'grid': {'crawler.mu': [0.1]}, 'random': {'n': 1, 'seed': 0, 'params': {}}},
     'grid or random, not both'),
    ({'periods': 2}, 'sweep.periods: must be an integer from 4 to'),
    ({'grid': {'gait.asymmetry': [1.5]}}, 'asymmetry'),
    ({'grid': {'crawler.masses[1]': [-1.0]}}, 'scene.crawler.masses[1]'),
    ({'colour': 'red'}, "unknown key 'colour'"),
])
def test_a_bad_spec_is_refused_with_a_message_naming_the_field(bad, fragment):
    with pytest.raises(SpecError, match=None) as info:
        spec(**bad)
    assert fragment in str(info.value)
    assert '\n' not in str(info.value)


def test_a_spec_over_a_non_periodic_gait_is_refused():
    base = dict(BASE, gait={'type': 'spline', 'times': [0, 1, 2], 'lengths': [0.1, 0.12, 0.1]})
    with pytest.raises(SpecError, match='periodic'):
        spec_from_dict({'base': base})


def test_a_spec_file_is_read_and_a_missing_key_names_the_file(tmp_path):
    good = tmp_path / 'good.yaml'
    good.write_text('sweep:\n  base:\n    crawler: {masses: [1.0, 1.0], mu: 0.3}\n'
                    '    gait: {type: sinusoid, mean: 0.1, amplitude: 0.01, frequency: 1}\n'
                    '  grid: {gait.amplitude: [1e-3, 2e-2]}\n')
    s = load_spec(good)
    assert s.name == 'good' and len(s) == 2
    bad = tmp_path / 'bad.yaml'
    bad.write_text('scene: {}\n')
    with pytest.raises(SpecError, match='bad.yaml: not a sweep file'):
        load_spec(bad)


RANDOM = {'crawler.mu': {'uniform': [0.1, 0.5]}, 'bodies': {'integers': [2, 4]},
          'gait.type': {'choice': ['scallop', 'stroke']}}


def test_random_scene_k_draws_from_the_kth_child_of_the_seed_sequence():
    s = spec(random={'n': 40, 'seed': 11, 'params': {'crawler.mu': {'uniform': [0.1, 0.5]}}})
    children = np.random.SeedSequence(11).spawn(40)       # numpy's own way to split a seed
    expected = [np.random.Generator(np.random.PCG64(c)).uniform(0.1, 0.5) for c in children]
    assert [p['crawler.mu'] for p in s.param_sets()] == expected


@pytest.mark.parametrize('chunk_size', [1, 7, 250])
def test_the_scenes_do_not_depend_on_the_chunk_size(chunk_size):
    from crawler_sim.sweep.runner import chunk_params, n_chunks
    reference = list(spec(random={'n': 300, 'seed': 2, 'params': RANDOM}).param_sets())
    s = spec(random={'n': 300, 'seed': 2, 'params': RANDOM}, chunk_size=chunk_size)
    planned = [p for i in range(n_chunks(s)) for p in chunk_params(s, i)]
    assert planned == reference
    assert len({(p['crawler.mu'], p['bodies']) for p in planned}) == 300   # no repeated scene


class Budget:
    """Counts calls of a function and fails past ``limit``: a chunk that enumerated the scenes
    before it would call it billions of times, so it stops there instead of running for hours."""

    def __init__(self, fn, limit: int) -> None:
        self.fn, self.limit, self.calls = fn, limit, 0

    def __call__(self, *args):
        self.calls += 1
        assert self.calls <= self.limit, 'more calls than the chunk needs: scenes enumerated'
        return self.fn(*args)


def test_the_last_chunk_of_a_billion_random_scenes_is_planned_from_its_own_scenes(monkeypatch):
    from crawler_sim.sweep import spec as spec_module
    from crawler_sim.sweep.runner import chunk_params, n_chunks
    s = spec(random={'n': 10**9, 'seed': 5, 'params': RANDOM}, chunk_size=100)
    budget = Budget(spec_module._draw, 100 * len(RANDOM))
    monkeypatch.setattr(spec_module, '_draw', budget)
    last = chunk_params(s, n_chunks(s) - 1)
    assert len(last) == 100 and budget.calls == 100 * len(RANDOM)
    monkeypatch.undo()
    assert chunk_params(s, n_chunks(s) - 1) == last          # the same scenes every time
    assert last[-1] == s.param_set(10**9 - 1) != s.param_set(10**9 - 2)


def test_scene_k_of_a_billion_scene_grid_is_the_kth_combination(monkeypatch):
    from crawler_sim.sweep import spec as spec_module
    from crawler_sim.sweep.runner import chunk_params
    s = spec(grid={'crawler.mu': {'linspace': [0.1, 0.5, 1000]},
                   'gait.asymmetry': {'linspace': [0.1, 0.9, 1000]},
                   'gait.amplitude': {'logspace': [0.01, 0.03, 1000]}}, chunk_size=9)
    mu, r = np.linspace(0.1, 0.5, 1000), np.linspace(0.1, 0.9, 1000)
    a = np.geomspace(0.01, 0.03, 1000)
    budget = Budget(spec_module._plain, 9 * 3)
    monkeypatch.setattr(spec_module, '_plain', budget)
    # scene 123456789 = 9 * 13717421 starts a chunk; its digits with the last axis fastest are
    # (123, 456, 789)
    chunk = chunk_params(s, 13717421)
    monkeypatch.undo()
    assert len(chunk) == 9 and budget.calls == 9 * 3
    assert chunk[0] == {'crawler.mu': mu[123], 'gait.asymmetry': r[456],
                        'gait.amplitude': a[789]}
    assert s.param_set(10**9 - 1) == {'crawler.mu': 0.5, 'gait.asymmetry': 0.9,
                                      'gait.amplitude': 0.03}
    with pytest.raises(IndexError):
        s.param_set(10**9)
