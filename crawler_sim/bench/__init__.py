"""Benchmarks and stress runs of the crawler_sim solvers (issue 6).

* :func:`run_bench`: work-precision of every method and of the scipy baselines on the bench
  scenes (``config/bench/*.yaml``), throughput figures and the issue's floors; writes JSON,
  Markdown and a PNG. ``crawler-sim bench`` and ``python -m crawler_sim.bench`` call it.
* :func:`run_stress`: randomised and extreme scenes checked with ``verify`` and against each
  other, for a wall-time budget. ``crawler-sim stress`` and
  ``python -m crawler_sim.bench stress`` call it.
"""
from __future__ import annotations

from .runner import run_bench
from .scenes import BenchScene, load_bench_scene, load_bench_scenes

__all__ = ['BenchScene', 'load_bench_scene', 'load_bench_scenes', 'run_bench', 'run_stress']


def run_stress(seconds: float = 60.0, seed: int = 0, progress=None) -> dict:
    """Randomised and extreme stress checks of every method (see ``bench.stress``)."""
    from .stress import run_stress as _run
    return _run(seconds=seconds, seed=seed, progress=progress)
