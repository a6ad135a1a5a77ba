"""The ``crawler-sim`` command line: help, simulate, the bag subcommands, replay, exit codes, and
one-line errors without tracebacks."""
from __future__ import annotations

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from crawler_sim import cli
from crawler_sim.core.scene import Scene, load_scene

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / 'config' / 'scenes'
SCENES = ('scallop_2body', 'wave_3body', 'slope_climb', 'bang_bang')
FIGURES = ('displacement', 'mean speed', 'stick fraction', 'events', 'dissipated energy',
           'actuator work', 'cost of transport', 'verify', 'wall time')
PNG_MAGIC = b'\x89PNG\r\n\x1a\n'

HELP = {  # subcommand -> what its --help must mention
    'simulate': ('SCENE.yaml', '--method', '--t-end', '--dt', '--out', '--plot', '--json',
                 '--penalty', '--as-node'),
    'replay': ('BAG', '--method', '--tol'),
    'info': ('BAG',),
    'plot': ('BAG', '--output'),
    'recover': ('BAG_OR_MCAP', '--output'),
    'sweep': ('SPEC.yaml', '--output', '--csv', '--scheduler', '--workers', '--checkpoint'),
    'optimize': ('SCENE.yaml', '--objective', '--family', '--max-speed', '--max-acceleration',
                 '--scheduler', '--output', '--history'),
    'export': ('BAG', '--parquet', '--csv'),
}


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join([str(REPO), env.get('PYTHONPATH', '')]).rstrip(os.pathsep)
    env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    env['MPLBACKEND'] = 'Agg'
    return env


def run_subprocess(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'crawler_sim.cli', *args], cwd=cwd,
                          env=_env(), capture_output=True, text=True, timeout=120)


def run_inprocess(capsys, *args: str) -> subprocess.CompletedProcess:
    code = cli.main(list(args))
    out, err = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)


@pytest.fixture(params=['subprocess', 'in-process'])
def crawler_sim_cli(request, capsys):
    """Runs the command line either as ``python -m crawler_sim.cli`` or through ``main()``."""
    if request.param == 'subprocess':
        return run_subprocess
    return lambda *args, cwd=None: run_inprocess(capsys, *args)


@pytest.fixture
def ros_env(monkeypatch):
    """The bag finds the message definitions through the ament index (the venv's share/)."""
    if 'AMENT_PREFIX_PATH' not in os.environ:
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)


def assert_one_error_line(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith('crawler-sim: error: ')]
    assert len(errors) == 1, proc.stderr
    assert 'Traceback' not in proc.stderr
    for fragment in fragments:
        assert fragment in errors[0], errors[0]


# --- help -----------------------------------------------------------------------------------

def test_the_top_level_help_lists_every_subcommand_and_the_exit_codes():
    proc = run_subprocess('--help')
    assert proc.returncode == 0, proc.stderr
    for name in HELP:
        assert name in proc.stdout
    assert 'exit codes' in proc.stdout


@pytest.mark.parametrize('command', list(HELP))
def test_every_subcommands_help_exits_0_and_mentions_its_arguments(command, capsys):
    proc = run_inprocess(capsys, command, '--help')
    assert proc.returncode == 0
    for arg in HELP[command]:
        assert arg in proc.stdout, f'{command} --help does not mention {arg}'


def test_no_subcommand_prints_the_help_and_exits_2(capsys):
    proc = run_inprocess(capsys)
    assert proc.returncode == 2
    assert 'simulate' in proc.stderr


# --- simulate ---------------------------------------------------------------------------------

@pytest.mark.parametrize('name', SCENES)
def test_simulate_prints_the_figures_of_each_shipped_scene(crawler_sim_cli, name):
    proc = crawler_sim_cli('simulate', str(CONFIG / f'{name}.yaml'))
    assert proc.returncode == 0, proc.stderr
    for figure in FIGURES:
        assert figure in proc.stdout
    assert f'{name} (' in proc.stdout
    assert 'ok at 1e-9' in proc.stdout


