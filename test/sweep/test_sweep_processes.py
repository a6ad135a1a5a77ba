"""A local sweep driver that dies takes its worker processes with it.

Real processes: ``crawler-sim sweep --workers 2`` is started as a subprocess, its two pool
workers are found in /proc, the driver is sent a signal, and the workers must be gone (or
zombies waiting to be reaped: dead) within a deadline that is generous compared with the
milliseconds it takes. Without the fix, SIGTERM and SIGKILL leave them running, re-parented to
init, and SIGINT leaves them finishing chunks that last minutes.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not sys.platform.startswith('linux'), reason='reads /proc')

# chunks of 20000 scenes take minutes each: a worker that is not killed is still computing
SPEC = '''sweep:
  name: long
  periods: 20
  samples_per_period: 50
  chunk_size: 20000
  base:
    crawler: {masses: [1.0, 1.0], mu: [0.3, 0.3]}
    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 1.0, asymmetry: 0.3}
  random:
    n: 1000000
    seed: 0
    params:
      crawler.mu[1]: {uniform: [0.1, 0.6]}
'''


def stat(pid: int) -> tuple[str, int, int] | None:
    """(state, parent pid, start time in clock ticks) of a process, None if it is gone."""
    try:
        text = Path(f'/proc/{pid}/stat').read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    fields = text[text.rindex(')') + 2:].split()     # after "pid (comm) "
    return fields[0], int(fields[1]), int(fields[19])


def children(parent: int) -> dict[int, int]:
    """pid -> start time of the live children of ``parent``."""
    out = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            st = stat(int(entry))
            if st is not None and st[1] == parent and st[0] != 'Z':
                out[int(entry)] = st[2]
    return out


def alive(pid: int, started: int) -> bool:
    """Whether that process (the same one: same start time) still runs (a zombie is dead)."""
    st = stat(pid)
    return st is not None and st[2] == started and st[0] != 'Z'


def poll(condition, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


@pytest.mark.parametrize('sig', [signal.SIGTERM, signal.SIGINT, signal.SIGKILL],
                         ids=['SIGTERM', 'SIGINT', 'SIGKILL'])
def test_a_killed_sweep_driver_takes_its_workers_with_it(tmp_path, sig):
    spec = tmp_path / 'long.yaml'
    spec.write_text(SPEC)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    driver = subprocess.Popen([sys.executable, '-m', 'crawler_sim.cli', 'sweep', str(spec),
                               '-o', str(tmp_path / 'out.parquet'), '--workers', '2',
                               '--quiet'],
                              cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, start_new_session=True)
    workers: dict[int, int] = {}
    try:
        # the driver imports, runs one short scene, then forks its two workers
        assert poll(lambda: len(children(driver.pid)) == 2, 300), \
            f'no workers; driver exit {driver.poll()}'
        workers = children(driver.pid)
        time.sleep(0.5)                  # both in their first chunk
        assert all(alive(pid, t) for pid, t in workers.items())
        driver.send_signal(sig)
        assert poll(lambda: not any(alive(pid, t) for pid, t in workers.items()), 20), \
            f'workers still running after {sig.name}: {[stat(p) for p in workers]}'
        code = driver.wait(timeout=60)
        assert code == (130 if sig == signal.SIGINT else -sig)
    finally:
        for pid, started in workers.items():      # never leave a stray process behind
            if alive(pid, started):
                os.kill(pid, signal.SIGKILL)
        if driver.poll() is None:
            driver.kill()
            driver.wait()
        if driver.stderr is not None:
            driver.stderr.close()
