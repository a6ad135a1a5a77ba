"""Running a sweep: chunks of scenes, local processes or a Dask client, checkpoints, metadata.

The scenes of a spec are cut into chunks of ``spec.chunk_size`` in spec order; one chunk is one
task (a local process job or a Dask task) and gives one DataFrame (:func:`run_chunk`, a pure
function of the spec and the chunk index). The result is the chunks concatenated in order, so it
does not depend on where or in which order the chunks ran: local and Dask give the same
DataFrame bit for bit.

With a ``checkpoint`` directory every finished chunk is written there as Parquet as soon as it
arrives, and a later run of the same spec reads finished chunks instead of recomputing them
(resuming after an interruption). The directory holds the spec; another spec is refused. Each
chunk carries its identity (spec digest, scene range, rows, a digest of its values) and every
finished chunk is verified before anything is computed: one that does not match is refused
naming its file, never dropped or counted twice (`crawler_sim.sweep.checkpoint`).

Local worker processes die with the driver: each arms the Linux parent-death signal (SIGKILL)
when it starts, so a driver killed by SIGTERM or SIGKILL takes them with it, and a driver that is
interrupted (Ctrl-C) or fails kills them before the error propagates.

The driver streams: chunks are planned lazily (each from its own index, O(chunk_size)), only a
few chunks per worker are in flight at once, and with a checkpoint a finished chunk lives on
disk, not in the driver's memory, until the result is assembled at the end. So a spec of a
billion scenes starts computing, reporting progress and checkpointing at once, with the
driver's memory bounded by the chunks in flight.
"""
from __future__ import annotations

from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
import ctypes
import itertools
import json
import math
import multiprocessing
import os
import signal
import sys
import time
from typing import Any, Callable, Iterable, Iterator

import pandas as pd

from .. import __version__
from ..core.scene import SceneError
from .checkpoint import Checkpoint, CheckpointError
from .metrics import FIGURES, scene_figures
from .spec import SweepSpec, spec_from_dict

__all__ = ['sweep', 'run_chunk', 'chunk_params', 'chunk_len', 'n_chunks', 'assemble',
           'metadata', 'Progress', 'Checkpoint']

Progress = Callable[[int, int], None]


def n_chunks(spec: SweepSpec) -> int:
    """Number of chunks of ``spec`` (`SweepSpec.n_chunks`)."""
    return spec.n_chunks


def chunk_len(spec: SweepSpec, index: int) -> int:
    """Number of scenes of chunk ``index`` (the last chunk may be short)."""
    return len(spec.chunk_scenes(index))


def chunk_params(spec: SweepSpec, index: int) -> list[dict]:
    """The parameter sets of chunk ``index`` (scenes index * chunk_size onwards), each computed
    from its scene index: O(chunk_size) wherever the chunk lies in the spec."""
    return [spec.param_set(k) for k in spec.chunk_scenes(index)]


def _row(spec: SweepSpec, scene_index: int, params: dict) -> dict:
    row: dict[str, Any] = {'scene': scene_index}
    for key in spec.params:
        value = params.get(key)
        row[key] = json.dumps(value) if isinstance(value, (list, dict)) else value
    try:
        row.update(scene_figures(spec.scene(params), spec.periods, spec.samples_per_period))
        row['error'] = ''
    except (SceneError, ValueError, ArithmeticError, RuntimeError) as exc:
        # one bad combination (or a solver failure) is a row with its reason, not a lost sweep
        row['error'] = f'{type(exc).__name__}: {exc}'.splitlines()[0]
    return row


def run_chunk(spec_data: dict, index: int) -> pd.DataFrame:
    """Rows of chunk ``index`` of the spec given as plain data (``SweepSpec.to_dict()``).

    A pure function: the same arguments give the same DataFrame on any machine and process.
    """
    spec = spec_from_dict(spec_data)
    start = index * spec.chunk_size
    rows = [_row(spec, start + k, p) for k, p in enumerate(chunk_params(spec, index))]
    return _columns(pd.DataFrame(rows), spec)


def _columns(df: pd.DataFrame, spec: SweepSpec) -> pd.DataFrame:
    """Fixed column order and dtypes, whatever rows a chunk holds (errors only, p varies)."""
    for name in FIGURES:
        if name not in df:
            df[name] = pd.NA if name in ('steady', 'verify_ok') else math.nan
    sticks = sorted((c for c in df if c.startswith('stick_fraction_')),
                    key=lambda c: int(c.rsplit('_', 1)[1]))
    for name in FIGURES + tuple(sticks):
        if name in ('bodies', 'transient_periods'):
            df[name] = df[name].astype('Int64')
        elif name in ('steady', 'verify_ok'):
            df[name] = df[name].astype('boolean')
        else:
            df[name] = df[name].astype('float64')
    df['error'] = df['error'].astype(str) if 'error' in df else ''
    params = [k for k in spec.params if k not in FIGURES]    # 'bodies' is also a figure
    return df[['scene', *params, *FIGURES, *sticks, 'error']]


