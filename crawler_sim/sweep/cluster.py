"""Sweeps on a Dask distributed cluster (``crawler-sim sweep --scheduler ADDRESS``, ``client=``).

One Dask task is one chunk of ``spec.chunk_size`` scenes (a few hundred milliseconds of work,
not a one-millisecond job), computed by the same pure function as a local run
(`crawler_sim.sweep.runner.run_chunk`), so the assembled DataFrame is bit-identical. The spec
is sent once (``client.scatter``) and every task only carries its chunk index. Results are
gathered as they finish so the driver can checkpoint them (resume after an interruption).
A few tasks per worker thread are in flight at once, the next submitted as one finishes, so a
sweep of millions of chunks neither floods the scheduler nor the driver's memory.

The workers must be able to import ``crawler_sim`` (the same version as the driver).
"""
from __future__ import annotations

import itertools
from typing import Any, Callable, Iterable
import uuid

import pandas as pd

from .runner import run_chunk
from .spec import SweepSpec

__all__ = ['run_on_client', 'connect', 'check_workers']


def connect(address: str) -> Any:
    """A ``dask.distributed.Client`` connected to the scheduler at ``address``
    (e.g. ``tcp://10.0.0.5:8786``); raises OSError when it cannot be reached."""
    from distributed import Client

    try:
        return Client(address, timeout='20s')
    except (OSError, TimeoutError) as exc:
        raise OSError(f'cannot reach the Dask scheduler at {address}: {exc}') from None


def check_workers(client: Any) -> None:
    """Raise RuntimeError naming every worker of ``client`` (and its scheduler) that cannot
    import ``crawler_sim`` or has another version than this process, and how to fix it.

    Without this check such a worker fails to unpickle the first task and Dask reports it as
    ``FutureCancelledError ... already forgotten``. The probe is the builtin ``eval`` of an
    import expression: a builtin unpickles on any worker, a function of crawler_sim would not.
    """
    from crawler_sim import __version__

    probe = "__import__('crawler_sim').__version__"
    found = client.run(eval, probe, on_error='return')
    try:        # the scheduler unpickles task graphs too
        found['the scheduler'] = client.run_on_scheduler(eval, probe)
    except Exception as exc:
        found['the scheduler'] = exc
    bad = []
    for worker, got in sorted(found.items()):
        if isinstance(got, BaseException):
            bad.append(f'{worker}: cannot import crawler_sim ({type(got).__name__}: {got})')
        elif got != __version__:
            bad.append(f'{worker}: crawler_sim {got}')
    if bad:
        raise RuntimeError(f'Dask workers not ready for crawler_sim {__version__} (this '
                           f'process): {"; ".join(bad)}. Install the same crawler_sim on every '
                           'worker and the scheduler (pip install ".[sweep]" from this checkout, '
                           'or put it on their PYTHONPATH) and restart them.')


def run_on_client(client: Any, spec: SweepSpec, todo: Iterable[int],
                  on_done: Callable[[int, pd.DataFrame], None], *,
                  window: int | None = None) -> None:
    """Run chunks ``todo`` of ``spec`` on ``client``; ``on_done(index, frame)`` as each ends.

    At most ``window`` tasks are in flight (default: twice the cluster's worker threads, at
    least 4); ``todo`` is consumed lazily. Workers that cannot run crawler_sim are named
    before any task is sent (:func:`check_workers`).
    """
    from distributed import as_completed

    check_workers(client)
    data = client.scatter(spec.to_dict(), broadcast=True)
    run_id = uuid.uuid4().hex[:12]      # keys unique per call, readable on the dashboard
    todo = iter(todo)
    window = window or max(4, 2 * sum(client.nthreads().values()))
    live: dict[str, tuple[Any, int]] = {}       # key -> (future, chunk index)

    def submit(i: int) -> Any:
        fut = client.submit(run_chunk, data, i, key=f'crawler-sweep-{spec.name}-{run_id}-{i}',
                            pure=False)
        live[fut.key] = (fut, i)
        return fut

    running = as_completed([submit(i) for i in itertools.islice(todo, window)])
    try:
        for fut in running:
            _, i = live.pop(fut.key)
            on_done(i, fut.result())
            for nxt in itertools.islice(todo, 1):
                running.add(submit(nxt))
    finally:
        client.cancel([f for f, _ in live.values()])
