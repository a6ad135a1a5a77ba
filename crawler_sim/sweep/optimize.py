"""Gait optimisation: the stroke that maximises mean speed or minimises cost of transport under
the actuator limits of sim_node (`crawler_sim.core.actuator.ActuatorLimits`).

Families (the vector z that is optimised, with its bounds):

- ``scallop``: ``amplitude`` [m], ``frequency`` [Hz], ``asymmetry`` (fraction of the period
  spent extending), and for p > 2 ``phase_lag`` [rad] of linkage j+1 behind linkage j (the
  parameters of gait_node, which plays the result directly);
- ``stroke``: the bang-bang `PiecewiseParabolic.stroke` with ``amplitude``, ``frequency``,
  ``asymmetry`` (phase times r T / 2 and (1 - r) T / 2), and for p > 2 ``phase_lag`` as above;
- ``fourier``: the cos and sin coefficients [m] of K harmonics of every linkage at the base
  gait's frequency.

Scores (``score``):

- ``node`` (the default): the stroke as the robot gets it. gait_node preloads it as one
  trajectory (``STREAM``: 100 samples per second with velocities and accelerations), sim_node's
  actuator follows it on its tick grid, and the core solves the crawler under the lengths the
  actuator produced (``crawler_sim.core.plant.streams``): the figures are those of the run
  ``crawler-sim optimize`` writes the files for (OUT for gait_node, OUT_sim.yaml for sim_node).
  The default because the optimiser's output is played by the node: a stroke scored on its
  ideal lengths can crawl backwards once a servo with finite bandwidth shapes it (issue 24).
  Feasible: every length within sim_node's [min_length, max_length] (it rejects the trajectory
  otherwise) and l > 0; the servo's speed and acceleration limits are part of the plant.
- ``ideal``: the stroke's own lengths l(t) drive the crawler (an ideal actuator). Feasible when,
  over one period, |l'| <= max_speed, |l''| <= max_acceleration, l > 0 and its frequency (its
  highest harmonic for ``fourier``) is at most the actuator bandwidth.

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
from ..core.plant import PlantConfig
from ..core.plant.streams import Stream, simulate_as_node
from ..core.scene import Scene, scene_to_dict
from ..core.solvers.base import capabilities
from .metrics import run_figures, scene_figures
from .spec import SpecError
from crawler_sim.core.simtime import to_seconds

__all__ = ['FAMILIES', 'OBJECTIVES', 'SCORES', 'STREAM', 'PENALTY', 'LIMITS', 'Family',
           'Objective', 'OptimizeError', 'OptimizeResult', 'optimize', 'family',
           'gait_node_params', 'sim_node_params', 'plant_for']

OBJECTIVES = ('speed', 'cot')
SCORES = ('node', 'ideal')
#: how gait_node plays an optimised stroke: one preloaded trajectory of 10 minutes, 100 samples
#: per second (the same command stream whatever the timing: what was scored is what is played)
STREAM = Stream('trajectory', rate=100.0, preload=True, duration=600.0)
FAMILIES = ('scallop', 'stroke', 'fourier')
PENALTY = 1e6     # score of an infeasible stroke (plus its violation); speeds are << 1 m/s
_GRID = 2048      # samples per period for the feasibility check (plus the breakpoints)

#: name -> (lowest, highest) of optimize's settings, checked before anything is built from them
#: (`optimize`). ``parameters``: the size of z (fourier: 2 x linkages x harmonics);
#: ``population``: differential evolution's popsize x parameters, the rows of its population
#: array (parameters x population x 8 bytes: 16 MB at the limits) and the evaluations of one
#: generation. Scored as the node runs it, the scene's bodies are sim_node's (2 to
#: `core.plant.config.MAX_BODIES`).
LIMITS: dict[str, tuple[int, int]] = {
    'harmonics': (1, 32), 'periods': (4, 10_000), 'maxiter': (0, 10_000),
    'popsize': (1, 1_000), 'local_maxiter': (0, 100_000), 'workers': (1, 1_024),
    'parameters': (1, 200), 'population': (1, 10_000),
}


class OptimizeError(SpecError):
    """optimize's settings (or its scene, for the score) out of range: a refused input (the
    command line's exit 2, as a SpecError); one line naming the setting and its range."""


def _check_settings(base: Scene, score: str, settings: dict[str, Any]) -> None:
    """The settings, and the scene's bodies for the score, before anything is built from them:
    a 1e6-body scene reached a 3.8 GiB allocation and 1000 bodies were refused by the plant
    only after a large one (issue 38)."""
    for name, value in settings.items():
        lo, hi = LIMITS[name]
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or \
                not lo <= value <= hi:
            raise OptimizeError(f'{name}: must be an integer from {lo} to {hi}, got {value!r}')
    p = base.crawler.p
    if score == 'node':
        from ..core.plant.config import MAX_BODIES
        if p > MAX_BODIES:
            raise OptimizeError(f'scene.crawler.masses: scored as the node runs it, the crawler '
                                f'must have 2 to {MAX_BODIES} bodies (sim_node\'s limit), got '
                                f'{p}; use --score ideal for more')