def assemble(spec: SweepSpec, frames: Iterable[pd.DataFrame]) -> pd.DataFrame:
    """The sweep's DataFrame from its chunks in order, with the spec and version in ``attrs``."""
    df = pd.concat(list(frames), ignore_index=True)
    # a body that exists in some chunks only: its stick fraction is NaN elsewhere
    df = _columns(df.copy(), spec)
    df = df.set_index('scene')
    df.attrs['crawler_sim'] = metadata(spec)
    return df


def metadata(spec: SweepSpec) -> dict:
    """What re-runs a sweep: the spec as plain data and the package version."""
    return {'kind': 'sweep', 'version': __version__, 'spec': spec.to_dict()}


def bar(label: str) -> Progress:
    """A progress bar on stderr: rewritten in place on a terminal, a line per 10 % otherwise."""
    tty = sys.stderr.isatty()
    start = time.perf_counter()
    shown = [-1]

    def show(done: int, total: int) -> None:
        frac = done / total if total else 1.0
        elapsed = time.perf_counter() - start
        eta = f'{elapsed / frac - elapsed:.0f} s' if frac > 0 else '?'
        text = (f'{label}: [{"#" * int(30 * frac):<30}] {done}/{total} scenes '
                f'{elapsed:.1f} s, ETA {eta}')
        if tty:
            print('\r' + text, end='\n' if done >= total else '', file=sys.stderr, flush=True)
        elif int(10 * frac) > shown[0]:
            shown[0] = int(10 * frac)
            print(text, file=sys.stderr, flush=True)
    return show


def _warm_up(spec: SweepSpec) -> None:
    """Run a short first scene, so forked workers inherit scipy's root finders (about 1 s of
    imports) instead of each paying for them."""
    try:
        scene_figures(spec.scene(spec.param_set(0)), 4, 4)
    except (SceneError, ValueError, ArithmeticError, RuntimeError):
        pass


_PR_SET_PDEATHSIG = 1         # <linux/prctl.h>


def _die_with_parent(parent: int) -> None:
    """Ask Linux to SIGKILL this process when its parent dies (prctl PR_SET_PDEATHSIG), then
    exit if the parent ``parent`` already died before that was armed (we were re-parented).
    Elsewhere (no prctl) only the driver's own clean-up on an exception applies."""
    if sys.platform.startswith('linux'):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL),
                                                    0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:
        os._exit(1)       # the driver is gone: nobody would read our results


def _worker_init(parent: int) -> None:
    """Pool worker set-up: die with the driver; leave Ctrl-C to the driver (a terminal sends it
    to the whole process group), which then stops the workers itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent(parent)


def _kill_workers(pool: ProcessPoolExecutor, before: set) -> None:
    """Kill the pool's worker processes now: Python 3.14's ``kill_workers``, else the
    multiprocessing children that appeared since ``before`` (the pool's, started by it)."""
    kill = getattr(pool, 'kill_workers', None)
    if kill is not None:
        kill()
        return
    for proc in set(multiprocessing.active_children()) - before:
        proc.kill()
        proc.join(timeout=5)


def _local(spec: SweepSpec, todo: Iterator[int], n_todo: int, workers: int,
           on_done: Callable) -> None:
    """Run chunks ``todo`` (``n_todo`` of them) in this process or in ``workers`` processes."""
    data = spec.to_dict()
    if workers <= 1 or n_todo <= 1:
        for i in todo:
            on_done(i, run_chunk(data, i))
        return
    _warm_up(spec)
    methods = multiprocessing.get_all_start_methods()
    # fork: the workers inherit the imported package instead of importing it again
    ctx = multiprocessing.get_context('fork' if 'fork' in methods else None)
    workers = min(workers, n_todo)
    before = set(multiprocessing.active_children())
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                             initargs=(os.getpid(),)) as pool:
        try:
            _stream(pool, data, todo, 2 * workers, on_done)
        except BaseException:
            # interrupted (Ctrl-C) or failed (a chunk, a full disk): the chunks in flight are
            # abandoned, so stop their workers now rather than wait for them to finish
            pool.shutdown(wait=False, cancel_futures=True)
            _kill_workers(pool, before)
            raise


