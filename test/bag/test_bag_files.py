"""`crawler_sim.bag.files`, the one way the package writes a file: never an input (by identity),
never inside an input bag folder, never through a link, atomically."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from crawler_sim.bag import files
from crawler_sim.bag.files import (OutputRefused, check_new_folder, check_output, reading,
                                   temporary_target, write_atomically, write_text)


def snapshot(folder: Path) -> dict[str, tuple[str, bytes | str]]:
    """Every entry under ``folder``: links by target, files by content (nothing followed)."""
    out: dict[str, tuple[str, bytes | str]] = {}
    for path in sorted(folder.rglob('*')):
        name = str(path.relative_to(folder))
        if path.is_symlink():
            out[name] = ('link', os.readlink(path))
        elif path.is_dir():
            out[name] = ('dir', b'')
        elif not path.is_file():
            out[name] = ('other', b'')             # a FIFO: reading it would block
        else:
            out[name] = ('file', path.read_bytes())
    return out


@pytest.fixture
def victim(tmp_path) -> Path:
    """A file of the user's outside the output folder, which no write may change."""
    folder = tmp_path / 'home'
    folder.mkdir()
    path = folder / 'thesis.tex'
    path.write_bytes(b'years of work')
    return path


@pytest.fixture
def out_dir(tmp_path) -> Path:
    folder = tmp_path / 'out'
    folder.mkdir()
    return folder


# ---------------------------------------------------------------- atomic writes

def test_a_write_replaces_an_earlier_output_and_leaves_nothing_else(out_dir):
    path = out_dir / 'table.csv'
    path.write_bytes(b'old')
    assert write_text(path, 'new') == path
    assert snapshot(out_dir) == {'table.csv': ('file', b'new')}


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(out_dir):
    path = out_dir / 'table.csv'
    path.write_bytes(b'old')

    def half(fh):
        fh.write(b'half of the new')
        raise OSError(28, 'No space left on device')

    with pytest.raises(OSError, match='cannot write: No space left on device') as info:
        write_atomically(path, half)
    assert info.value.filename == str(path)
    assert snapshot(out_dir) == {'table.csv': ('file', b'old')}


def test_an_interrupted_write_keeps_the_old_file_and_leaves_no_temporary(out_dir):
    path = out_dir / 'table.csv'
    path.write_bytes(b'old')

    def interrupted(fh):
        fh.write(b'half')
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(path, interrupted)
    assert snapshot(out_dir) == {'table.csv': ('file', b'old')}


def test_a_writer_that_closes_the_file_itself_still_writes_it(out_dir):
    def write_and_close(fh):
        fh.write(b'data')
        fh.close()                    # pyarrow and others may close what they are given

    write_atomically(out_dir / 'x.bin', write_and_close)
    assert snapshot(out_dir) == {'x.bin': ('file', b'data')}


def test_the_new_file_has_the_usual_permissions(out_dir):
    old = os.umask(0o022)
    try:
        write_text(out_dir / 'a.txt', 'x')
    finally:
        os.umask(old)
    assert (out_dir / 'a.txt').stat().st_mode & 0o777 == 0o644


# ---------------------------------------------------------------- links

def test_a_link_planted_at_the_temporary_name_is_neither_followed_nor_truncated(
        out_dir, victim, monkeypatch):
    # the attacker guesses the name (here: made guessable) and plants a link there first
    names = iter(['0123456789abcdef', 'fedcba9876543210'])
    monkeypatch.setattr(files.secrets, 'token_hex', lambda n: next(names))
    planted = out_dir / '.table.csv.0123456789abcdef.tmp'
    planted.symlink_to(victim)
    write_text(out_dir / 'table.csv', 'results')
    assert victim.read_bytes() == b'years of work'
    assert snapshot(out_dir) == {'.table.csv.0123456789abcdef.tmp': ('link', str(victim)),
                                 'table.csv': ('file', b'results')}


@pytest.mark.parametrize('dangling', [False, True])
def test_an_output_that_is_a_link_is_replaced_and_its_target_untouched(out_dir, victim,
                                                                       dangling):
    target = out_dir / 'nowhere' if dangling else victim
    (out_dir / 'table.csv').symlink_to(target)
    write_text(out_dir / 'table.csv', 'results')
    assert victim.read_bytes() == b'years of work' and not (out_dir / 'nowhere').exists()
    assert snapshot(out_dir) == {'table.csv': ('file', b'results')}


def test_a_folder_the_user_names_through_a_link_is_followed(tmp_path):
    scratch = tmp_path / 'scratch'
    scratch.mkdir()
    (tmp_path / 'runs').symlink_to(scratch)
    write_text(tmp_path / 'runs' / 'a.txt', 'x')
    assert (scratch / 'a.txt').read_text() == 'x'


def test_temporary_names_say_which_output_they_were_for(out_dir, monkeypatch):
    seen = []
    real = files._temporary

    def spy(folder_fd, name):
        made = real(folder_fd, name)
        seen.append(made[0])
        return made

    monkeypatch.setattr(files, '_temporary', spy)
    write_text(out_dir / 'chunk_000001.parquet', 'x')
    assert temporary_target(seen[0]) == 'chunk_000001.parquet'
    assert temporary_target('chunk_000001.parquet') is None
    assert temporary_target('chunk_000001.parquet.tmp') is None


# ---------------------------------------------------------------- refusals