def test_simulate_json_gives_the_trajectorys_figures(capsys):
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'wave_3body.yaml'), '--t-end', '4',
                         '--json')
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(proc.stdout)
    tr = load_scene(CONFIG / 'wave_3body.yaml').with_run(t_end=4.0).simulate()
    assert figures['displacement'] == tr.displacement
    assert figures['mean_speed_last_period'] == tr.mean_speed(1.0)
    assert figures['stick_fraction'] == tr.stick_fraction.tolist()
    assert figures['events'] == len(tr.events)
    assert figures['dissipated_energy'] == tr.dissipated_energy
    assert figures['actuator_work'] == tr.actuator_work
    assert figures['cost_of_transport'] == tr.cost_of_transport
    assert figures['verify_ok'] is True
    assert figures['t_end'] == 4.0


def test_simulate_options_override_the_scene(capsys):
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'scallop_2body.yaml'), '--method',
                         'implicit', '--dt', '0.002', '--t-end', '1', '--json')
    assert proc.returncode == 0, proc.stderr
    figures = json.loads(proc.stdout)
    assert (figures['method'], figures['t_end'], figures['samples']) == ('implicit', 1.0, 501)


def test_simulate_plot_without_a_bag_writes_a_png(tmp_path, capsys):
    png = tmp_path / 'run.png'
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'bang_bang.yaml'), '--t-end', '2',
                         '--plot', str(png))
    assert proc.returncode == 0, proc.stderr
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_simulate_reports_progress_on_stderr_not_stdout(capsys):
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'bang_bang.yaml'), '--json')
    assert 'simulating bang_bang' in proc.stderr
    json.loads(proc.stdout)


# --- errors -------------------------------------------------------------------------------------

def _scene_file(tmp_path: Path, name: str, old: str, new: str) -> str:
    text = (CONFIG / 'wave_3body.yaml').read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return str(path)


BAD_INPUT = {  # case -> (edit of wave_3body.yaml or None, extra arguments, error fragments)
    'missing file': (None, (), ('nope.yaml: no such file',)),
    'negative mass': (('masses: [1.0, 1.0, 1.0]', 'masses: [1.0, -1.0, 1.0]'), (),
                      ('scene.crawler.masses[1]: must be in [1e-09, 1e+09] kg, got -1.0',)),
    'wrong list length': (('mu: 0.3 ', 'mu: [0.3, 0.3] '), (),
                          ('scene.crawler.mu: must have 1 or 3 entries (one per body), got 2',)),
    'gait for other bodies': (('phase: [0.0, -2.0943951023931953]', 'phase: [0.0, 1.0, 2.0]'),
                              (), ('scene.gait.phase: must have 1 or 2 entries',)),
    'unknown method in scene': (('method: exact', 'method: rk4'), (),
                                ("scene.run.method: unknown method 'rk4'",)),
    'unknown method option': (None, ('--method', 'rk4'), ("--method: invalid choice: 'rk4'",)),
    'unknown gait': (('type: sinusoid', 'type: zigzag'), (), ("unknown gait 'zigzag'",)),
    'malformed yaml': (('mean: 0.1 ', 'mean: [0.1 '), (), ('invalid YAML at line',)),
    'bad t-end': (None, ('--t-end', '-1'), ('--t-end: must be finite and > 0',)),
}


@pytest.mark.parametrize('case', list(BAD_INPUT))
def test_bad_input_gives_one_error_line_and_exit_2(case, crawler_sim_cli, tmp_path):
    edit, extra, fragments = BAD_INPUT[case]
    if case == 'missing file':
        scene = 'nope.yaml'
    elif edit is None:
        scene = str(CONFIG / 'wave_3body.yaml')
    else:
        scene = _scene_file(tmp_path, 'bad.yaml', *edit)
    proc = crawler_sim_cli('simulate', scene, *extra, cwd=tmp_path)
    assert proc.returncode == 2
    assert_one_error_line(proc, *fragments)
    assert proc.stdout == ''


