"""Scenes: every shipped scene loads, runs and passes verify; bad scenes give one clear error."""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

import crawler_sim as cs
from crawler_sim.core.scene import (GAIT_TYPES, SceneError, load_scene, scene_from_dict,
                               scene_to_dict)

CONFIG = Path(__file__).resolve().parents[2] / 'config'
NAMED = ('scallop_2body', 'wave_3body', 'slope_climb', 'bang_bang')


def _is_scene_file(path: Path) -> bool:
    data = yaml.safe_load(path.read_text())
    return isinstance(data, dict) and 'scene' in data


SCENE_FILES = sorted(p for p in CONFIG.glob('scenes/*.yaml') if _is_scene_file(p)) + sorted(
    p for p in CONFIG.glob('bench/*.yaml') if _is_scene_file(p))


def _short(scene):
    """The scene cut to about three gait periods (at most its own t_end)."""
    period = scene.gait.period or 1.0
    return scene.with_run(t_end=min(scene.run.t_end, 3.0 * period))


def test_the_named_scenes_are_shipped_as_scene_files():
    names = {p.stem for p in SCENE_FILES}
    assert set(NAMED) <= names


@pytest.mark.parametrize('path', SCENE_FILES, ids=lambda p: str(p.relative_to(CONFIG)))
def test_every_scene_file_loads_runs_and_passes_verify(path):
    scene = _short(load_scene(path))
    tr = scene.simulate()
    assert tr.t[-1] == pytest.approx(scene.run.t_end)
    assert tr.x.shape == (len(tr), scene.crawler.p)
    if scene.run.method == 'exact':
        # with the gait: the kinematic checks (required friction, slide signs, shooting)
        report = cs.verify(tr, scene.gait)
        assert report.kinematic
        assert report.ok(1e-9), report


@pytest.mark.parametrize('path', SCENE_FILES, ids=lambda p: str(p.relative_to(CONFIG)))
def test_every_scene_survives_the_bag_round_trip_bit_for_bit(path):
    scene = _short(load_scene(path))
    again = scene_from_dict(yaml.safe_load(yaml.safe_dump(scene_to_dict(scene))))
    np.testing.assert_array_equal(again.crawler.friction, scene.crawler.friction)
    np.testing.assert_array_equal(again.crawler.friction_backward,
                                  scene.crawler.friction_backward)
    np.testing.assert_array_equal(again.simulate().x, scene.simulate().x)


@pytest.mark.parametrize('name', NAMED)
def test_each_named_scene_crawls_forward(name):
    tr = load_scene(CONFIG / 'scenes' / f'{name}.yaml').simulate()
    assert tr.displacement > 0.1          # metres in the scene's 20 s


# --- every gait type ------------------------------------------------------------------------

