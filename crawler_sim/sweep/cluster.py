"""Sweeps on a Dask distributed cluster (``crawler-sim sweep --scheduler ADDRESS``, ``client=``).

One Dask task is one chunk of ``spec.chunk_size`` scenes (a few hundred milliseconds of work,
not a one-millisecond job), computed by the same pure function as a local run
(`crawler_sim.sweep.runner.run_chunk`), so the assembled DataFrame is bit-identical. Every
task carries the spec as plain data (a few kB) and its chunk index, so a task whose worker dies
is run again elsewhere (scattered data lost with its worker cancelled its dependents). Results are
gathered as they finish so the driver can checkpoint them (resume after an interruption).
A few tasks per worker thread are in flight at once, the next submitted as one finishes, so a
sweep of millions of chunks neither floods the scheduler nor the driver's memory.

Nothing waits on the cluster without a deadline (:func:`deadline`: Dask's own
``distributed.comm.timeouts.connect``, 30 s unless configured): connecting, checking the
workers, each result, and, while chunks run, the scheduler must answer a
ping once per deadline without a finished chunk (a chunk itself may take as long as it takes;
a scheduler with no worker for a whole deadline is a failure too). A call that does not
return in time is abandoned (its thread is a daemon) and every failure of the cluster (no
answer, a closed connection, cancelled futures, a worker killed too often) is one
:class:`ClusterError` naming the scheduler: Dask's client, given a peer that accepts and never
answers, waited for ever (issue 38).

The workers must be able to import ``crawler_sim`` (the same version as the driver).
"""
from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import queue
import threading
import time
from typing import Any, Callable, Iterable
import uuid

import pandas as pd

from .runner import run_chunk
from .spec import SweepSpec

__all__ = ['ClusterError', 'run_on_client', 'connect', 'check_workers', 'deadline', 'gather']


class ClusterError(RuntimeError):
    """The Dask cluster failed or did not answer in time (the work failed: exit 1 on the
    command line). One line naming the scheduler, what failed and what to do."""


def deadline() -> float:
    """Seconds any wait on the cluster may last: Dask's ``distributed.comm.timeouts.connect``
    (30 s by default; ``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=60s`` changes it)."""
    import dask
    from dask.utils import parse_timedelta

    return float(parse_timedelta(dask.config.get('distributed.comm.timeouts.connect'),
                                 default='s'))


def _address(client: Any) -> str:
    try:
        return str(client.scheduler.address)
    except AttributeError:
        return '(unknown address)'


def _is_cluster_failure(exc: BaseException) -> bool:
    """A failure of the cluster or of the connection to it (not an error of our own code,
    such as a full disk while a chunk is saved, which is raised as it is)."""
    return (isinstance(exc, (OSError, TimeoutError, asyncio.CancelledError,
                             concurrent.futures.CancelledError))
            or type(exc).__module__.split('.')[0] in ('distributed', 'tornado'))


def _failure(address: str, what: str, exc: BaseException) -> ClusterError:
    text = ' '.join(str(exc).split())[:200]
    return ClusterError(f'Dask scheduler {address}: {what} failed ({type(exc).__name__}'
                        f'{": " + text if text else ""}); check that the scheduler runs and '
                        'is reachable')


def _within(seconds: float, what: str, address: str, fn: Callable, *args: Any,
            **kw: Any) -> Any:
    """``fn(*args, **kw)``, or a ClusterError if it does not return within ``seconds``.

    The call runs in a daemon thread and is abandoned at the deadline: Dask's client has no
    deadline of its own on every call (it waits for ever on a peer that accepts a connection
    and never answers, whatever its ``timeout``)."""
    box: dict[str, Any] = {}

    def call() -> None:
        try:
            box['value'] = fn(*args, **kw)
        except BaseException as exc:       # handed to the caller's thread
            box['error'] = exc

    worker = threading.Thread(target=call, daemon=True, name=f'crawler-sim: {what}')
    worker.start()
    worker.join(seconds)
    if worker.is_alive():
        raise ClusterError(f'Dask scheduler {address}: no answer within {seconds:g} s '
                           f'({what}); check that the scheduler runs and is reachable')
    if 'error' in box:
        exc = box['error']
        if _is_cluster_failure(exc):
            raise _failure(address, what, exc) from None
        raise exc
    return box['value']


def connect(address: str) -> Any:
    """A ``dask.distributed.Client`` connected to the scheduler at ``address``
    (e.g. ``tcp://10.0.0.5:8786``) within :func:`deadline`; ClusterError when it cannot be
    reached, refuses, or does not answer in time."""
    from distributed import Client

    limit = deadline()
    return _within(limit, 'connecting', address, Client, address, timeout=limit)


