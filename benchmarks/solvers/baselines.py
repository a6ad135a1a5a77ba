"""The baselines users write by hand: scipy ``solve_ivp`` on a regularised friction law.

Both baselines integrate the centre of mass X and its velocity V (MODEL.md section 2), with
e_i'(t) the bodies' velocities relative to the centre of mass, from the gait:

* ``penalised``: the seed's Moreau-Yosida penalisation (its eq. 4) generalised to p bodies,
  ``M V' = F_ext - sum_i clip(n (V + e_i'), -f_minus_i, f_plus_i)``;
* ``tanh``: a smoothed Coulomb law, ``M V' = F_ext - sum_i f_i(v_i) tanh(v_i / eps)`` with
  ``v_i = V + e_i'`` and ``f_i = f_plus_i`` for v_i > 0, ``f_minus_i`` otherwise.

Each is given its analytic Jacobian. The right-hand sides are written the way a careful user
would: plain Python floats and the gait rates in scalar math (``rate_function``), so the
comparison is with a fast hand-written integrator, not with numpy call overhead.
A run that exceeds its wall-time budget stops with status "timeout" (a counter checks the clock
every 1024 calls of the right-hand side).
"""
from __future__ import annotations

import bisect
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from crawler_sim.core import gaits
from crawler_sim.core.model import Crawler

__all__ = ['BaselineResult', 'rate_function', 'make_ode', 'run_baseline', 'baseline_history']

TWO_PI = 2.0 * math.pi


class BudgetExceeded(RuntimeError):
    """The right-hand side was called after the run's wall-time budget ran out."""


@dataclass
class BaselineResult:
    """One ``solve_ivp`` run sampled on ``t``: centre of mass ``X`` and velocity ``V`` (N,)."""

    t: NDArray[np.float64]
    X: NDArray[np.float64]
    V: NDArray[np.float64]
    status: str          # 'ok', 'failed' (solve_ivp status < 0) or 'timeout'
    message: str
    nfev: int
    njev: int
    sol: object = None   # the dense output when asked for


# ----------------------------------------------------------------------------- gait rates

def rate_function(gait: gaits.Gait) -> Callable[[float], list[float]]:
    """l'(t) as a list of floats, in scalar math for the built-in periodic gaits.

    Sinusoid, Scallop and Fourier are written out (the formulas of ``crawler_sim.core.gaits``); other
    gaits use ``gait.at`` (or ``gait(t)``). The test suite checks these against ``gait(t)``.
    """
    if isinstance(gait, gaits.Sinusoid):
        w = gait._w if hasattr(gait, '_w') else TWO_PI * gait.frequency
        aw = (gait.amplitude * w).tolist()
        ph = gait.phase.tolist()
        links = list(zip(aw, ph))
        return lambda t: [a * math.cos(w * t + p) for a, p in links]
    if isinstance(gait, gaits.Scallop):
        r, f = gait.asymmetry, gait.frequency
        c, s, w = math.cos(math.pi * r), math.sin(math.pi * r), TWO_PI * gait.frequency
        links = [(a * w, p - math.pi * r) for a, p in zip(gait.amplitude.tolist(),
                                                          gait.phase.tolist())]

        def scallop(t: float) -> list[float]:
            base = TWO_PI * ((f * t) % 1.0)
            out = []
            for aw, ph in links:
                x = base + ph
                cx = math.cos(x)
                inv_d = 1.0 / (1.0 - c * cx)
                out.append(aw * (cx - c) * inv_d * s * inv_d)
            return out
        return scallop
    if isinstance(gait, gaits.Fourier):
        f = gait.frequency
        w = TWO_PI * f
        K = gait.cos.shape[1]
        rows = [[(w * (k + 1) * gait.sin[j, k], -w * (k + 1) * gait.cos[j, k]) for k in range(K)]
                for j in range(gait.n_links)]

        def fourier(t: float) -> list[float]:
            th = TWO_PI * ((f * t) % 1.0)
            cs = [(math.cos((k + 1) * th), math.sin((k + 1) * th)) for k in range(K)]
            return [sum(b * ck + a * sk for (b, a), (ck, sk) in zip(row, cs)) for row in rows]
        return fourier
    if isinstance(gait, gaits.PiecewiseParabolic) and gait.periodic:
        return _parabolic_rates(gait)
    at = getattr(gait, 'at', None) or gait
    return lambda t: at(t)[1].tolist()


