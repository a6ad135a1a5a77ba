"""Independent references of the positive actuator work of a run (the cost of transport's
numerator), for tests and benchmarks: only runs sampled at chosen times, SciPy's brentq and
Gauss-Legendre quadrature (``positive_work_reference``), or, where the power is a cubic
between events and joins (constant-jerk gaits), numpy's polynomial fit and companion-matrix
roots refined in long double (``positive_work_of_cubic_pieces``: roots closer than the first
one's grid); none of crawler_sim.core.dense's own root finding or closed forms."""
from __future__ import annotations

import numpy as np

import crawler_sim as cs

__all__ = ['positive_work_reference', 'positive_work_of_cubic_pieces']


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


def positive_work_of_cubic_pieces(crawler: cs.Crawler, g, t_end: float, a: float, b: float,
                                  joins=()) -> tuple[float, float]:
    """Integral of max(power, 0) over [a, b] for a gait whose power is a cubic between the
    run's events and ``joins`` (a constant-jerk gait's piece starts): on each such piece the
    power at 9 Chebyshev points (a run sampled there), its cubic by least squares, the cubic's
    roots by numpy.roots (the companion matrix's eigenvalues), each refined by 6 Newton steps
    in long double, and the positive part integrated exactly between them in long double.
    Returns (the integral [J], the fit's largest residual over the piece's largest |power|:
    near the rounding when the power is a cubic there)."""
    events = np.array([e.time for e in cs.simulate(crawler, g, t_end).events
                       if a < e.time < b])
    joins = np.asarray(joins, dtype=float)
    edges = np.union1d(np.union1d([a, b], events), joins[(joins > a) & (joins < b)])
    lo, hi = edges[:-1], edges[1:]
    lo, hi = lo[hi > lo], hi[hi > lo]
    u = 0.5 - 0.5 * np.cos((np.arange(9) + 0.5) * np.pi / 9)
    s = cs.simulate(crawler, g, t_end, t_eval=(lo[:, None] + (hi - lo)[:, None] * u).ravel())
    P = np.sum(s.linkage_force * s.rates, axis=1).reshape(lo.size, u.size)
    total, worst = np.longdouble(0.0), 0.0
    for k in range(lo.size):
        c = np.polynomial.polynomial.polyfit(u, P[k], 3)
        fit = np.polynomial.polynomial.polyval(u, c)
        worst = max(worst, float(np.abs(fit - P[k]).max() / max(np.abs(P[k]).max(), 1e-300)))
        cl = c.astype(np.longdouble)
        roots = np.roots(c[::-1]) if np.any(c[1:]) else np.zeros(0)
        roots = roots.real[np.abs(roots.imag) <= 1e-9].astype(np.longdouble)
        for _ in range(6):
            f = cl[0] + roots * (cl[1] + roots * (cl[2] + roots * cl[3]))
            df = cl[1] + roots * (2 * cl[2] + roots * 3 * cl[3])
            roots = roots - np.where(df != 0, f / np.where(df != 0, df, 1), 0)
        pts = np.sort(np.concatenate([[0.0], roots[(roots > 0) & (roots < 1)], [1.0]])
                      .astype(np.longdouble))

        def integral(x):
            return x * (cl[0] + x * (cl[1] / 2 + x * (cl[2] / 3 + x * cl[3] / 4)))
        for x0, x1 in zip(pts[:-1], pts[1:]):
            m = (x0 + x1) / 2
            if cl[0] + m * (cl[1] + m * (cl[2] + m * cl[3])) > 0:
                total += (integral(x1) - integral(x0)) * np.longdouble(hi[k] - lo[k])
    return float(total), worst
