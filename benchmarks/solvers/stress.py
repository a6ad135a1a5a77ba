"""Stress checks of numerical stability: random scenes, extremes and grazing contacts.

(Over 400 lines: one check per function, and they share the auditing helpers.)

Every check returns a `CheckResult` (``ok``, a message listing each problem, figures). The test
suite (``test/test_stress.py``) runs them with small sizes and hypothesis-drawn scenes;
`run_stress` runs them with larger sizes, many random scenes and the 1e5-period run.

What is checked
---------------
* the differential fuzz of issue 14 (`check_fuzz`): every gait family of test/support/fuzz.py,
  the exact method against the independent oracle (test/support/oracle.py) at 1e-10, each case
  also streamed onto its event times and the floats either side (issue 37);
* issue 37's long runs: Custom gaits with ``period=`` for 1e4 periods against their built-in
  twins (`check_custom_period_long`), and every periodic family for 1e4 periods, periodic skip
  on and off, against the oracle extrapolated by whole periods (`check_long_periodic`);
* every method's output passes ``verify`` at a tolerance that suits the method (`tolerances`)
  and holds no NaN or infinity;
* method "implicit" converges to method "exact" as dt shrinks (first order);
* extremes: mass ratio 1e6, friction ratio 1e6, p = 100, a 1 kHz gait, implicit steps longer
  than the gait period, penalty n = 1e12, and very long runs (the steady displacement per
  period stays constant to 1e-9 relative);
* grazing: a body velocity that touches zero without crossing, a stuck body's required force
  that touches its bound without crossing, and two transitions closer together than the
  solver's bracketing grid and than the output sampling; the stick/slip history is compared with
  the analytic one or with a fine independent computation (method "implicit" at a tiny dt).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import time
from typing import Any, Callable

import numpy as np

from crawler_sim.core import gaits
from crawler_sim.core.model import Crawler
from crawler_sim.core.stepper import Stepper, simulate
from crawler_sim.core.trajectory import Trajectory
from crawler_sim.core.verify import verify
from . import metrics

__all__ = ['CheckResult', 'random_spec', 'build', 'check_random_scene', 'EXTREMES', 'GRAZING',
           'check_fuzz', 'check_custom_period_long', 'check_long_periodic', 'check_long_run', 'check_tolerance_ladder', 'run_stress', 'tolerances']

G = 9.81
EXACT_TOL = 1e-9        # verify tolerance of method "exact"
IMPLICIT_TOL = 1e-8     # and of method "implicit" (rounding accumulates over the steps)
_EPS = float(np.finfo(float).eps)


@dataclass
class CheckResult:
    """Outcome of one stress check."""

    name: str
    ok: bool = True
    problems: list = field(default_factory=list)
    figures: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def message(self) -> str:
        return f'{self.name}: ' + ('ok' if self.ok else '; '.join(self.problems))

    def fail(self, text: str) -> None:
        self.ok = False
        self.problems.append(text)

    def to_dict(self) -> dict:
        return {'name': self.name, 'ok': self.ok, 'problems': list(self.problems),
                'figures': self.figures, 'seconds': self.seconds}


def _timed(fn: Callable[..., CheckResult]) -> Callable[..., CheckResult]:
    def wrapper(*args: Any, **kw: Any) -> CheckResult:
        t0 = time.perf_counter()
        try:
            res = fn(*args, **kw)
        except Exception as exc:  # noqa: BLE001 (a crash is a failed check, with its message)
            res = CheckResult(fn.__name__.removeprefix('check_'))
            res.fail(f'raised {type(exc).__name__}: {exc}')
        res.seconds = time.perf_counter() - t0
        return res
    wrapper.__name__ = fn.__name__
    wrapper.__doc__ = fn.__doc__
    return wrapper


# ----------------------------------------------------------------------------- auditing

def tolerances(crawler: Crawler, method: str, tr: Trajectory | None = None,
               penalty: float | None = None) -> float:
    """The ``verify`` tolerance for a method's output.

    "exact" and "implicit" satisfy the friction law exactly, so only rounding remains. The
    penalised law leaves a creep |v| < f / n inside its linear zone, so its relative violation is
    up to f_max / (n v_max) (dissipation gap and stuck velocity, see ``verify``). And it
    computes a force in that zone as n v: the rounding of v, ~eps (|V| + |e_i'|) <= 3 eps v_max,
    becomes a force error of 3 n eps v_max per body and step, an impulse error of up to
    3 p n eps v_max T over a run, against verify's momentum scale >= (sum of f) T: a relative
    momentum residual of up to 3 p n eps v_max / sum f (stress seed 13, scene 2741: masses of
    1e-3 kg, frictions of 1e-2 N, n = 1e8: 2.6e-8, against 1e-8 without this term).
    """
    if method == 'exact':
        return EXACT_TOL
    if method == 'implicit':
        return IMPLICIT_TOL
    f_max = float(max(crawler.friction.max(), crawler.friction_backward.max()))
    f_sum = float(crawler.friction.sum() + crawler.friction_backward.sum())
    v_max = float(np.abs(tr.v).max()) if tr is not None else 1.0
    creep = 2.0 * f_max / (float(penalty) * max(v_max, 1e-300))
    rounding = 4.0 * crawler.p * float(penalty) * _EPS * v_max / max(f_sum, 1e-300)
    return creep + rounding + IMPLICIT_TOL


def _finite(tr: Trajectory) -> bool:
    arrays = (tr.t, tr.x, tr.v, tr.friction, tr.linkage_force, tr.impulse)
    return all(bool(np.all(np.isfinite(a))) for a in arrays) and all(
        math.isfinite(e.time) for e in tr.events)


def audit(res: CheckResult, tr: Trajectory, label: str, tol: float) -> None:
    """Fail ``res`` if ``tr`` holds a NaN / inf or does not pass ``verify`` at ``tol``."""
    if not _finite(tr):
        res.fail(f'{label}: NaN or inf in the output')
        return
    rep = verify(tr)
    key = label.split()[0]
    res.figures[f'verify_{key}'] = max(res.figures.get(f'verify_{key}', 0.0), rep.worst)
    if not rep.ok(tol):
        res.fail(f'{label}: verify worst {rep.worst:.2e} > {tol:.1e} (momentum '
                 f'{rep.momentum_rel:.1e}, bound {rep.friction_bound_rel:.1e}, complementarity '
                 f'{rep.complementarity_rel:.1e}, stuck velocity {rep.stuck_velocity_rel:.1e}, '
                 f'contact {rep.contact}) at t = {rep.t_worst:.6g}')


def _scale(tr: Trajectory) -> float:
    """Length scale of a run: the span of every body's position [m]."""
    return float(np.ptp(tr.x)) + 1e-300


# ----------------------------------------------------------------------------- random scenes

def random_spec(rng: np.random.Generator, p_range: tuple[int, int] = (2, 12)) -> dict:
    """A random scene as plain data (see `build`): p bodies, masses and frictions over six
    orders of magnitude, some frictionless bodies, direction-dependent friction, a slope, a
    random smooth gait (Sinusoid or Fourier with random phases) and sometimes v0 != 0."""
    p = int(rng.integers(p_range[0], p_range[1] + 1))
    masses = (10.0 ** rng.uniform(-3, 3, p)).tolist()
    f = 10.0 ** rng.uniform(-3, 3, p)
    f[rng.random(p) < 0.15] = 0.0
    fb = f * 10.0 ** rng.uniform(-1, 1, p) if rng.random() < 0.5 else f.copy()
    fb[rng.random(p) < 0.05] = 0.0
    slope = float(rng.uniform(-0.5, 0.5)) if rng.random() < 0.3 else 0.0
    freq = float(10.0 ** rng.uniform(-0.5, 1.0))
    n = p - 1
    # amplitudes up to 0.1 m about a mean of 0.2 m: a Fourier gait's harmonics add up to at
    # most 1.83 x 0.1 m, so every length stays > 0 (a gait whose bodies cross is refused)
    if rng.random() < 0.5:
        gait = {'type': 'sinusoid', 'mean': 0.2,
                'amplitude': (10.0 ** rng.uniform(-3, -1, n)).tolist(),
                'frequency': freq, 'phase': rng.uniform(0, 2 * math.pi, n).tolist()}
    else:
        K = int(rng.integers(1, 4))
        amp = 10.0 ** rng.uniform(-3, -1, (n, 1)) / np.arange(1, K + 1)
        ph = rng.uniform(0, 2 * math.pi, (n, K))
        gait = {'type': 'fourier', 'mean': 0.2, 'cos': (amp * np.cos(ph)).tolist(),
                'sin': (amp * np.sin(ph)).tolist(), 'frequency': freq}
    v0 = float(rng.normal(0.0, 0.05)) if rng.random() < 0.3 else 0.0
    return {'masses': masses, 'friction': f.tolist(), 'friction_backward': fb.tolist(),
            'slope': slope, 'gait': gait, 'periods': float(rng.uniform(1.0, 2.0)), 'v0': v0}


def build(spec: dict) -> tuple[Crawler, gaits.Gait, float, float]:
    """(crawler, gait, t_end, v0) from a `random_spec` dictionary."""
    crawler = Crawler(spec['masses'], spec['friction'], spec['friction_backward'],
                      spec.get('slope', 0.0))
    g = spec['gait']
    if g['type'] == 'sinusoid':
        gait = gaits.Sinusoid(g['mean'], g['amplitude'], g['frequency'], g['phase'],
                              n_links=crawler.p - 1)
    else:
        gait = gaits.Fourier(g['mean'], (np.asarray(g['cos']), np.asarray(g['sin'])),
                             g['frequency'], n_links=crawler.p - 1)
    return crawler, gait, spec['periods'] * gait.period, float(spec.get('v0', 0.0))


@_timed
def check_random_scene(spec: dict, *, divs: tuple[int, ...] = (100, 400, 1600),
                       penalty: float = 1e8) -> CheckResult:
    """Every method on one random scene: verify, finiteness, implicit -> exact as dt shrinks."""
    res = CheckResult('random_scene')
    crawler, gait, t_end, v0 = build(spec)
    T = gait.period
    res.figures.update(p=crawler.p, t_end=t_end)
    grid = np.linspace(0.0, t_end, int(math.ceil(32 * t_end / T)) + 1)
    ex = simulate(crawler, gait, t_end, t_eval=grid, v0=v0)
    audit(res, ex, 'exact', EXACT_TOL)
    if not res.ok:
        return res
    scale = _scale(ex)
    errs = []
    for d in divs:
        im = simulate(crawler, gait, t_end, 'implicit', dt=T / d, t_eval=grid, v0=v0)
        audit(res, im, f'implicit dt=T/{d}', IMPLICIT_TOL)
        errs.append(float(np.max(np.abs(im.x - ex.x))) if _finite(im) else math.inf)
    # A stiff scene (a body of 1e-3 kg against 1e2 N of friction, or a heavy body launched at
    # v0 against 669 N: time scales of 1e-4 to 5e-5 s) is not yet in the first-order regime at
    # T/1600: up to four finer steps before calling it a failure (stress seed 7: scene 1490,
    # errors 9.1e-6, 9.1e-6, 9.0e-6, then 3.0e-6; scene 3121, 1.3e-6 down to T/25600, where
    # the independent oracle agrees with the exact run to 9e-11).
    levels = list(divs)
    while not _converges(errs[-3:], scale) and len(levels) < len(divs) + 4:
        levels.append(4 * levels[-1])
        im = simulate(crawler, gait, t_end, 'implicit', dt=T / levels[-1], t_eval=grid, v0=v0)
        errs.append(float(np.max(np.abs(im.x - ex.x))) if _finite(im) else math.inf)
    res.figures.update(err_implicit=errs, scale=scale)
    if not _converges(errs[-3:], scale):
        res.fail(f'implicit does not converge to exact: max |x - x_exact| = '
                 f'{", ".join(f"{e:.3e}" for e in errs)} at dt = T/{tuple(levels)} '
                 f'(scale {scale:.3e} m)')
    pe = simulate(crawler, gait, t_end, 'penalty', dt=T / divs[0], penalty=penalty, t_eval=grid,
                  v0=v0)
    audit(res, pe, 'penalty', tolerances(crawler, 'penalty', pe, penalty))
    return res


def _converges(errs: list[float], scale: float) -> bool:
    """First order in dt, robust to a lucky cancellation at one coarse step: the finest error
    is at most half the larger of the coarser ones (or at rounding level)."""
    return errs[-1] <= 0.5 * max(errs[:-1]) + 1e-9 * scale


# ----------------------------------------------------------------------------- extremes

def _compare_exact_implicit(res: CheckResult, crawler: Crawler, gait: gaits.Gait, t_end: float,
                            divs: tuple[int, ...], *, grid_per_period: int = 32) -> Trajectory:
    T = gait.period or t_end
    grid = np.linspace(0.0, t_end, int(math.ceil(grid_per_period * t_end / T)) + 1)
    ex = simulate(crawler, gait, t_end, t_eval=grid)
    audit(res, ex, 'exact', EXACT_TOL)
    errs = []
    for d in divs:
        im = simulate(crawler, gait, t_end, 'implicit', dt=T / d, t_eval=grid)
        audit(res, im, f'implicit dt=T/{d}', IMPLICIT_TOL)
        errs.append(float(np.max(np.abs(im.x - ex.x))) if _finite(im) else math.inf)
    scale = _scale(ex)
    res.figures.update(err_implicit=errs, scale=scale, displacement=ex.displacement,
                       events=len(ex.events))
    if len(errs) > 1 and not _converges(errs, scale):
        res.fail(f'implicit does not converge to exact: errors {errs} for dt = T/{divs}')
    return ex


@_timed
def check_mass_ratio(ratio: float = 1e6, divs: tuple = (100, 400, 1600)) -> CheckResult:
    """Masses 1e-3 and 1e3 kg (ratio 1e6), mu = 0.3, an asymmetric stroke."""
    res = CheckResult(f'mass_ratio_{ratio:g}')
    m = math.sqrt(ratio)
    for masses in ([1 / m, m], [m, 1 / m], [1 / m, m, 1 / m]):
        crawler = Crawler.from_coefficients(masses, 0.3)
        gait = gaits.Scallop(0.1, 0.02, 2.0, 0.25, n_links=len(masses) - 1)
        _compare_exact_implicit(res, crawler, gait, 2 * gait.period, divs)
    return res


@_timed
def check_friction_ratio(ratio: float = 1e6, divs: tuple = (100, 400, 1600)) -> CheckResult:
    """Friction forces 1e-3 and 1e3 N on 1 kg bodies (ratio 1e6), both directions and mixed."""
    res = CheckResult(f'friction_ratio_{ratio:g}')
    f = math.sqrt(ratio)
    cases = (([1 / f, f], None), ([f, 1 / f], None), ([1.0, 1.0], [1 / f, f]),
             ([1 / f, 1.0, f], [f, 1.0, 1 / f]))
    for fwd, bwd in cases:
        crawler = Crawler([1.0] * len(fwd), fwd, bwd)
        gait = gaits.Sinusoid(0.1, 0.05, 1.0, [0.0, -1.0][:len(fwd) - 1], n_links=len(fwd) - 1)
        _compare_exact_implicit(res, crawler, gait, 2 * gait.period, divs)
    return res


@_timed
def check_many_bodies(p: int = 100, periods: float = 1.0, divs: tuple = (64,)) -> CheckResult:
    """A p-body travelling wave (random masses and anisotropic frictions): every method."""
    res = CheckResult(f'p_{p}')
    rng = np.random.default_rng(p)
    masses = rng.uniform(0.5, 2.0, p)
    crawler = Crawler.from_coefficients(masses, rng.uniform(0.2, 0.4, p),
                                        rng.uniform(0.4, 0.8, p))
    gait = gaits.Sinusoid(0.05, 0.01, 1.0, -0.3 * np.arange(p - 1), n_links=p - 1)
    t_end = periods * gait.period
    t0 = time.perf_counter()
    _compare_exact_implicit(res, crawler, gait, t_end, divs, grid_per_period=16)
    res.figures['exact_and_implicit_s'] = time.perf_counter() - t0
    pe = simulate(crawler, gait, t_end, 'penalty', dt=gait.period / divs[0], penalty=1e8,
                  t_eval=np.linspace(0, t_end, 17))
    audit(res, pe, 'penalty', tolerances(crawler, 'penalty', pe, 1e8))
    return res


@_timed
def check_high_frequency(freq: float = 1000.0, periods: float = 5.0,
                         divs: tuple = (50, 200, 800)) -> CheckResult:
    """A 1 kHz stroke (10 um, accelerations ~40 g) on two light bodies."""
    res = CheckResult(f'frequency_{freq:g}Hz')
    crawler = Crawler.from_coefficients([0.002, 0.005], 0.4, 0.6)
    gait = gaits.Fourier(0.01, ([0.0, 0.0], [1e-5, 4e-6]), freq)
    _compare_exact_implicit(res, crawler, gait, periods * gait.period, divs)
    return res


@_timed
def check_implicit_large_steps(ratios: tuple = (1.0, 3.7, 10.0, 100.0)) -> CheckResult:
    """Method "implicit" with steps of 1 to 100 gait periods: finite, verify-clean and bounded
    (no velocity beyond the largest imposed relative velocity plus the exact run's, no position
    beyond the exact run's range plus the stroke)."""
    res = CheckResult('implicit_steps_longer_than_period')
    crawler = Crawler.from_coefficients([0.5, 1.0, 0.7], 0.3, [0.5, 0.3, 0.6], slope=0.05)
    gait = gaits.Scallop(0.1, 0.02, 2.0, 0.2, [0.0, -1.0])
    T = gait.period
    t_end = 200 * T
    ex = simulate(crawler, gait, t_end, t_eval=np.linspace(0, t_end, 401))
    # bounded: no body faster than the exact run's fastest plus twice the fastest linkage
    # rate, so positions grow at most linearly at that speed (a step of one period or more
    # samples the gait at one phase: it aliases, but it must not blow up)
    vmax = float(np.abs(ex.v).max()) + 2 * float(np.abs(gait(np.linspace(0, T, 257))[1]).max())
    span = float(np.ptp(gait(np.linspace(0, T, 257))[0].sum(axis=1))) + 1e-9
    for r in ratios:
        im = simulate(crawler, gait, t_end, 'implicit', dt=r * T)
        audit(res, im, f'implicit dt={r:g}T', IMPLICIT_TOL)
        if _finite(im):
            v = float(np.abs(im.v).max())
            grow = float(np.max(np.abs(im.x - im.x[0]) - vmax * im.t[:, None]))
            res.figures[f'vmax_dt_{r:g}T'] = v
            if v > vmax:
                res.fail(f'implicit dt={r:g}T: |v| up to {v:.3g} m/s > bound {vmax:.3g} m/s')
            if grow > span:
                res.fail(f'implicit dt={r:g}T: positions grow faster than the velocity bound')
    return res


@_timed
def check_penalty_huge_n(n: float = 1e12, divs: tuple = (100, 1600)) -> CheckResult:
    """The penalty method at n = 1e12: stable, verify-clean to its creep bound, and converging
    to "exact" with dt like "implicit" (the regularisation error is below the step error)."""
    res = CheckResult(f'penalty_n_{n:g}')
    crawler = Crawler.from_coefficients([0.5, 1.0], 0.3, [0.3, 0.6])
    gait = gaits.Scallop(0.1, 0.02, 2.0, 0.2)
    T = gait.period
    t_end = 3 * T
    grid = np.linspace(0, t_end, 97)
    ex = simulate(crawler, gait, t_end, t_eval=grid)
    errs = []
    for d in divs:
        pe = simulate(crawler, gait, t_end, 'penalty', dt=T / d, penalty=n, t_eval=grid)
        audit(res, pe, f'penalty dt=T/{d}', tolerances(crawler, 'penalty', pe, n))
        errs.append(float(np.max(np.abs(pe.x - ex.x))) if _finite(pe) else math.inf)
    res.figures['err_penalty'] = errs
    if not errs[-1] <= 0.5 * errs[0]:
        res.fail(f'penalty n={n:g} does not converge with dt: errors {errs}')
    return res


def long_run_scene() -> tuple[Crawler, gaits.Gait]:
    """The two-body asymmetric scallop stroke of the bench (0.5 kg, 1 kg, mu = 0.3)."""
    return Crawler.from_coefficients([0.5, 1.0], 0.3), gaits.Scallop(0.1, 0.02, 2.0, 0.2)


@_timed
def check_long_run(periods: int = 10_000, *, transient: int = 5,
                   rtol: float = 1e-9) -> CheckResult:
    """``periods`` gait periods with method "exact", every period computed (periodic skip off)
    and body 0 read at each multiple of the period (streaming ``Stepper``, no history): the
    displacement per period after the transient stays constant to ``rtol`` relative (no
    drift), and the default run (periodic skip on, one ``advance``) ends where the full
    computation does, to 1e-9 relative."""
    res = CheckResult(f'long_run_{periods}')
    crawler, gait = long_run_scene()
    T = gait.period
    t0 = time.perf_counter()
    st = Stepper(crawler, gait, periodic_skip=False)   # no history kept: memory stays flat
    X = np.empty(periods + 1)
    X[0] = st.state.x[0]
    for k in range(1, periods + 1):
        st.advance(k * T)
        X[k] = st.state.x[0]
    elapsed = time.perf_counter() - t0
    d = np.diff(X)[transient:]
    ref = float(np.median(d))
    dev = float(np.max(np.abs(d - ref)) / abs(ref))
    m = min(100, d.size)
    first, last = float(np.mean(d[:m])), float(np.mean(d[-m:]))
    res.figures.update(periods=periods, seconds=elapsed, periods_per_s=periods / elapsed,
                       displacement_per_period=ref, max_rel_deviation=dev,
                       drift_rel=abs(last - first) / abs(ref), final_x0=float(X[-1]))
    if not np.all(np.isfinite(X)):
        res.fail('non-finite positions')
    if not dev <= rtol:
        k = int(np.argmax(np.abs(d - ref)))
        res.fail(f'displacement per period varies by {dev:.2e} relative (> {rtol:g}); worst '
                 f'period {k + transient + 1}: {d[k]!r} vs median {ref!r}')
    t1 = time.perf_counter()
    sk = Stepper(crawler, gait)
    sk.advance(periods * T)
    res.figures['skip_seconds'] = time.perf_counter() - t1
    gap = abs(float(sk.state.x[0]) - float(X[-1])) / abs(float(X[-1]) - float(X[0]))
    res.figures['skip_vs_full_rel'] = gap
    if not gap <= 1e-9:
        res.fail(f'periodic skip ends {gap:.2e} (relative) away from the full computation')
    return res


EXTREMES: dict[str, Callable[..., CheckResult]] = {
    'mass_ratio': check_mass_ratio,
    'friction_ratio': check_friction_ratio,
    'many_bodies': check_many_bodies,
    'high_frequency': check_high_frequency,
    'implicit_large_steps': check_implicit_large_steps,
    'penalty_huge_n': check_penalty_huge_n,
}


# ----------------------------------------------------------------------------- grazing

class RampCosine(gaits.Gait):
    """One linkage with l'(t) = A (c + cos w t): l(t) = l0 + A (c t + sin(w t) / w).

    Aperiodic for c != 0 (the length keeps growing); vectorised. With c = 1 the rate touches
    zero at w t = pi (mod 2 pi) without changing sign; with c = cos(theta) < 1 it is negative
    only for |w t - pi| < theta (mod 2 pi)."""

    def __init__(self, A: float, c: float, w: float, l0: float = 0.1) -> None:
        self.n_links = 1
        self.period = None
        self.A, self.c, self.w, self.l0 = float(A), float(c), float(w), float(l0)

    def _eval(self, t):
        A, c, w = self.A, self.c, self.w
        t = t[:, None]
        return (self.l0 + A * (c * t + np.sin(w * t) / w), A * (c + np.cos(w * t)),
                -A * w * np.sin(w * t))

    def at(self, t: float):
        A, c, w = self.A, self.c, self.w
        return (np.array([self.l0 + A * (c * t + math.sin(w * t) / w)]),
                np.array([A * (c + math.cos(w * t))]), np.array([-A * w * math.sin(w * t)]))

    def jerk_bound(self, t0: float, t1: float) -> np.ndarray:
        # l''' = -A w^2 cos(w t): the pieces the gait is sampled into are checked against it
        return np.array([abs(self.A) * self.w ** 2])


def _kinematic_pair(A: float, c: float, w: float, f0: float = 0.05, m=(0.3, 0.7),
                    f1: tuple | None = None) -> tuple[Crawler, RampCosine, float]:
    """Two bodies on a `RampCosine` gait: body 1 held (friction 100 times what it must supply,
    unless ``f1`` = (forward, backward) is given), body 0 with light friction ``f0``, so body 0
    moves at -l'(t) while body 1 stays put.

    Returns (crawler, gait, v0) with v0 = -l'(0) the initial velocity of body 0 that keeps
    body 1 at rest from the start."""
    m0, m1 = m
    if f1 is None:
        hold = 100.0 * (m0 * A * w + f0)
        f1 = (hold, hold)
    crawler = Crawler([m0, m1], [f0, f1[0]], [f0, f1[1]])
    gait = RampCosine(A, c, w)
    return crawler, gait, -A * (c + 1.0)


def _analytic_positions(gait: RampCosine, t: np.ndarray) -> np.ndarray:
    """Body 1 fixed at l(0) (body 0 starts at x = 0), body 0 at l(0) - l(t)."""
    l = gait(t)[0][:, 0]
    x1 = float(gait(0.0)[0][0])
    return np.stack([x1 - l, np.full(t.size, x1)], axis=1)


def _history_check(res: CheckResult, tr: Trajectory, initial, events, t_end: float,
                   max_mismatch: float, label: str) -> float:
    ev = metrics.canonical_events(tr.events, t_end)
    mis = metrics.history_mismatch(tr.contact[0].tolist(), ev, initial, events, t_end)
    res.figures[f'mismatch_{label}'] = mis
    if not mis <= max_mismatch:
        shown = [tuple(round(x, 12) for x in e) for e in ev[:8]]
        res.fail(f'{label}: stick/slip history differs from the expected one for {mis:.3e} s '
                 f'(> {max_mismatch:.1e} s); events {shown}')
    return mis


@_timed
def check_touching_velocity(periods: int = 3) -> CheckResult:
    """Body 0's velocity -A (1 + cos w t) touches zero at w t = pi (mod 2 pi) without crossing.

    Expected: body 1 stuck and body 0 sliding backward throughout (isolated zero-velocity
    instants are not stick phases); positions analytic. A double root is resolved only to the
    float conditioning of a tangency: near w t = pi, v = -A w^2 (t - t*)^2 / 2 stays within
    rounding r of zero over a width 2 sqrt(2 r / A) / w, so a mode flip inside that band is
    allowed; anything longer fails. The gait, a user's class, is sampled into pieces that hold
    its values to 64 eps of their scale (``solvers.proxy``): r = 64 eps A, a band of 5.4e-8 s
    a touch (the pieces' l' is within 18 eps A of the closed form here)."""
    res = CheckResult('grazing_velocity_touches_zero')
    w = 2 * math.pi
    crawler, gait, v0 = _kinematic_pair(0.02, 1.0, w)
    t_end = periods * 1.0
    grid = np.linspace(0, t_end, 7)
    tr = simulate(crawler, gait, t_end, t_eval=grid, v0=v0, max_step=1.0 / 64)
    audit(res, tr, 'exact', EXACT_TOL)
    err = float(np.max(np.abs(tr.x - _analytic_positions(gait, grid))))
    res.figures['position_error'] = err
    if not err <= 1e-12:
        res.fail(f'positions off the analytic solution by {err:.2e} m')
    band = 2.0 * math.sqrt(2.0 * 64.0 * np.finfo(float).eps) / w   # float width of a touch
    _history_check(res, tr, [-1, 0], [], t_end, periods * band, 'exact')
    return res


@_timed
def check_touching_force(periods: int = 3) -> CheckResult:
    """Body 1's required friction touches its forward bound once per period without exceeding.

    Body 0 slides backward at -A (1.5 + cos w t); body 1 must supply R1 = m0 A w sin(w t) - f0,
    which reaches -(m0 A w + f0) = -f_plus(body 1) at w t = 3 pi / 2. Expected: body 1 stuck
    throughout; positions analytic. A slip that rounding starts at a touch must be negligible:
    the gait, a user's class, is sampled into pieces that hold l'' to 64 eps of its scale, so
    the force can dip past the bound by ~1e-16 N there (the pieces at this touch: 1.9e-16 N).
    From the touch the force returns inside its bound as c s^2 (c = m0 A w^3 / 2), so such a
    slip moves body 1 by at most c s^4 / (12 m1) in s seconds: a slip shorter than
    (12 m1 r / c)^(1/4), r = 16 eps |x_1| the rounding of body 1's position, moves it by less
    than that rounding (4.5e-4 s here); longer ones fail."""
    res = CheckResult('grazing_force_touches_bound')
    w, A, f0, m0 = 2 * math.pi, 0.02, 0.05, 0.3
    bound = m0 * A * w + f0
    crawler, gait, v0 = _kinematic_pair(A, 1.5, w, f0=f0, m=(m0, 0.7), f1=(bound, 10 * bound))
    t_end = periods * 1.0
    grid = np.linspace(0, t_end, 7)
    tr = simulate(crawler, gait, t_end, t_eval=grid, v0=v0, max_step=1.0 / 64)
    audit(res, tr, 'exact', EXACT_TOL)
    err = float(np.max(np.abs(tr.x - _analytic_positions(gait, grid))))
    res.figures['position_error'] = err
    if not err <= 1e-9:
        res.fail(f'positions off the analytic solution by {err:.2e} m')
    c, x1 = m0 * A * w ** 3 / 2.0, float(gait(0.0)[0][0])
    band = (12.0 * float(crawler.masses[1]) * 16.0 * np.finfo(float).eps * abs(x1) / c) ** 0.25
    _history_check(res, tr, [-1, 0], [], t_end, periods * band, 'exact')
    return res


@_timed
def check_close_events(theta: float = 1e-3, periods: int = 2, *, fine_dt: float | None = None
                       ) -> CheckResult:
    """Body 0's velocity -A (cos(theta) + cos w t) is positive only for |w t - pi| < theta:
    two transitions 2 theta / w apart, far closer than the bracketing grid (T / 64) and the
    output sampling (T / 3). Expected: exactly those transitions, at their analytic times;
    optionally compared with method "implicit" at ``fine_dt`` as an independent computation."""
    res = CheckResult(f'close_events_theta_{theta:g}')
    w = 2 * math.pi
    crawler, gait, v0 = _kinematic_pair(0.02, math.cos(theta), w)
    t_end = float(periods)
    grid = np.linspace(0, t_end, 3 * periods + 1)
    tr = simulate(crawler, gait, t_end, t_eval=grid, v0=v0, max_step=1.0 / 64)
    audit(res, tr, 'exact', EXACT_TOL)
    expected = []
    for k in range(periods):
        expected.append((k + (math.pi - theta) / w, 0, -1, 1))
        expected.append((k + (math.pi + theta) / w, 0, 1, -1))
    ev = metrics.canonical_events(tr.events, t_end)
    err, missing = metrics.event_error(ev, expected)
    res.figures.update(event_error=err, missing=missing, n_events=len(ev),
                       separation=2 * theta / w, dip_relative=0.5 * theta ** 2)
    if 0.5 * theta ** 2 < 1e-11:
        # The forward slide peaks at A theta^2 / 2, within ~1e-13 relative of rounding: finding
        # it or not are both right, anything else (or a wrong position) is not.
        mis = metrics.history_mismatch(tr.contact[0].tolist(), ev, [-1, 0], expected, t_end)
        res.figures['mismatch'] = mis
        if not mis <= periods * 2 * theta / w * (1 + 1e-6):
            res.fail(f'history differs from the analytic one for {mis:.2e} s (more than the '
                     f'rounding-level slides last): {ev[:8]}')
    elif missing or len(ev) != len(expected) or not err <= 1e-9:
        res.fail(f'transitions {[(round(e[0], 12), e[1], e[2], e[3]) for e in ev]} != expected '
                 f'{[(round(e[0], 12), e[1], e[2], e[3]) for e in expected]} (max time error '
                 f'{err:.2e} s, {missing} missing)')
    pos = float(np.max(np.abs(tr.x - _analytic_positions(gait, grid))))
    if not pos <= 1e-12:
        res.fail(f'positions off the analytic solution by {pos:.2e} m')
    if fine_dt:
        im = simulate(crawler, gait, t_end, 'implicit', dt=fine_dt, t_eval=grid, v0=v0)
        mis = metrics.history_mismatch(
            im.contact[0].tolist(), metrics.canonical_events(im.events, t_end), [-1, 0],
            expected, t_end)
        res.figures['implicit_mismatch'] = mis
        if not mis <= 4 * fine_dt * (len(expected) + 1):
            res.fail(f'implicit at dt={fine_dt:g} differs from the analytic history for '
                     f'{mis:.2e} s')
    return res


@_timed
def check_history_against_fine(name: str = 'wave_3body', periods: float = 1.0,
                               divs: tuple = (1_000, 10_000)) -> CheckResult:
    """The exact stick/slip history of a bench scene against method "implicit" at fine steps
    (an independent computation): the mismatch shrinks with dt and stays within a few steps
    per transition."""
    from .scenes import load_bench_scenes
    res = CheckResult(f'history_vs_fine_{name}')
    sc = load_bench_scenes([name])[0]
    T = sc.period
    t_end = periods * T
    ex = simulate(sc.crawler, sc.gait, t_end, t_eval=[0.0, t_end])
    ref_ev = metrics.canonical_events(ex.events, t_end)
    mis = []
    for d in divs:
        im = simulate(sc.crawler, sc.gait, t_end, 'implicit', dt=T / d, t_eval=[0.0, t_end])
        ev = metrics.canonical_events(im.events, t_end)
        mis.append(metrics.history_mismatch(im.contact[0].tolist(), ev, ex.contact[0].tolist(),
                                            ref_ev, t_end))
    res.figures.update(mismatch=mis, transitions=len(ref_ev))
    bound = 8 * (T / divs[-1]) * (len(ref_ev) + 1)
    if not (mis[-1] <= bound and mis[-1] <= 0.5 * mis[0] + 1e-12):
        res.fail(f'exact history vs implicit: mismatch {mis} s for dt = T/{divs} (bound at the '
                 f'finest step {bound:.2e} s)')
    return res


@_timed
def check_tolerance_ladder(name: str = 'scallop_2body',
                           tols: tuple = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12,
                                          1e-13, 1e-14),
                           divs: tuple = (4, 8, 16, 32, 128, 512)) -> CheckResult:
    """Method "exact" on a bench scene over every event tolerance (periodic skip on and off)
    and every bracketing grid ``max_step = T / d``: no run fails, each ends within
    ``1e3 tol v_max`` (+ rounding) of the tightest run."""
    from .scenes import load_bench_scenes
    res = CheckResult(f'tolerance_ladder_{name}')
    sc = load_bench_scenes([name])[0]
    T, t_end = sc.period, sc.t_end
    ref = simulate(sc.crawler, sc.gait, t_end, t_eval=[0.0, t_end], tol=min(tols),
                   periodic_skip=False)
    vmax = float(np.abs(ref.v).max()) if _finite(ref) else 1.0
    scale = abs(ref.displacement) + float(np.ptp(ref.x))
    runs = [({'tol': tol, 'periodic_skip': skip}, tol) for tol in tols for skip in (True, False)]
    runs += [({'max_step': T / d, 'periodic_skip': False}, 1e-13) for d in divs]
    worst = 0.0
    for kw, tol in runs:
        try:
            tr = simulate(sc.crawler, sc.gait, t_end, t_eval=[0.0, t_end], **kw)
        except Exception as exc:  # noqa: BLE001 (each failing setting is reported)
            res.fail(f'{kw}: {type(exc).__name__}: {exc}')
            continue
        err = abs(tr.displacement - ref.displacement)
        worst = max(worst, err / (tol * vmax * 1e3 + 1e-12 * scale))
        if not err <= 1e3 * tol * vmax + 1e-12 * scale:
            res.fail(f'{kw}: displacement {tr.displacement!r} vs {ref.displacement!r}')
    res.figures.update(runs=len(runs), worst_relative_to_bound=worst)
    return res