def _stream(pool: ProcessPoolExecutor, data: dict, todo: Iterator[int], window: int,
            on_done: Callable) -> None:
    """Keep ``window`` chunks in flight on ``pool``; hand each result to ``on_done`` as it
    arrives. Submitting every chunk up front held millions of pending calls in the driver."""
    pending: dict[Future, int] = {}
    for i in itertools.islice(todo, window):
        pending[pool.submit(run_chunk, data, i)] = i
    while pending:
        finished, _ = wait(pending, return_when=FIRST_COMPLETED)
        for fut in finished:
            on_done(pending.pop(fut), fut.result())
            for i in itertools.islice(todo, 1):
                pending[pool.submit(run_chunk, data, i)] = i


# Up to this many scenes a checkpointed sweep also keeps its finished chunks in memory: the
# result holds them anyway, and reading back thousands of small Parquet files costs seconds.
# Beyond it (a run that may last days) they live on disk only, so the driver's memory stays
# flat while it runs; the result is read back at the end.
_IN_MEMORY_SCENES = 1_000_000


def sweep(spec: SweepSpec | dict | str | os.PathLike, *, client: Any = None,
          workers: int | None = None, checkpoint: str | os.PathLike | None = None,
          progress: bool | Progress = False) -> pd.DataFrame:
    """Run every scene of ``spec`` and return one row per scene (index ``scene``).

    Parameters
    ----------
    spec : SweepSpec, its plain-data form, or the path of a sweep YAML file.
    client : a ``dask.distributed.Client``; the chunks run on its cluster. Default: local.
    workers : local processes (default: every core); 1 runs in this process.
    checkpoint : directory of finished chunks; an interrupted sweep resumes from it.
    progress : True for a bar on stderr, or a callable ``(done_scenes, total_scenes)``.

    Returns
    -------
    DataFrame with the swept parameters, the figures of `crawler_sim.sweep.metrics.FIGURES`,
    ``stick_fraction_<i>`` per body and ``error`` ('' when the scene ran). ``attrs['crawler_sim']``
    holds the spec and the package version.
    """
    if isinstance(spec, (str, os.PathLike)):
        from .spec import load_spec
        spec = load_spec(spec)
    elif isinstance(spec, dict):
        spec = spec_from_dict(spec)
    total_chunks, total = n_chunks(spec), len(spec)
    report = bar(f'sweep {spec.name}') if progress is True else progress or None
    store = Checkpoint(checkpoint, spec) if checkpoint is not None else None
    # a checkpointed spec of more than _IN_MEMORY_SCENES keeps its chunks on disk only
    on_disk = store is not None and total > _IN_MEMORY_SCENES
    frames: dict[int, pd.DataFrame] = {}
    finished = _verified(store, frames, on_disk) if store is not None else set()
    done = [sum(chunk_len(spec, i) for i in finished)]     # scenes finished

    def on_done(i: int, df: pd.DataFrame) -> None:
        if store is not None:
            store.save(i, df)
        if not on_disk:
            frames[i] = df
        done[0] += len(df)
        if report:
            report(done[0], total)

    if report:
        report(done[0], total)
    todo = (i for i in range(total_chunks) if i not in finished)
    n_todo = total_chunks - len(finished)
    if n_todo:
        if store is not None:
            store.check_writable()
        if client is not None:
            from .cluster import ClusterError, run_on_client
            try:
                run_on_client(client, spec, todo, on_done)
            except ClusterError as exc:
                # the chunks written so far stay: say where, and that a rerun resumes there
                kept = (f'; {len(store.finished())} finished chunks are kept in {store.dir}: '
                        'run the same command again to resume' if store is not None else '')
                raise ClusterError(f'{exc}{kept}') from None
        else:
            _local(spec, todo, n_todo, workers or os.cpu_count() or 1, on_done)
    return assemble(spec, (frames[i] if i in frames else store.load(i)    # type: ignore
                           for i in range(total_chunks)))


def _verified(store: Checkpoint, frames: dict[int, pd.DataFrame], on_disk: bool) -> set[int]:
    """Indices of the checkpoint's chunks, each verified (`Checkpoint.load`) before anything is
    computed; kept in ``frames`` unless ``on_disk``. Every chunk that fails is named in one
    CheckpointError (the first in full, then the others' file names)."""
    bad: list[tuple[int, CheckpointError]] = []
    found = store.finished()
    for i in found:
        try:
            df = store.load(i)
        except CheckpointError as exc:
            bad.append((i, exc))
            continue
        if not on_disk:
            frames[i] = df
    if bad:
        first = str(bad[0][1])
        if len(bad) > 1:
            others = ', '.join(store.path(i).name for i, _ in bad[1:4])
            first += (f' (and {len(bad) - 1} other chunks fail: {others}'
                      f'{", ..." if len(bad) > 4 else ""})')
        raise CheckpointError(first)
    return set(found)
