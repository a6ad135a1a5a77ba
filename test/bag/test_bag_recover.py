"""Crash safety: a recorder killed with SIGKILL keeps what it flushed.

``recover`` turns the unfinished file into a bag that crawler_sim, mcap_ros2 and rosbags read.
"""
from __future__ import annotations

from collections import Counter
import os
from pathlib import Path
import signal
import subprocess
import sys
import warnings

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
from numpy.testing import assert_array_equal
import pytest
import yaml

from crawler_sim.bag import BagError, BagWarning, load, record_arrays, recover
from crawler_sim.bag.recover import default_destination
from test.support.synthetic import synthetic_arrays

REPO = Path(__file__).resolve().parents[2]
STEPS, FLUSH_EVERY, SEED = 1000, 300, 5
TOPICS_PER_STEP = 4          # body_states, joint_states, contact_states, odom

RECORDER_SCRIPT = """
import sys, time
from crawler_sim.bag import Recorder
from test.support.synthetic import synthetic_arrays
path, n, every, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
a = synthetic_arrays(n, 3, seed=seed)
rec = Recorder(path, masses=a['masses'], scene={'p': 3}, flush_interval=1e9)
for i in range(n):
    rec.record_state(a['t'][i], a['x'][i], a['v'][i], a['friction'][i], a['contact'][i],
                     a['lengths'][i], a['rates'][i], a['linkage_force'][i])
    if (i + 1) % every == 0:
        rec.flush()
        print('flushed', i + 1, flush=True)
print('written', flush=True)
time.sleep(600)
"""


def read_all_three(bag: Path) -> dict[str, Counter]:
    """Message counts per topic from crawler_sim.bag.load, mcap_ros2 and rosbags."""
    from rosbags.highlevel import AnyReader
    counts = {'mcap_ros2': Counter(), 'rosbags': Counter()}
    mcap_file = next(bag.glob('*.mcap'))
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages(log_time_order=False):
            assert msg is not None
            counts['mcap_ros2'][channel.topic] += 1
    with AnyReader([bag]) as reader:
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            counts['rosbags'][connection.topic] += 1
    return counts


@pytest.fixture(scope='module')
def killed_bag(tmp_path_factory) -> tuple[Path, int]:
    """A bag whose recorder was killed with SIGKILL after its last flush; (path, steps flushed)."""
    path = tmp_path_factory.mktemp('killed') / 'run'
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get('PYTHONPATH', ''))
    proc = subprocess.Popen(
        [sys.executable, '-c', RECORDER_SCRIPT, str(path), str(STEPS), str(FLUSH_EVERY),
         str(SEED)], stdout=subprocess.PIPE, text=True, env=env)
    flushed = 0
    try:
        for line in proc.stdout:
            if line.startswith('flushed'):
                flushed = int(line.split()[1])
            elif line.startswith('written'):
                break
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert flushed == STEPS // FLUSH_EVERY * FLUSH_EVERY
    return path, flushed


def test_killed_recorder_leaves_no_metadata_yaml_and_loads_what_it_flushed(killed_bag):
    path, flushed = killed_bag
    assert not (path / 'metadata.yaml').exists()
    with pytest.warns(BagWarning, match='no MCAP footer'):
        run = load(path)
    assert run.truncated
    assert flushed <= len(run) <= STEPS
    a = synthetic_arrays(STEPS, 3, seed=SEED)
    assert_array_equal(run.x, a['x'][:len(run)])
    assert_array_equal(run.contact, a['contact'][:len(run)])
    assert_array_equal(run.linkage_force, a['linkage_force'][:len(run)])
    assert run.scene == {'p': 3, 'crawler_sim_version': run.scene['crawler_sim_version']}