GRAZING: dict[str, Callable[..., CheckResult]] = {
    'touching_velocity': check_touching_velocity,
    'touching_force': check_touching_force,
    'close_events': check_close_events,
    'history_vs_fine': check_history_against_fine,
}


# ----------------------------------------------------------------------------- differential fuzz

@_timed
def check_fuzz(n_per_family: int = 30, seed: int = 0, families: tuple[str, ...] | None = None,
               streams: bool = True) -> CheckResult:
    """The long profile of the differential fuzz (issue 14): ``n_per_family`` cases of every
    gait family of test/support/fuzz.py (or of ``families``), exact method against the
    independent oracle (test/support/oracle.py) at 1e-10; with ``streams`` each case with one
    gait also streamed onto its event times and one float either side, after first steps of
    one float and of 1e-200 s (issue 37: ``check_stream``)."""
    from test.support import fuzz as test_fuzz
    res = CheckResult(f'differential_fuzz[{n_per_family} per family, seed {seed}]')
    out = test_fuzz.run_fuzz(n_per_family, seed, families or test_fuzz.FAMILIES,
                             streams=streams)
    res.figures = {k: out[k] for k in ('cases', 'failed', 'errors', 'worst_x')}
    res.figures['by_family'] = out.get('by_family', {})
    for text in out['failures']:
        res.fail(text)
    return res


