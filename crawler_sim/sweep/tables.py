"""Tables: runs as pandas DataFrames, and Parquet / CSV files that carry their metadata.

A simulated `Trajectory` and a recorded bag (`crawler_sim.bag.load`) become the same two frames:

- samples: one row per sample, index ``t`` [s]; per body i the columns ``x_i`` [m], ``v_i``
  [m/s], ``friction_i`` [N] (force of the ground on the body), ``contact_i`` (+1 sliding forward,
  0 stuck, -1 backward); per linkage j ``length_j`` [m], ``rate_j`` [m/s], ``linkage_force_j``
  [N] (on body j+1, positive pushes apart); and ``com`` [m], the centre of mass when the masses
  are known.
- events: one row per contact change, columns ``t`` [s], ``body``, ``old``, ``new``.

:func:`write_table` stores a frame's ``attrs['crawler_sim']`` (the sweep spec or the scene, and
the package version) with the file: Parquet schema metadata under the key ``crawler_sim``, or for
CSV a JSON file beside it, ``<name>.csv.json`` (the CSV itself is plain: ``pd.read_csv`` and
``np.genfromtxt`` read it as is). :func:`read_table` restores it into ``attrs`` (also from the
first line ``# crawler_sim: {JSON}`` of CSV files written before).

Files are written through :func:`crawler_sim.bag.files.write_atomically` (the package's one
way to write a file, re-exported here): a temporary file created exclusively beside the output,
never through a link, renamed over it once complete; an output that is one of the command's
inputs is refused. A failed write (a full disk, an unwritable directory) removes the temporary
file and raises an OSError naming the file, e.g. ``out.parquet: cannot write: No space left on
device``. Every file of a table (the CSV and its sidecar) is checked before the first is
written.
"""
from __future__ import annotations

import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from ..bag.files import OutputRefused, check_outputs, write_atomically
from ..core.trajectory import Trajectory, sample_frame

__all__ = ['trajectory_frames', 'run_frames', 'frames', 'write_table', 'read_table',
           'export_bag', 'export_paths', 'table_files', 'write_atomically', 'FORMATS']

FORMATS = ('parquet', 'csv')
_META_KEY = 'crawler_sim'
_CSV_PREFIX = f'# {_META_KEY}: '


def _samples(t: np.ndarray, x, v, friction, contact, lengths, rates, force,
             masses: np.ndarray | None) -> pd.DataFrame:
    # the one layout of a run's samples, shared with Trajectory.to_pandas and Run.to_pandas
    return sample_frame(t, x, v, friction, contact, lengths, rates, force, masses)


def _events(t, body, old, new) -> pd.DataFrame:
    return pd.DataFrame({'t': np.asarray(t, dtype=np.float64),
                         'body': np.asarray(body, dtype=np.int64),
                         'old': np.asarray(old, dtype=np.int8),
                         'new': np.asarray(new, dtype=np.int8)})


def trajectory_frames(tr: Trajectory) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(samples, events) of a simulated run (see the module doc for the columns)."""
    samples = _samples(tr.t, tr.x, tr.v, tr.friction, tr.contact, tr.lengths, tr.rates,
                       tr.linkage_force, tr.crawler.masses)
    ev = tr.events
    events = _events([e.time for e in ev], [e.body for e in ev], [e.old for e in ev],
                     [e.new for e in ev])
    meta = {'kind': 'trajectory', 'version': __version__, 'method': tr.method,
            'crawler': tr.crawler.to_dict()}
    samples.attrs[_META_KEY] = events.attrs[_META_KEY] = meta
    return samples, events


def run_frames(run: Any) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(samples, events) of a recorded run (`crawler_sim.bag.Run`, as `crawler_sim.bag.load`
    returns it); ``com`` is added when the bag's scene gives the masses."""
    crawler = run.scene.get('crawler') if isinstance(run.scene, dict) else None
    masses = None
    if isinstance(crawler, dict) and 'masses' in crawler:
        m = np.asarray(crawler['masses'], dtype=float)
        masses = m if m.size == run.x.shape[1] else None
    samples = _samples(run.t, run.x, run.v, run.friction, run.contact, run.lengths, run.rates,
                       run.linkage_force, masses)
    ev = run.events
    events = _events(ev.t, ev.body, ev.old, ev.new)
    meta = {'kind': 'bag', 'version': __version__, 'path': str(run.path), 'scene': run.scene,
            'truncated': bool(run.truncated)}
    samples.attrs[_META_KEY] = events.attrs[_META_KEY] = meta
    return samples, events


