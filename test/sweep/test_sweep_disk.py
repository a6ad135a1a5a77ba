"""A full disk or an unwritable output: an error naming the file, and no temporary file left.

A real "No space left on device" comes from /dev/full: the temporary file a write of the output
goes through (`crawler_sim.bag.files`, created beside it under a random name that nothing can
plant a link at) has /dev/full put behind its descriptor, so the kernel fails the write exactly
as on a full disk.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

import pandas as pd
import pytest

from crawler_sim import cli
from crawler_sim.bag import files
from crawler_sim.sweep import spec_from_dict
from crawler_sim.sweep.checkpoint import STAMP, Checkpoint
from crawler_sim.sweep.tables import read_table, write_table

pytestmark = pytest.mark.skipif(not os.path.exists('/dev/full'), reason='needs /dev/full')

FRAME = pd.DataFrame({'x': [float(i) for i in range(50_000)]})   # larger than any write buffer
SPEC_YAML = '''sweep:
  name: tiny
  periods: 4
  samples_per_period: 8
  chunk_size: 2
  base:
    crawler: {masses: [0.5, 1.0], mu: 0.3}
    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 2.0, asymmetry: 0.2}
  grid:
    gait.asymmetry: [0.2, 0.5, 0.8]
'''


FULL: set[str] = set()             # outputs whose next write finds the disk full


@pytest.fixture(autouse=True)
def _full_disk(monkeypatch):
    """Writes of the outputs in FULL go to /dev/full (through the temporary's descriptor)."""
    real = files._temporary
    FULL.clear()

    def temporary(folder_fd: int, name: str):
        tmp, fd, made = real(folder_fd, name)
        target = os.path.join(os.readlink(f'/proc/self/fd/{folder_fd}'), name)
        if target in FULL:                  # once: the next write of that output has room
            FULL.discard(target)
            dev = os.open('/dev/full', os.O_WRONLY)
            os.dup2(dev, fd)
            os.close(dev)
        return tmp, fd, made

    monkeypatch.setattr(files, '_temporary', temporary)


def full(path: Path) -> Path:
    """Make the disk full for the next write of the output ``path``; returns ``path``."""
    FULL.add(os.path.realpath(path))
    return path


def leftovers(directory: Path) -> list[str]:
    return sorted(str(p.relative_to(directory)) for p in directory.rglob('*.tmp'))


@pytest.mark.parametrize('suffix', ['parquet', 'csv'])
def test_a_table_on_a_full_disk_is_an_error_naming_it_and_the_old_file_stays(tmp_path, suffix):
    path = tmp_path / f'out.{suffix}'
    write_table(FRAME.head(3), path)                 # an older result that must survive
    full(path)
    with pytest.raises(OSError) as info:
        write_table(FRAME, path)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(path)
    assert str(path) in str(info.value) and 'No space left on device' in str(info.value)
    assert leftovers(tmp_path) == []
    assert len(read_table(path)) == 3


def test_a_table_in_an_unwritable_place_is_an_error_naming_it(tmp_path):
    (tmp_path / 'file').write_text('not a directory')
    path = tmp_path / 'file' / 'out.parquet'
    with pytest.raises(files.OutputRefused, match=f'{path}: the folder .* is not a folder'):
        write_table(FRAME, path)
    assert leftovers(tmp_path) == [] and (tmp_path / 'file').read_text() == 'not a directory'


def test_a_checkpoint_chunk_on_a_full_disk_is_an_error_naming_it(tmp_path):
    spec = spec_from_dict({'base': {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
                                    'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                             'frequency': 1.0, 'asymmetry': 0.5}}})
    stamp = full(tmp_path / STAMP)
    with pytest.raises(OSError) as info:
        Checkpoint(tmp_path, spec)
    # no half-written stamp, which a later run would take for the stamp of another spec
    assert info.value.filename == str(tmp_path / STAMP) and not stamp.exists()
    assert not (tmp_path / STAMP).exists()
    store = Checkpoint(tmp_path, spec)
    chunk = tmp_path / 'chunk_000004.parquet'
    full(chunk)
    with pytest.raises(OSError) as info:
        store.save(4, FRAME)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(chunk)
    assert leftovers(tmp_path) == [] and not chunk.exists() and not store.done(4)


def run(capsys, *args: str) -> tuple[int, list[str]]:
    code = cli.main(list(args))
    err = capsys.readouterr().err
    return code, [ln for ln in err.splitlines() if ln.startswith('crawler-sim: error:')]


def test_the_sweep_command_on_a_full_disk_names_the_file_and_leaves_no_tmp(tmp_path, capsys):
    spec = tmp_path / 'tiny.yaml'
    spec.write_text(SPEC_YAML)
    out = tmp_path / 'tiny.parquet'
    chunks = tmp_path / 'tiny.parquet.chunks'
    chunks.mkdir()
    full(chunks / 'chunk_000001.parquet')            # the checkpoint's disk fills up
    code, errors = run(capsys, 'sweep', str(spec), '-o', str(out), '--workers', '1', '--quiet')
    assert code == 1 and errors == [f'crawler-sim: error: {chunks / "chunk_000001.parquet"}: '
                                    'cannot write: No space left on device']
    assert leftovers(tmp_path) == [] and not out.exists()
    # then the output's disk: the chunks stay for a resumed run, the table is not half-written
    full(out)
    code, errors = run(capsys, 'sweep', str(spec), '-o', str(out), '--workers', '1', '--quiet')
    assert code == 1 and errors == [f'crawler-sim: error: {out}: cannot write: No space left '
                                    'on device']
    assert leftovers(tmp_path) == [] and not out.exists()
    assert sorted(p.name for p in chunks.glob('chunk_*')) == [
        'chunk_000000.parquet', 'chunk_000001.parquet']
