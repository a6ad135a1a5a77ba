"""Checkpoints of a sweep that prove themselves: finished chunks as Parquet files in a directory.

A checkpoint directory holds ``checkpoint.json`` (the format, the package version and the spec)
and one ``chunk_NNNNNN.parquet`` per finished chunk (at least six digits, no other spelling).
Each chunk carries its identity in its Parquet schema metadata (key ``crawler_sim_chunk``):

- ``spec``: the SHA-256 of the spec's canonical JSON (the spec it belongs to),
- ``chunk``, ``first_scene``, ``rows``: which chunk it is and the scenes it holds,
- ``digest``: the SHA-256 of the spec digest, the chunk index and the chunk's values (column
  names, Arrow types and every value, floats to the bit).

:meth:`Checkpoint.load` verifies all of it, and that the ``scene`` column is exactly the
chunk's range, before a chunk is used; the sweep loads every finished chunk before it computes
anything (`crawler_sim.sweep.runner.sweep`). A chunk that fails (emptied, truncated to garbage,
copied from another chunk or another spec, values changed, a directory or a link in its place)
and any entry of the directory that is not one of the names above is refused with
:class:`CheckpointError`, one line naming the file and what to do: nothing the directory holds
is overwritten or deleted by a sweep, and no chunk is silently dropped or counted twice. The
digest guards against accidents (a copy, an edit, a damaged disk), not against someone who
recomputes it on purpose.

Checkpoints of format 1 (crawler_sim 0.1.0 before issue 38: a ``spec.json`` stamp, chunks
without identity) are refused, not migrated: their chunks carry nothing to verify them by, and
trusting them is exactly how rows were lost.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
import re
import stat
from typing import Any

import pandas as pd

from .. import __version__
from ..bag.files import temporary_target
from .spec import SpecError, SweepSpec
from .tables import write_atomically

__all__ = ['Checkpoint', 'CheckpointError', 'FORMAT', 'STAMP', 'chunk_name', 'spec_digest']

#: the format of the checkpoint directory and its chunks (1: crawler_sim 0.1.0, no identity)
FORMAT = 2
STAMP = 'checkpoint.json'
_OLD_STAMP = 'spec.json'            # format 1's stamp: the spec alone
_KEY = b'crawler_sim_chunk'
_CHUNK = re.compile(r'^chunk_(\d{6,})\.parquet$')
_REDO = 'move it away (or delete the checkpoint) and run again: a missing chunk is recomputed'


class CheckpointError(SpecError):
    """A checkpoint directory or one of its chunks cannot be used: one line naming the file,
    why, and what to do. A refused input (exit 2 on the command line, as a SpecError)."""


def chunk_name(index: int) -> str:
    """The file name of chunk ``index``: ``chunk_NNNNNN.parquet``."""
    return f'chunk_{index:06d}.parquet'


def spec_digest(spec: SweepSpec) -> str:
    """SHA-256 (hex) of the spec's canonical JSON: what ties a chunk to its spec."""
    return hashlib.sha256(_spec_json(spec).encode()).hexdigest()


def _spec_json(spec: SweepSpec) -> str:
    return json.dumps(spec.to_dict(), sort_keys=True)


def _ours(name: str) -> bool:
    """A name a checkpoint writes: its stamp, a chunk, or their temporary files (left by a
    run killed while writing; a later write leaves and removes its own)."""
    base = temporary_target(name) or name
    m = _CHUNK.match(base)
    return base == STAMP or (m is not None and chunk_name(int(m.group(1))) == base)


def _values_digest(spec_hex: str, index: int, table: Any) -> str:
    """SHA-256 of the spec digest, the chunk index, the column names and types and every value
    (JSON: floats by their shortest exact repr, so the digest sees every bit of them)."""
    h = hashlib.sha256(f'{spec_hex}:{index}:'.encode())
    h.update(json.dumps([[f.name, str(f.type)] for f in table.schema]).encode())
    h.update(json.dumps(table.to_pydict(), allow_nan=True, default=str).encode())
    return h.hexdigest()