def frames(obj: Any) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(samples, events) of a `Trajectory`, a loaded bag, or a bag path (loaded here)."""
    if isinstance(obj, Trajectory):
        return trajectory_frames(obj)
    if isinstance(obj, (str, os.PathLike)):
        from ..bag import load
        obj = load(obj)
    return run_frames(obj)


def _format(path: Path, fmt: str | None, error: type[Exception] = ValueError) -> str:
    """The table format of ``path``; ``error`` (an output's: OutputRefused) if there is none."""
    fmt = fmt or path.suffix.lstrip('.').lower()
    if fmt not in FORMATS:
        raise error(f'{path}: format must be one of {", ".join(FORMATS)} (from the '
                         f'suffix .parquet or .csv, or given), got {fmt!r}')
    return fmt


def write_table(df: pd.DataFrame, path: str | os.PathLike, fmt: str | None = None) -> Path:
    """Write ``df`` to Parquet or CSV (``fmt`` or the suffix) with its ``attrs['crawler_sim']``,
    atomically (:func:`write_atomically`; OSError naming ``path`` if it cannot be written,
    :class:`crawler_sim.bag.files.OutputRefused` for an output that may not be written: both
    files of a CSV table are checked before either is written)."""
    path = Path(path)
    fmt = _format(path, fmt, OutputRefused)
    check_outputs(*table_files(path, fmt))
    meta = json.dumps(df.attrs.get(_META_KEY, {'version': __version__}), sort_keys=True,
                      default=str)
    if fmt == 'parquet':
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(df)
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               _META_KEY.encode(): meta.encode()})
        return write_atomically(path, lambda fh: pq.write_table(table, fh))

    def write_csv(fh: io.BufferedIOBase) -> None:
        if _write_csv_fast(df, fh):
            return
        text = io.TextIOWrapper(fh, encoding='utf-8', newline='')
        # no float_format: each float's shortest repr, which reads back exactly as '%.17g'
        # does, in 0.8x the time (200,001 x 12 numbers: 1.59 s against 2.01 s of CPU)
        df.to_csv(text)
        text.flush()
        text.detach()                               # the writer closes the file itself
    write_atomically(_sidecar(path), lambda fh: fh.write((meta + '\n').encode('utf-8')))
    return write_atomically(path, write_csv)


_CSV_ROWS = 65536                                   # rows formatted and written at a time
_CSV_SPECIAL = frozenset(',"\r\n')                   # a name with one of these is quoted


def _csv_plain(df: pd.DataFrame) -> bool:
    """Whether :func:`_write_csv_fast` writes ``df`` exactly as ``df.to_csv()`` would: a flat
    index and columns, plain names (nothing the csv module quotes), at least one row and column,
    every column and the index NumPy float64 without NaN, or NumPy integers."""
    if (isinstance(df.index, pd.MultiIndex) or isinstance(df.columns, pd.MultiIndex)
            or not len(df.index) or not len(df.columns)):
        return False
    for name in (df.index.name if df.index.name is not None else '', *df.columns):
        if not isinstance(name, str) or not _CSV_SPECIAL.isdisjoint(name):
            return False
    for dtype in (df.index.dtype, *df.dtypes):
        if not isinstance(dtype, np.dtype):
            return False                            # pandas extension types: categorical ...
        if dtype.kind == 'f':
            if dtype.itemsize != 8:                 # float32's own repr is not float64's
                return False
        elif dtype.kind not in 'iu':
            return False
    return not any(np.isnan(a).any() for a in _csv_arrays(df) if a.dtype.kind == 'f')


def _csv_arrays(df: pd.DataFrame) -> list[np.ndarray]:
    """The index and each column of ``df`` as NumPy arrays, in the CSV's order."""
    return [np.asarray(df.index), *(df.iloc[:, i].to_numpy() for i in range(df.shape[1]))]


def _csv_text(a: np.ndarray) -> list[str]:
    """The CSV text of each value of a float64 or integer array, as pandas writes it.

    pandas writes ``a.astype(str)``: for float64 NumPy's shortest repr, which is Python's
    ``repr(float)`` (-0.0, 5e-324, 1e+16, inf alike; NaN is refused by :func:`_csv_plain`),
    for integers ``str``. Python's repr is about twice as fast; a column with few distinct
    values (a velocity while stuck, a contact state) is formatted once per distinct bit
    pattern (not value: -0.0 is not 0.0)."""
    if a.dtype.kind != 'f':
        return list(map(str, a.tolist()))
    bits = a.view(np.int64)
    distinct, where = np.unique(bits, return_inverse=True)
    if 5 * len(distinct) > 4 * len(a):
        return list(map(float.__repr__, a.tolist()))
    text = np.array(list(map(float.__repr__, distinct.view(np.float64).tolist())),
                    dtype=object)
    return text[where].tolist()


