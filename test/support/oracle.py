"""Independent reference solvers for the crawler, written apart from ``crawler_sim.core.solvers``:

- ``Oracle`` (p bodies, MODEL.md sections 1-2), for the differential tests;
- ``two_body_reference`` (two bodies, closed forms between events), for the benchmarks' error
  figures (see its docstring).

``Oracle``: an independent reference solver for the crawler (MODEL.md sections 1-2).

Written separately from ``crawler_sim.core.solvers`` on purpose: it imports nothing from them
(nor ``model.kinematics``) and trades speed for simplicity.

Method: event driven on the reduced inclusion  M V' in F_ext - sum_i dphi_i(V + e_i'(t)).

* The caller gives the linkage kinematics as a vectorised function ``kin(t) -> (l, l', l'')`` of
  arrays of shape (N, p-1), and every time where l'' may jump (``breakpoints``).
* Between events the motion is closed form: all bodies sliding, V is linear in t; a cluster C of
  bodies stuck together, V = -e_j'(t) for j in C.
* Events are searched on a fixed fine grid of step ``h`` (plus every breakpoint and sample time):
  a sign change of an event function at two grid points, or a sign change of its derivative with
  the extremum crossing zero (velocity events: the derivative is known in closed form, a + e_i''
  or e_i'' - e_j''; force events: a parabola through three grid values flags a possible dip,
  confirmed by a golden-section search). Each bracket is bisected to one ulp of t.
* The new mode at an event is the solution of the acceleration-level inclusion (MODEL.md 2.3):
  M a in R - sum_{i in Z} dphi_i(a + e_i''), solved by trying every kink and every interval
  between kinks. A body whose required force leaves its interval is released in the direction
  of the exit (the inclusion at the crossing instant is degenerate and would keep it stuck).

How its accuracy is established (test/core/solvers/test_fuzz_oracle.py): closed-form scenes (zero friction,
pure slides, a rigid link equal to one body), invariances (scaling, mirror symmetry), grid
self-convergence (h and h/4 agree to <= 1e-12 on the fuzz scene families) and a fully
independent fine implicit-Euler prox (``prox_implicit``, MODEL.md section 3) agreeing to O(dt).
It can miss an event whose event function dips to zero and back within one grid step without
its derivative changing sign at grid points (a dip of the derivative itself); ``h`` well below
the fastest time scale of the gait makes that vanishingly unlikely on the fuzz families.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import brentq

from crawler_sim.core.gaits import Gait
from crawler_sim.core.model import Crawler

Kin = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


class OracleError(RuntimeError):
    """The oracle could not make progress (it gives up instead of guessing)."""


def _offsets(masses: np.ndarray, l: np.ndarray) -> np.ndarray:
    """e_i = s_i - sum_k m_k s_k / M with s_0 = 0, s_i = l_0 + ... + l_{i-1}."""
    s = np.concatenate([np.zeros(l.shape[:-1] + (1,)), np.cumsum(l, axis=-1)], axis=-1)
    return s - (s @ masses)[..., None] / masses.sum()


class Oracle:
    """Reference solution of one crawler under one kinematics function on [0, t_end]."""

    def __init__(self, masses: Sequence[float], f_plus: Sequence[float],
                 f_minus: Sequence[float], f_ext: float, kin: Kin,
                 breakpoints: Sequence[float] = ()) -> None:
        self.m = np.asarray(masses, float)
        self.M = float(self.m.sum())
        self.fp = np.asarray(f_plus, float)
        self.fm = np.asarray(f_minus, float)
        self.fext = float(f_ext)
        self.kin = kin
        self.breaks = np.asarray(sorted(breakpoints), float)
        self.p = self.m.size
        self.n_events = 0

    @classmethod
    def for_crawler(cls, crawler, kin: Kin, breakpoints: Sequence[float] = ()) -> Oracle:
        """From a ``crawler_sim.Crawler``'s plain parameters (F_ext recomputed here)."""
        M = float(np.sum(crawler.masses))
        fext = -M * crawler.gravity * math.sin(crawler.slope)
        return cls(crawler.masses, crawler.friction, crawler.friction_backward, fext, kin,
                   breakpoints)

    # ------------------------------------------------------------------ kinematics
    def e(self, t: np.ndarray):
        """(e, e', e'') at times t, each of shape (N, p)."""
        l, ld, ldd = (np.asarray(a, float) for a in self.kin(np.atleast_1d(np.asarray(t, float))))
        return _offsets(self.m, l), _offsets(self.m, ld), _offsets(self.m, ldd)

    def e1(self, t: float):
        a, b, c = self.e(np.array([t]))
        return a[0], b[0], c[0]

    # ------------------------------------------------------------------ modes
    def _force(self, s: np.ndarray, idx: Sequence[int] | None = None) -> np.ndarray:
        """Friction F_i of the bodies ``idx`` (all) sliding with signs s[idx] (F_i in dphi_i)."""
        idx = list(range(self.p)) if idx is None else list(idx)
        si = s[idx]
        return np.where(si > 0, self.fp[idx], np.where(si < 0, -self.fm[idx], 0.0))

    def _accel(self, R: float, Z: list[int], edd: np.ndarray) -> float:
        """The unique a with M a in R - sum_{i in Z} dphi_i(a + e_i'')."""
        if not Z:
            return R / self.M
        kinks = sorted(set(float(-edd[i]) for i in Z))
        ez = edd[Z]
        fp, fm = self.fp[Z], self.fm[Z]
        tol = 1e-13 * (max(abs(k) for k in kinks) + abs(R) / self.M + 1e-300)

        def at_kink(c: float) -> bool:
            r = c + ez
            lo = R - self.M * c - np.sum(np.where(r > tol, fp, np.where(r < -tol, -fm, fp)))
            hi = R - self.M * c - np.sum(np.where(r > tol, fp, np.where(r < -tol, -fm, -fm)))
            return lo <= 0.0 <= hi

        bounds = [-math.inf] + kinks + [math.inf]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            mid = (lo + hi) / 2 if math.isfinite(lo + hi) else (hi - 1.0 if math.isfinite(hi)
                                                                 else lo + 1.0)
            if not math.isfinite(mid):
                mid = 0.0
            s = np.sign(mid + ez)
            a = (R - np.sum(np.where(s > 0, fp, -fm))) / self.M
            if lo < a < hi:
                return a
        for c in kinks:
            if at_kink(c):
                return c
        # rounding: the kink whose interval misses zero by the least
        return min(kinks, key=lambda c: abs(R - self.M * c
                                            - np.sum(np.where(c + ez > 0, fp, -fm))))

    def _decide(self, t: float, V: float, forced: Sequence[int] = ()):
        """Mode just after t: (signs s (p,), stuck cluster list)."""
        _, ed, edd = self.e1(t)
        u = V + ed
        Z = sorted(set(int(i) for i in np.nonzero(np.abs(u) <= self.tol_v)[0]) | set(forced))
        s = np.sign(u).astype(int)
        others = [i for i in range(self.p) if i not in Z]
        R = self.fext - float(np.sum(self._force(s, others))) if others else self.fext
        a = self._accel(R, Z, edd)
        stuck = []
        for i in Z:
            r = a + edd[i]
            if abs(r) <= self.tol_a:
                stuck.append(i)
                s[i] = 0
            else:
                s[i] = 1 if r > 0 else -1
        return s, stuck

    # ------------------------------------------------------------------ root search helpers
    @staticmethod
    def _bisect(fn: Callable[[float], float], a: float, b: float) -> float:
        """Smallest representable t in (a, b] with fn(t) <= 0, given fn(a) > 0 >= fn(b)."""
        for _ in range(200):
            m = 0.5 * (a + b)
            if m <= a or m >= b:
                break
            if fn(m) > 0:
                a = m
            else:
                b = m
        return b

    @staticmethod
    def _golden_min(fn: Callable[[float], float], a: float, b: float) -> float:
        """Location of the minimum of a unimodal fn on [a, b]."""
        g = (math.sqrt(5) - 1) / 2
        c, d = b - g * (b - a), a + g * (b - a)
        fc, fd = fn(c), fn(d)
        for _ in range(100):
            if fc < fd:
                b, d, fd = d, c, fc
                c = b - g * (b - a)
                fc = fn(c)
            else:
                a, c, fc = c, d, fd
                d = a + g * (b - a)
                fd = fn(d)
            if b - a <= 4 * np.spacing(max(abs(a), abs(b), 1e-300)):
                break
        return 0.5 * (a + b)

    def _first_crossing(self, tg: np.ndarray, g: np.ndarray, dg: np.ndarray | None,
                        fn: Callable[[float], float], dfn: Callable[[float], float] | None):
        """First t > tg[0] where fn (positive at tg[0]+) reaches <= 0, searched on grid tg.

        ``g`` holds fn on tg; ``dg`` its derivative (or None: parabola test). Returns t or None.
        """
        n = tg.size
        neg = np.nonzero(g[1:] <= 0)[0]
        k_stop = neg[0] + 1 if neg.size else n     # first grid index with fn <= 0
        # dips between grid points before k_stop
        cand = None
        if k_stop > 1:
            if dg is not None:
                d0, d1 = dg[:k_stop - 1], dg[1:k_stop]
                dips = np.nonzero((d0 < 0) & (d1 > 0))[0]
            else:
                gg = g[:k_stop]
                if gg.size >= 3:
                    curv = gg[2:] - 2 * gg[1:-1] + gg[:-2]
                    slope = 0.5 * (gg[2:] - gg[:-2])
                    with np.errstate(divide='ignore', invalid='ignore'):
                        vmin = gg[1:-1] - slope ** 2 / (2 * curv)
                        where = -slope / curv       # vertex, in grid steps from the middle
                    # a parabola through three grid values whose vertex lies between them and
                    # reaches (nearly) zero: a possible dip, confirmed by a golden search
                    dips = np.nonzero((curv > 0) & (np.abs(where) <= 1.0)
                                      & (vmin <= 0.25 * curv))[0]
                else:
                    dips = np.array([], int)
            for k in dips:
                a, b = (tg[k], tg[k + 1]) if dg is not None else (tg[k], tg[k + 2])
                if dfn is not None:
                    # derivative root by bisection (dfn < 0 at a, > 0 at b)
                    tm = self._bisect(lambda t: -dfn(t), a, b)
                else:
                    tm = self._golden_min(fn, a, b)
                if fn(tm) <= 0:
                    cand = self._bisect(fn, a, tm) if fn(a) > 0 else a
                    break
        if cand is None and k_stop < n:
            k = k_stop
            cand = self._bisect(fn, tg[k - 1], tg[k]) if fn(tg[k - 1]) > 0 else tg[k - 1]
        return cand

    # ------------------------------------------------------------------ driver
    def solve(self, t_end: float, t_eval: Sequence[float], *, x0: float = 0.0, v0: float = 0.0,
              h: float = 1e-4, max_events: int = 200000):
        """Positions and velocities (N, p) of the bodies at ``t_eval`` (sorted, in [0, t_end])."""
        t_eval = np.asarray(t_eval, float)
        grid = np.arange(0.0, t_end, h)
        grid = np.union1d(np.union1d(grid, [t_end]), t_eval)
        br = self.breaks[(self.breaks > 0) & (self.breaks < t_end)]
        grid = np.union1d(grid, br)
        E, Ed, Edd = self.e(grid)
        self.grid, self.E, self.Ed, self.Edd = grid, E, Ed, Edd
        vscale = float(np.max(np.abs(Ed))) + abs(v0) + 1e-300
        fsum = float(np.sum(np.maximum(self.fp, self.fm))) + abs(self.fext)
        ascale = float(np.max(np.abs(Edd))) + fsum / self.M + 1e-300
        vscale += ascale * t_end * 1e-3
        self.tol_v = 1e-11 * vscale
        self.tol_a = 1e-10 * ascale
        self.fscale = fsum + self.M * ascale

        e0, ed0, _ = self.e1(0.0)
        X, V, t = x0 - e0[0], v0 - ed0[0], 0.0
        s, stuck = self._decide(0.0, V)
        out_x = np.empty((t_eval.size, self.p))
        out_v = np.empty((t_eval.size, self.p))
        k = 0                       # grid index of t
        filled = 0
        last_t, same = -1.0, 0
        window = 512
        while True:
            t_next, X1, V1, info = self._phase(k, t, X, V, s, stuck, t_end, k + 1 + window)
            # fill samples in [t, t_next]
            while filled < t_eval.size and t_eval[filled] <= t_next:
                ts = t_eval[filled]
                Xs, Vs = info['eval'](ts)
                e, ed, _ = self.e1(ts)
                out_x[filled] = Xs + e
                out_v[filled] = Vs + ed
                filled += 1
            if t_next >= t_end:
                break
            if info.get('continue'):
                t, X, V = t_next, X1, V1
                k = int(np.searchsorted(grid, t, side='right')) - 1
                window = min(2 * window, 1 << 16)
                continue
            window = 512
            self.n_events += 1
            if self.n_events > max_events:
                raise OracleError(f'more than {max_events} events')
            same = same + 1 if t_next == last_t else 0
            if same > 20:
                raise OracleError(f'no progress at t = {t_next}')
            last_t = t_next
            t, X, V = t_next, X1, V1
            k = int(np.searchsorted(grid, t, side='right')) - 1
            if info['release'] is not None:
                s = s.copy()
                for i in stuck:
                    s[i] = info['release']
                stuck = []
            else:
                s, stuck = self._decide(t, V, info['forced'])
        return out_x, out_v

    def _phase(self, k: int, t0: float, X0: float, V0: float, s: np.ndarray, stuck: list,
               t_end: float, k_hi: int):
        """Advance one closed-form phase from t0 (grid index k, grid[k] <= t0) to its end, or
        to grid[k_hi - 1] when no event comes before (then the driver continues the same
        phase from there: a cut at a grid point changes nothing in the closed form)."""
        grid, Ed, Edd = self.grid, self.Ed, self.Edd
        k_hi = max(k_hi, k + 2)
        tg = np.concatenate([[t0], grid[k + 1:k_hi]])
        sl = slice(k + 1, k_hi)
        e_t0, ed_t0, edd_t0 = self.e1(t0)
        sliding = [i for i in range(self.p) if i not in stuck]
        events = []                 # (time, kind, body)
        if not stuck:
            a = (self.fext - float(np.sum(self._force(s)))) / self.M

            def evaluate(t, X0=X0, V0=V0, a=a, t0=t0):
                dt = t - t0
                return X0 + V0 * dt + 0.5 * a * dt * dt, V0 + a * dt
            for i in sliding:
                if s[i] == 0:
                    continue
                si = float(s[i])
                g = si * (V0 + a * (tg - t0) + np.concatenate([[ed_t0[i]], Ed[sl, i]]))
                dg = si * (a + np.concatenate([[edd_t0[i]], Edd[sl, i]]))
                g[0] = abs(g[0])        # starts at (or just after) zero: look after t0
                fn = (lambda t, i=i, si=si:
                      si * (V0 + a * (t - t0) + self.e1(t)[1][i]) if t > t0 else 1.0)
                dfn = lambda t, i=i, si=si: si * (a + self.e1(t)[2][i])
                tc = self._first_crossing(tg, g, dg, fn, dfn)
                if tc is not None:
                    events.append((tc, 'v', i))
        else:
            j = stuck[0]
            Fs = float(np.sum(self._force(s, sliding))) if sliding else 0.0
            up = float(np.sum(self.fp[stuck]))
            dn = float(np.sum(self.fm[stuck]))

            def evaluate(t, X0=X0, j=j, ej0=e_t0[j]):
                e, ed, _ = self.e1(t)
                return X0 - (e[j] - ej0), -ed[j]
            edj = np.concatenate([[ed_t0[j]], Ed[sl, j]])
            eddj = np.concatenate([[edd_t0[j]], Edd[sl, j]])
            for i in sliding:
                si = float(s[i])
                g = si * (np.concatenate([[ed_t0[i]], Ed[sl, i]]) - edj)
                dg = si * (np.concatenate([[edd_t0[i]], Edd[sl, i]]) - eddj)
                g[0] = abs(g[0])
                fn = (lambda t, i=i, si=si:
                      si * (self.e1(t)[1][i] - self.e1(t)[1][j]) if t > t0 else 1.0)
                dfn = lambda t, i=i, si=si: si * (self.e1(t)[2][i] - self.e1(t)[2][j])
                tc = self._first_crossing(tg, g, dg, fn, dfn)
                if tc is not None:
                    events.append((tc, 'v', i))
            # the cluster stays rigid: when a member's relative rate leaves zero, stop there
            for i in stuck[1:]:
                rel = np.abs(np.concatenate([[ed_t0[i]], Ed[sl, i]]) - edj)
                bad = np.nonzero(rel > self.tol_v)[0]
                if bad.size:
                    kb = max(int(bad[0]) - 1, 0)
                    events.append((float(tg[kb]) if kb > 0 else float(tg[1]), 'c', i))
            F = self.fext - Fs + self.M * eddj          # required friction of the cluster
            tolF = 1e-12 * self.fscale
            for sign, bound, rel in ((1.0, up, 1), (-1.0, dn, -1)):
                g = bound + tolF - sign * F
                fn = (lambda t, sign=sign, bound=bound:
                      bound + tolF - sign * (self.fext - Fs + self.M * self.e1(t)[2][j]))
                if g[0] <= 0:
                    events.append((t0, 'f', rel))
                    continue
                tc = self._first_crossing(tg, g, None, fn, None)
                if tc is not None:
                    events.append((tc, 'f', rel))
        if not events:
            t_stop = float(tg[-1]) if tg.size > 1 else t_end
            X1, V1 = evaluate(t_stop)
            return t_stop, X1, V1, {'eval': evaluate, 'release': None, 'forced': (),
                                    'continue': t_stop < t_end}
        tmin = min(ev[0] for ev in events)
        first = [ev for ev in events if ev[0] == tmin]
        X1, V1 = evaluate(tmin)
        release = next((ev[2] for ev in first if ev[1] == 'f'), None)
        forced = tuple(ev[2] for ev in first if ev[1] == 'v')
        if release is not None and forced:
            release = None          # decide everything from the inclusion at this instant
        return tmin, X1, V1, {'eval': evaluate, 'release': release, 'forced': forced}