def _check_search(fam: Family, p: int, popsize: int) -> None:
    """The size of z and of differential evolution's population (``popsize`` x parameters
    rows of parameters each), before the search allocates them."""
    n = len(fam.names)
    lo, hi = LIMITS['parameters']
    if n > hi:
        raise OptimizeError(f'{fam.name} family: {n} parameters for {p} bodies and '
                            f'{fam.harmonics} harmonics; allowed {lo} to {hi}')
    lo, hi = LIMITS['population']
    if popsize * n > hi:
        raise OptimizeError(f'popsize: popsize x parameters must be from {lo} to {hi} (strokes '
                            f'per generation), got {popsize} x {n} = {popsize * n}')


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
        lag = float(z[3]) if n > 1 else 0.0
        phase = [-j * lag for j in range(n)]
        if self.name == 'stroke':
            return gaits.PiecewiseParabolic.stroke(mean, amp, freq, r, phase, n_links=n)
        return gaits.Scallop(mean, amp, freq, r, phase, n_links=n)

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


def plant_for(base: Scene, fam: Family, limits: ActuatorLimits) -> PlantConfig:
    """sim_node's plant for the base scene's crawler (its static bounds, the fixed values of
    the optimisation, too), method and stiction rule, at rest at the family's mean
    lengths, with the actuator ``limits`` (the length limits wide enough for the family)."""
    return PlantConfig.for_crawler(base.crawler, fam.mean, limits, method=base.run.method,
                                   initial_position=float(base.run.x0),
                                   stiction_rule=base.run.stiction_rule)


def _violation(gait: gaits.Gait, fam: Family, z: np.ndarray, limits: ActuatorLimits,
               lengths: tuple[float, float] | None = None) -> float:
    """Relative excess over the limits (0 when feasible). ``lengths``: score "node", only the
    plant's [min_length, max_length] (and l > 0) bound the stroke."""
    T = gait.period
    t = np.linspace(0.0, T, _GRID, endpoint=False)
    t = np.union1d(t, gait.breakpoints(0.0, T))
    l, ld, ldd = gait(t)
    short = max(0.0, -float(l.min()) / min(fam.mean) + 1e-3) if l.min() <= 0 else 0.0
    if lengths is not None:
        lo, hi = lengths
        scale = min(fam.mean)
        return (short + max(0.0, (lo - float(l.min())) / scale)
                + max(0.0, (float(l.max()) - hi) / scale))
    v = max(0.0, float(np.abs(ld).max()) / limits.max_speed - 1.0)
    a = max(0.0, float(np.abs(ldd).max()) / limits.max_acceleration - 1.0)
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
    score: str = 'node'
    plant: dict | None = None        # sim_node's plant parameter values (score "node")
    stream: Stream = STREAM

    def figures(self, gait: gaits.Gait) -> dict[str, Any]:
        """The figures of ``gait`` over ``periods`` periods, scored as ``score`` says."""
        from ..core.scene import scene_from_dict
        from dataclasses import replace

        if self.score == 'ideal':
            scene = replace(scene_from_dict(self.base), gait=gait)
            return scene_figures(scene, self.periods, self.samples_per_period)
        T = gait.period
        t_end = self.periods * T
        plant = PlantConfig.from_values(self.plant)
        # the points after t_end do not change l(t) before it: a shorter preload scores the
        # same run (the played one holds 10 minutes)
        stream = replace(self.stream, duration=min(self.stream.duration,
                                                   t_end + 2.0 / self.stream.rate))
        n = self.periods * self.samples_per_period
        if not capabilities(plant.values['method']).fixed_step:   # the grid, plus every event
            tr = simulate_as_node(plant, gait, stream, t_end, dt=t_end / n)
        else:                                      # the node's step, sampled on the grid
            tr = simulate_as_node(plant, gait, stream, t_end, dt=to_seconds(plant.dt_ns),
                                  t_eval=np.linspace(0.0, t_end, n + 1))
        return run_figures(tr, T, self.periods)

    def evaluate(self, z: Iterable[float]) -> dict[str, Any]:
        """{score, feasible, violation, mean_speed, cost_of_transport, error} of z."""
        z = np.asarray(list(z), dtype=float)
        out: dict[str, Any] = {'score': PENALTY, 'feasible': False, 'violation': math.nan,
                               'mean_speed': math.nan, 'cost_of_transport': math.nan,
                               'error': ''}
        try:
            gait = self.fam.gait(z)
            lengths = ((self.plant['min_length'], self.plant['max_length'])
                       if self.score == 'node' else None)
            viol = _violation(gait, self.fam, z, self.limits, lengths)
            out['violation'] = viol
            if viol > 0:
                out['score'] = PENALTY * (1.0 + viol)
                return out
            fig = self.figures(gait)
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
    score: str = 'node'
    plant: PlantConfig | None = None     # the sim_node plant it was scored on (score "node")
    stream: Stream = STREAM

    @property
    def params(self) -> dict[str, float]:
        return {k: float(v) for k, v in zip(self.family.names, self.x)}


