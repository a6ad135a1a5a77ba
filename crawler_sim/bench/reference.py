"""An independent event-driven reference for two-body crawlers (the bench's error figures).

Written from the model (MODEL.md s. 2 for p = 2), not from the exact solver, and deliberately
simple: the centre of mass X, V moves in one of two kinds of mode,

- both bodies sliding with signs s_0, s_1: V' = (F_ext + R_0 + R_1) / M with the sliding
  forces R_i = -f+_i (s_i > 0) or +f-_i (s_i < 0), so V and X are polynomials in t;
- body j stuck (v_j = V + c_j l' = 0, c_0 = -m_1 / M, c_1 = m_0 / M): V = -c_j l'(t) and the
  ground holds it with R_j = -M c_j l'' - F_ext - R_k, admissible while -f+_j <= R_j <= f-_j;

and it changes mode where a sliding velocity or a stuck body's force reaches its bound. Event
times: the event functions are sampled on a uniform grid (``scan``, 1e-5 s: far below the gait's
time scales here), the first sign change is bracketed and refined by ``scipy.optimize.brentq``
to a few ulps. No Taylor bounds, no look-ahead rules, no periodic skip: nothing shared with
``exact.py`` but the model. A stick that lasts less than one scan step would be missed; on the
bench's smooth Fourier scenes events are 0.05 s apart or more.

The implicit method with Richardson extrapolation (the bench's first reference) is limited to
about 1e-10 m on these scenes by its rounding after 1e6-1e7 steps; this one reaches 1e-13.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from ..core.gaits import Gait
from ..core.model import Crawler

__all__ = ['two_body_reference']


def two_body_reference(crawler: Crawler, gait: Gait, T: float, grid: np.ndarray,
                       scan: float = 1e-5) -> dict:
    """x_0(T) [m] and the centre of mass on ``grid`` [m] of a two-body crawler starting at rest
    with body 0 at x = 0; ``grid`` sorted in [0, T]."""
    if crawler.p != 2:
        raise ValueError(f'two_body_reference needs p = 2 bodies, got {crawler.p}')
    m0, m1 = (float(v) for v in crawler.masses)
    M = m0 + m1
    c = (-m1 / M, m0 / M)                     # x_i = X + c_i l, v_i = V + c_i l'
    fp = [float(v) for v in crawler.friction]
    fm = [float(v) for v in crawler.friction_backward]
    fext = float(crawler.external_force)

    def lv(t):
        l, ld, ldd = gait(np.atleast_1d(np.asarray(t, dtype=float)))
        return l[:, 0], ld[:, 0], ldd[:, 0]

    def slide_force(i, s):
        return -fp[i] if s > 0 else fm[i]

    t = 0.0
    l0, ld0, _ = lv(0.0)
    X, V = -c[0] * l0[0], -c[0] * ld0[0]       # body 0 at 0, at rest
    pieces = []                                # (t0, t1, mode, X0, V0, a, stuck body, x_j)
    while t < T:
        _, ld, _ = lv(t)
        v = [V + c[i] * ld[0] for i in range(2)]
        # the mode at t: a body at zero velocity sticks if the ground can hold it while the
        # other slides; decided a little after t (1e-9 s), where a force that reached its bound
        # at an event has left it and a velocity at a turning point has its new sign
        zero = [abs(v[i]) <= 1e-12 * (1 + abs(V)) for i in range(2)]
        _, ld_a, ldd_a = lv(t + 1e-9)
        mode = None
        for j in (i for i in range(2) if zero[i]):
            k = 1 - j
            sk = 1.0 if (c[k] - c[j]) * ld_a[0] > 0 else -1.0
            need = -M * c[j] * ldd_a[0] - fext - slide_force(k, sk)
            if -fp[j] <= need <= fm[j]:
                mode = ('stick', j, sk)
                break
            if not zero[k]:
                sj = 1.0 if need < -fp[j] else -1.0
                mode = ('slide', (sj, sk) if j == 0 else (sk, sj))
        if mode is None:
            if any(zero):
                raise RuntimeError(f'both bodies at rest and neither held at t = {t}: '
                                   'not handled by this reference')
            mode = ('slide', (np.sign(v[0]), np.sign(v[1])))
        if mode[0] == 'slide':
            s = mode[1]
            a = (fext + slide_force(0, s[0]) + slide_force(1, s[1])) / M

            def g(tt, X0=X, V0=V, t0=t, a=a, s=s):
                _, ldt, _ = lv(tt)
                Vt = V0 + a * (tt - t0)
                return np.minimum(s[0] * (Vt + c[0] * ldt), s[1] * (Vt + c[1] * ldt))
        else:
            _, j, sk = mode
            k = 1 - j

            def g(tt, j=j, k=k, sk=sk):
                _, ldt, lddt = lv(tt)
                need = -M * c[j] * lddt - fext - slide_force(k, sk)
                return np.minimum(np.minimum(need + fp[j], fm[j] - need),
                                  sk * (c[k] - c[j]) * ldt)
        t1 = _first_root(g, t, T, scan)
        if mode[0] == 'slide':
            pieces.append((t, t1, 'slide', X, V, a, -1, 0.0))
            d = t1 - t
            X, V = X + d * (V + 0.5 * a * d), V + a * d
        else:
            l_t, _, _ = lv(t)
            x_j = X + c[j] * l_t[0]
            pieces.append((t, t1, 'stick', X, V, 0.0, j, x_j))
            l1, ld1, _ = lv(t1)
            X, V = x_j - c[j] * l1[0], -c[j] * ld1[0]
        t = t1
    com = np.array([_com(pieces, tt, lv, c) for tt in np.asarray(grid, dtype=float)])
    lT, _, _ = lv(T)
    return {'x0': X + c[0] * lT[0], 'com': com, 'events': len(pieces) - 1}


def _first_root(g, t0: float, t_end: float, scan: float) -> float:
    """First t in (t0, t_end] where g (vectorised, > 0 just after t0) reaches 0, or t_end."""
    chunk = 4096
    a = t0
    while a < t_end:
        ts = np.minimum(a + scan * np.arange(1, chunk + 1), t_end)
        vals = g(ts)
        bad = np.nonzero(vals <= 0.0)[0]
        if bad.size:
            i = int(bad[0])
            lo = a if i == 0 else float(ts[i - 1])
            hi = float(ts[i])
            if g(np.array([lo]))[0] <= 0.0:
                return lo              # zero at the start of the bracket (t0 itself excluded)
            return brentq(lambda x: float(g(np.array([x]))[0]), lo, hi, xtol=1e-16,
                          rtol=4 * np.finfo(float).eps, maxiter=200)
        if ts[-1] >= t_end:
            return t_end
        a = float(ts[-1])
    return t_end


def _com(pieces, tt: float, lv, c) -> float:
    for t0, t1, kind, X0, V0, a, j, x_j in pieces:
        if tt <= t1:
            if kind == 'slide':
                d = tt - t0
                return X0 + d * (V0 + 0.5 * a * d)
            l_t, _, _ = lv(tt)
            return x_j - c[j] * l_t[0]
    raise ValueError(f'time {tt} beyond the reference run')