def check_workers(client: Any) -> None:
    """Raise RuntimeError naming every worker of ``client`` (and its scheduler) that cannot
    import ``crawler_sim`` or has another version than this process, and how to fix it.

    Without this check such a worker fails to unpickle the first task and Dask reports it as
    ``FutureCancelledError ... already forgotten``. The probe is the builtin ``eval`` of an
    import expression: a builtin unpickles on any worker, a function of crawler_sim would not.
    """
    from crawler_sim import __version__

    address, limit = _address(client), deadline()
    probe = "__import__('crawler_sim').__version__"
    found = _within(limit, 'asking the workers for crawler_sim', address, client.run, eval,
                    probe, on_error='return')
    try:        # the scheduler unpickles task graphs too
        found['the scheduler'] = _within(limit, 'asking the scheduler for crawler_sim',
                                         address, client.run_on_scheduler, eval, probe)
    except ClusterError:
        raise
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


class _Finished:
    """Futures handed over as they finish (done, failed or cancelled), with a deadline on the
    cluster while none does: the scheduler must answer a ping, and have workers."""

    def __init__(self, client: Any, limit: float) -> None:
        self.client, self.limit, self.address = client, limit, _address(client)
        self._queue: queue.Queue = queue.Queue()

    def watch(self, fut: Any) -> Any:
        fut.add_done_callback(self._queue.put)
        return fut

    def next(self) -> Any:
        """The next finished future; ClusterError if the scheduler stops answering or has no
        worker for a whole deadline."""
        no_workers_since: float | None = None
        while True:
            try:
                return self._queue.get(timeout=self.limit)
            except queue.Empty:
                pass
            threads = _within(self.limit, 'answering while chunks run', self.address,
                              self.client.nthreads)
            if sum(threads.values()) > 0:
                no_workers_since = None
            elif no_workers_since is None:
                no_workers_since = time.monotonic()
            elif time.monotonic() - no_workers_since >= self.limit:
                raise ClusterError(f'Dask scheduler {self.address}: no worker for '
                                   f'{self.limit:g} s; start workers for it')

    def result(self, fut: Any, what: str) -> Any:
        """The result of a finished future (fetched within the deadline); a cluster failure
        (cancelled, lost, a worker killed too often) as a ClusterError."""
        return _within(self.limit, what, self.address, fut.result)


def gather(client: Any, futures: list) -> list:
    """The results of ``futures`` in order, every wait with a deadline (see the module doc)."""
    finished = _Finished(client, deadline())
    for fut in futures:
        finished.watch(fut)
    for _ in futures:
        finished.next()
    return [finished.result(fut, f'fetching result {k}') for k, fut in enumerate(futures)]


def run_on_client(client: Any, spec: SweepSpec, todo: Iterable[int],
                  on_done: Callable[[int, pd.DataFrame], None], *,
                  window: int | None = None) -> None:
    """Run chunks ``todo`` of ``spec`` on ``client``; ``on_done(index, frame)`` as each ends.

    At most ``window`` tasks are in flight (default: twice the cluster's worker threads, at
    least 4); ``todo`` is consumed lazily. Workers that cannot run crawler_sim are named
    before any task is sent (:func:`check_workers`). Every wait has a deadline
    (:func:`deadline`); a failure of the cluster is a :class:`ClusterError`.
    """
    limit, address = deadline(), _address(client)
    check_workers(client)
    # the spec (plain data, a few kB) goes inside each task, not scattered: Dask's active
    # memory manager keeps one replica of scattered data, and the worker holding it, killed,
    # took it with it: its dependents were cancelled ('cancelled for reason: unknown'), where
    # a task holding its own arguments is simply run again elsewhere
    data = spec.to_dict()
    run_id = uuid.uuid4().hex[:12]      # keys unique per call, readable on the dashboard
    todo = iter(todo)
    if window is None:
        threads = _within(limit, 'listing the workers', address, client.nthreads)
        window = max(4, 2 * sum(threads.values()))
    finished = _Finished(client, limit)
    live: dict[str, tuple[Any, int]] = {}       # key -> (future, chunk index): held while live

    def submit(i: int) -> None:
        fut = client.submit(run_chunk, data, i, key=f'crawler-sweep-{spec.name}-{run_id}-{i}',
                            pure=False)
        live[fut.key] = (finished.watch(fut), i)

    try:
        for i in itertools.islice(todo, window):
            submit(i)
        while live:
            fut = finished.next()
            _, i = live.pop(fut.key)
            df = finished.result(fut, f'gathering chunk {i}')
            on_done(i, df)              # our own errors (a full disk) are raised as they are
            for nxt in itertools.islice(todo, 1):
                submit(nxt)
    finally:
        if live:                        # interrupted or failed: stop the tasks in flight
            try:
                _within(limit, 'cancelling', address, client.cancel,
                        [f for f, _ in live.values()])
            except Exception:
                pass
