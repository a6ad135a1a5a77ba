"""Figures for hostile sweep input (issue 25): not a test, a script that prints measurements.

    .venv/bin/python -m benchmarks.sweep_hostile [bombs plan stream chunks kill]

Each measurement runs in a fresh subprocess of the same Python with the same PYTHONPATH (so
the crawler_sim it imports is the one measured), under a 4 GB address-space limit and a
timeout, so a spec that would exhaust the machine ends as MemoryError or TIMEOUT instead.

- bombs: time and peak RSS added while loading each hostile spec (RSS after the imports is
  the baseline), and the first line of the outcome.
- plan: time to plan the last chunk of a 1e6 and a 1e9-scene spec (random and grid).
- stream: a random n = 1e9 sweep, 2 workers, checkpointed: scenes done and driver RSS over 20 s.
- chunks: wall and CPU time of 3000 scenes with chunk_size 1 and 250 (2 workers).
- kill: seconds until both workers are gone after SIGTERM, SIGINT and SIGKILL of the driver.
"""
from __future__ import annotations

import os
from pathlib import Path
import resource
import signal
import subprocess
import sys
import tempfile
import time
from typing import Iterable

BASE = ('  base:\n    crawler: {masses: [1.0, 1.0], mu: [0.3, 0.3]}\n'
        '    gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 1.0, asymmetry: 0.3}\n')
LIMIT_AS = 4 * 1024**3


def laughs(levels: int) -> str:
    parts = ['&l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]']
    parts += [f'&l{k} [' + ', '.join([f'*l{k - 1}'] * 9) + ']' for k in range(1, levels)]
    return '[' + ', '.join(parts) + ']'


def merges(levels: int) -> str:
    parts = ['&m0 {a: 1, b: 2, c: 3}']
    parts += [f'&m{k} {{<<: [' + ', '.join([f'*m{k - 1}'] * 9) + f'], k{k}: 0}}'
              for k in range(1, levels)]
    return '[' + ', '.join(parts) + ']'


def bomb_specs(levels: int) -> dict[str, str]:
    b = laughs(levels)
    return {
        f'laughs 9^{levels} in description':
            f'sweep:\n{BASE}  description: {b}\n  grid: {{gait.asymmetry: [0.3]}}\n',
        f'laughs 9^{levels} in name': f'sweep:\n{BASE}  name: {b}\n',
        f'laughs 9^{levels} in a grid value':
            f'sweep:\n{BASE}  grid: {{crawler.masses: [[1.0, 1.0], {b}]}}\n',
        f'laughs 9^{levels} in choice':
            f'sweep:\n{BASE}  random: {{n: 3, seed: 0, params: {{gait.type: {{choice: {b}}}}}}}\n',
        f'merge keys 9^{levels} in description':
            f'sweep:\n{BASE}  description: {merges(levels)}\n',
    }


SIZE_SPECS = {
    'random n = 1e9 (accepted: streams)':
        f'sweep:\n{BASE}  random:\n    n: 1000000000\n    seed: 0\n    params:\n'
        '      crawler.mu[1]: {uniform: [0.1, 0.6]}\n',
    'grid of 1e15 scenes': f'sweep:\n{BASE}  grid:\n' + ''.join(
        f'    {p}: {{linspace: [0.1, 0.2, 1000]}}\n' for p in
        ('crawler.mu[1]', 'crawler.slope_deg', 'gait.asymmetry', 'gait.amplitude',
         'gait.frequency')),
    'linspace n = 1e9': f'sweep:\n{BASE}  grid: {{gait.asymmetry: {{linspace: [0.1, 0.9, '
                        f'1000000000]}}}}\n',
}

LOAD = '''
import resource, sys, time
from crawler_sim.sweep import load_spec, runner
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
try:
    spec = load_spec(sys.argv[1])
    runner.Checkpoint(sys.argv[2], spec)       # what a run does next: the spec as JSON
    out = f'accepted, {len(spec)} scenes'
except BaseException as exc:
    out = f'{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ""}'
dt = time.perf_counter() - t
extra = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024
print(f'{dt:.3f} s, +{extra:.1f} MB peak RSS: {out[:150]}')
'''

PLAN = '''
import sys, time
from crawler_sim.sweep import spec_from_dict
from crawler_sim.sweep.runner import chunk_params, n_chunks
base = {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
        'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                 'asymmetry': 0.5}}
n, kind = int(float(sys.argv[1])), sys.argv[2]
if kind == 'random':
    d = {'base': base, 'random': {'n': n, 'seed': 0, 'params': {
        'crawler.mu': {'uniform': [0.1, 0.5]}, 'gait.asymmetry': {'uniform': [0.1, 0.9]},
        'bodies': {'integers': [2, 4]}}}}
else:
    side = round(n ** (1 / 3))
    d = {'base': base, 'grid': {'crawler.mu': {'linspace': [0.1, 0.5, side]},
                                'gait.asymmetry': {'linspace': [0.1, 0.9, side]},
                                'gait.amplitude': {'linspace': [0.01, 0.03, side]}}}
spec = spec_from_dict(d)
t = time.perf_counter()
chunk_params(spec, n_chunks(spec) - 1)
print(f'{time.perf_counter() - t:.4f} s')
'''


def limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_AS, LIMIT_AS))


def python(args: list[str], timeout: float, **kw) -> str:
    try:
        proc = subprocess.run([sys.executable, *args], capture_output=True, text=True,
                              timeout=timeout, preexec_fn=limited, **kw)
    except subprocess.TimeoutExpired:
        return f'TIMEOUT after {timeout:.0f} s'
    lines = (proc.stdout.strip() or proc.stderr.strip() or f'exit {proc.returncode}').splitlines()
    return lines[-1]