def test_simulate_refuses_to_overwrite_a_bag_before_simulating(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(Scene, 'simulate', lambda self, **kw: pytest.fail('simulated anyway'))
    (tmp_path / 'run').mkdir()
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'bang_bang.yaml'), '--out',
                         str(tmp_path / 'run'))
    assert proc.returncode == 2
    assert_one_error_line(proc, 'run exists already, not overwriting')


def test_an_unknown_subcommand_is_a_usage_error(capsys):
    proc = run_inprocess(capsys, 'frobnicate')
    assert proc.returncode == 2
    assert_one_error_line(proc, "invalid choice: 'frobnicate'")


def test_a_solver_failure_is_one_error_line_and_exit_1(monkeypatch, capsys):
    def fail(self, **kwargs):
        raise RuntimeError('exact solver stalled at t = 0.5 s')

    monkeypatch.setattr(Scene, 'simulate', fail)
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'bang_bang.yaml'))
    assert proc.returncode == 1
    assert_one_error_line(proc, 'exact solver stalled at t = 0.5 s')


def test_an_unexpected_exception_is_one_line_unless_debug(monkeypatch, capsys):
    def bug(self, **kwargs):
        raise TypeError('unsupported operand')

    monkeypatch.setattr(Scene, 'simulate', bug)
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'bang_bang.yaml'))
    assert proc.returncode == 1
    assert_one_error_line(proc, 'internal error (TypeError: unsupported operand)', '--debug')
    with pytest.raises(TypeError):
        cli.main(['--debug', 'simulate', str(CONFIG / 'bang_bang.yaml')])
    # anywhere on the line (issue 43: it worked only before the command)
    with pytest.raises(TypeError):
        cli.main(['simulate', str(CONFIG / 'bang_bang.yaml'), '--debug'])


@pytest.mark.parametrize('command', ['info', 'plot', 'replay', 'recover'])
def test_a_missing_bag_is_one_error_line_and_exit_2(command, capsys, tmp_path):
    args = [command, str(tmp_path / 'nobag')]
    if command == 'plot':
        args += ['-o', str(tmp_path / 'x.png')]
    proc = run_inprocess(capsys, *args)
    assert proc.returncode == 2
    assert_one_error_line(proc, 'nobag: no such')


def test_a_file_that_is_not_a_bag_is_one_error_line_and_exit_1(capsys, tmp_path, ros_env):
    path = tmp_path / 'notes.mcap'
    path.write_text('not a bag\n')
    proc = run_inprocess(capsys, 'info', str(path))
    assert proc.returncode == 1
    assert_one_error_line(proc, 'notes.mcap')


def test_a_missing_part_of_the_package_is_one_error_line(monkeypatch, capsys, tmp_path):
    bag = tmp_path / 'run.mcap'
    bag.write_bytes(b'not a bag')
    monkeypatch.setitem(sys.modules, 'crawler_sim.bag', None)
    proc = run_inprocess(capsys, 'info', str(bag))
    assert proc.returncode == 1
    assert_one_error_line(proc, 'crawler_sim.bag')


def test_the_benchmarks_are_not_user_commands():
    """They need the source tree (scenes, oracles): ``python -m benchmarks.solvers``."""
    from crawler_sim.cli import build_parser
    commands = build_parser()._subparsers._group_actions[0].choices
    assert 'bench' not in commands and 'stress' not in commands
    assert {'simulate', 'replay', 'info', 'plot', 'recover', 'sweep', 'optimize'} <= set(commands)


# --- bags: record, info, plot, replay, recover -------------------------------------------------

@pytest.fixture
def offline_bag(tmp_path, capsys, ros_env) -> Path:
    bag = tmp_path / 'run'
    proc = run_inprocess(capsys, 'simulate', str(CONFIG / 'wave_3body.yaml'), '--t-end', '5',
                         '--out', str(bag))
    assert proc.returncode == 0, proc.stderr
    assert str(bag) in proc.stdout
    assert bag.is_dir()
    return bag


