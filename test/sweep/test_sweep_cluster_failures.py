"""A sweep on a Dask cluster cannot hang (issue 38, item 4): every wait has a deadline (Dask's
``distributed.comm.timeouts.connect``, set short here), and every failure of the cluster is one
line naming the scheduler, with the finished chunks kept for a resume.

The endpoints that misbehave are plain sockets in the test (one accepts and never answers, one
accepts and closes); the killed scheduler and worker are real processes started by the test.
No wall-clock assertion: a subprocess timeout far above the deadline fails a hang.
"""
from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import threading
from typing import Iterator

import dask
import pandas as pd
import pytest

from crawler_sim.sweep import sweep
from crawler_sim.sweep.cluster import ClusterError
from test.support.dask_cluster import REPO, local_cluster

pytest.importorskip('distributed')

SPEC = {'name': 'far', 'periods': 4, 'samples_per_period': 8, 'chunk_size': 2,
        'base': {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
                 'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                          'asymmetry': 0.5}},
        'random': {'n': 24, 'seed': 3, 'params': {'gait.asymmetry': {'uniform': [0.1, 0.9]}}}}
DEADLINE = 2          # seconds, for the command under test
HANG = 120            # seconds after which the test itself fails: far above the deadline


@contextlib.contextmanager
def endpoint(behaviour: str) -> Iterator[str]:
    """A TCP endpoint on localhost that accepts connections and then says nothing
    (``'silent'``, the connections held open) or closes them at once (``'close'``)."""
    server = socket.socket()
    server.bind(('127.0.0.1', 0))
    server.listen(16)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            if behaviour == 'close':
                conn.close()
            else:
                held.append(conn)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f'tcp://127.0.0.1:{server.getsockname()[1]}'
    finally:
        stop.set()
        thread.join()
        for conn in held:
            conn.close()
        server.close()


def sweep_command(tmp_path: Path, address: str) -> subprocess.CompletedProcess:
    spec = tmp_path / 'far.yaml'
    spec.write_text(json.dumps({'sweep': SPEC}))
    env = dict(os.environ, PYTHONPATH=str(REPO),
               DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=f'{DEADLINE}s')
    return subprocess.run([sys.executable, '-m', 'crawler_sim.cli', 'sweep', str(spec), '-o',
                           str(tmp_path / 'far.parquet'), '--scheduler', address, '--quiet'],
                          env=env, cwd=tmp_path, capture_output=True, text=True, timeout=HANG)


@pytest.mark.parametrize('behaviour', ['silent', 'close'])
def test_a_scheduler_that_accepts_and_then_fails_ends_the_command_with_one_line(tmp_path,
                                                                                 behaviour):
    with endpoint(behaviour) as address:
        done = sweep_command(tmp_path, address)
    errors = [ln for ln in done.stderr.splitlines() if ln.startswith('crawler-sim: error:')]
    assert done.returncode == 1, done.stderr
    assert len(errors) == 1 and f'Dask scheduler {address}: ' in errors[0], done.stderr
    assert 'internal error' not in done.stderr and 'Traceback' not in done.stderr
    if behaviour == 'silent':
        assert f'no answer within {DEADLINE} s (connecting)' in errors[0]
    assert not (tmp_path / 'far.parquet').exists()


def test_every_worker_killed_mid_sweep_loses_nothing(tmp_path):
    """Both workers SIGKILLed after the first chunk: their nannies start new ones and every
    chunk is run again there, the frame equal to a one-process run. Before, the spec was
    scattered to the workers, and data that only dead workers held cannot be recomputed: every
    chunk not finished was cancelled ('cancelled for reason: unknown', a ClusterError). The
    same loss struck one killed worker when Dask's memory manager had kept its only replica."""
    whole = sweep(SPEC, workers=1)
    with local_cluster(tmp_path, workers=2) as client:
        pids = sorted(client.run(os.getpid).values())
        killed: list[int] = []

        def kill_every_worker(done: int, total: int) -> None:
            if done and not killed:
                for pid in pids:
                    killed.append(pid)
                    os.kill(pid, signal.SIGKILL)

        df = sweep(SPEC, client=client, progress=kill_every_worker)
    assert killed == pids and len(pids) == 2
    pd.testing.assert_frame_equal(df, whole, check_exact=True)


def test_a_killed_worker_is_replaced_and_a_killed_scheduler_is_one_line_and_a_resume(tmp_path):
    whole = sweep(SPEC, workers=1)
    ck = tmp_path / 'ck'
    with dask.config.set({'distributed.comm.timeouts.connect': f'{DEADLINE}s'}), \
            local_cluster(tmp_path, workers=2) as client:
        # a worker killed after the first chunk: Dask runs its tasks elsewhere, nothing lost
        pids = client.run(os.getpid)
        killed: list[int] = []

        def kill_a_worker(done: int, total: int) -> None:
            if done and not killed:
                killed.append(min(pids.values()))
                os.kill(killed[0], signal.SIGKILL)

        df = sweep(SPEC, client=client, progress=kill_a_worker)
        assert killed
        pd.testing.assert_frame_equal(df, whole, check_exact=True)
        # the scheduler killed after the first chunk: one line naming it and the resume
        client.wait_for_workers(1, timeout=60)
        address = client.scheduler.address
        scheduler = client.run_on_scheduler(os.getpid)

        def kill_the_scheduler(done: int, total: int) -> None:
            if done:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(scheduler, signal.SIGKILL)

        with pytest.raises(ClusterError) as err:
            sweep(SPEC, client=client, checkpoint=ck, progress=kill_the_scheduler)
    text = str(err.value)
    assert text.startswith(f'Dask scheduler {address}: ') and '\n' not in text
    assert f'finished chunks are kept in {ck}: run the same command again to resume' in text
    kept = len(list(ck.glob('chunk_*.parquet')))
    assert 1 <= kept < 12
    resumed = sweep(SPEC, workers=1, checkpoint=ck)
    pd.testing.assert_frame_equal(resumed, whole, check_exact=True)


def test_a_scheduler_frozen_mid_sweep_is_one_line_within_the_deadline_not_a_hang(tmp_path):
    # SIGSTOP: the connection stays open and nothing answers (a scheduler swapped out, a host
    # that froze); the sweep's ping of the scheduler finds it silent
    ck = tmp_path / 'ck'
    with dask.config.set({'distributed.comm.timeouts.connect': f'{DEADLINE}s'}), \
            local_cluster(tmp_path, workers=1) as client:
        address = client.scheduler.address
        scheduler = client.run_on_scheduler(os.getpid)

        def freeze(done: int, total: int) -> None:
            if done:
                os.kill(scheduler, signal.SIGSTOP)

        try:
            with pytest.raises(ClusterError) as err:
                sweep(SPEC, client=client, checkpoint=ck, progress=freeze)
        finally:
            os.kill(scheduler, signal.SIGCONT)
    text = str(err.value)
    assert text.startswith(f'Dask scheduler {address}: no answer within {DEADLINE} s ')
    assert f'kept in {ck}: run the same command again to resume' in text