def bombs(tmp: Path) -> None:
    specs = {**bomb_specs(9), **bomb_specs(12), **SIZE_SPECS}
    for k, (label, text) in enumerate(specs.items()):
        path = tmp / f'bomb{k}.yaml'
        path.write_text(text)
        print(f'  {label:40s} {python(["-c", LOAD, str(path), str(tmp / f"ck{k}")], 150)}',
              flush=True)


def plan(tmp: Path) -> None:
    for n in ('1e6', '1e9'):
        for kind in ('random', 'grid'):
            print(f'  last chunk of {n} {kind:6s}: {python(["-c", PLAN, n, kind], 120)}',
                  flush=True)


def cli(tmp: Path, spec_text: str, name: str, *extra: str) -> subprocess.Popen:
    spec = tmp / f'{name}.yaml'
    spec.write_text(spec_text)
    return subprocess.Popen([sys.executable, '-m', 'crawler_sim.cli', 'sweep', str(spec), '-o',
                             str(tmp / f'{name}.parquet'), '--quiet', *extra],
                            cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            preexec_fn=limited, start_new_session=True)


def rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def stream(tmp: Path) -> None:
    text = SIZE_SPECS['random n = 1e9 (accepted: streams)'].replace(
        '  random:', '  chunk_size: 10\n  random:')
    proc = cli(tmp, text, 'billion', '--workers', '2')
    chunks = tmp / 'billion.parquet.chunks'
    start = time.monotonic()
    try:
        for t in (2, 5, 10, 20):
            time.sleep(max(0.0, start + t - time.monotonic()))
            if proc.poll() is not None:
                print(f'  driver exited {proc.returncode}: '
                      f'{proc.stderr.read().decode().strip()[-200:]}')
                return
            done = len(list(chunks.glob('chunk_*.parquet'))) * 10 if chunks.exists() else 0
            print(f'  t = {t:2d} s: {done:6d} scenes checkpointed, driver RSS '
                  f'{rss_mb(proc.pid):.0f} MB', flush=True)
    finally:
        kill_tree(proc)


def kill_tree(proc: subprocess.Popen, workers: Iterable[int] = ()) -> None:
    """Kill the driver and its workers: those it has now and ``workers`` (seen before it died:
    orphans are not its children any more)."""
    workers = [*workers, *children(proc.pid)]
    if proc.poll() is None:
        proc.kill()
        proc.wait()
    for pid in workers:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def chunks(tmp: Path) -> None:
    for size in (1, 250):
        text = (f'sweep:\n{BASE}  periods: 20\n  chunk_size: {size}\n  random:\n    n: 3000\n'
                '    seed: 0\n    params:\n      crawler.mu[1]: {uniform: [0.1, 0.6]}\n'
                '      gait.asymmetry: {uniform: [0.15, 0.85]}\n')
        t, cpu = time.perf_counter(), children_cpu()
        proc = cli(tmp, text, f'c{size}', '--workers', '2')
        err = proc.communicate(timeout=900)[1].decode().strip()
        print(f'  chunk_size {size:3d}: {time.perf_counter() - t:.1f} s wall, '
              f'{children_cpu() - cpu:.1f} s CPU (driver and workers), exit {proc.returncode} '
              f'{err[-150:]}', flush=True)


def children_cpu() -> float:
    """CPU seconds of the waited-for children (the driver includes its workers)."""
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def children(parent: int) -> list[int]:
    out = []
    for entry in filter(str.isdigit, os.listdir('/proc')):
        try:
            fields = Path(f'/proc/{entry}/stat').read_text().rsplit(')', 1)[1].split()
        except (FileNotFoundError, ProcessLookupError):
            continue
        if int(fields[1]) == parent and fields[0] != 'Z':
            out.append(int(entry))
    return out


def running(pid: int) -> bool:
    try:
        return Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0] != 'Z'
    except (FileNotFoundError, ProcessLookupError):
        return False


def kill(tmp: Path) -> None:
    text = (f'sweep:\n{BASE}  chunk_size: 20000\n  random:\n    n: 1000000\n    seed: 0\n'
            '    params:\n      crawler.mu[1]: {uniform: [0.1, 0.6]}\n')
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGKILL):
        proc = cli(tmp, text, f'kill{sig.value}', '--workers', '2')
        workers: list[int] = []
        try:
            end = time.monotonic() + 300
            while len(children(proc.pid)) < 2 and time.monotonic() < end:
                time.sleep(0.05)
            workers = children(proc.pid)
            time.sleep(0.5)
            t = time.monotonic()
            proc.send_signal(sig)
            while any(running(p) for p in workers) and time.monotonic() < t + 30:
                time.sleep(0.01)
            left = [p for p in workers if running(p)]
            gone = f'{time.monotonic() - t:.2f} s' if not left else f'NOT within 30 s ({left})'
            try:
                code = f'exit {proc.wait(timeout=60)}'
            except subprocess.TimeoutExpired:
                code = 'still running after 60 s'
            print(f'  {sig.name}: {len(workers)} workers gone after {gone}; driver {code}',
                  flush=True)
        finally:
            kill_tree(proc, workers)


def main(argv: list[str]) -> None:
    import crawler_sim
    print(f'crawler_sim from {Path(crawler_sim.__file__).parent}')
    sections = {'bombs': bombs, 'plan': plan, 'stream': stream, 'chunks': chunks, 'kill': kill}
    for name in argv or list(sections):
        print(f'{name}:', flush=True)
        with tempfile.TemporaryDirectory() as tmp:
            sections[name](Path(tmp))


if __name__ == '__main__':
    main(sys.argv[1:])
