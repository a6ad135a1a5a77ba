"""The static bounds and the stiction rule as sweep axes (issue 40).

Expected numbers are hand-derived in STICTION.md s. 8 and re-derived here:
T3 (the bang-bang inchworm, period 6 s, extension A tau^2 = 2.5 m): with stiction one body always
holds, so the centre of mass advances 2.5 m per period; kinetic only it glides, 2.8125 m.
T5 (two bodies at a stroke reversal, body 0 stuck before t = 1): Rule S 'incumbent' keeps body 0
anchored for ever (stick fractions 1 and 0), 'margin' anchors body 1 from t = 1 on (0 and 1).
Every body slides its share of the stroke at its kinetic force: the stroke's total variation is
1 m per period (|l'| = 0.5 |1 - t| on each quarter: 4 x 0.25 m), at 1 N: 1 J per period.
"""
from __future__ import annotations

import pytest

from crawler_sim.sweep import spec_from_dict, sweep
from crawler_sim.sweep.spec import apply_params

#: T3: two 1 kg bodies, kinetic 1 N forward / 4 N backward
INCHWORM = {'crawler': {'masses': [1.0, 1.0], 'friction': 1.0, 'friction_backward': 4.0,
                        'static_friction': 1.0, 'static_friction_backward': 4.0},
            'gait': {'type': 'piecewise_parabolic', 'times': [0, 1, 2, 3, 4, 5, 6],
                     'accelerations': [2.5, -2.5, 0.0, -2.5, 2.5, 0.0], 'l0': 0.5}}
#: T5: body 0 kinetic 1 N / static 2 N, body 1 kinetic 1 N / static 2.5 N, isotropic;
#: l'' = +0.5 on [0, 2), -0.5 on [2, 4), l'(0) = -0.5; body 0 at rest at t = 0
REVERSAL = {'crawler': {'masses': [1.0, 1.0], 'friction': 1.0, 'static_friction': [2.0, 2.5]},
            'gait': {'type': 'piecewise_parabolic', 'times': [0, 2, 4],
                     'accelerations': [0.5, -0.5], 'l0': 1.0, 'v0': -0.5}}


def test_static_bounds_as_grid_axes_change_the_crawl_as_derived_by_hand():
    df = sweep({'name': 'stiction_grid', 'base': INCHWORM, 'periods': 4,
                'samples_per_period': 24,
                'grid': {'crawler.static_friction': [1.0, 2.0],
                         'crawler.static_friction_backward': [4.0, 5.0]}}, workers=1)
    assert (df['error'] == '').all(), df['error'].tolist()
    kinetic = df[(df['crawler.static_friction'] == 1.0)
                 & (df['crawler.static_friction_backward'] == 4.0)].iloc[0]
    stiction = df[(df['crawler.static_friction'] == 2.0)
                  & (df['crawler.static_friction_backward'] == 5.0)].iloc[0]
    assert kinetic['displacement_per_period'] == pytest.approx(2.8125, abs=1e-12)
    assert stiction['displacement_per_period'] == pytest.approx(2.5, abs=1e-12)
    assert stiction['mean_speed'] == pytest.approx(2.5 / 6, abs=1e-12)


def test_the_stiction_rule_is_an_axis_that_reaches_the_run():
    df = sweep({'name': 'rules', 'base': REVERSAL, 'periods': 4, 'samples_per_period': 40,
                'grid': {'run.stiction_rule': ['incumbent', 'margin']}}, workers=1)
    assert (df['error'] == '').all(), df['error'].tolist()
    inc, mar = (df[df['run.stiction_rule'] == r].iloc[0] for r in ('incumbent', 'margin'))
    assert (inc['stick_fraction_0'], inc['stick_fraction_1']) == pytest.approx((1.0, 0.0),
                                                                             abs=1e-12)
    assert (mar['stick_fraction_0'], mar['stick_fraction_1']) == pytest.approx((0.0, 1.0),
                                                                             abs=1e-12)
    for row in (inc, mar):             # the slider dissipates 1 N x 1 m per period
        assert row['dissipated_energy'] == pytest.approx(1.0, abs=1e-12)
        assert row['mean_speed'] == pytest.approx(0.0, abs=1e-12)