def test_an_output_that_is_an_input_is_refused_by_identity(tmp_path):
    spec = tmp_path / 'spec.yaml'
    spec.write_text('sweep: {}')
    os.link(spec, tmp_path / 'hard.yaml')
    (tmp_path / 'soft.yaml').symlink_to(spec)
    with reading(tmp_path / 'soft.yaml'):           # the input named through a link too
        for name in ('spec.yaml', 'hard.yaml', 'soft.yaml'):
            with pytest.raises(OutputRefused, match=f'{name}: is an input of this command'):
                write_text(tmp_path / name, 'results')
    assert spec.read_text() == 'sweep: {}'
    write_text(tmp_path / 'hard.yaml', 'x')          # outside the block: an ordinary file
    assert spec.read_text() == 'sweep: {}'            # replaced by name, the input kept


@pytest.mark.parametrize('given', ['folder', 'mcap'])
def test_an_output_inside_an_input_bag_folder_is_refused(tmp_path, given):
    bag = tmp_path / 'run'
    (bag / 'deeper').mkdir(parents=True)
    (bag / 'run_0.mcap').write_bytes(b'mcap')
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}')
    before = snapshot(tmp_path)
    source = bag if given == 'folder' else bag / 'run_0.mcap'
    with reading(source):
        for out in (bag / 'new.csv', bag / 'deeper' / 'x.png', bag / 'metadata.yaml'):
            with pytest.raises(OutputRefused, match=f'{out}: .*input'):
                write_text(out, 'x')
        with pytest.raises(OutputRefused, match='lies inside the input bag folder'):
            check_new_folder(bag / 'recovered')
        write_text(tmp_path / 'beside.csv', 'x')        # beside the bag is fine
    assert snapshot(tmp_path) == {**before, 'beside.csv': ('file', b'x')}


def test_a_loose_mcap_files_folder_is_not_a_bag_folder(tmp_path):
    (tmp_path / 'loose.mcap').write_bytes(b'mcap')
    with reading(tmp_path / 'loose.mcap'):
        write_text(tmp_path / 'loose.csv', 'x')
    assert (tmp_path / 'loose.csv').read_text() == 'x'


@pytest.mark.parametrize('case, fragment', [
    ('directory', 'is a directory'),
    ('link to a directory', 'is a directory'),
    ('fifo', 'is not a regular file'),
    ('missing folder', 'the folder .* does not exist'),
    ('file as folder', 'the folder .* is not a folder'),
])
def test_outputs_that_are_no_file_are_refused_before_anything_is_written(tmp_path, case,
                                                                         fragment):
    (tmp_path / 'dir').mkdir()
    (tmp_path / 'file').write_text('data')
    path = {'directory': tmp_path / 'dir',
            'link to a directory': tmp_path / 'dirlink',
            'fifo': tmp_path / 'fifo',
            'missing folder': tmp_path / 'nope' / 'x.csv',
            'file as folder': tmp_path / 'file' / 'x.csv'}[case]
    if case == 'link to a directory':
        path.symlink_to(tmp_path / 'dir')
    if case == 'fifo':
        os.mkfifo(path)
    before = snapshot(tmp_path)
    with pytest.raises(OutputRefused, match=f'{path}: {fragment}'):
        write_text(path, 'x')
    with pytest.raises(OutputRefused):
        check_output(path)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize('kind', ['folder', 'file', 'dangling link'])
def test_a_new_folder_never_replaces_anything(tmp_path, kind):
    path = tmp_path / 'run'
    if kind == 'folder':
        path.mkdir()
    elif kind == 'file':
        path.write_text('x')
    else:
        path.symlink_to(tmp_path / 'nowhere')
    with pytest.raises(OutputRefused, match='run exists already, not overwriting'):
        check_new_folder(path)


def test_two_outputs_of_one_command_on_one_file_are_refused(tmp_path):
    (tmp_path / 'sub').mkdir()
    (tmp_path / 'link').symlink_to(tmp_path / 'sub')
    with pytest.raises(OutputRefused, match='named for two outputs of this command'):
        files.check_outputs(tmp_path / 'sub' / 'a.csv', tmp_path / 'link' / 'a.csv')
    assert files.check_outputs(tmp_path / 'a.csv', tmp_path / 'a.csv.json') == [
        tmp_path / 'a.csv', tmp_path / 'a.csv.json']


def test_reading_blocks_nest_and_end(tmp_path):
    a, b = tmp_path / 'a.yaml', tmp_path / 'b.yaml'
    a.write_text('a')
    b.write_text('b')
    with reading(a):
        with reading(a, b):
            with pytest.raises(OutputRefused):
                check_output(b)
        with pytest.raises(OutputRefused):
            check_output(a)                          # still an input of the outer block
        check_output(b)
    check_output(a)


# ---------------------------------------------------------------- files written as they happen

@pytest.mark.parametrize('planted', ['link', 'dangling link', 'file'])
def test_a_new_stream_file_never_opens_what_is_there(out_dir, victim, planted):
    path = out_dir / 'sim_node.log'
    if planted == 'file':
        path.write_bytes(b'an earlier log')
    else:
        path.symlink_to(victim if planted == 'link' else out_dir / 'nowhere')
    before = snapshot(out_dir)
    with pytest.raises(FileExistsError):
        files.open_new(path)
    assert snapshot(out_dir) == before and victim.read_bytes() == b'years of work'


def test_a_new_stream_file_is_written_and_read_back(out_dir):
    with files.open_new(out_dir / 'a.log', readable=True) as fh:
        fh.write(b'line\n')
        fh.flush()
        assert os.pread(fh.fileno(), 5, 0) == b'line\n'
    with reading(out_dir / 'a.log'), pytest.raises(OutputRefused):
        files.open_new(out_dir / 'a.log')