def prox_implicit(oracle: Oracle, t_end: float, dt: float, x0: float = 0.0,
                  v0: float = 0.0) -> tuple[float, np.ndarray]:
    """Fully independent check: implicit-Euler prox of MODEL.md section 3, first order in dt.

    Returns (t_end, x (p,)). V_{k+1} minimises M/(2h)(V - V_k)^2 - F_ext V + sum phi_i(V + e_i');
    the minimiser is found exactly by checking each kink and each interval between kinks.
    """
    n = int(round(t_end / dt))
    ts = np.linspace(0.0, t_end, n + 1)
    E, Ed, _ = oracle.e(ts)
    M, fp, fm, fx = oracle.M, oracle.fp, oracle.fm, oracle.fext
    X = x0 - E[0, 0]
    V = v0 - Ed[0, 0]
    for k in range(1, n + 1):
        h = ts[k] - ts[k - 1]
        c = -Ed[k]                      # kinks: V = -e_i'
        # subgradient of the objective: M/h (V - Vk) - F_ext + sum dphi_i(V - c_i), increasing
        order = np.sort(c)
        Vn = None
        for lo, hi in zip(np.r_[-np.inf, order], np.r_[order, np.inf]):
            if lo == hi:
                continue
            mid = (lo + hi) / 2 if np.isfinite(lo + hi) else (hi - 1 if np.isfinite(hi)
                                                               else lo + 1)
            sl = np.sign(mid - c)
            cand = V + h / M * (fx - np.sum(np.where(sl > 0, fp, -fm)))
            if lo <= cand <= hi:
                Vn = cand
                break
        if Vn is None:
            for ck in order:
                r = ck - c
                lo = M / h * (ck - V) - fx + np.sum(np.where(r > 0, fp, np.where(r < 0, -fm, -fm)))
                hi = M / h * (ck - V) - fx + np.sum(np.where(r > 0, fp, np.where(r < 0, -fm, fp)))
                if lo <= 0 <= hi:
                    Vn = ck
                    break
        V = Vn
        X = X + h * V
    return t_end, X + E[-1]