def check_custom_period_long(n_cases: int = 4, periods: int = 10_000, seed: int = 0
                             ) -> CheckResult:
    """Issue 37 item 1: Custom gaits with ``period=`` (the fuzz family ``custom_period``,
    Custom copies of sharp Scallops) run for ``periods`` periods with the periodic skip off
    and on: no failure (the search ran out of steps past 512 s), and each run ends within
    1e-9 x max(1 m, periods x the gait's stroke, the distance run: a crawler on a slope may slide
    away; plus what 1e-10 m/s more of v0 moves it: the scene's conditioning) of the built-in
    Scallop it copies, run the same
    way (another path: the Scallop's closed form, not Chebyshev pieces of the user's functions)."""
    from test.support import fuzz as test_fuzz
    res = CheckResult(f'custom_period_long[{n_cases} cases x {periods} periods, seed {seed}]')
    worst = 0.0
    for k in range(n_cases):
        case = test_fuzz.draw_case('custom_period', seed + k)
        t_end = periods * case.gait.period
        ll = case.kin(np.linspace(0.0, case.gait.period, 4001))[0]
        scale = max(1.0, periods * float(np.ptp(ll, axis=0).sum()))
        for skip in (False, True):
            try:
                x = simulate(case.crawler, test_fuzz.draw_case('custom_period', seed + k).gait,
                             t_end, t_eval=[0.0, t_end], v0=case.v0, periodic_skip=skip).x[-1]
            except Exception as exc:  # noqa: BLE001 (a failure is the finding)
                res.fail(f'{case!r}, periodic_skip={skip}: {type(exc).__name__}: {exc}')
                continue
            ref = simulate(case.crawler, case.twin, t_end, t_eval=[0.0, t_end], v0=case.v0,
                           periodic_skip=skip).x[-1]
            # the scene's own conditioning: what 1e-10 m/s more of v0 does to the end (a slow
            # transient amplifies differences at the sampling's rounding)
            bent = simulate(case.crawler, case.twin, t_end, t_eval=[0.0, t_end],
                            v0=case.v0 + 1e-10, periodic_skip=skip).x[-1]
            size = max(scale, float(np.abs(ref).max()))
            cond = float(np.abs(bent - ref).max())
            err = float(np.abs(x - ref).max()) / (size + cond / 1e-9)
            worst = max(worst, err)
            if not err <= 1e-9:
                res.fail(f'{case!r}, periodic_skip={skip}: {err:.2e} x {size:.3g} m from its '
                         f'built-in twin (> 1e-9; 1e-10 m/s of v0 moves it {cond:.2g} m)')
    res.figures.update(cases=n_cases, periods=periods, worst_rel=worst)
    return res


