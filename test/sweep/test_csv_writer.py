"""The fast CSV writer of `write_table` (issue 43): byte for byte what ``DataFrame.to_csv``
writes, and ``to_csv`` itself for every frame it does not handle exactly."""
from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest

from crawler_sim.sweep import tables
from crawler_sim.sweep.tables import read_table, write_table

SPECIAL = [0.0, -0.0, 1e-300, -1e-300, 5e-324, -5e-324, 2.2250738585072014e-308, 1e-5, 1e-4,
           9.999999999999999e-05, 0.1, 0.30000000000000004, 1.0, -1.0, 100.0, 12345.0, 1e15,
           9999999999999998.0, 1e16, 1e16 + 2.0, 2.0 ** 53, 2.0 ** 63, 1e22, 1e300,
           1.7976931348623157e308, -1.7976931348623157e308, np.inf, -np.inf, 1 / 3, 2 / 3]


def _floats(rng: np.random.Generator, n: int) -> np.ndarray:
    """Floats of every magnitude: the special ones, random bit patterns (subnormal to huge),
    integral values, and k * 1e-4 (a run's times)."""
    bits = rng.integers(0, 2 ** 64, n, dtype=np.uint64).view(np.float64)
    bits = np.where(np.isfinite(bits), bits, 1.5)
    parts = [np.array(SPECIAL), bits, np.round(rng.standard_normal(n) * 1e6),
             np.arange(n) * 1e-4, rng.standard_normal(n) * 10.0 ** rng.integers(-320, 300, n)]
    return np.concatenate(parts)[:n]


def _frame(n: int, seed: int = 0, index_name: str | None = 't') -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    df = pd.DataFrame({
        'x_0': _floats(rng, n),
        # few distinct values (formatted once each), -0.0 and 0.0 among them
        'v_0': rng.choice(np.array([0.0, -0.0, 0.25, -1e-300, 7e22, np.inf]), n),
        'contact_0': rng.integers(-1, 2, n).astype(np.int8),
        'body': rng.integers(-2 ** 62, 2 ** 62, n, dtype=np.int64),
        'u': rng.integers(0, 2 ** 64 - 1, n, dtype=np.uint64),
        'com': rng.permutation(_floats(rng, n)),
    }, index=pd.Index(np.arange(n) * 1e-4, name=index_name))
    return df


def _pandas(df: pd.DataFrame) -> bytes:
    text = io.StringIO()
    df.to_csv(text)
    return text.getvalue().encode('utf-8')


def _fast(df: pd.DataFrame) -> bytes | None:
    out = io.BytesIO()
    return out.getvalue() if tables._write_csv_fast(df, out) else None


@pytest.mark.parametrize('index_name', ['t', None])
@pytest.mark.parametrize('rows', [1, 2, 7, 1000])
def test_fast_writer_is_to_csv_byte_for_byte(monkeypatch, rows, index_name):
    monkeypatch.setattr(tables, '_CSV_ROWS', 300)          # several chunks, a partial last one
    df = _frame(rows, seed=rows, index_name=index_name)
    fast = _fast(df)
    assert fast is not None, 'a plain frame takes the fast path'
    assert fast == _pandas(df)


def test_fast_writer_unnamed_range_index_and_events_layout():
    df = pd.DataFrame({'t': [0.471392676, 0.471392676, 0.971392676],
                       'body': np.array([0, 1, 0], dtype=np.int64),
                       'old': np.array([0, 1, 1], dtype=np.int8),
                       'new': np.array([1, 0, 0], dtype=np.int8)})
    for frame in (df, df.set_index('t')):
        assert _fast(frame) == _pandas(frame)
    assert _pandas(df).startswith(b',t,body,old,new\n0,0.471392676,0,0,1\n')


def test_every_bit_pattern_class_formats_as_numpy_does():
    # pandas writes float64 as ndarray.astype(str); the fast writer uses repr (and distinct
    # values once): the same text for 200,000 random finite bit patterns
    rng = np.random.default_rng(43)
    bits = rng.integers(0, 2 ** 64, 200_000, dtype=np.uint64).view(np.float64)
    bits = bits[np.isfinite(bits)]
    assert tables._csv_text(bits) == bits.astype(str).tolist()
    repeated = np.repeat(bits[:100], 50)                   # takes the distinct-values path
    assert tables._csv_text(repeated) == repeated.astype(str).tolist()


@pytest.mark.parametrize('change', [
    'nan column', 'nan index', 'float32', 'object column', 'string index', 'comma name',
    'quote name', 'newline name', 'int name', 'multiindex columns', 'multiindex rows', 'empty',
    'no columns', 'nullable ints', 'bool', 'categorical', 'datetime'])
def test_other_frames_fall_back_to_to_csv(tmp_path, change):
    df = _frame(20)
    if change == 'nan column':
        df.iloc[3, 0] = np.nan
    elif change == 'nan index':
        df.index = pd.Index([np.nan, *df.index[1:]], name='t')
    elif change == 'float32':
        df['x_0'] = df['x_0'].astype(np.float32)
    elif change == 'object column':
        df['x_0'] = ['a,b'] * len(df)
    elif change == 'string index':
        df.index = pd.Index([f'r{i}' for i in range(len(df))], name='t')
    elif change == 'comma name':
        df = df.rename(columns={'x_0': 'x,0'})
    elif change == 'quote name':
        df.index.name = 'say "t"'
    elif change == 'newline name':
        df = df.rename(columns={'com': 'c\nom'})
    elif change == 'int name':
        df = df.rename(columns={'com': 5})
    elif change == 'multiindex columns':
        df.columns = pd.MultiIndex.from_tuples([('a', c) for c in df.columns])
    elif change == 'multiindex rows':
        df.index = pd.MultiIndex.from_arrays([df.index, df.index], names=['t', 's'])
    elif change == 'empty':
        df = df.iloc[:0]
    elif change == 'no columns':
        df = df[[]]
    elif change == 'nullable ints':
        df['body'] = df['body'].astype('Int64')
    elif change == 'bool':
        df['contact_0'] = df['contact_0'] > 0
    elif change == 'categorical':
        df['contact_0'] = df['contact_0'].astype('category')
    elif change == 'datetime':
        df['x_0'] = pd.Timestamp('2026-01-01') + pd.to_timedelta(np.arange(len(df)), 's')
    assert _fast(df) is None
    path = write_table(df, tmp_path / 'f.csv')
    assert path.read_bytes() == _pandas(df)


def test_write_table_csv_file_is_to_csv(tmp_path):
    df = _frame(5000, seed=4)
    df.attrs['crawler_sim'] = {'kind': 'test'}
    path = write_table(df, tmp_path / 'f.csv')
    assert path.read_bytes() == _pandas(df)
    back = read_table(path)
    assert back.attrs['crawler_sim'] == {'kind': 'test'}
    np.testing.assert_array_equal(back['x_0'].to_numpy(), df['x_0'].to_numpy())
    assert np.signbit(back['v_0'].to_numpy()).tolist() == np.signbit(df['v_0']).tolist()