def _write_csv_fast(df: pd.DataFrame, fh: io.BufferedIOBase) -> bool:
    """Write ``df`` as ``df.to_csv()`` writes it (byte for byte: header, index column, each
    float's shortest repr, ints as ints, the platform's line ending), 1.7x as fast; False,
    writing nothing, for a frame it does not handle exactly (see :func:`_csv_plain`)."""
    if not _csv_plain(df):
        return False
    nl = os.linesep
    header = [df.index.name if df.index.name is not None else '', *df.columns]
    fh.write((','.join(header) + nl).encode('utf-8'))
    arrays = _csv_arrays(df)
    for start in range(0, len(df.index), _CSV_ROWS):
        columns = [_csv_text(a[start:start + _CSV_ROWS]) for a in arrays]
        fh.write((nl.join(map(','.join, zip(*columns))) + nl).encode('utf-8'))
    return True


def table_files(path: str | os.PathLike, fmt: str | None = None) -> list[Path]:
    """Every file :func:`write_table` writes for ``path``: the table, and a CSV's sidecar."""
    path = Path(path)
    return [path, _sidecar(path)] if _format(path, fmt, OutputRefused) == 'csv' else [path]


def _sidecar(path: Path) -> Path:
    """The metadata file of a CSV table: ``<name>.json`` beside it."""
    return path.with_name(path.name + '.json')


def read_table(path: str | os.PathLike) -> pd.DataFrame:
    """Read a table written by :func:`write_table`, with ``attrs['crawler_sim']`` restored.

    ValueError naming the file (or its sidecar) if it cannot be read as one: not Parquet/CSV,
    not UTF-8, metadata that is not a JSON object."""
    path = Path(path)
    fmt = _format(path, None)
    try:
        if fmt == 'parquet':
            import pyarrow.parquet as pq

            table = pq.read_table(path)
            df = table.to_pandas()
            raw = (table.schema.metadata or {}).get(_META_KEY.encode())
            meta = _metadata(raw, f'{path}: its {_META_KEY} metadata') if raw else {}
        else:
            with open(path, encoding='utf-8') as fh:
                first = fh.readline()
                meta = (_metadata(first[len(_CSV_PREFIX):], f'{path}: its first line')
                        if first.startswith(_CSV_PREFIX) else {})
                if not meta:                # the current layout: a plain CSV and its sidecar
                    fh.seek(0)
                    side = _sidecar(path)
                    meta = (_metadata(side.read_bytes(), str(side)) if side.is_file()
                            else {})
                df = pd.read_csv(fh, index_col=0)
    except _Unreadable as exc:
        raise ValueError(str(exc)) from None
    except ValueError as exc:       # pyarrow, pandas, UTF-8: their messages name no file
        reason = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise ValueError(f'{path}: not a {fmt} table crawler_sim can read ({reason})') from None
    df.attrs[_META_KEY] = meta
    return df


class _Unreadable(Exception):
    """Metadata that is not what :func:`write_table` writes (the message names where)."""


def _metadata(raw: str | bytes, where: str) -> dict:
    """The metadata JSON object of a table, else :class:`_Unreadable` naming ``where``."""
    try:
        meta = json.loads(raw)
    except ValueError as exc:               # JSONDecodeError, UnicodeDecodeError
        raise _Unreadable(f'{where}: not the JSON metadata of a table ({exc})') from None
    if not isinstance(meta, dict):
        raise _Unreadable(f'{where}: the metadata must be a JSON object, got '
                          f'{type(meta).__name__}')
    return meta


def export_bag(bag: str | os.PathLike, out: str | os.PathLike, fmt: str | None = None
               ) -> tuple[Path, Path]:
    """Write a bag's samples to ``out`` and its events next to it (``<stem>_events<suffix>``).

    Every output file is checked (:func:`crawler_sim.bag.files.check_output`, with ``bag`` as
    the input) before the bag is read or anything is written."""
    from ..bag.files import reading

    out = Path(out)
    fmt = _format(out, fmt, OutputRefused)
    events_path = export_paths(out, fmt)[1]
    with reading(bag):
        check_outputs(*table_files(out, fmt), *table_files(events_path, fmt))
        samples, events = frames(bag)
        write_table(samples, out, fmt)
        write_table(events.set_index('t'), events_path, fmt)
    return out, events_path


def export_paths(out: str | os.PathLike, fmt: str | None = None) -> tuple[Path, Path]:
    """The two tables :func:`export_bag` writes for ``out``: samples and events."""
    out = Path(out)
    fmt = _format(out, fmt)
    return out, out.with_name(f'{out.stem}_events.{fmt}')