def _parabolic_rates(gait: gaits.PiecewiseParabolic) -> Callable[[float], list[float]]:
    tk = gait.times.tolist()
    T = gait.period
    acc = gait.accelerations
    v_knots = gait(np.asarray(tk[:-1]))[1]          # l' at the start of each piece
    pieces = [(tk[k], v_knots[k].tolist(), acc[k].tolist()) for k in range(len(tk) - 1)]
    starts = tk[:-1]
    t0 = tk[0]

    def parabolic(t: float) -> list[float]:
        u = t0 + ((t - t0) % T)
        k = min(max(bisect.bisect_right(starts, u) - 1, 0), len(pieces) - 1)
        a_t, v, a = pieces[k]
        d = u - a_t
        return [vj + aj * d for vj, aj in zip(v, a)]
    return parabolic


# ----------------------------------------------------------------------------- the ODEs

def make_ode(crawler: Crawler, gait: gaits.Gait, model: str, reg: float):
    """(rhs, jac, rel_velocities) of the regularised ODE in y = (X, V).

    ``model`` is 'penalised' (``reg`` = the seed's n [N s/m]) or 'tanh' (``reg`` = eps [m/s]).
    ``rel_velocities(t)`` gives e'(t) as a list (body i velocity = V + e_i').
    """
    rates = rate_function(gait)
    m = crawler.masses
    M = float(m.sum())
    w = (m / M).tolist()
    fp = crawler.friction.tolist()
    fm = crawler.friction_backward.tolist()
    fext = crawler.external_force
    p = len(w)
    reg = float(reg)
    bodies = list(zip(fp, fm))

    if p == 2:
        w0, w1 = w

        def rel(t: float) -> list[float]:
            ld = rates(t)[0]
            return [-w1 * ld, w0 * ld]
    else:
        def rel(t: float) -> list[float]:
            s = 0.0
            S = [0.0]
            for r in rates(t):
                s += r
                S.append(s)
            mean = sum(wi * si for wi, si in zip(w, S))
            return [si - mean for si in S]

    if model == 'penalised':
        n = reg

        def rhs(t: float, y: NDArray) -> list[float]:
            V = float(y[1])
            F = fext
            for (a, b), ep in zip(bodies, rel(t)):
                z = n * (V + ep)
                F -= a if z > a else (-b if z < -b else z)
            return [V, F / M]

        def jac(t: float, y: NDArray) -> NDArray:
            V = float(y[1])
            k = 0
            for (a, b), ep in zip(bodies, rel(t)):
                z = n * (V + ep)
                k += -b < z < a
            return np.array([[0.0, 1.0], [0.0, -n * k / M]])
    elif model == 'tanh':
        eps = reg

        def rhs(t: float, y: NDArray) -> list[float]:
            V = float(y[1])
            F = fext
            for (a, b), ep in zip(bodies, rel(t)):
                v = V + ep
                F -= (a if v > 0.0 else b) * math.tanh(v / eps)
            return [V, F / M]

        def jac(t: float, y: NDArray) -> NDArray:
            V = float(y[1])
            d = 0.0
            for (a, b), ep in zip(bodies, rel(t)):
                v = V + ep
                th = math.tanh(v / eps)
                d += (a if v > 0.0 else b) * (1.0 - th * th) / eps
            return np.array([[0.0, 1.0], [0.0, -d / M]])
    else:
        raise ValueError(f"model must be 'penalised' or 'tanh', got {model!r}")
    return rhs, jac, rel