def test_simulate_out_records_a_bag_that_info_and_plot_read(offline_bag, capsys, tmp_path):
    proc = run_inprocess(capsys, 'info', str(offline_bag))
    assert proc.returncode == 0, proc.stderr
    assert '/body_states' in proc.stdout
    png = tmp_path / 'plot.png'
    proc = run_inprocess(capsys, 'plot', str(offline_bag), '-o', str(png))
    assert proc.returncode == 0, proc.stderr
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_replay_of_an_offline_run_matches_bit_for_bit(offline_bag, capsys):
    proc = run_inprocess(capsys, 'replay', str(offline_bag))
    assert proc.returncode == 0, proc.stderr
    assert 'max |dx|  0 m' in proc.stdout
    assert 'match' in proc.stdout


def test_replay_with_another_method_reports_the_mismatch_and_exits_1(offline_bag, capsys):
    proc = run_inprocess(capsys, 'replay', str(offline_bag), '--method', 'implicit')
    assert proc.returncode == 1
    assert 'MISMATCH' in proc.stdout
    assert_one_error_line(proc, 'replay differs from the recording by')


def test_recover_salvages_a_truncated_recording(offline_bag, capsys, tmp_path):
    mcap = next(offline_bag.glob('*.mcap'))
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(mcap.read_bytes()[: mcap.stat().st_size * 2 // 3])
    out = tmp_path / 'fixed'
    proc = run_inprocess(capsys, 'recover', str(cut), '-o', str(out))
    assert proc.returncode == 0, proc.stderr
    assert 'readable part recovered' in proc.stdout
    proc = run_inprocess(capsys, 'replay', str(out))
    assert proc.returncode == 0, proc.stderr


def test_replay_of_a_node_recording_reproduces_its_ticks_bit_for_bit(tmp_path, capsys, ros_env):
    """Record with the real node (ticks driven directly, commands over DDS), then replay the
    bag with the core."""
    pytest.importorskip('rclpy')
    from std_msgs.msg import Float64MultiArray

    from test.support.ros import Harness

    h = Harness()
    try:
        node = h.sim(seed=True, record=True, record_dir=str(tmp_path), record_name='node_run',
                     masses=[1.0, 0.5, 1.0], friction=[3.0], friction_backward=[5.0])
        pub = h.publisher(Float64MultiArray, 'linkage_cmd')
        commands = {0: [0.15, 0.1], 300: [0.08, 0.14], 700: [0.12, 0.12]}
        for k in range(1000):
            if k in commands:
                h.send(pub, Float64MultiArray(data=commands[k]), node, 'commands_accepted')
            node.tick()
        final = node.state
    finally:
        h.close()
    proc = run_inprocess(capsys, 'replay', str(tmp_path / 'node_run'))
    assert proc.returncode == 0, proc.stderr
    # ticks driven directly (no run loop, so no sample at t = 0): one sample per publish tick
    assert '(node run, 100 samples, 3 commands)' in proc.stdout
    assert 'max |dx|  0 m' in proc.stdout and 'max |dv|  0 m/s' in proc.stdout
    assert np.any(final.x != 0.0)      # the crawler did move


def test_simulate_as_the_node_runs_it_differs_from_the_ideal_stroke_and_replays(tmp_path,
                                                                                capsys):
    """``--as-node preload``: the scene's gait played through sim_node's actuator. The seed's
    stroke asks more than the servo gives (|l''| up to 22 m/s^2 against 5), so the crawl
    differs from the ideal one; the bag records how it was driven and replays bit for bit."""
    scene = CONFIG / 'scallop_2body.yaml'
    out = tmp_path / 'bag'
    proc = run_inprocess(capsys, 'simulate', str(scene), '--as-node', 'preload', '--json',
                         '--out', str(out))
    assert proc.returncode == 0, proc.stderr
    fig = json.loads(proc.stdout)
    ideal = json.loads(run_inprocess(capsys, 'simulate', str(scene), '--json').stdout)
    assert fig['as_node'] == 'preload at 50 Hz'
    assert abs(fig['mean_speed'] - ideal['mean_speed']) > 0.1 * abs(ideal['mean_speed'])
    rep = run_inprocess(capsys, 'replay', str(out))
    assert rep.returncode == 0 and 'max |dx|  0 m' in rep.stdout and 'as sim_node' in rep.stdout