def _mapper(client: Any, workers: int) -> tuple[Callable, Callable[[], None]]:
    """A map(func, iterable) for the evaluations and a function that releases it."""
    if client is not None:
        from .cluster import check_workers, gather
        check_workers(client)

        def dask_map(func: Callable, xs: Iterable) -> list:
            futures = client.map(func.evaluate, [list(map(float, x)) for x in xs], pure=False)
            return gather(client, futures)      # every wait with a deadline (cluster.py)
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
             client: Any = None, workers: int = 1, score: str = 'node',
             stream: Stream = STREAM,
             progress: Callable[[str], None] | None = None) -> OptimizeResult:
    """Search the family's stroke for ``base`` (crawler and run options; its gait gives the mean
    lengths) that maximises the steady mean speed (``objective='speed'``) or minimises the cost
    of transport (``'cot'``) under ``limits`` (default: sim_node's actuator defaults), scored
    as sim_node runs it when gait_node plays it with ``stream`` (``score='node'``) or on its
    ideal lengths (``'ideal'``); see the module docstring.

    ``client`` (a Dask client) or ``workers`` > 1 (local processes) evaluate each generation of
    the global stage in parallel. Deterministic for a given ``seed``.
    """
    from scipy.optimize import differential_evolution, minimize

    if objective not in OBJECTIVES:
        raise ValueError(f'objective must be one of {", ".join(OBJECTIVES)}, got {objective!r}')
    if score not in SCORES:
        raise ValueError(f'score must be one of {", ".join(SCORES)}, got {score!r}')
    _check_settings(base, score, {
        'harmonics': harmonics, 'periods': periods, 'maxiter': maxiter, 'popsize': popsize,
        'local_maxiter': local_maxiter, 'workers': workers})
    limits = limits or ActuatorLimits()
    fam = family(family_name, base, limits, harmonics)
    _check_search(fam, base.crawler.p, popsize)
    plant = plant_for(base, fam, limits) if score == 'node' else None
    obj = Objective(scene_to_dict(base), fam, limits, objective, periods, score=score,
                    plant=None if plant is None else plant.values, stream=stream)
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
    return OptimizeResult(fam, objective, x, best, fam.gait(x), history, score, plant, stream)


def gait_node_params(result: OptimizeResult, scene_file: str | None = None) -> dict | None:
    """The ROS 2 parameter file content (``gait_node: ros__parameters: ...``) that makes
    gait_node send what was scored: the best stroke as gait_node's own gait parameters for a
    Scallop of one mean length, otherwise ``gait_file`` pointing at ``scene_file`` (the scene
    with the best gait), sent as ``result.stream`` says (one preloaded trajectory); None when
    neither applies."""
    fam, st = result.family, result.stream
    send = {'mode': st.mode, 'rate': st.rate, 'preload': st.preload, 'duration': st.duration,
            'horizon': st.horizon, 'n_links': fam.n_links}
    if fam.name != 'scallop' or len(set(fam.mean)) != 1:
        if scene_file is None:
            return None
        return {'gait_node': {'ros__parameters': {'gait_file': str(scene_file), **send}}}
    p = result.params
    return {'gait_node': {'ros__parameters': {
        'gait': 'scallop', 'mean': float(fam.mean[0]),
        'amplitude': p['amplitude'], 'frequency': p['frequency'], 'asymmetry': p['asymmetry'],
        'phase_lag': p.get('phase_lag', 0.0), **send}}}


def sim_node_params(result: OptimizeResult) -> dict | None:
    """The sim_node parameter file content (``crawler_sim: ros__parameters: ...``) of the plant
    the stroke was scored on (score "node"; None for "ideal"): the crawler as friction forces
    (the static ones and the stiction rule too when it has stiction), the actuator limits, the
    length limits and the method."""
    if result.plant is None:
        return None
    names = ('masses', 'friction', 'friction_backward', 'slope', 'gravity', 'initial_lengths',
             'initial_position', 'min_length', 'max_length', 'method', 'actuator_bandwidth',
             'actuator_max_speed', 'actuator_max_acceleration', 'integration_rate',
             'publish_rate')
    v = result.plant.values
    if result.plant.crawler.has_stiction:     # the static bounds, as forces (with stiction only)
        names += ('static_friction', 'static_friction_backward', 'stiction_rule')
    return {'crawler_sim': {'ros__parameters': {
        name: (list(v[name]) if isinstance(v[name], (list, tuple)) else v[name])
        for name in names}}}
