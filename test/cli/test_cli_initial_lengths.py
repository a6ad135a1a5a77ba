"""``simulate --as-node --initial-lengths``: the servo's start length, as sim_node's
``initial_lengths`` (issue 43: the command line could not set it, so the demo's 98.7 mm, which
starts at 0.1 m, could not be reproduced offline; ``--as-node`` always started at rest at the
gait's first length, 0.08 m for the seed's Scallop)."""
from __future__ import annotations

import json

import numpy as np

from crawler_sim.bag import load
from crawler_sim.core.scene import load_scene

from .test_cli import CONFIG, assert_one_error_line, run_inprocess

SCENE = CONFIG / 'scallop_2body.yaml'


def _figures(capsys, *extra: str) -> dict:
    proc = run_inprocess(capsys, 'simulate', str(SCENE), '--as-node', 'preload', '--t-end',
                         '2', '--json', *extra)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_the_start_length_is_where_the_servo_rests_at_t0_and_the_run_replays(tmp_path, capsys):
    out = tmp_path / 'bag'
    _figures(capsys, '--initial-lengths', '0.1', '--out', str(out))
    run = load(out)
    # at rest at the start length: the first recorded length is 0.1 m (the gait starts at
    # 0.08 m, so the default start would read 0.08), every body at rest
    assert abs(run.lengths[0, 0] - 0.1) < 1e-12
    assert np.all(run.v[0] == 0.0)
    assert run.scene['as_node']['initial_lengths'] == [0.1]
    rep = run_inprocess(capsys, 'replay', str(out))
    assert rep.returncode == 0 and 'max |dx|  0 m' in rep.stdout, rep.stdout + rep.stderr


def test_the_gaits_first_length_as_start_is_the_default_run(capsys):
    # invariant: the default start is the gait at t = 0, so naming it changes nothing, while
    # another start changes the crawl (the servo's transient differs)
    first = float(np.atleast_1d(load_scene(SCENE).gait.length(0.0))[0])
    default = _figures(capsys)
    named = _figures(capsys, '--initial-lengths', repr(first))
    other = _figures(capsys, '--initial-lengths', '0.1')
    assert named['displacement'] == default['displacement']
    assert other['displacement'] != default['displacement']


def test_a_start_length_without_as_node_or_of_the_wrong_count_is_refused(capsys):
    proc = run_inprocess(capsys, 'simulate', str(SCENE), '--initial-lengths', '0.1')
    assert proc.returncode == 2
    assert_one_error_line(proc, '--initial-lengths', '--as-node')
    proc = run_inprocess(capsys, 'simulate', str(SCENE), '--as-node', 'preload',
                         '--initial-lengths', '0.1', '0.2')
    assert proc.returncode == 2
    assert_one_error_line(proc, '--initial-lengths', '(1)', 'got 2')
    proc = run_inprocess(capsys, 'simulate', str(SCENE), '--as-node', 'preload',
                         '--initial-lengths', '-0.1')
    assert proc.returncode == 2
    assert_one_error_line(proc, '--initial-lengths')
