"""A Dask worker that cannot run crawler_sim is named before any task is sent (issue 27: it
surfaced as ``FutureCancelledError ... already forgotten``). Real scheduler and worker
processes; the worker's PYTHONPATH lacks this checkout, as on a cluster without the package."""
from __future__ import annotations

import pytest

from crawler_sim.sweep import sweep
from crawler_sim.sweep.spec import spec_from_dict
from test.support.dask_cluster import local_cluster

pytest.importorskip('distributed')

SPEC = {'name': 'probe', 'base': {'crawler': {'masses': [0.5, 1.0], 'mu': 0.3},
                                  'gait': {'type': 'sinusoid', 'mean': 0.1,
                                           'amplitude': 0.02, 'frequency': 2.0},
                                  'run': {'t_end': 2.0}},
        'grid': {'gait.amplitude': [0.01, 0.02]}}


def test_a_worker_without_crawler_sim_is_named_with_the_fix(tmp_path):
    with local_cluster(tmp_path, workers=1, importable=False) as client:
        with pytest.raises(RuntimeError) as err:
            sweep(spec_from_dict(SPEC), client=client)
        worker = next(iter(client.scheduler_info()['workers']))
    text = str(err.value)
    assert f'{worker}: cannot import crawler_sim' in text
    assert "No module named 'crawler_sim'" in text and 'Install the same crawler_sim' in text
