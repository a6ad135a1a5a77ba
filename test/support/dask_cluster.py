"""A real Dask scheduler and two workers on localhost for the sweep tests that need one.

The fixture is made available to the sweep tests by test/sweep/conftest.py.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

import pytest

REPO = Path(__file__).resolve().parents[2]     # the repository (test/support/ -> ..)


def _wait_for(path: Path, procs: list, timeout: float = 90.0) -> None:
    end = time.monotonic() + timeout
    while not path.exists():
        for p in procs:
            if p.poll() is not None:
                raise RuntimeError(f'{p.args} exited with {p.returncode}')
        if time.monotonic() > end:
            raise TimeoutError(f'{path} not written')
        time.sleep(0.2)


@contextlib.contextmanager
def local_cluster(tmp: Path, workers: int = 2, *, importable: bool = True):
    """A real Dask scheduler and ``workers`` one-thread workers as separate processes on
    localhost, and a Client to them. ``importable`` False: the workers' PYTHONPATH lacks this
    checkout (the scheduler keeps it) (they cannot import crawler_sim, as on a cluster where it is not installed)."""
    import distributed

    sched_file = tmp / 'scheduler.json'
    env = dict(os.environ, DASK_DISTRIBUTED__WORKER__DAEMON='False', PYTHONPATH=str(REPO))
    worker_env = dict(env)
    if not importable:
        del worker_env['PYTHONPATH']
    dask_bin = shutil.which('dask', path=str(Path(sys.executable).parent)) or 'dask'
    procs = [subprocess.Popen([dask_bin, 'scheduler', '--host', '127.0.0.1', '--port', '0',
                               '--no-dashboard', '--scheduler-file', str(sched_file)],
                              env=env, cwd=tmp, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        _wait_for(sched_file, procs)
        for k in range(workers):
            procs.append(subprocess.Popen(
                [dask_bin, 'worker', '--scheduler-file', str(sched_file), '--nthreads', '1',
                 '--nworkers', '1', '--no-dashboard', '--name', f'w{k}',
                 '--local-directory', str(tmp / f'w{k}')],
                env=worker_env, cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        client = distributed.Client(scheduler_file=str(sched_file), timeout='60s')
        client.wait_for_workers(workers, timeout=90)
        yield client
        client.close()
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope='module')
def dask_client(tmp_path_factory):
    """A real Dask scheduler and two one-thread workers as separate processes on localhost."""
    pytest.importorskip('distributed')
    with local_cluster(tmp_path_factory.mktemp('dask')) as client:
        yield client
