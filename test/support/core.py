"""Scenes shared by the core tests."""
import numpy as np

import crawler_sim as cs
from crawler_sim.core import gaits


def wave(p, amp=0.02, freq=1.0, lag=0.7, mean=0.1):
    """A travelling-wave sinusoid for p bodies (p - 1 linkages)."""
    n = p - 1
    return gaits.Sinusoid(mean + 0.01 * np.arange(n), amp * (1 + 0.1 * np.arange(n)), freq,
                          -lag * np.arange(n))


def random_crawler(p, slope=0.0, seed=0):
    """p bodies with random masses and direction-dependent friction (backward >= forward)."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(0.5, 1.5, p)
    f = rng.uniform(0.5, 1.5, p)
    fb = f * rng.uniform(1.0, 2.5, p)
    return cs.Crawler(m, f, fb, slope=slope)