def check_long_periodic(n_per_family: int = 2, periods: int = 10_000, seed: int = 0,
                        families: tuple[str, ...] = ('sinusoid', 'fourier', 'scallop', 'stroke',
                                                     'spline_periodic', 'custom_period')
                        ) -> CheckResult:
    """Issue 37 item 4: fuzz cases of every periodic gait family run for ``periods`` periods
    with the periodic skip on and off, each against an independent reference: the oracle
    (test/support/oracle.py) run up to two periods past where the skip found the state
    repeating, then whole periods of its last displacement (a run that never repeats, such as
    a crawler sliding off a slope, has no reference: there skip on and off must agree). Each
    within 1e-9 x max(1 m, periods x the gait's stroke, the distance run)."""
    from test.support import fuzz as test_fuzz
    from test.support.oracle import Oracle
    res = CheckResult(f'long_periodic[{n_per_family} per family x {periods} periods, '
                      f'seed {seed}]')
    worst, n_ref = 0.0, 0
    for fam in families:
        for k in range(n_per_family):
            case = test_fuzz.draw_case(fam, seed + k)
            P = case.gait.period
            t_end = periods * P
            runs = {}
            for skip in (True, False):
                tr = simulate(case.crawler, test_fuzz.draw_case(fam, seed + k).gait, t_end,
                              t_eval=[0.0, t_end], v0=case.v0, periodic_skip=skip)
                runs[skip] = (float(tr.x[-1, 0]), tr.info['skipped_periods'])
            ll = case.kin(np.linspace(0.0, P, 4001))[0]
            stroke = periods * float(np.ptp(ll, axis=0).sum())
            skipped = runs[True][1]
            if skipped:
                K = periods - skipped + 2
                o = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints)
                xo, _ = o.solve(K * P, [(K - 1) * P, K * P], v0=case.v0,
                                h=test_fuzz.oracle_h(case))
                ref = float(xo[1, 0]) + (periods - K) * float(xo[1, 0] - xo[0, 0])
                n_ref += 1
            else:
                ref = runs[False][0]
            size = max(1.0, stroke, abs(ref))
            for skip, (x, _) in runs.items():
                err = abs(x - ref) / size
                worst = max(worst, err)
                if not err <= 1e-9:
                    res.fail(f'{case!r}, periodic_skip={skip}: {abs(x - ref):.3g} m from the '
                             f'reference (> 1e-9 x {size:.3g} m; {skipped} periods skipped)')
    res.figures.update(worst_rel=worst, with_oracle_reference=n_ref)
    return res