def test_bodies_repeats_the_static_bounds_and_an_entry_expands_a_scalar():
    base = {**INCHWORM, 'crawler': {'masses': [1.0, 2.0], 'mu': [0.3, 0.4],
                                    'mu_static': [0.5, 0.6], 'mu_static_backward': 0.7}}
    scene = apply_params(base, {'bodies': 3})
    assert scene['crawler']['masses'] == [1.0, 1.0, 1.0]
    assert scene['crawler']['mu_static'] == 0.5 and scene['crawler']['mu'] == 0.3
    scene = apply_params(base, {'crawler.mu_static_backward[1]': 0.9})
    assert scene['crawler']['mu_static_backward'] == [0.7, 0.9]


def test_a_static_bound_below_its_kinetic_one_is_a_row_naming_it_not_a_lost_sweep():
    df = sweep({'name': 'low', 'base': INCHWORM, 'periods': 4, 'samples_per_period': 12,
                'grid': {'crawler.static_friction_backward': [5.0, 3.0]}}, workers=1)
    assert df.loc[0, 'error'] == ''
    assert df.loc[1, 'error'].startswith('SceneError')
    assert 'static_friction_backward[0] must be >= friction_backward[0]' in df.loc[1, 'error']


def test_the_first_scene_of_a_spec_is_checked_when_it_is_read():
    from crawler_sim.sweep.spec import SpecError
    bad = {**INCHWORM, 'crawler': {**INCHWORM['crawler'], 'mu_static': 0.5}}
    with pytest.raises(SpecError, match='mu_static goes with mu, not with friction'):
        spec_from_dict({'name': 'mixed', 'base': bad, 'periods': 4,
                        'grid': {'crawler.gravity': [9.81]}})


def test_the_optimisers_plant_and_sim_node_file_carry_the_fixed_static_bounds_and_rule():
    """The crawler is what the optimiser keeps fixed: its static bounds and rule go into the
    plant it scores on and into the sim_node parameter file it writes, which rebuilds the
    same crawler bit for bit; a crawler without stiction writes no static key."""
    from crawler_sim.core.plant import PlantConfig
    from crawler_sim.core.scene import scene_from_dict
    from crawler_sim.sweep.optimize import optimize, sim_node_params
    gait = {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
            'asymmetry': 0.3}
    base = scene_from_dict({'crawler': {'masses': [1.0, 1.0], 'mu': 0.3, 'mu_static': 0.6,
                                        'mu_static_backward': 0.45},
                            'gait': gait, 'run': {'stiction_rule': 'margin'}})
    result = optimize(base, maxiter=0, local_maxiter=0, popsize=1, periods=4)
    assert result.plant.crawler.to_dict() == base.crawler.to_dict()
    assert result.plant.values['stiction_rule'] == 'margin'
    params = sim_node_params(result)['crawler_sim']['ros__parameters']
    again = PlantConfig.defaults(**params)
    for name in ('friction', 'friction_backward', 'static_friction',
                 'static_friction_backward'):
        assert getattr(again.crawler, name).tolist() == getattr(base.crawler, name).tolist()
    assert again.values['stiction_rule'] == 'margin'
    kinetic = scene_from_dict({'crawler': {'masses': [1.0, 1.0], 'mu': 0.3}, 'gait': gait})
    params = sim_node_params(optimize(kinetic, maxiter=0, local_maxiter=0, popsize=1,
                                      periods=4))['crawler_sim']['ros__parameters']
    assert not {'static_friction', 'static_friction_backward', 'stiction_rule'} & set(params)
