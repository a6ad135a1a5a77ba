"""Running sweeps: local processes, a real Dask scheduler with two workers, checkpoints."""
from __future__ import annotations

import sys

import pandas as pd
import pytest


from crawler_sim.sweep import runner, spec_from_dict, sweep
from crawler_sim.sweep.metrics import scene_figures

SPEC = {'name': 'small', 'periods': 8, 'samples_per_period': 20, 'chunk_size': 7,
        'base': {'crawler': {'masses': [1.0, 1.0], 'mu': 0.3},
                 'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02, 'frequency': 1.0,
                          'asymmetry': 0.5}},
        'random': {'n': 30, 'seed': 5, 'params': {
            'crawler.mu[1]': {'uniform': [0.1, 0.6]}, 'gait.asymmetry': {'uniform': [0.1, 0.9]},
            'bodies': {'choice': [2, 3]}}}}


@pytest.fixture(scope='module')
def serial() -> pd.DataFrame:
    return sweep(SPEC, workers=1)


def test_a_sweep_has_one_row_per_scene_equal_to_that_scene_run_on_its_own(serial):
    spec = spec_from_dict(SPEC)
    assert len(serial) == 30 and list(serial.index) == list(range(30))
    assert (serial['error'] == '').all()
    for k in (0, 13, 29):
        params = list(spec.param_sets())[k]
        alone = scene_figures(spec.scene(params), 8, 20)   # the figures computed directly
        assert serial.loc[k, 'mean_speed'] == alone['mean_speed']
        assert serial.loc[k, 'bodies'] == params['bodies']
        assert serial.loc[k, 'gait.asymmetry'] == params['gait.asymmetry']
    two = serial['bodies'] == 2
    assert serial.loc[two, 'stick_fraction_2'].isna().all()
    assert serial.loc[~two, 'stick_fraction_2'].notna().all()
    meta = serial.attrs['crawler_sim']
    assert meta['spec'] == spec.to_dict() and meta['version']


def test_local_processes_give_the_same_frame_bit_for_bit(serial):
    pd.testing.assert_frame_equal(sweep(SPEC, workers=2), serial, check_exact=True)


def test_an_invalid_combination_is_a_row_with_its_error_not_a_lost_sweep():
    spec = {k: v for k, v in SPEC.items() if k != 'random'}
    spec['grid'] = {'gait.amplitude': [0.02, -0.01]}     # a negative half stroke is invalid
    df = sweep(spec, workers=1)
    assert df.loc[0, 'error'] == '' and df.loc[1, 'error'].startswith('SceneError')
    assert 'amplitude' in df.loc[1, 'error'] and pd.isna(df.loc[1, 'mean_speed'])


def test_a_checkpointed_sweep_resumes_without_recomputing_finished_chunks(serial, tmp_path,
                                                                          monkeypatch):
    ck = tmp_path / 'ck'
    sweep(SPEC, workers=1, checkpoint=ck)
    chunks = sorted(ck.glob('chunk_*.parquet'))
    assert len(chunks) == 5                          # ceil(30 / 7)
    chunks[2].unlink()                               # as if interrupted before chunk 2 ended
    calls = []
    real = runner.run_chunk
    monkeypatch.setattr(runner, 'run_chunk', lambda data, i: calls.append(i) or real(data, i))
    again = sweep(SPEC, workers=1, checkpoint=ck)
    assert calls == [2]
    pd.testing.assert_frame_equal(again, serial, check_exact=True)


def test_a_checkpoint_of_another_spec_is_refused(tmp_path):
    sweep(dict(SPEC, random=dict(SPEC['random'], n=3)), workers=1, checkpoint=tmp_path)
    with pytest.raises(ValueError, match='checkpoint of another sweep spec'):
        sweep(SPEC, workers=1, checkpoint=tmp_path)


def test_a_dask_cluster_gives_the_local_frame_bit_for_bit_using_both_workers(serial, dask_client):
    df = sweep(SPEC, client=dask_client)
    pd.testing.assert_frame_equal(df, serial, check_exact=True)
    workers = dask_client.run(lambda: 'crawler_sim.sweep.runner' in sys.modules)
    assert len(workers) == 2 and all(workers.values())   # both imported and ran chunks


def test_a_dask_sweep_resumes_from_a_local_checkpoint(serial, dask_client, tmp_path):
    ck = tmp_path / 'ck'
    sweep(SPEC, workers=1, checkpoint=ck)
    for path in sorted(ck.glob('chunk_*.parquet'))[1:4]:
        path.unlink()
    df = sweep(SPEC, client=dask_client, checkpoint=ck)
    pd.testing.assert_frame_equal(df, serial, check_exact=True)
    assert len(list(ck.glob('chunk_*.parquet'))) == 5