class Checkpoint:
    """Finished chunks of one spec in a directory (see the module doc).

    Opening checks the directory: a stamp of another spec or of format 1, or an entry that a
    checkpoint does not write, is refused (:class:`CheckpointError`); a new directory gets the
    stamp.
    """

    def __init__(self, directory: str | os.PathLike, spec: SweepSpec) -> None:
        self.dir = Path(directory)
        self.spec = spec
        self.digest = spec_digest(spec)
        if self.dir.exists() and not self.dir.is_dir():
            raise CheckpointError(f'{self.dir}: the checkpoint must be a directory, this is a '
                                  'file; choose another checkpoint directory')
        self.dir.mkdir(parents=True, exist_ok=True)
        names = sorted(e.name for e in os.scandir(self.dir))
        if _OLD_STAMP in names and STAMP not in names:
            raise CheckpointError(
                f'{self.dir / _OLD_STAMP}: a checkpoint of format 1 (crawler_sim 0.1.0 before '
                f'issue 38), whose chunks carry no identity to verify them by; this version '
                f'reads format {FORMAT} only: finish the sweep with the version that started '
                'it, or delete the checkpoint to start again')
        strays = [n for n in names if not _ours(n)]
        if strays:
            more = f' (and {len(strays) - 1} more)' if len(strays) > 1 else ''
            raise CheckpointError(
                f'{self.dir / strays[0]}: not a file a checkpoint writes{more} (only {STAMP} '
                'and chunk_NNNNNN.parquet); move it away, or choose another checkpoint '
                'directory (a finished sweep deletes its checkpoint)')
        stamp = self.dir / STAMP
        data = json.dumps({'format': FORMAT, 'crawler_sim': __version__,
                           'spec': spec.to_dict()}, sort_keys=True)
        if stamp.exists():
            self._check_stamp(stamp)
        else:
            self.check_writable()
            write_atomically(stamp, lambda fh: fh.write(data.encode('utf-8')))

    def _check_stamp(self, stamp: Path) -> None:
        try:
            found = json.loads(stamp.read_text(encoding='utf-8'))
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise CheckpointError(f'{stamp}: not a checkpoint stamp ({type(exc).__name__}); '
                                  'delete the checkpoint to start again') from None
        if not isinstance(found, dict) or 'format' not in found or 'spec' not in found:
            raise CheckpointError(f'{stamp}: not a checkpoint stamp (no format and spec); '
                                  'delete the checkpoint to start again')
        if found['format'] != FORMAT:
            raise CheckpointError(f'{stamp}: checkpoint format {found["format"]!r} (written by '
                                  f'crawler_sim {found.get("crawler_sim", "?")}); this version '
                                  f'reads format {FORMAT}: delete the checkpoint to start again')
        if json.dumps(found['spec'], sort_keys=True) != _spec_json(self.spec):
            raise CheckpointError(f'{self.dir}: checkpoint of another sweep spec; use another '
                                  'directory or delete it')

    def check_writable(self) -> None:
        """Refuse a directory this process cannot write, before any work is done for it."""
        if not os.access(self.dir, os.W_OK | os.X_OK):
            raise CheckpointError(f'{self.dir}: the checkpoint directory is not writable; '
                                  'make it writable or choose another one')

    def path(self, index: int) -> Path:
        """The file of chunk ``index``."""
        return self.dir / chunk_name(index)

    def done(self, index: int) -> bool:
        """Whether chunk ``index`` has a file (not yet verified: see :meth:`load`)."""
        return os.path.lexists(self.path(index))

    def finished(self) -> list[int]:
        """Indices of the chunk files, in order, from one listing of the directory (not one stat
        per chunk: a spec of a billion scenes has millions of chunks)."""
        found = []
        for entry in os.scandir(self.dir):
            m = _CHUNK.match(entry.name)
            if m is not None and chunk_name(int(m.group(1))) == entry.name:
                found.append(int(m.group(1)))
        return sorted(found)

    def load(self, index: int) -> pd.DataFrame:
        """Chunk ``index``, verified (its file, its identity, its scenes, its values): a
        :class:`CheckpointError` naming the file says what does not match."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = self.path(index)

        def refuse(why: str) -> CheckpointError:
            return CheckpointError(f'{path}: {why}; {_REDO}')

        try:
            mode = os.lstat(path).st_mode
        except OSError as exc:
            raise refuse(f'cannot be read ({exc.strerror})') from None
        if not stat.S_ISREG(mode):
            kind = 'a directory' if stat.S_ISDIR(mode) else (
                'a symbolic link' if stat.S_ISLNK(mode) else 'not a regular file')
            raise refuse(f'{kind}, not a chunk file')
        if index >= self.spec.n_chunks:
            raise refuse(f'this spec has chunks 0 to {self.spec.n_chunks - 1} only')
        try:
            table = pq.read_table(path)
        except (pa.ArrowException, OSError, ValueError, EOFError) as exc:
            reason = ' '.join(str(exc).replace(str(path), 'the file').split())[:120]
            reason = reason or type(exc).__name__
            raise refuse(f'not a readable Parquet file ({reason})') from None
        raw = (table.schema.metadata or {}).get(_KEY)
        try:
            ident = json.loads(raw) if raw is not None else None
        except ValueError:
            ident = None
        if not isinstance(ident, dict):
            raise refuse('carries no chunk identity (not written by a checkpoint of this '
                         'format)')
        scenes = self.spec.chunk_scenes(index)
        start, rows = scenes.start, len(scenes)
        if ident.get('spec') != self.digest:
            raise refuse('a chunk of another sweep spec')
        if ident.get('chunk') != index or ident.get('first_scene') != start:
            raise refuse(f'holds chunk {ident.get("chunk")!r} (scenes from '
                         f'{ident.get("first_scene")!r}), not chunk {index} (scenes from {start})')
        if ident.get('rows') != rows or table.num_rows != rows:
            raise refuse(f'holds {table.num_rows} rows (its identity says '
                         f'{ident.get("rows")!r}); chunk {index} has {rows}')
        if ident.get('digest') != _values_digest(self.digest, index, _bare(table)):
            raise refuse('its values do not match its digest (changed after it was written)')
        if 'scene' not in table.column_names or (
                table.column('scene').to_pylist() != list(range(start, start + rows))):
            raise refuse(f'its scene column is not scenes {start} to {start + rows - 1}')
        return table.to_pandas()

    def save(self, index: int, df: pd.DataFrame) -> None:
        """Write chunk ``index`` with its identity, atomically: a killed run never leaves half a
        chunk, a failed write (full disk) no temporary file, and the OSError names the chunk's
        path."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(df, preserve_index=False)
        ident = {'format': FORMAT, 'spec': self.digest, 'chunk': index,
                 'first_scene': index * self.spec.chunk_size, 'rows': table.num_rows,
                 'digest': _values_digest(self.digest, index, _bare(table))}
        table = table.replace_schema_metadata({**(table.schema.metadata or {}),
                                               _KEY: json.dumps(ident).encode()})
        write_atomically(self.path(index), lambda fh: pq.write_table(table, fh))


def _bare(table: Any) -> Any:
    """The table without schema metadata: the digest covers values, names and types only."""
    return table.replace_schema_metadata(None)
