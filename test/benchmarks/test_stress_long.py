"""The long stress profile (issue 27: under test/ with a marker): every fixed check at full size,
the 1e5-period run, then random scenes for ``CRAWLER_STRESS_SECONDS`` (default 600) of wall time.

Not part of ``make test`` (``setup.cfg`` deselects the ``long`` marker); run it with

    python -m pytest -m long test/benchmarks/test_stress_long.py

or, printing one line per check, ``python -m benchmarks.solvers stress --seconds 600``.
"""
from __future__ import annotations

import os

import pytest

from benchmarks.solvers.stress import run_stress


@pytest.mark.long
def test_the_long_stress_profile_passes_every_check():
    seconds = float(os.environ.get('CRAWLER_STRESS_SECONDS', '600'))
    res = run_stress(seconds=seconds, progress=print)
    assert res['ok'], '\n'.join(res['failures']
                                + [f'reproduce: check_random_scene({s})'
                                   for s in res.get('failed_specs', [])])