# ----------------------------------------------------------------------------- the long run

def run_stress(seconds: float = 60.0, seed: int = 0,
               progress: Callable[..., None] | None = None) -> dict:
    """The long stress run: extremes and grazing at full size, the 1e5-period run, then random
    scenes until ``seconds`` of wall time have passed (at least 20).

    Returns a dict with ``ok``, ``failures`` (messages), each check's figures and the random
    specs that failed (to reproduce with ``check_random_scene(spec)``).
    """
    say = progress or (lambda *a, **k: None)
    t_start = time.perf_counter()
    results: list[CheckResult] = []

    def record(res: CheckResult) -> None:
        results.append(res)
        say(f'{"ok  " if res.ok else "FAIL"} {res.name} ({res.seconds:.1f} s)'
            + ('' if res.ok else ': ' + '; '.join(res.problems)))

    fixed = [
        lambda: check_mass_ratio(), lambda: check_friction_ratio(),
        lambda: check_many_bodies(100, 2.0, (64, 512)), lambda: check_high_frequency(),
        lambda: check_implicit_large_steps(), lambda: check_penalty_huge_n(),
        lambda: check_touching_velocity(5), lambda: check_touching_force(5),
        lambda: check_close_events(1e-3, 1, fine_dt=2e-5), lambda: check_close_events(1e-5, 5), lambda: check_close_events(1e-6, 5),
        lambda: check_history_against_fine('wave_3body'),
        lambda: check_history_against_fine('scallop_2body'),
        lambda: check_history_against_fine('slope_climb'),
        lambda: check_tolerance_ladder('scallop_2body'),
        lambda: check_tolerance_ladder('wave_3body'),
        lambda: check_tolerance_ladder('stiff_hf'),
        lambda: check_tolerance_ladder('slope_climb'),
        lambda: check_long_run(100_000),
        lambda: check_fuzz(30, seed),
        lambda: check_custom_period_long(4, 10_000, seed),
        lambda: check_long_periodic(2, 10_000, seed),
    ]
    for k, check in enumerate(fixed):
        say(k, len(fixed), 'fixed checks')
        record(check())
    rng = np.random.default_rng(seed)
    failed_specs = []
    n_random = 0
    deadline = t_start + max(float(seconds), 0.0)
    while n_random < 20 or time.perf_counter() < deadline:
        spec = random_spec(rng)
        res = check_random_scene(spec)
        res.name = f'random_scene[{n_random}] p={len(spec["masses"])}'
        n_random += 1
        if not res.ok:
            failed_specs.append(spec)
        if not res.ok or n_random % 10 == 0:
            record(res)
        else:
            results.append(res)
        if n_random >= 10_000:
            break
    failures = [r.message for r in results if not r.ok]
    say(f'stress: {len(results)} checks ({n_random} random scenes), {len(failures)} failed, '
        f'{time.perf_counter() - t_start:.0f} s')
    return {'ok': not failures, 'failures': failures, 'seed': seed, 'random_scenes': n_random,
            'failed_specs': failed_specs,
            'checks': [r.to_dict() for r in results if not r.name.startswith('random_scene')
                       or not r.ok],
            'seconds': time.perf_counter() - t_start}
