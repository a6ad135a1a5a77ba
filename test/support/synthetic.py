"""Deterministic synthetic run arrays, for tests and load benchmarks of the bag code.

The numbers are random but shaped like a recording (p bodies, p-1 linkages, contact states in
{-1, 0, 1}); they are not a physical trajectory.
"""
from __future__ import annotations

from typing import Any

import numpy as np


def synthetic_arrays(n: int, p: int = 3, *, dt: float = 0.01, t0: float = 0.0,
                     seed: int = 0) -> dict[str, Any]:
    """Keyword arrays for :func:`crawler_sim.bag.record_arrays`, plus ``masses``.

    ``t`` (n,) [s] spaced ``dt``; ``x, v, friction, contact`` (n, p); ``lengths, rates,
    linkage_force`` (n, p-1); ``masses`` (p,) [kg].
    """
    rng = np.random.default_rng(seed)
    return {
        't': t0 + dt * np.arange(n),
        'x': np.cumsum(rng.normal(scale=1e-3, size=(n, p)), axis=0) + np.arange(p) * 0.1,
        'v': rng.normal(size=(n, p)),
        'friction': rng.normal(size=(n, p)),
        'contact': rng.integers(-1, 2, size=(n, p)).astype(np.int8),
        'lengths': 0.1 + rng.normal(scale=0.01, size=(n, p - 1)),
        'rates': rng.normal(size=(n, p - 1)),
        'linkage_force': rng.normal(size=(n, p - 1)),
        'masses': 1.0 + rng.random(p),
    }
