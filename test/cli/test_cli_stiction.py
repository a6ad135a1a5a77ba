"""Stiction scenes (issue 40) through ``crawler-sim simulate``, ``--stiction-rule``, the bag of an
offline stiction run replayed bit for bit, and the scene keys' checks.

Expected numbers are STICTION.md s. 8, derived by hand there (and re-derived in the comments):
T3, the bang-bang inchworm: with stiction (Rule S) one body always holds, so the centre of mass
advances exactly the stroke's extension A tau^2 = 2.5 m per 6 s period; with kinetic friction
only the pair glides, 1.40625 m per half period, 2.8125 m per period. T2(a), the rigid pair
launched uphill at 1 m/s on tan(alpha) = 1/2: it stops at t_s = sqrt(5)/(1.8 g) after
X_s = sqrt(5)/(3.6 g) and holds (pull 3g/sqrt(5) within the static capacity 3.6g/sqrt(5));
kinetic only it slides back down at 0.2 g/sqrt(5): X(2) = X_s - 0.1 g/sqrt(5) (2 - t_s)^2.
"""
from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from crawler_sim import Crawler, cli
from crawler_sim.core.friction import RULES
from crawler_sim.core.scene import SceneError, load_scene, scene_from_dict, scene_to_dict

SCENES = Path(__file__).resolve().parents[2] / 'config' / 'scenes'
INCHWORM = SCENES / 'stiction_inchworm.yaml'
SLOPE = SCENES / 'stiction_slope_hold.yaml'
G = 9.81
T_S = math.sqrt(5) / (1.8 * G)
X_S = math.sqrt(5) / (3.6 * G)


def simulate_json(capsys, *args: str) -> dict:
    code = cli.main(['simulate', *args, '--json'])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


def test_the_inchworm_scene_advances_the_stroke_per_period_with_stiction(capsys):
    figures = simulate_json(capsys, str(INCHWORM))
    assert figures['displacement'] == pytest.approx(3 * 2.5, abs=1e-12)    # 18 s, 3 periods
    tr = load_scene(INCHWORM).simulate()
    X = tr.state_at([0.0, 6.0, 12.0, 18.0]).x.mean(axis=1)       # equal masses: X = mean
    np.testing.assert_allclose(X - X[0], [0.0, 2.5, 5.0, 7.5], rtol=0, atol=1e-12)


def test_simulate_reports_the_rule_and_the_instants_where_it_chose(capsys):
    # at t = 1 + 3k the stuck body's need flips to +1.5 N (l'' = -A): it holds (<= 2 N
    # static), and the kinetic continuation (break away, both slide) is consistent too (the
    # kinetic solution is always one, STICTION.md F2): two per period, 6 in 18 s. Elsewhere
    # one continuation only (t = 0: 6.5 N > 2 N rules out body 1 and the slide pattern's
    # a = 1.5 < 1.25 fails; at the dwells the pair at rest with no force stays at rest).
    figures = simulate_json(capsys, str(INCHWORM))
    assert figures['stiction_rule'] == 'incumbent' and figures['stiction_choices'] == 6
    code = cli.main(['simulate', str(INCHWORM)])
    assert code == 0
    assert 'rule incumbent, 6 instants where it chose' in capsys.readouterr().out
    assert 'stiction_rule' not in simulate_json(capsys, str(SCENES / 'bang_bang.yaml'),
                                                '--t-end', '1')


def test_the_inchworm_without_its_static_keys_glides_as_the_kinetic_crawler(tmp_path, capsys):
    data = yaml.safe_load(INCHWORM.read_text())
    for key in ('static_friction', 'static_friction_backward'):
        del data['scene']['crawler'][key]
    kinetic = tmp_path / 'kinetic.yaml'
    kinetic.write_text(yaml.safe_dump(data))
    figures = simulate_json(capsys, str(kinetic))
    assert figures['displacement'] == pytest.approx(3 * 2.8125, abs=1e-12)


def test_the_slope_scene_stops_uphill_and_holds(capsys):
    scene = load_scene(SLOPE)
    tr = scene.simulate()
    X = tr.state_at([0.0, T_S, 2.0]).x @ scene.crawler.masses / scene.crawler.total_mass
    assert X[1] - X[0] == pytest.approx(X_S, abs=1e-12)
    assert X[2] - X[0] == pytest.approx(X_S, abs=1e-12)        # held: not a nanometre back
    stops = [e for e in tr.events if e.new == 0]
    assert [e.time for e in stops] == pytest.approx([T_S, T_S], abs=1e-12)
    kinetic = replace(scene, crawler=Crawler(scene.crawler.masses, mu=[0.5, 0.35],
                                             slope=scene.crawler.slope))
    Xk = kinetic.simulate().state_at([0.0, 2.0]).x @ scene.crawler.masses / 3.0
    assert Xk[1] - Xk[0] == pytest.approx(X_S - 0.1 * G / math.sqrt(5) * (2 - T_S) ** 2,
                                          abs=1e-12)
    assert simulate_json(capsys, str(SLOPE))['displacement'] == pytest.approx(X_S, abs=1e-12)


