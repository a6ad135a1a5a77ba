"""Sweep benchmark: local processes against a Dask cluster on the same machine.

    python -m benchmarks.sweep --scenes 10000 --repeat 3

Random two-body scenes (config/sweeps/random_2body.yaml's family: masses, frictions per
direction, slope, scallop or bang-bang stroke) of 20 periods each, exact method. Each repeat
runs the local sweep (a fresh process pool on every core) and the Dask sweep (a LocalCluster with
one single-threaded worker process per core, started once before timing) back to back; the
figures are medians over the repeats, Dask's overhead is (Dask - local) / local, and every Dask
DataFrame is compared with the local one bit for bit.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import resource
import statistics
import sys
import time

import pandas as pd

from crawler_sim.sweep.runner import sweep
from crawler_sim.sweep.spec import load_spec, spec_from_dict

__all__ = ['bench_spec', 'run', 'main']

SPEC_FILE = Path(__file__).resolve().parents[1] / 'config' / 'sweeps' / 'random_2body.yaml'


def bench_spec(scenes: int, periods: int = 20, chunk_size: int = 250, seed: int = 0):
    """The benchmark's spec: random_2body with ``scenes`` draws of ``periods`` periods."""
    data = load_spec(SPEC_FILE).to_dict()
    data['random'].update(n=scenes, seed=seed)
    data.update(periods=periods, chunk_size=chunk_size, name=f'bench_{scenes}')
    return spec_from_dict(data)


def _cpu(children: bool = True) -> float:
    """CPU seconds of this process and (``children``) its finished children (the local pool's
    workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    total = own.ru_utime + own.ru_stime
    if children:
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        total += kids.ru_utime + kids.ru_stime
    return total


def _process_cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    return own.ru_utime + own.ru_stime


def _worker_cpu(client) -> float:
    """CPU seconds used so far by every Dask worker process."""
    return float(sum(client.run(_process_cpu).values()))


def run(scenes: int, repeat: int, workers: int, chunk_size: int,
        log=print) -> dict:
    """Time the local and the Dask sweep ``repeat`` times; return the figures."""
    from distributed import Client, LocalCluster

    spec = bench_spec(scenes, chunk_size=chunk_size)
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=':0')
    client = Client(cluster)
    startup = time.perf_counter() - t0
    local_t, dask_t, identical, local_cpu, dask_cpu = [], [], [], [], []
    reference: pd.DataFrame | None = None
    try:
        for k in range(repeat):
            cpu0 = _cpu()
            t = time.perf_counter()
            df_local = sweep(spec, workers=workers)
            local_t.append(time.perf_counter() - t)
            local_cpu.append(_cpu() - cpu0)
            own0, workers0 = _cpu(children=False), _worker_cpu(client)
            t = time.perf_counter()
            df_dask = sweep(spec, client=client)
            dask_t.append(time.perf_counter() - t)
            # the scheduler and the client live in this process, the workers in their own
            dask_cpu.append(_cpu(children=False) - own0 + _worker_cpu(client) - workers0)
            if reference is None:
                reference = df_local
            same = df_local.equals(reference) and df_dask.equals(reference)
            try:
                pd.testing.assert_frame_equal(df_dask, reference, check_exact=True)
            except AssertionError:
                same = False
            identical.append(same)
            log(f'repeat {k + 1}/{repeat}: local {local_t[-1]:.2f} s (CPU {local_cpu[-1]:.2f} s), '
                f'dask {dask_t[-1]:.2f} s (CPU {dask_cpu[-1]:.2f} s), bit-identical {same}, '
                f'load {os.getloadavg()[0]:.2f}')
    finally:
        client.close()
        cluster.close()
    local_med, dask_med = statistics.median(local_t), statistics.median(dask_t)
    errors = int((reference['error'] != '').sum()) if reference is not None else 0
    return {'scenes': scenes, 'periods': spec.periods, 'chunk_size': chunk_size,
            'workers': workers, 'repeat': repeat, 'local_s': local_t, 'dask_s': dask_t,
            'local_median_s': local_med, 'dask_median_s': dask_med,
            'dask_overhead_pct': 100.0 * (dask_med - local_med) / local_med,
            'dask_cluster_startup_s': startup, 'bit_identical': all(identical),
            'scene_errors': errors, 'local_cpu_s': local_cpu,
            'local_cpu_median_s': statistics.median(local_cpu), 'dask_cpu_s': dask_cpu,
            'dask_cpu_median_s': statistics.median(dask_cpu),
            'dask_cpu_overhead_pct': 100.0 * (statistics.median(dask_cpu)
                                              / statistics.median(local_cpu) - 1.0),
            'load_average_1min': os.getloadavg()[0],
            'ms_per_scene_per_worker': 1e3 * local_med * workers / scenes}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog='python -m benchmarks.sweep', description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--scenes', type=int, default=10_000)
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--workers', type=int, default=os.cpu_count() or 1)
    ap.add_argument('--chunk-size', type=int, default=250)
    ap.add_argument('--json', metavar='FILE', help='also write the figures as JSON')
    args = ap.parse_args(argv)
    res = run(args.scenes, args.repeat, args.workers, args.chunk_size,
              log=lambda m: print(m, file=sys.stderr, flush=True))
    cmd = ('python -m benchmarks.sweep ' + ' '.join(argv if argv is not None
                                                           else sys.argv[1:])).strip()
    print(f'command: {cmd}')
    print(f'{res["scenes"]} two-body scenes x {res["periods"]} periods, exact method, '
          f'{res["workers"]} workers, chunks of {res["chunk_size"]}')
    print(f'local (process pool): median {res["local_median_s"]:.2f} s '
          f'(runs {", ".join(f"{t:.2f}" for t in res["local_s"])}), '
          f'{res["ms_per_scene_per_worker"]:.2f} ms per scene per worker')
    print(f'local CPU time: median {res["local_cpu_median_s"]:.2f} s, i.e. '
          f'{res["local_cpu_median_s"] / res["workers"]:.2f} s of wall time on {res["workers"]} '
          f'idle cores, {1e3 * res["local_cpu_median_s"] / res["scenes"]:.2f} ms CPU per scene '
          f'(1-min load average at the end {res["load_average_1min"]:.2f} on '
          f'{os.cpu_count()} cores)')
    print(f'dask (LocalCluster):  median {res["dask_median_s"]:.2f} s '
          f'(runs {", ".join(f"{t:.2f}" for t in res["dask_s"])}); cluster start-up '
          f'{res["dask_cluster_startup_s"]:.2f} s, not counted')
    print(f'dask overhead: {res["dask_overhead_pct"]:+.1f} % of wall time (ratio '
          f'{res["dask_median_s"] / res["local_median_s"]:.3f}); CPU time median '
          f'{res["dask_cpu_median_s"]:.2f} s, {res["dask_cpu_overhead_pct"]:+.1f} % against local')
    print(f'bit-identical DataFrames: {res["bit_identical"]}; scenes with an error: '
          f'{res["scene_errors"]}')
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2))
    return 0 if res['bit_identical'] else 1


if __name__ == '__main__':
    sys.exit(main())
