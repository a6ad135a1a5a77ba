"""Bench scenes: a small, self-contained reader of ``benchmarks/scenes/*.yaml``.

The files use the project's scene layout (``scene:`` with ``crawler``, ``gait`` and ``run``) so
that ``crawler-sim simulate`` reads them too, plus a ``bench:`` section that only the benchmark
reads::

    scene:
      name: scallop_2body
      description: ...
      crawler: {masses: [0.5, 1.0], mu: 0.3}          # or friction / friction_backward [N];
                                                       # mu_backward, slope [rad] or slope_deg,
                                                       # gravity [m/s^2]
      gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 2.0, asymmetry: 0.2}
      run: {t_end: 5.0}
    bench:
      periods: 10                # overrides run.t_end: t_end = periods * gait period
      samples_per_period: 16     # the common t_eval grid of the position error

Gait types: ``sinusoid``, ``fourier``, ``scallop``, ``stroke`` (``PiecewiseParabolic.stroke``),
``piecewise_parabolic``, ``spline`` and ``constant`` (a ``Cubic`` with zero rates: a rest); the
other keys are the constructor's keyword arguments. Errors are ``ValueError`` naming the field.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import re
from typing import Any, Callable

import numpy as np
import yaml

from crawler_sim.core import gaits
from crawler_sim.core.model import Crawler

__all__ = ['BenchScene', 'bench_dir', 'load_bench_scene', 'load_bench_scenes', 'make_gait']


class _Loader(yaml.SafeLoader):
    """SafeLoader that reads ``1e-3`` as a float (YAML 1.2 style)."""


_Loader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                   |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                   |\.[0-9_]+(?:[eE][-+]?[0-9]+)?)$''', re.X),
    list('-+0123456789.'))


def _constant(l0: Any, **_: Any) -> gaits.Gait:
    """A rest: constant lengths ``l0`` [m] with zero rate, acceleration and jerk."""
    l0 = np.atleast_1d(np.asarray(l0, dtype=float))
    z = np.zeros_like(l0)
    return gaits.Cubic(0.0, l0, z, z, z)


_GAITS: dict[str, Callable[..., gaits.Gait]] = {
    'sinusoid': gaits.Sinusoid,
    'fourier': gaits.Fourier,
    'scallop': gaits.Scallop,
    'stroke': gaits.PiecewiseParabolic.stroke,
    'piecewise_parabolic': gaits.PiecewiseParabolic,
    'spline': gaits.Spline,
    'constant': _constant,
}


@dataclass(frozen=True)
class BenchScene:
    """One bench scene: the crawler, its gait and how long to run it.

    Attributes
    ----------
    name, description : str
    crawler : Crawler
    gait : Gait
    gait_spec : dict, the gait's YAML description (``type`` and parameters)
    t_end : float [s]
    periods : float or None, ``t_end / period`` for periodic gaits
    samples_per_period : int, the common output grid (16 per period, or 256 over the run)
    source : str, the file it came from ('' if built in code)
    """

    name: str
    description: str
    crawler: Crawler
    gait: gaits.Gait
    gait_spec: dict
    t_end: float
    periods: float | None
    samples_per_period: int = 16
    source: str = ''
    extra: dict = field(default_factory=dict)

    @property
    def period(self) -> float | None:
        """The gait period [s] (None for an aperiodic gait)."""
        return self.gait.period

    def grid(self) -> np.ndarray:
        """The common t_eval grid [s]: ``samples_per_period`` per period (else 256 samples)."""
        if self.period:
            n = int(round(self.t_end / self.period * self.samples_per_period))
        else:
            n = 256
        return np.linspace(0.0, self.t_end, max(n, 1) + 1)

    def with_periods(self, periods: float) -> BenchScene:
        """The same scene run for ``periods`` gait periods."""
        if not self.period:
            raise ValueError(f'scene {self.name}: periods needs a periodic gait')
        return BenchScene(self.name, self.description, self.crawler, self.gait, self.gait_spec,
                          periods * self.period, periods, self.samples_per_period, self.source,
                          self.extra)


def _need(d: dict, key: str, where: str) -> Any:
    if key not in d:
        raise ValueError(f'{where}.{key}: missing (required)')
    return d[key]


def _crawler(d: Any, where: str) -> Crawler:
    """The crawler of a bench scene: ``scene.crawler_from_mapping``, the one validator."""
    from crawler_sim.core.scene import crawler_from_mapping
    return crawler_from_mapping(d, where)


def make_gait(spec: dict, where: str = 'gait') -> gaits.Gait:
    """Build a gait from ``{'type': name, **constructor keyword arguments}``."""
    if not isinstance(spec, dict):
        raise ValueError(f'{where}: must be a mapping, got {type(spec).__name__}')
    params = dict(spec)
    kind = str(params.pop('type', '')).lower()
    if kind not in _GAITS:
        raise ValueError(f'{where}.type: unknown gait {kind!r}; expected one of '
                         f'{", ".join(_GAITS)}')
    if kind == 'fourier' and 'coefficients' in params:
        params['coefficients'] = tuple(np.asarray(params['coefficients'], dtype=float))
    try:
        return _GAITS[kind](**params)
    except TypeError as exc:
        raise ValueError(f'{where}: bad parameters for {kind}: {exc}') from None


def scene_from_dict(data: dict, *, name: str = 'scene', source: str = '') -> BenchScene:
    """A `BenchScene` from the parsed YAML (top-level keys ``scene`` and optional ``bench``)."""
    if not isinstance(data, dict) or 'scene' not in data:
        raise ValueError(f'{source or name}: not a scene file (no top-level "scene:" key)')
    sc = data['scene']
    bench = data.get('bench') or {}
    name = str(sc.get('name', name))
    crawler = _crawler(_need(sc, 'crawler', 'scene'), 'scene.crawler')
    spec = dict(_need(sc, 'gait', 'scene'))
    gait = make_gait(spec, 'scene.gait')
    if gait.n_links != crawler.p - 1:
        raise ValueError(f'scene.gait: has {gait.n_links} linkages, the crawler needs '
                         f'{crawler.p - 1}')
    periods = bench.get('periods')
    if periods is not None:
        if not gait.period:
            raise ValueError('bench.periods: needs a periodic gait')
        periods = float(periods)
        if not (math.isfinite(periods) and periods > 0):
            raise ValueError(f'bench.periods: must be finite and > 0, got {periods!r}')
        t_end = periods * gait.period
    else:
        t_end = float(_need(sc.get('run') or {}, 't_end', 'scene.run'))
        periods = t_end / gait.period if gait.period else None
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f'scene.run.t_end: must be finite and > 0, got {t_end!r}')
    spp = int(bench.get('samples_per_period', 16))
    if spp < 1:
        raise ValueError(f'bench.samples_per_period: must be >= 1, got {spp}')
    extra = {k: v for k, v in bench.items() if k not in ('periods', 'samples_per_period')}
    return BenchScene(name, str(sc.get('description', '')), crawler, gait, spec, t_end, periods,
                      spp, source, extra)


def load_bench_scene(path: str | Path) -> BenchScene:
    """Read one bench scene file."""
    path = Path(path)
    data = yaml.load(path.read_text(encoding='utf-8'), Loader=_Loader)  # noqa: S506 (safe)
    try:
        return scene_from_dict(data, name=path.stem, source=str(path))
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from None


def bench_dir() -> Path:
    """The directory of the bench scenes: benchmarks/scenes/."""
    return Path(__file__).resolve().parents[1] / 'scenes'


def load_bench_scenes(names: list[str] | None = None,
                      directory: str | Path | None = None) -> list[BenchScene]:
    """The bench scenes (all, or those named; a name may also be a path to a YAML file)."""
    directory = Path(directory) if directory is not None else bench_dir()
    available = {p.stem: p for p in sorted(directory.glob('*.yaml'))}
    if not names:
        return [load_bench_scene(p) for p in available.values()]
    out = []
    for name in names:
        path = Path(name)
        if path.suffix in ('.yaml', '.yml') and path.is_file():
            out.append(load_bench_scene(path))
        elif name in available:
            out.append(load_bench_scene(available[name]))
        else:
            raise ValueError(f'scenes: unknown bench scene {name!r}; available: '
                             f'{", ".join(available) or "(none in " + str(directory) + ")"}')
    return out
