"""Checkpoints that prove themselves (issue 38, item 3): a resumed sweep verifies every chunk
before it computes anything, and refuses (exit 2, one line naming the file) whatever does not
match, with no byte of the checkpoint changed; it never loses or duplicates a row."""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
import shutil

import pandas as pd
import pyarrow.parquet as pq
import pytest

from crawler_sim import cli
from crawler_sim.sweep import runner, spec_from_dict, sweep

# 14 scenes in chunks of 2: chunk 3 holds scenes 6 and 7
SPEC = {'name': 'ck', 'periods': 4, 'samples_per_period': 8, 'chunk_size': 2,
        'base': {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
                 'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                          'asymmetry': 0.5}},
        'grid': {'gait.asymmetry': [0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85,
                                    0.9, 0.95]}}
SPEC_YAML = json.dumps({'sweep': SPEC})       # JSON is YAML


@pytest.fixture(scope='module')
def whole() -> pd.DataFrame:
    return sweep(SPEC, workers=1)


@pytest.fixture(scope='module')
def finished(tmp_path_factory) -> Path:
    """A checkpoint of every chunk of SPEC (copied by each test before it tampers with it)."""
    ck = tmp_path_factory.mktemp('done') / 'ck'
    sweep(SPEC, workers=1, checkpoint=ck)
    return ck


def snapshot(directory: Path) -> dict[str, str]:
    """Every entry under ``directory``: a file's SHA-256, or what else it is."""
    out = {}
    for p in sorted(directory.rglob('*')):
        rel = str(p.relative_to(directory))
        out[rel] = ('link' if p.is_symlink() else 'dir' if p.is_dir()
                    else hashlib.sha256(p.read_bytes()).hexdigest())
    return out


def chunk(ck: Path, i: int) -> Path:
    return ck / f'chunk_{i:06d}.parquet'


def emptied(ck: Path) -> str:
    df = pd.read_parquet(chunk(ck, 3))
    df.iloc[:0].to_parquet(chunk(ck, 3), index=False)        # still valid Parquet
    return 'chunk_000003.parquet'


def replaced(ck: Path) -> str:
    shutil.copyfile(chunk(ck, 0), chunk(ck, 3))
    return 'chunk_000003.parquet'


def a_directory(ck: Path) -> str:
    chunk(ck, 5).unlink()
    chunk(ck, 5).mkdir()
    return 'chunk_000005.parquet'


def renamed(ck: Path) -> str:
    chunk(ck, 3).rename(ck / 'chunk_3.parquet')
    return 'chunk_3.parquet'


def garbage(ck: Path) -> str:
    data = chunk(ck, 3).read_bytes()
    chunk(ck, 3).write_bytes(data[:len(data) // 2])
    return 'chunk_000003.parquet'


def from_another_spec(ck: Path) -> str:
    other = ck.parent / 'other'
    sweep(dict(SPEC, periods=5), workers=1, checkpoint=other)
    shutil.copyfile(chunk(other, 3), chunk(ck, 3))
    shutil.rmtree(other)
    return 'chunk_000003.parquet'


def other_values(ck: Path) -> str:
    """The same rows and identity, one value changed (metadata kept, as pyarrow keeps it)."""
    table = pq.read_table(chunk(ck, 3))
    col = table.column_names.index('mean_speed')
    speeds = table.column(col).to_pylist()
    speeds[1] += 1e-3                     # a value that changes whatever it was (0.0 doubles)
    import pyarrow as pa
    table = table.set_column(col, table.field(col), pa.array(speeds, pa.float64()))
    pq.write_table(table, chunk(ck, 3))
    return 'chunk_000003.parquet'


def plain_pandas_rewrite(ck: Path) -> str:
    """Read and written back by pandas: the rows are right, the identity is gone."""
    pd.read_parquet(chunk(ck, 2)).to_parquet(chunk(ck, 2), index=False)
    return 'chunk_000002.parquet'


def extra_file(ck: Path) -> str:
    (ck / 'notes.txt').write_text('mine')
    return 'notes.txt'


def a_link(ck: Path) -> str:
    target = ck.parent / 'elsewhere.parquet'
    chunk(ck, 1).rename(target)
    chunk(ck, 1).symlink_to(target)
    return 'chunk_000001.parquet'


TAMPERING = [emptied, replaced, a_directory, renamed, garbage, from_another_spec, other_values,
             plain_pandas_rewrite, extra_file, a_link]


@pytest.mark.parametrize('tamper', TAMPERING, ids=lambda f: f.__name__)
def test_a_resumed_sweep_refuses_a_tampered_checkpoint_before_computing_and_changes_nothing(
        finished, tmp_path, monkeypatch, capsys, tamper):
    ck = tmp_path / 'out.parquet.chunks'
    shutil.copytree(finished, ck, symlinks=True)
    chunk(ck, 6).unlink()                 # one chunk still to compute: it must not be
    name = tamper(ck)
    before = snapshot(tmp_path)
    calls: list[int] = []
    real = runner.run_chunk
    monkeypatch.setattr(runner, 'run_chunk', lambda data, i: calls.append(i) or real(data, i))
    spec = tmp_path / 'ck.yaml'
    spec.write_text(SPEC_YAML)
    before[spec.name] = hashlib.sha256(spec.read_bytes()).hexdigest()
    code = cli.main(['sweep', str(spec), '-o', str(tmp_path / 'out.parquet'), '--workers', '1',
                     '--quiet'])
    errors = [ln for ln in capsys.readouterr().err.splitlines() if 'error' in ln]
    assert code == 2 and len(errors) == 1, errors
    assert errors[0].startswith(f'crawler-sim: error: {ck / name}: ')
    assert 'internal error' not in errors[0]
    assert calls == []                    # refused before computing anything
    assert snapshot(tmp_path) == before   # not a byte changed, nothing written
    assert not (tmp_path / 'out.parquet').exists()


def test_every_failing_chunk_is_counted_in_the_one_line(finished, tmp_path):
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    for i in (1, 3, 4):
        chunk(ck, i).write_bytes(b'not parquet')
    with pytest.raises(ValueError, match=r'chunk_000001\.parquet: not a readable Parquet file.*'
                       r'and 2 other chunks fail: chunk_000003\.parquet, chunk_000004\.parquet'):
        sweep(SPEC, workers=1, checkpoint=ck)


def test_after_the_refused_chunk_is_moved_away_the_resume_recomputes_it_exactly(
        finished, whole, tmp_path, monkeypatch):
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    replaced(ck)
    with pytest.raises(ValueError, match='holds chunk 0'):
        sweep(SPEC, workers=1, checkpoint=ck)
    chunk(ck, 3).unlink()
    calls: list[int] = []
    real = runner.run_chunk
    monkeypatch.setattr(runner, 'run_chunk', lambda data, i: calls.append(i) or real(data, i))
    df = sweep(SPEC, workers=1, checkpoint=ck)
    assert calls == [3]
    assert list(df.index) == list(range(14))          # no row lost, none twice
    pd.testing.assert_frame_equal(df, whole, check_exact=True)


def test_a_checkpoint_of_the_previous_format_is_refused_naming_its_format(finished, tmp_path):
    ck = tmp_path / 'ck'
    ck.mkdir()
    # format 1: spec.json holding the spec alone, chunks written by pandas without identity
    (ck / 'spec.json').write_text(json.dumps(spec_from_dict(SPEC).to_dict(), sort_keys=True))
    pd.read_parquet(chunk(finished, 0)).to_parquet(chunk(ck, 0), index=False)
    before = snapshot(ck)
    with pytest.raises(ValueError, match=r'spec\.json: a checkpoint of format 1 .* reads format '
                       '2 only'):
        sweep(SPEC, workers=1, checkpoint=ck)
    assert snapshot(ck) == before


def test_a_checkpoint_stamp_that_is_not_json_is_refused_naming_it(finished, tmp_path):
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    (ck / 'checkpoint.json').write_bytes(b'\x00garbage')
    with pytest.raises(ValueError, match=r'checkpoint\.json: not a checkpoint stamp'):
        sweep(SPEC, workers=1, checkpoint=ck)


def test_a_chunk_changed_while_a_large_sweep_runs_is_refused_when_read_back(
        finished, tmp_path, monkeypatch):
    # a spec of more than _IN_MEMORY_SCENES reads its chunks back at the end: verified again
    monkeypatch.setattr(runner, '_IN_MEMORY_SCENES', 4)
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    chunk(ck, 4).unlink()
    real = runner.run_chunk

    def run_and_tamper(data, i):
        replaced(ck)                      # chunk 3, verified at the start, changes meanwhile
        return real(data, i)

    monkeypatch.setattr(runner, 'run_chunk', run_and_tamper)
    with pytest.raises(ValueError, match=r'chunk_000003\.parquet: holds chunk 0'):
        sweep(SPEC, workers=1, checkpoint=ck)


@pytest.mark.skipif(os.geteuid() == 0, reason='root writes into a read-only directory')
def test_a_read_only_checkpoint_is_refused_before_computing(finished, tmp_path, monkeypatch):
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    chunk(ck, 2).unlink()
    ck.chmod(0o555)
    calls: list[int] = []
    monkeypatch.setattr(runner, 'run_chunk', lambda data, i: calls.append(i))
    try:
        with pytest.raises(ValueError, match='checkpoint directory is not writable'):
            sweep(SPEC, workers=1, checkpoint=ck)
    finally:
        ck.chmod(0o755)
    assert calls == []


def test_a_complete_read_only_checkpoint_still_gives_the_sweep(finished, whole, tmp_path):
    ck = tmp_path / 'ck'
    shutil.copytree(finished, ck)
    ck.chmod(0o555)
    try:
        df = sweep(SPEC, workers=1, checkpoint=ck)
    finally:
        ck.chmod(0o755)
    pd.testing.assert_frame_equal(df, whole, check_exact=True)
