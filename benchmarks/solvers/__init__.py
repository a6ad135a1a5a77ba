"""Benchmarks and stress runs of the crawler_sim solvers (run from a source checkout).

* :func:`run_bench`: work-precision of every method and of the scipy baselines on the bench
  scenes (``benchmarks/scenes/*.yaml``), throughput figures and their floors; writes JSON,
  Markdown and a PNG: ``python -m benchmarks.solvers [--quick]`` (``make bench``).
* ``python -m benchmarks.solvers compare``: the exact method against scipy's LSODA.
* :func:`run_stress`: randomised and extreme scenes checked with ``verify`` and against each
  other, for a wall-time budget: ``python -m benchmarks.solvers stress --seconds S``.
"""
from __future__ import annotations

from .runner import run_bench
from .scenes import BenchScene, load_bench_scene, load_bench_scenes

__all__ = ['BenchScene', 'load_bench_scene', 'load_bench_scenes', 'run_bench', 'run_stress']


def run_stress(seconds: float = 60.0, seed: int = 0, progress=None) -> dict:
    """Randomised and extreme stress checks of every method (see ``benchmarks.solvers.stress``)."""
    from .stress import run_stress as _run
    return _run(seconds=seconds, seed=seed, progress=progress)
