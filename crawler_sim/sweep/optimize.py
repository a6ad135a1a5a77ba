"""Gait optimisation: the stroke that maximises mean speed or minimises cost of transport under
the actuator limits of sim_node (`crawler_sim.core.actuator.ActuatorLimits`).

Families (the vector z that is optimised, with its bounds):

- ``scallop``: ``amplitude`` [m], ``frequency`` [Hz], ``asymmetry`` (fraction of the period
  spent extending), and for p > 2 ``phase_lag`` [rad] of linkage j+1 behind linkage j (the
  parameters of gait_node, which plays the result directly);
- ``stroke``: the bang-bang `PiecewiseParabolic.stroke` with ``amplitude``, ``frequency``,
  ``asymmetry`` (phase times r T / 2 and (1 - r) T / 2);
- ``fourier``: the cos and sin coefficients [m] of K harmonics of every linkage at the base
  gait's frequency.

A stroke is feasible when, over one period, |l'| <= max_speed, |l''| <= max_acceleration (the
servo's hard limits), l > 0 (the bodies do not pass through each other) and its frequency
(its highest harmonic for ``fourier``) is at most the actuator bandwidth, so the servo tracks it.
An infeasible z scores ``PENALTY`` plus its relative violation, so the optimisers keep away.
The global stage is ``scipy.optimize.differential_evolution``, every generation evaluated as one
batch through a map (serial, local processes, or a Dask client); the local stage polishes the
best point with bounded Nelder-Mead. Every evaluation is kept in the history.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Callable, Iterable

import numpy as np

from ..core import gaits
from ..core.actuator import ActuatorLimits
from ..core.scene import Scene, scene_to_dict
from .metrics import scene_figures

__all__ = ['FAMILIES', 'OBJECTIVES', 'PENALTY', 'Family', 'Objective', 'OptimizeResult',
           'optimize', 'family', 'gait_node_params']

OBJECTIVES = ('speed', 'cot')
FAMILIES = ('scallop', 'stroke', 'fourier')
PENALTY = 1e6     # score of an infeasible stroke (plus its violation); speeds are << 1 m/s
_GRID = 2048      # samples per period for the feasibility check (plus the breakpoints)


@dataclass(frozen=True)
class Family:
    """A parametrised stroke: names and bounds of z, and z -> gait."""

    name: str
    names: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    mean: tuple[float, ...]
    frequency: float = 1.0        # fourier only: the fixed fundamental [Hz]
    harmonics: int = 1            # fourier only

    @property
    def n_links(self) -> int:
        return len(self.mean)

    def gait(self, z: np.ndarray) -> gaits.Gait:
        n, mean = self.n_links, list(self.mean)
        if self.name == 'fourier':
            k = self.harmonics
            half = n * k
            cos = np.asarray(z[:half]).reshape(n, k)
            sin = np.asarray(z[half:]).reshape(n, k)
            return gaits.Fourier(mean, (cos, sin), self.frequency, n_links=n)
        amp, freq, r = float(z[0]), float(z[1]), float(z[2])
        if self.name == 'stroke':
            return gaits.PiecewiseParabolic.stroke(mean, amp, freq, r, n_links=n)
        lag = float(z[3]) if n > 1 else 0.0
        return gaits.Scallop(mean, amp, freq, r, [-j * lag for j in range(n)], n_links=n)

    def top_frequency(self, z: np.ndarray) -> float:
        return self.frequency * self.harmonics if self.name == 'fourier' else float(z[1])


def family(name: str, base: Scene, limits: ActuatorLimits, harmonics: int = 3) -> Family:
    """The family ``name`` around the base scene's gait (its mean lengths, and its frequency
    for ``fourier``), with bounds that the actuator limits make reachable."""
    if name not in FAMILIES:
        raise ValueError(f'family must be one of {", ".join(FAMILIES)}, got {name!r}')
    mean_arr = np.atleast_1d(np.asarray(base.gait_spec.get('mean', base.gait(0.0)[0]),
                                        dtype=float))
    n = base.crawler.p - 1
    mean = tuple(float(m) for m in np.broadcast_to(mean_arr, (n,)))
    amp_max = 0.9 * min(mean)                          # keeps l > 0 for a symmetric stroke
    f_max = limits.bandwidth
    if name == 'fourier':
        if not isinstance(harmonics, int) or harmonics < 1:
            raise ValueError(f'harmonics must be an integer >= 1, got {harmonics!r}')
        f0 = float(base.gait.period and 1.0 / base.gait.period or 1.0)
        c = amp_max / harmonics
        names = tuple(f'{t}_{j}_{k + 1}' for t in ('cos', 'sin') for j in range(n)
                      for k in range(harmonics))
        return Family(name, names, ((-c, c),) * len(names), mean, f0, harmonics)
    names = ('amplitude', 'frequency', 'asymmetry') + (('phase_lag',) if n > 1 else ())
    bounds = ((1e-4, amp_max), (0.05, f_max), (0.05, 0.95)) + (((-math.pi, math.pi),)
                                                                if n > 1 else ())
    return Family(name, names, bounds, mean)


def _violation(gait: gaits.Gait, fam: Family, z: np.ndarray, limits: ActuatorLimits) -> float:
    """Relative excess over the limits (0 when feasible)."""
    T = gait.period
    t = np.linspace(0.0, T, _GRID, endpoint=False)
    t = np.union1d(t, gait.breakpoints(0.0, T))
    l, ld, ldd = gait(t)
    v = max(0.0, float(np.abs(ld).max()) / limits.max_speed - 1.0)
    a = max(0.0, float(np.abs(ldd).max()) / limits.max_acceleration - 1.0)
    short = max(0.0, -float(l.min()) / min(fam.mean) + 1e-3) if l.min() <= 0 else 0.0
    f = max(0.0, fam.top_frequency(z) / limits.bandwidth - 1.0)
    return v + a + short + f


@dataclass(frozen=True)
class Objective:
    """Picklable score of a stroke z (lower is better), for local processes and Dask workers."""

    base: dict                 # scene_to_dict of the base scene
    fam: Family
    limits: ActuatorLimits
    objective: str = 'speed'
    periods: int = 12
    samples_per_period: int = 40

    def evaluate(self, z: Iterable[float]) -> dict[str, Any]:
        """{score, feasible, violation, mean_speed, cost_of_transport, error} of z."""
        from ..core.scene import scene_from_dict
        from dataclasses import replace

        z = np.asarray(list(z), dtype=float)
        out: dict[str, Any] = {'score': PENALTY, 'feasible': False, 'violation': math.nan,
                               'mean_speed': math.nan, 'cost_of_transport': math.nan,
                               'error': ''}
        try:
            gait = self.fam.gait(z)
            viol = _violation(gait, self.fam, z, self.limits)
            out['violation'] = viol
            if viol > 0:
                out['score'] = PENALTY * (1.0 + viol)
                return out
            scene = replace(scene_from_dict(self.base), gait=gait)
            fig = scene_figures(scene, self.periods, self.samples_per_period)
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            out['error'] = f'{type(exc).__name__}: {exc}'.splitlines()[0]
            out['score'] = PENALTY * 2
            return out
        out.update(feasible=True, mean_speed=fig['mean_speed'],
                   cost_of_transport=fig['cost_of_transport'])
        if self.objective == 'speed':
            out['score'] = -fig['mean_speed']
        else:
            # only forward motion counts; a crawler that does not move has an infinite cost
            cot = fig['cost_of_transport'] if fig['mean_speed'] > 0 else math.inf
            out['score'] = min(cot, PENALTY / 2)
        return out

    def __call__(self, z: Iterable[float]) -> float:
        return float(self.evaluate(z)['score'])


@dataclass
class OptimizeResult:
    """Best stroke, its figures and the history of every evaluation (stage 'global'/'local')."""

    family: Family
    objective: str
    x: np.ndarray
    best: dict
    gait: gaits.Gait
    history: list[dict] = field(default_factory=list)

    @property
    def params(self) -> dict[str, float]:
        return {k: float(v) for k, v in zip(self.family.names, self.x)}


def _mapper(client: Any, workers: int) -> tuple[Callable, Callable[[], None]]:
    """A map(func, iterable) for the evaluations and a function that releases it."""
    if client is not None:
        def dask_map(func: Callable, xs: Iterable) -> list:
            futures = client.map(func.evaluate, [list(map(float, x)) for x in xs], pure=False)
            return client.gather(futures)
        return dask_map, lambda: None
    if workers > 1:
        import multiprocessing
        pool = multiprocessing.get_context(
            'fork' if 'fork' in multiprocessing.get_all_start_methods() else None).Pool(workers)
        return (lambda func, xs: pool.map(func.evaluate, [list(map(float, x)) for x in xs]),
                pool.terminate)
    return (lambda func, xs: [func.evaluate(list(map(float, x))) for x in xs]), lambda: None


def optimize(base: Scene, *, objective: str = 'speed', family_name: str = 'scallop',
             limits: ActuatorLimits | None = None, harmonics: int = 3, periods: int = 12,
             maxiter: int = 15, popsize: int = 8, local_maxiter: int = 150, seed: int = 0,
             client: Any = None, workers: int = 1,
             progress: Callable[[str], None] | None = None) -> OptimizeResult:
    """Search the family's stroke for ``base`` (crawler and run options; its gait gives the mean
    lengths) that maximises the steady mean speed (``objective='speed'``) or minimises the cost
    of transport (``'cot'``) under ``limits`` (default: sim_node's actuator defaults).

    ``client`` (a Dask client) or ``workers`` > 1 (local processes) evaluate each generation of
    the global stage in parallel. Deterministic for a given ``seed``.
    """
    from scipy.optimize import differential_evolution, minimize

    if objective not in OBJECTIVES:
        raise ValueError(f'objective must be one of {", ".join(OBJECTIVES)}, got {objective!r}')
    limits = limits or ActuatorLimits()
    fam = family(family_name, base, limits, harmonics)
    obj = Objective(scene_to_dict(base), fam, limits, objective, periods)
    history: list[dict] = []
    run_map, close = _mapper(client, workers)

    def record(stage: str, xs: list, results: list[dict]) -> list[float]:
        for x, r in zip(xs, results):
            history.append({'stage': stage, 'evaluation': len(history),
                            **dict(zip(fam.names, map(float, x))), **r})
        return [r['score'] for r in results]

    def batch(func: Callable, xs: Iterable) -> list[float]:
        xs = [np.asarray(x, dtype=float) for x in xs]
        scores = record('global', xs, run_map(obj, xs))
        if progress:
            best = min(h['score'] for h in history)
            progress(f'global: {len(history)} evaluations, best score {best:.6g}')
        return scores

    try:
        glob = differential_evolution(obj, fam.bounds, maxiter=maxiter, popsize=popsize,
                                      seed=seed, polish=False, updating='deferred',
                                      workers=batch, tol=1e-8)
    finally:
        close()

    def local(z: np.ndarray) -> float:
        return record('local', [z], [obj.evaluate(z)])[0]

    loc = minimize(local, glob.x, method='Nelder-Mead', bounds=fam.bounds,
                   options={'maxiter': local_maxiter, 'xatol': 1e-6, 'fatol': 1e-10})
    if progress:
        progress(f'local: {len(history)} evaluations, best score {loc.fun:.6g}')
    best = min(history, key=lambda h: h['score'])
    x = np.array([best[k] for k in fam.names])
    return OptimizeResult(fam, objective, x, best, fam.gait(x), history)


def gait_node_params(result: OptimizeResult, scene_file: str | None = None) -> dict | None:
    """The ROS 2 parameter file content (``gait_node: ros__parameters: ...``) that makes
    gait_node play the best stroke: its own gait parameters for a Scallop of one mean length,
    otherwise ``gait_file`` pointing at ``scene_file`` (the scene with the best gait); None
    when neither applies."""
    fam = result.family
    if fam.name != 'scallop' or len(set(fam.mean)) != 1:
        if scene_file is None:
            return None
        return {'gait_node': {'ros__parameters': {'gait_file': str(scene_file)}}}
    p = result.params
    return {'gait_node': {'ros__parameters': {
        'gait': 'scallop', 'n_links': fam.n_links, 'mean': float(fam.mean[0]),
        'amplitude': p['amplitude'], 'frequency': p['frequency'], 'asymmetry': p['asymmetry'],
        'phase_lag': p.get('phase_lag', 0.0)}}}
