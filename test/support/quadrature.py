"""An independent reference of the positive actuator work of a run (the cost of transport's
numerator), for tests and benchmarks: only runs sampled at chosen times, SciPy's brentq and
Gauss-Legendre quadrature, none of crawler_sim.core.dense's own root finding or closed forms."""
from __future__ import annotations

import numpy as np

import crawler_sim as cs

__all__ = ['positive_work_reference']


def positive_work_reference(crawler: cs.Crawler, g, t_end: float, a: float, b: float,
                            joins=()) -> float:
    """Integral of max(power, 0) over [a, b] by runs sampled at chosen times only: the power's
    sign changes bracketed on a 40,001-point grid (plus the events) and narrowed by brentq,
    each evaluation a run sampled at that time; then 20-point Gauss-Legendre on stretches of at
    most 5 ms between events, ``joins`` (times where the gait's jerk jumps) and roots."""
    from scipy.optimize import brentq

    events = np.array([e.time for e in cs.simulate(crawler, g, t_end).events
                       if a < e.time < b])
    joins = np.asarray(joins, dtype=float)
    events = np.union1d(events, joins[(joins > a) & (joins < b)])
    grid = np.union1d(np.linspace(a, b, 40001), events)
    s = cs.simulate(crawler, g, t_end, t_eval=grid)
    P = np.sum(s.linkage_force * s.rates, axis=1)

    def power(t):
        r = cs.simulate(crawler, g, t_end, t_eval=[t])
        return float(np.sum(r.linkage_force * r.rates))
    roots = []
    for k in np.flatnonzero(np.sign(P[1:]) != np.sign(P[:-1])):
        x0, x1 = np.nextafter(grid[k], grid[k + 1]), np.nextafter(grid[k + 1], grid[k])
        if np.sign(power(x0)) != np.sign(power(x1)):      # not a jump at an event
            roots.append(brentq(power, x0, x1, xtol=1e-15, rtol=1e-15))
    edges = np.union1d(np.union1d([a, b], events), roots)
    cuts = [np.linspace(lo, hi, int(np.ceil((hi - lo) / 0.005)) + 1)
            for lo, hi in zip(edges, edges[1:]) if hi > lo]
    lo = np.concatenate([c[:-1] for c in cuts])
    hi = np.concatenate([c[1:] for c in cuts])
    u, w = np.polynomial.legendre.leggauss(20)
    nodes = (0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * u).ravel()
    weights = (0.5 * (hi - lo)[:, None] * w).ravel()
    order = np.argsort(nodes)
    s = cs.simulate(crawler, g, t_end, t_eval=nodes[order])
    return float(np.maximum(np.sum(s.linkage_force * s.rates, axis=1), 0.0) @ weights[order])