# ------------------------------------------------------------------- the two-body reference
#An independent event-driven reference for two-body crawlers (the bench's error figures).
#
# Written from the model (MODEL.md s. 2 for p = 2), not from the exact solver, and deliberately
# simple: the centre of mass X, V moves in one of two kinds of mode,
#
# - both bodies sliding with signs s_0, s_1: V' = (F_ext + R_0 + R_1) / M with the sliding
#   forces R_i = -f+_i (s_i > 0) or +f-_i (s_i < 0), so V and X are polynomials in t;
# - body j stuck (v_j = V + c_j l' = 0, c_0 = -m_1 / M, c_1 = m_0 / M): V = -c_j l'(t) and the
#   ground holds it with R_j = -M c_j l'' - F_ext - R_k, admissible while -f+_j <= R_j <= f-_j;
#
# and it changes mode where a sliding velocity or a stuck body's force reaches its bound. Event
# times: the event functions are sampled on a uniform grid (``scan``, 1e-5 s: far below the gait's
# time scales here), the first sign change is bracketed and refined by ``scipy.optimize.brentq``
# to a few ulps. No Taylor bounds, no look-ahead rules, no periodic skip: nothing shared with
# ``exact.py`` but the model. A stick that lasts less than one scan step would be missed; on the
# bench's smooth Fourier scenes events are 0.05 s apart or more.
#
# The implicit method with Richardson extrapolation (the bench's first reference) is limited to
# about 1e-10 m on these scenes by its rounding after 1e6-1e7 steps; this one reaches 1e-13.
#



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