GAIT_EXAMPLES = {
    'sinusoid': {'mean': 0.1, 'amplitude': [0.02, 0.01], 'frequency': 1.0, 'phase': [0, -1.5]},
    'fourier': {'mean': 0.1, 'frequency': 1.5,
                'coefficients': [[[0.01, 0.002], [0.0, 0.001]],      # cos, one row per linkage
                                 [[0.0, 0.003], [0.01, 0.0]]]},      # sin
    'scallop': {'mean': [0.1, 0.12], 'amplitude': 0.02, 'frequency': 2, 'asymmetry': 0.3},
    'piecewise_parabolic': {'times': [0, 0.25, 0.5, 0.75, 1.0],
                            'accelerations': [[1, 2], [-1, -2], [-1, -2], [1, 2]],
                            'l0': [0.1, 0.12]},
    'stroke': {'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0, 'asymmetry': 0.2},
    'spline': {'times': [0, 0.5, 1, 2],
               'lengths': [[0.1, 0.1], [0.12, 0.09], [0.1, 0.11], [0.1, 0.1]]},
}
THREE_BODIES = {'masses': [1.0, 0.8, 1.2], 'friction': [3.0, 2.0, 3.0], 'friction_backward': 4}


def test_the_gait_examples_cover_every_gait_type():
    assert set(GAIT_EXAMPLES) == set(GAIT_TYPES)


@pytest.mark.parametrize('kind', GAIT_TYPES)
def test_every_gait_type_builds_from_its_parameters_and_runs_exactly(kind):
    scene = scene_from_dict({'crawler': THREE_BODIES, 'gait': {'type': kind,
                                                               **GAIT_EXAMPLES[kind]},
                             'run': {'t_end': 2.0}})
    assert scene.gait.n_links == 2
    assert scene.gait_spec['type'] == kind
    assert cs.verify(scene.simulate(), scene.gait).ok(1e-9)


def test_gait_type_names_also_match_the_class_names():
    gait = {'type': 'PiecewiseParabolic', **GAIT_EXAMPLES['piecewise_parabolic']}
    scene = scene_from_dict({'crawler': THREE_BODIES, 'gait': gait})
    assert isinstance(scene.gait, cs.gaits.PiecewiseParabolic)


def test_the_stroke_type_is_the_piecewise_parabolic_stroke_helper():
    scene = scene_from_dict({'crawler': {'masses': [1, 1], 'mu': 0.3},
                             'gait': {'type': 'stroke', **GAIT_EXAMPLES['stroke']}})
    expected = cs.gaits.PiecewiseParabolic.stroke(0.1, 0.02, 1.0, 0.2)
    t = np.linspace(0.0, 2.0, 101)
    for got, want in zip(scene.gait(t), expected(t)):
        np.testing.assert_array_equal(got, want)


# --- crawler and run options ----------------------------------------------------------------

def test_coefficients_give_the_same_crawler_as_from_coefficients():
    spec = {'masses': [1.0, 2.0], 'mu': [0.3, 0.4], 'mu_backward': 0.6, 'slope_deg': 10.0,
            'gravity': 9.8}
    scene = scene_from_dict({'crawler': spec, 'gait': {'type': 'stroke',
                                                       **GAIT_EXAMPLES['stroke']}})
    want = cs.Crawler.from_coefficients([1.0, 2.0], [0.3, 0.4], 0.6, math.radians(10.0), 9.8)
    np.testing.assert_array_equal(scene.crawler.friction, want.friction)
    np.testing.assert_array_equal(scene.crawler.friction_backward, want.friction_backward)


def test_run_options_reach_simulate_and_can_be_overridden():
    scene = load_scene(CONFIG / 'scenes' / 'scallop_2body.yaml')
    scene = scene.with_run(method='implicit', dt=2e-3, t_end=1.0)
    tr = scene.simulate()
    assert tr.method == 'implicit'
    assert tr.info['dt'] == 2e-3
    assert tr.t[-1] == 1.0


def test_yaml_exponent_floats_without_a_dot_are_read_as_numbers(tmp_path):
    text = (CONFIG / 'scenes' / 'scallop_2body.yaml').read_text() + '    tol: 1e-12\n    dt: 5e-4\n'
    path = tmp_path / 's.yaml'
    path.write_text(text)
    run = load_scene(path).run
    assert (run.tol, run.dt) == (1e-12, 5e-4)


# --- errors -----------------------------------------------------------------------------------

BASE = yaml.safe_load((CONFIG / 'scenes' / 'wave_3body.yaml').read_text())['scene']


def _set(path: str, value):
    def edit(d):
        *keys, last = path.split('.')
        for k in keys:
            d = d.setdefault(k, {})
        if value is _DELETE:
            del d[last]
        else:
            d[last] = value
    return edit


_DELETE = object()

BAD = [  # (edit, message the error must contain)
    (_set('crawler.masses', [1.0, -1.0, 1.0]),
     'scene.crawler.masses[1]: must be in [1e-09, 1e+09] kg, got -1.0'),
    (_set('crawler.masses', [1.0]), 'scene.crawler.masses: must list p >= 2 bodies, got 1'),
    (_set('crawler.masses', 'heavy'), 'scene.crawler.masses: must be a number or a list'),
    (_set('crawler.mu', [0.3, 0.3]),
     'scene.crawler.mu: must have 1 or 3 entries (one per body), got 2'),
    (_set('crawler.mu_backward', float('nan')),
     'scene.crawler.mu_backward: must be in [0, 1000], got nan'),
    (_set('crawler.friction', 3.0), 'give exactly one of mu (coefficients) or friction'),
    (_set('crawler.mu', _DELETE), 'give exactly one of mu (coefficients) or friction'),
    (_set('crawler.slope', 2.0), 'scene.crawler.slope: must be in (-pi/2, pi/2)'),
    (_set('crawler.gravity', -9.81), 'scene.crawler.gravity: must be finite and >= 0'),
    (_set('crawler.colour', 'red'), "scene.crawler: unknown key 'colour'"),
    (_set('gait.type', 'zigzag'), "scene.gait.type: unknown gait 'zigzag'; expected one of"),
    (_set('gait.amplitude', _DELETE), 'scene.gait.amplitude: missing (required)'),
    (_set('gait.phase', [0.0, 1.0, 2.0]), 'scene.gait.phase: must have 1 or 2 entries'),
    (_set('gait.frequency', 0.0), 'scene.gait.frequency: must be in [0.001, 10000] Hz, got 0.0'),
    (_set('gait.mean', [0.1, 'a']), 'scene.gait.mean[1]: must be a number'),
    (_set('run.method', 'rk4'), "scene.run.method: unknown method 'rk4'; expected one of exact"),
    (_set('run.t_end', -1.0), 'scene.run.t_end: must be finite and > 0 s, got -1.0'),
    (_set('run.method', 'penalty'), 'scene.run.penalty: required for method penalty'),
    (_set('run.penalty', [1e4, 1e4]), 'scene.run.penalty: must have 1 or 3 entries'),
    (_set('run.steps', 10), "scene.run: unknown key 'steps'"),
    (_set('crawler', _DELETE), 'scene.crawler: missing (required)'),
]


@pytest.mark.parametrize('edit,message', BAD, ids=[m for _, m in BAD])
def test_an_invalid_scene_raises_one_line_naming_the_field(edit, message):
    spec = copy.deepcopy(BASE)
    edit(spec)
    with pytest.raises(SceneError) as info:
        scene_from_dict(spec)
    text = str(info.value)
    assert message in text
    assert '\n' not in text


def test_a_gait_for_the_wrong_number_of_bodies_is_rejected():
    spec = copy.deepcopy(BASE)
    spec['crawler']['masses'] = [1.0, 1.0, 1.0, 1.0]
    spec['gait'] = {'type': 'spline', **GAIT_EXAMPLES['spline']}
    with pytest.raises(SceneError, match=r'drives 2 linkages, .* lists 4 bodies'):
        scene_from_dict(spec)


def test_a_file_error_names_the_file(tmp_path):
    path = tmp_path / 'bad.yaml'
    spec = copy.deepcopy(BASE)
    spec['crawler']['masses'][2] = 0.0
    path.write_text(yaml.safe_dump({'scene': spec}))
    with pytest.raises(SceneError, match=r'^.*bad\.yaml: scene\.crawler\.masses\[2\]: '):
        load_scene(path)


def test_malformed_yaml_reports_the_line(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('scene:\n  crawler: [1, 2\n  gait: {}\n')
    with pytest.raises(SceneError, match=r'broken\.yaml: invalid YAML at line 3'):
        load_scene(path)


def test_a_yaml_file_without_a_scene_key_is_not_a_scene(tmp_path):
    path = tmp_path / 'params.yaml'
    path.write_text('crawler_sim:\n  ros__parameters:\n    masses: [1.0, 1.0]\n')
    with pytest.raises(SceneError, match='no top-level "scene:" key'):
        load_scene(path)


def test_a_missing_scene_file_is_an_os_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_scene(tmp_path / 'nope.yaml')


# --- issue 11 point 9: values that used to reach the solver as degenerate cases ---------------
# Each of these was accepted by the loader and then failed inside the solver with an internal
# message ("min() arg is an empty sequence", "float division by zero", "cannot convert float
# infinity to integer") and exit 1, or ran forever. Found by a scan of every numeric field of the
# shipped scenes over 0, +-1, 1e-320 .. 1e308; the allowed ranges are scene.LIMITS.
DEGENERATE = [  # (file, field, value, message the SceneError must contain)
    ('scallop_2body', 'run.t_end', 1e-30, 'scene.run.t_end: must be in [1e-06, 1e+07] s'),
    ('scallop_2body', 'run.t_end', 1e30, 'scene.run.t_end: must be in [1e-06, 1e+07] s'),
    ('scallop_2body', 'gait.asymmetry', 1e-12, 'scene.gait.asymmetry: must be in [0.001, 0.999]'),
    ('scallop_2body', 'gait.asymmetry', 0.999999, 'scene.gait.asymmetry: must be in'),
    ('scallop_2body', 'gait.frequency', 1e30, 'scene.gait.frequency: must be in [0.001, 10000] Hz'),
    ('bang_bang', 'gait.frequency', 1e-300, 'scene.gait.frequency: must be in'),
    ('bang_bang', 'run.tol', 1.0, 'scene.run.tol: must be in [1e-15, 1e-06] s'),
    ('bang_bang', 'run.max_step', 1e-320, 'scene.run.max_step: must be >= max(1e-6 s, t_end / 1e7)'),
    ('bang_bang', 'run.max_step', 1e-12, 'scene.run.max_step: must be >='),
    ('wave_3body', 'run.dt', 1e-300, 'scene.run.dt: must be >= max(1e-9 s, t_end / 1e8)'),
    ('wave_3body', 'crawler.mu', 1e30, 'scene.crawler.mu[0]: must be in [0, 1000]'),
    ('wave_3body', 'crawler.gravity', 1e30, 'scene.crawler.gravity: must be in [0, 1000] m/s^2'),
    ('wave_3body', 'crawler.masses', [1e308] * 3, 'scene.crawler.masses[0]: must be in'),
    ('wave_3body', 'gait.amplitude', 1e308, 'scene.gait.amplitude: must be in [-1e+06, 1e+06] m'),
]


@pytest.mark.parametrize('name,field,value,message', DEGENERATE,
                         ids=[f'{n}:{f}={v if not isinstance(v, list) else v[0]}'
                              for n, f, v, _ in DEGENERATE])
def test_a_degenerate_scene_value_is_a_scene_error_naming_the_field(name, field, value, message):
    spec = yaml.safe_load((CONFIG / 'scenes' / f'{name}.yaml').read_text())['scene']
    _set(field, value)(spec)
    with pytest.raises(SceneError) as info:
        scene_from_dict(spec)
    assert message in str(info.value)


_CLI_CASES = DEGENERATE[:4] + DEGENERATE[6:8] + DEGENERATE[12:13]


@pytest.mark.parametrize('name,field,value,message', _CLI_CASES,
                         ids=[f'{f}={v if not isinstance(v, list) else v[0]}'
                              for _, f, v, _ in _CLI_CASES])
def test_crawler_sim_simulate_exits_2_naming_the_field_for_a_degenerate_value(
        tmp_path, capsys, name, field, value, message):
    # issue 11 points 2 and 9: masses [1e308] * 3 used to give NaN outputs and exit 0
    from crawler_sim import cli
    spec = yaml.safe_load((CONFIG / 'scenes' / f'{name}.yaml').read_text())
    _set(field, value)(spec['scene'])
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(spec))
    code = cli.main(['simulate', str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    for internal in ('min() arg', 'division by zero', 'infinity to integer', 'internal error'):
        assert internal not in err



# --- lengths <= 0 (issue 43) ------------------------------------------------------------------

def test_a_scene_whose_gait_length_reaches_zero_is_refused_in_one_line_naming_the_gait():
    seed = yaml.safe_load((CONFIG / 'scenes' / 'scallop_2body.yaml').read_text())
    seed['scene']['gait']['amplitude'] = 0.2                  # 0.1 +/- 0.2 m: down to -0.1 m
    with pytest.raises(SceneError, match=r'^scene\.gait \(scallop\): gait length of linkage 0 '
                                         r'reaches -0\.1 m at t = 0 s'):
        scene_from_dict(seed)                                 # at load, before any work
    spline = {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3}, 'run': {'t_end': 2.0},
              'gait': {'type': 'spline', 'times': [0, 0.5, 1, 2],
                       'lengths': [0.1, 0.02, -0.05, 0.1]}}   # known from the run's samples
    with pytest.raises(SceneError, match=r'^scene\.gait \(spline\): gait length of linkage 0 '
                                         r'reaches -0\.000338608 m at t = 0\.592 s') as info:
        scene_from_dict(spline).simulate()
    assert '\n' not in str(info.value)


def test_the_cli_refuses_such_a_scene_with_exit_code_2(tmp_path, capsys):
    from crawler_sim.cli import main
    seed = yaml.safe_load((CONFIG / 'scenes' / 'scallop_2body.yaml').read_text())
    seed['scene']['gait']['amplitude'] = 0.2
    path = tmp_path / 'crossing.yaml'
    path.write_text(yaml.safe_dump(seed))
    assert main(['simulate', str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'scene.gait (scallop): gait length of linkage 0 reaches' in err[0]