def test_the_cli_rules_are_the_cores():
    assert cli.RULES == RULES


def test_the_stiction_rule_flag_reaches_the_run(capsys, monkeypatch):
    import crawler_sim.core.scene as scene_mod
    seen = []
    real = scene_mod.simulate

    def spy(*args, **kwargs):
        seen.append(kwargs.get('stiction_rule'))
        return real(*args, **kwargs)
    monkeypatch.setattr(scene_mod, 'simulate', spy)
    simulate_json(capsys, str(INCHWORM), '--stiction-rule', 'margin', '--t-end', '6')
    assert seen == ['margin']
    code = cli.main(['simulate', str(INCHWORM), '--stiction-rule', 'sticky'])
    assert code == 2 and 'invalid choice' in capsys.readouterr().err


def test_an_offline_stiction_run_replays_bit_for_bit_from_its_bag(tmp_path, capsys):
    out = tmp_path / 'worm'
    simulate_json(capsys, str(INCHWORM), '--out', str(out), '--t-end', '12')
    code = cli.main(['replay', str(out), '--tol', '1e-300'])
    assert code == 0, capsys.readouterr()
    from crawler_sim import bag
    res = cli._replay(bag.load(out), None, 0.0)
    assert res['max_position_error'] == 0.0 and res['max_velocity_error'] == 0.0
    # the bag holds the static bounds: the crawler comes back with its stiction
    again = scene_from_dict({k: v for k, v in bag.load(out).scene.items()
                             if k in ('name', 'description', 'crawler', 'gait', 'run')})
    np.testing.assert_array_equal(again.crawler.static_friction, [2.0, 2.0])
    np.testing.assert_array_equal(again.crawler.static_friction_backward, [5.0, 5.0])


def test_a_scene_round_trips_its_static_bounds_and_rule_bit_for_bit():
    scene = load_scene(SLOPE).with_run(stiction_rule='margin')
    again = scene_from_dict(yaml.safe_load(yaml.safe_dump(scene_to_dict(scene))))
    for name in ('friction', 'friction_backward', 'static_friction',
                 'static_friction_backward'):
        np.testing.assert_array_equal(getattr(again.crawler, name),
                                      getattr(scene.crawler, name))
    assert again.run.stiction_rule == 'margin'


def base(**crawler) -> dict:
    return {'crawler': {'masses': [1.0, 1.0], **crawler},
            'gait': {'type': 'sinusoid', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0},
            'run': {'t_end': 1.0}}


@pytest.mark.parametrize('crawler,run,named', [
    ({'mu': 0.3, 'mu_static': 0.2}, {}, 'scene.crawler.mu_static[0] must be >= mu[0]'),
    ({'mu': 0.3, 'mu_static': [0.5, 0.5, 0.5]}, {}, 'scene.crawler.mu_static: must have 1 or 2'),
    ({'mu': 0.3, 'mu_static': '.nan'}, {}, 'scene.crawler.mu_static'),
    ({'mu': 0.3, 'mu_static': 2e3}, {}, 'scene.crawler.mu_static[0]: must be in [0, 1000]'),
    ({'mu': 0.3, 'static_friction': 5.0}, {}, 'scene.crawler.static_friction goes with friction, not with mu'),
    ({'friction': 3.0, 'mu_static_backward': 0.5}, {},
     'scene.crawler.mu_static_backward goes with mu, not with friction'),
    ({'friction': 3.0, 'static_friction_backward': [4.0, 2.0]}, {},
     'scene.crawler.static_friction_backward[1] must be >= friction_backward[1]'),
    ({'mu': 0.3, 'mu_static': 0.5}, {'stiction_rule': 'first'},
     'scene.run.stiction_rule: unknown rule'),
    ({'mu': 0.3, 'mu_static': 0.5}, {'initial_stuck': 2},
     'scene.run.initial_stuck: must be null or a body index in [0, 1]'),
    ({'mu': 0.3, 'mu_static': 0.5}, {'initial_stuck': 1},
     'scene.run.initial_stuck: body 1 must be at rest'),
    ({'mu': 0.3, 'mu_static': 0.5}, {'method': 'penalty', 'penalty': 1e4},
     "scene.run.method: method 'penalty' cannot simulate static friction"),
])
def test_bad_stiction_keys_give_one_line_naming_the_field(crawler, run, named):
    data = base(**crawler)
    if crawler.get('mu_static') == '.nan':
        data['crawler']['mu_static'] = math.nan
    data['run'].update(run)
    with pytest.raises(SceneError) as info:
        scene_from_dict(data)
    assert named in str(info.value)
    assert '\n' not in str(info.value)