def _two_rates(gait: gaits.Gait) -> Callable[[float], tuple[float, float]]:
    """(l', l'') of a one-linkage gait in scalar math (a Fourier gait written out: the baseline
    pays for one series per right-hand side, as hand-written code would), else ``gait.at``."""
    if isinstance(gait, gaits.Fourier) and gait.n_links == 1:
        f = gait.frequency
        w = TWO_PI * f
        coef = [((k + 1) * w, float(a), float(b)) for k, (a, b) in
                enumerate(zip(gait.cos[0].tolist(), gait.sin[0].tolist()))]

        def fourier(t: float) -> tuple[float, float]:
            th = TWO_PI * ((f * t) % 1.0)
            ld = ldd = 0.0
            for k, (wk, a, b) in enumerate(coef, start=1):
                c, s = math.cos(k * th), math.sin(k * th)
                ld += wk * (b * c - a * s)
                ldd -= wk * wk * (a * c + b * s)
            return ld, ldd
        return fourier

    def generic(t: float) -> tuple[float, float]:
        _, ld, ldd = gait.at(t)
        return float(ld[0]), float(ldd[0])
    return generic


def seed_penalised_lsoda(crawler: Crawler, gait: gaits.Gait, t_end: float, t_eval: NDArray, *,
                         n: float = 1e8, rtol: float = 1e-10, atol: float = 1e-10,
                         max_step: float = math.inf) -> NDArray:
    """x_0 [m] at ``t_eval`` from scipy LSODA on the seed's penalised ODE itself (seed eq. 4,
    MODEL.md s. 4), two bodies, in the seed's own state (x_0, y = x_0'):

        M y' + clip(n y, -f+_0, f-_0) + clip(n (y + l'), -f+_1, f-_1) = F_ext - m_1 l'',

    with its analytic Jacobian; body 0 starts at rest at x = 0. (``run_baseline`` integrates
    the same model in the centre of mass's (X, V); on the issue 14 scenes LSODA takes very
    different steps in the two sets of coordinates: in (X, V) it steps over whole strokes of
    m = (1, 2), f = (1, 1) in 3.6 ms and ends 0.8 m off.)"""
    if crawler.p != 2:
        raise ValueError(f'seed_penalised_lsoda needs p = 2 bodies, got {crawler.p}')
    m1 = float(crawler.masses[1])
    M = float(crawler.masses.sum())
    (fp0, fp1), (fm0, fm1) = crawler.friction.tolist(), crawler.friction_backward.tolist()
    fext = float(crawler.external_force)
    rates = _two_rates(gait)

    def rhs(t: float, s: NDArray) -> list[float]:
        y = float(s[1])
        ld, ldd = rates(t)
        z0, z1 = n * y, n * (y + ld)
        r0 = fp0 if z0 > fp0 else (-fm0 if z0 < -fm0 else z0)
        r1 = fp1 if z1 > fp1 else (-fm1 if z1 < -fm1 else z1)
        return [y, (fext - m1 * ldd - r0 - r1) / M]

    def jac(t: float, s: NDArray) -> list[list[float]]:
        y = float(s[1])
        z0, z1 = n * y, n * (y + rates(t)[0])
        d = (n if -fm0 < z0 < fp0 else 0.0) + (n if -fm1 < z1 < fp1 else 0.0)
        return [[0.0, 1.0], [0.0, -d / M]]

    sol = solve_ivp(rhs, (0.0, float(t_end)), [0.0, 0.0], method='LSODA', jac=jac, rtol=rtol,
                    atol=atol, t_eval=np.asarray(t_eval, dtype=float), max_step=max_step)
    if sol.status != 0:
        raise RuntimeError(f'LSODA on the seed ODE failed: {sol.message}')
    return sol.y[0]