def test_recover_after_sigkill_gives_a_bag_all_three_readers_read(killed_bag, tmp_path):
    path, flushed = killed_bag
    result = recover(path, tmp_path / 'fixed')
    assert not result.complete and result.problems
    assert result.topics['/body_states'] >= flushed
    steps = result.topics['/body_states']
    assert result.messages == TOPICS_PER_STEP * steps + 1           # + the scene message
    assert result.metadata == 1                                      # crawler_sim.scene
    with warnings.catch_warnings():
        warnings.simplefilter('error')                               # a clean bag now
        run = load(tmp_path / 'fixed')
    a = synthetic_arrays(STEPS, 3, seed=SEED)
    assert len(run) == steps and not run.truncated
    assert_array_equal(run.v, a['v'][:steps])
    assert run.scene['p'] == 3
    counts = read_all_three(tmp_path / 'fixed')
    assert counts['mcap_ros2'] == counts['rosbags'] == Counter(result.topics)
    meta = yaml.safe_load((tmp_path / 'fixed' / 'metadata.yaml').read_text())
    assert meta['rosbag2_bagfile_information']['message_count'] == result.messages


@pytest.fixture(scope='module')
def complete_bag(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('complete') / 'run'
    a = synthetic_arrays(400, 3, seed=2)
    masses = a.pop('masses')
    record_arrays(path, **a, masses=masses, scene={'p': 3},
                  commands=(a['t'][::40], a['lengths'][::40]), chunk_size=8_192)
    return path


@pytest.mark.parametrize('fraction', [0.05, 0.35, 0.8, 0.999])
def test_recover_salvages_a_file_cut_anywhere(complete_bag, tmp_path, fraction):
    data = (complete_bag / 'run_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:int(len(data) * fraction)])
    result = recover(cut)
    assert result.bag == tmp_path / 'cut_recovered'
    # Cut in the summary (0.999): the data section is whole, nothing is lost.
    assert result.complete == (fraction > 0.99)
    assert (result.topics['/body_states'] == 400) == (fraction > 0.99)
    counts = read_all_three(result.bag)
    assert counts['mcap_ros2'] == counts['rosbags'] == +Counter(result.topics)
    if result.topics.get('/body_states'):
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            # a cut inside a time step loses that step's last topics: dropping it is expected
            warnings.filterwarnings('ignore', message='.*time steps without all')
            run = load(result.bag)
        full = load(complete_bag)
        assert_array_equal(run.x, full.x[:len(run)])


def test_recover_of_a_complete_bag_copies_everything(complete_bag, tmp_path):
    result = recover(complete_bag, tmp_path / 'copy')
    assert result.complete and not result.problems
    assert result.messages == sum(s.count for s in load(complete_bag).topics.values())
    original, copy = load(complete_bag), load(tmp_path / 'copy')
    for key in ('t', 'x', 'v', 'friction', 'contact', 'lengths', 'rates', 'linkage_force'):
        assert_array_equal(getattr(copy, key), getattr(original, key))
    assert_array_equal(copy.commands.values, original.commands.values)
    assert copy.scene == original.scene


def test_recover_refuses_an_existing_destination_and_non_mcap_sources(complete_bag, tmp_path):
    (tmp_path / 'taken').mkdir()
    with pytest.raises(BagError, match='exists already'):
        recover(complete_bag, tmp_path / 'taken')
    junk = tmp_path / 'junk.mcap'
    junk.write_bytes(np.random.default_rng(0).bytes(1000))
    with pytest.raises(BagError, match='not an MCAP file'):
        recover(junk, tmp_path / 'out')
    assert not (tmp_path / 'out').exists()
    with pytest.raises(BagError, match='no such file'):
        recover(tmp_path / 'missing.mcap')


def test_default_destination_sits_next_to_the_bag_directory(tmp_path):
    bag = tmp_path / 'run'
    bag.mkdir()
    (bag / 'run_0.mcap').touch()
    assert default_destination(bag) == tmp_path / 'run_recovered'
    assert default_destination(bag / 'run_0.mcap') == tmp_path / 'run_recovered'
    assert default_destination(tmp_path / 'x.mcap') == tmp_path / 'x_recovered'