def test_the_benchmark_compares_local_and_a_local_dask_cluster_and_finds_them_identical():
    from benchmarks import sweep as bench
    res = bench.run(scenes=12, repeat=1, workers=2, chunk_size=4, log=lambda message: None)
    assert res['bit_identical'] and res['scene_errors'] == 0
    assert len(res['local_s']) == len(res['dask_s']) == 1
    # the overhead is derived from the two medians it reports
    assert res['dask_overhead_pct'] == pytest.approx(
        100 * (res['dask_median_s'] / res['local_median_s'] - 1))


BILLION = dict(SPEC, name='billion', periods=4, samples_per_period=4, chunk_size=2,
               random={'n': 10**9, 'seed': 1,
                       'params': {'crawler.mu[1]': {'uniform': [0.1, 0.6]}}})


class Stop(Exception):
    """Raised by a progress callback to end a sweep that would run for years."""


def stop_after(chunks: int, reports: list):
    def progress(done: int, total: int) -> None:
        reports.append((done, total))
        if len(reports) > chunks:
            raise Stop
    return progress


def budget(fn, limit: int):
    """``fn`` that fails past ``limit`` calls: a driver that walked every chunk of a billion
    scenes up front stops there instead of running for hours."""
    calls = [0]

    def wrapped(*args, **kw):
        calls[0] += 1
        assert calls[0] <= limit, f'{fn.__name__} called for every chunk up front'
        return fn(*args, **kw)
    return wrapped


def test_a_billion_scene_sweep_starts_at_once_checkpoints_and_resumes(tmp_path, monkeypatch):
    monkeypatch.setattr(runner.Checkpoint, 'done', budget(runner.Checkpoint.done, 100))
    reports: list = []
    with pytest.raises(Stop):
        sweep(BILLION, workers=1, checkpoint=tmp_path, progress=stop_after(3, reports))
    assert reports == [(0, 10**9), (2, 10**9), (4, 10**9), (6, 10**9)]
    assert sorted(p.name for p in tmp_path.glob('chunk_*')) == [
        'chunk_000000.parquet', 'chunk_000001.parquet', 'chunk_000002.parquet']
    # resumed: the finished scenes count from the start, the next chunk is the fourth
    reports.clear()
    with pytest.raises(Stop):
        sweep(BILLION, workers=1, checkpoint=tmp_path, progress=stop_after(1, reports))
    assert reports == [(6, 10**9), (8, 10**9)]
    again = pd.read_parquet(tmp_path / 'chunk_000003.parquet')
    assert list(again['scene']) == [6, 7] and (again['error'] == '').all()


def test_local_workers_get_a_few_chunks_at_a_time_not_the_whole_sweep(tmp_path, monkeypatch):
    submitted: list[int] = []

    class Counting(runner.ProcessPoolExecutor):
        def submit(self, fn, data, index):
            submitted.append(index)
            assert len(submitted) <= 50, 'every chunk submitted up front'
            return super().submit(fn, data, index)

    monkeypatch.setattr(runner, 'ProcessPoolExecutor', Counting)
    monkeypatch.setattr(runner.Checkpoint, 'done', budget(runner.Checkpoint.done, 100))
    reports: list = []
    with pytest.raises(Stop):
        sweep(BILLION, workers=2, checkpoint=tmp_path, progress=stop_after(6, reports))
    done = [d for d, _ in reports]
    assert done == sorted(done) and done[-1] == 12
    # in flight: two per worker; the next chunk is submitted when one ends
    assert len(submitted) <= 4 + 6 and submitted == list(range(len(submitted)))


def test_a_dask_sweep_keeps_a_few_tasks_in_flight_not_the_whole_sweep(dask_client, monkeypatch):
    from crawler_sim.sweep.cluster import run_on_client
    spec = spec_from_dict(BILLION)
    monkeypatch.setattr(dask_client, 'submit', budget(dask_client.submit, 50))
    done: list[int] = []

    def on_done(i: int, df: pd.DataFrame) -> None:
        done.append(i)
        assert list(df['scene']) == [2 * i, 2 * i + 1]
        if len(done) == 6:
            raise Stop

    with pytest.raises(Stop):
        run_on_client(dask_client, spec, range(runner.n_chunks(spec)), on_done)
    assert sorted(done) == sorted(set(done)) and len(done) == 6


def test_a_large_checkpointed_sweep_keeps_chunks_on_disk_and_reads_them_back(serial, tmp_path,
                                                                            monkeypatch):
    monkeypatch.setattr(runner, '_IN_MEMORY_SCENES', 10)     # SPEC's 30 scenes count as large
    loaded: list[int] = []
    real = runner.Checkpoint.load
    monkeypatch.setattr(runner.Checkpoint, 'load',
                        lambda self, i: loaded.append(i) or real(self, i))
    df = sweep(SPEC, workers=2, checkpoint=tmp_path)
    assert loaded == [0, 1, 2, 3, 4]              # every chunk came back from disk, in order
    pd.testing.assert_frame_equal(df, serial, check_exact=True)