def run_baseline(crawler: Crawler, gait: gaits.Gait, t_end: float, t_eval: NDArray, *,
                 solver: str, model: str, reg: float, rtol: float, atol: float,
                 budget: float = 10.0, dense: bool = False,
                 max_step: float = math.inf) -> BaselineResult:
    """Integrate a regularised ODE with ``solve_ivp(method=solver)`` from rest (body 0 at x = 0,
    v = 0, as ``simulate`` starts) and sample X, V at ``t_eval``. ``max_step`` [s] bounds the
    solver's step (scipy's default: unbounded)."""
    rhs, jac, rel = make_ode(crawler, gait, model, reg)
    l0 = np.atleast_1d(gait(0.0)[0])
    s0 = np.concatenate([[0.0], np.cumsum(l0)])
    m = crawler.masses
    X0 = float(s0 @ m) / float(m.sum())             # body 0 at x = 0: X = x_0 - e_0
    V0 = -rel(0.0)[0]                                # body 0 at rest
    deadline = time.perf_counter() + budget
    calls = [0]

    def rhs_guarded(t: float, y: NDArray) -> list[float]:
        calls[0] += 1
        if not calls[0] & 1023 and time.perf_counter() > deadline:
            raise BudgetExceeded
        return rhs(t, y)

    try:
        sol = solve_ivp(rhs_guarded, (0.0, t_end), [X0, V0], method=solver, jac=jac,
                        rtol=rtol, atol=atol, t_eval=t_eval, dense_output=dense,
                        max_step=max_step)
    except BudgetExceeded:
        nan = np.full(t_eval.size, np.nan)
        return BaselineResult(t_eval, nan, nan, 'timeout', f'over the {budget:g} s budget',
                              calls[0], 0)
    status = 'ok' if sol.status == 0 and sol.y.shape[1] == t_eval.size else 'failed'
    if status != 'ok':
        nan = np.full(t_eval.size, np.nan)
        return BaselineResult(t_eval, nan, nan, status, str(sol.message), int(sol.nfev),
                              int(sol.njev))
    return BaselineResult(t_eval, sol.y[0], sol.y[1], status, str(sol.message), int(sol.nfev),
                          int(sol.njev), sol.sol if dense else None)


def _states(V: NDArray, ep: NDArray, crawler: Crawler, model: str, reg: float) -> NDArray:
    """Contact states (N, p) of the regularised model: stuck = inside the regularised zone."""
    v = V[:, None] + ep
    if model == 'penalised':
        z = reg * v
        return np.where(z >= crawler.friction, 1, np.where(z <= -crawler.friction_backward, -1, 0))
    # tanh: a body counts as stuck while |v| <= 3 eps (tanh(3) = 0.995)
    return np.where(v > 3.0 * reg, 1, np.where(v < -3.0 * reg, -1, 0))


def baseline_history(crawler: Crawler, gait: gaits.Gait, t_end: float, sol, *, model: str,
                     reg: float, per_period: int = 512) -> tuple[NDArray, list[tuple]]:
    """Stick/slip history of a dense baseline run: (initial states (p,), events).

    States are read on a fine grid (``per_period`` points per gait period, or 20000 over the
    run) and each change is located by bisection on the dense output to 1e-14 relative. Events
    closer together than the grid spacing may merge (the history is a diagnostic, not timed).
    """
    T = gait.period or t_end
    n = max(int(math.ceil(t_end / T * per_period)), 64)
    tg = np.linspace(0.0, t_end, n + 1)
    rel = make_ode(crawler, gait, model, reg)[2]

    def states_at(tt: NDArray) -> NDArray:
        ep = np.array([rel(float(x)) for x in tt])
        return _states(np.atleast_1d(sol(tt)[1]), ep, crawler, model, reg)

    state = states_at(tg)
    events = []
    for k in np.nonzero(np.any(state[1:] != state[:-1], axis=1))[0]:
        for i in np.nonzero(state[k + 1] != state[k])[0]:
            lo, hi = float(tg[k]), float(tg[k + 1])
            for _ in range(64):
                mid = 0.5 * (lo + hi)
                if mid in (lo, hi):
                    break
                if states_at(np.array([mid]))[0, i] == state[k, i]:
                    lo = mid
                else:
                    hi = mid
            events.append((hi, int(i), int(state[k, i]), int(state[k + 1, i])))
    events.sort()
    return state[0], events
