"""Record names: confined to record_dir, unique per process (issue 11 point 8)."""
from __future__ import annotations

import os
from pathlib import Path
import re

import pytest

from crawler_sim.bag import BagWriter, Recorder, load
from crawler_sim.bag.naming import check_record_name, claim_directory, default_name

JOINT_STATE = 'sensor_msgs/msg/JointState'


@pytest.mark.parametrize('name', ['../x', '../../x', '/tmp/abs', 'a/b', '..', '.', '',
                                  'a\\b', 'sp ace', 'nul\0', 'é', 'x' * 201, 'a\nb'])
def test_names_that_could_leave_record_dir_or_are_not_portable_are_refused(name):
    with pytest.raises(ValueError, match=r'record_name .*A-Z a-z 0-9 \. _ -'):
        check_record_name(name)


@pytest.mark.parametrize('name', ['run', 'run_1.v2', '-x', 'A-Z_09', 'x' * 200, '...'])
def test_plain_names_are_accepted_unchanged(name):
    assert check_record_name(name) == name


@pytest.mark.parametrize('name', ['../escape', '/abs/path', 'a/b'])
def test_create_writes_nothing_outside_record_dir(tmp_path, name):
    record_dir = tmp_path / 'inner' / 'runs'
    with pytest.raises(ValueError, match='record_name'):
        BagWriter.create(record_dir, name)
    # nothing was created anywhere under tmp_path except (possibly) the empty record_dir
    created = [p for p in tmp_path.rglob('*') if p.is_file()]
    assert created == []
    assert not (tmp_path / 'inner' / 'escape').exists() and not Path('/abs/path').exists()


def test_default_name_carries_time_and_pid():
    assert re.fullmatch(rf'crawler_sim_\d{{8}}-\d{{6}}_{os.getpid()}', default_name())


def test_two_writers_with_the_same_name_get_separate_folders(tmp_path):
    # as two nodes started in the same second with the default name
    first = BagWriter.create(tmp_path, 'same')
    second = BagWriter.create(tmp_path, 'same')
    third = Recorder.create(tmp_path, 'same', masses=[1.0, 1.0])
    assert [first.path.name, second.path.name, third.writer.path.name] == [
        'same', 'same_2', 'same_3']
    for k, w in enumerate((first, second)):
        from sensor_msgs.msg import JointState
        w.write('/body_states', JOINT_STATE, JointState(
            name=['body_0'], position=[float(k)], velocity=[0.0], effort=[0.0]), 0)
        w.close()
    third.record_state(0.0, [0.0, 0.1], [0.0, 0.0], [0.0, 0.0], [0, 0], [0.1], [0.0], [0.0])
    third.close()
    assert load(tmp_path / 'same').x[0, 0] == 0.0
    assert load(tmp_path / 'same_2').x[0, 0] == 1.0
    assert len(load(tmp_path / 'same_3')) == 1


def test_default_names_in_the_same_second_do_not_collide(tmp_path):
    a = claim_directory(tmp_path, '')
    b = claim_directory(tmp_path, None)
    assert a != b and a.parent == b.parent == tmp_path
    assert b.name == a.name + '_2'


def test_a_file_in_place_of_record_dir_is_a_clear_error(tmp_path):
    from crawler_sim.bag import BagError
    (tmp_path / 'file').write_text('x')
    with pytest.raises(BagError, match='record_dir'):
        BagWriter.create(tmp_path / 'file', 'run')
