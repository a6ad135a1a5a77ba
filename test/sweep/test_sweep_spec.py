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
