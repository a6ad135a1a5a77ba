"""A real Dask scheduler and two workers on localhost for the sweep tests that need one.

The fixture is made available to the sweep tests by test/sweep/conftest.py.
"""
from __future__ import annotations

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


@pytest.fixture(scope='module')
def dask_client(tmp_path_factory):
    """A real Dask scheduler and two one-thread workers as separate processes on localhost."""
    distributed = pytest.importorskip('distributed')
    tmp = tmp_path_factory.mktemp('dask')
    sched_file = tmp / 'scheduler.json'
    env = dict(os.environ, PYTHONPATH=str(REPO), DASK_DISTRIBUTED__WORKER__DAEMON='False')
    dask_bin = shutil.which('dask', path=str(Path(sys.executable).parent)) or 'dask'
    procs = [subprocess.Popen([dask_bin, 'scheduler', '--host', '127.0.0.1', '--port', '0',
                               '--no-dashboard', '--scheduler-file', str(sched_file)],
                              env=env, cwd=tmp, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        _wait_for(sched_file, procs)
        for k in range(2):
            procs.append(subprocess.Popen(
                [dask_bin, 'worker', '--scheduler-file', str(sched_file), '--nthreads', '1',
                 '--nworkers', '1', '--no-dashboard', '--name', f'w{k}',
                 '--local-directory', str(tmp / f'w{k}')],
                env=env, cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        client = distributed.Client(scheduler_file=str(sched_file), timeout='60s')
        client.wait_for_workers(2, timeout=90)
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
