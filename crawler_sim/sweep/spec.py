"""Sweep specifications: a base scene and the parameters to vary, as a grid or a random sample.

A spec file has one top-level key ``sweep``::

    sweep:
      name: friction_vs_asymmetry          # optional; defaults to the file name
      base:                                # a scene, as under ``scene:`` in config/scenes/*.yaml
        crawler: {masses: [1.0, 1.0], mu: 0.3}
        gait: {type: scallop, mean: 0.1, amplitude: 0.02, frequency: 1.0, asymmetry: 0.5}
      periods: 20                          # gait periods per scene (>= 4; base run.t_end unused)
      samples_per_period: 50               # uniform samples per period (events are added)
      grid:                                # every combination of these values ...
        crawler.mu_backward: [0.3, 0.6]
        gait.asymmetry: {linspace: [0.1, 0.9, 9]}
      random:                              # ... or n random draws (not both)
        n: 1000
        seed: 0
        params:
          crawler.mu: {uniform: [0.1, 0.5]}
          gait.frequency: {loguniform: [0.5, 4.0]}
          bodies: {choice: [2, 3, 4]}

A parameter is a dotted path into the base scene (``crawler.masses``, ``crawler.slope_deg``,
``gait.type``, ``gait.amplitude`` ...; ``crawler.masses[1]`` sets one entry of a list) or the
special name ``bodies`` (number of bodies p: the masses, and per-body friction lists, are the
base's first entry repeated p times). Grid values are a list or ``{linspace: [a, b, n]}`` /
``{logspace: [a, b, n]}`` (a, b the end values, not exponents). Random draws are
``{uniform: [a, b]}``, ``{loguniform: [a, b]}``, ``{integers: [a, b]}`` (both ends included) or
``{choice: [...]}``; they use numpy's PCG64 generator seeded with ``seed``, so a spec gives the
same scenes on every machine.

Every invalid value raises :class:`SpecError` naming the field, e.g.
``sweep.grid.gait.asymmetry.linspace: must be [a, b, n] with n >= 1, got [0.1, 0.9]``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
import itertools
import math
from pathlib import Path
import re
from typing import Any, Iterator, Mapping

import numpy as np

from ..core.scene import Scene, SceneError, read_section, scene_from_dict

__all__ = ['SpecError', 'SweepSpec', 'load_spec', 'spec_from_dict', 'apply_params']

_SPEC_KEYS = ('name', 'description', 'base', 'periods', 'samples_per_period', 'grid', 'random',
              'chunk_size')
_GRID_KINDS = ('linspace', 'logspace')
_RANDOM_KINDS = ('uniform', 'loguniform', 'integers', 'choice')
_PATH = re.compile(r'^(bodies|(crawler|gait|run)\.[A-Za-z_]+(\[\d+\])?)$')
_PER_BODY = ('masses', 'mu', 'mu_backward', 'friction', 'friction_backward')


class SpecError(ValueError):
    """A sweep spec is malformed or out of range; the message is one line naming the field."""


def _plain(value: Any) -> Any:
    """numpy scalars to Python numbers (so scene dicts and metadata are plain YAML/JSON)."""
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


def _int(path: str, value: Any, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise SpecError(f'{path}: must be an integer >= {lo}, got {value!r}')
    return int(value)


def _pair(path: str, value: Any, *, positive: bool = False) -> tuple[float, float]:
    ok = (isinstance(value, (list, tuple)) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                  and math.isfinite(v) for v in value))
    if not ok or value[1] < value[0] or (positive and value[0] <= 0):
        rule = '0 < a <= b' if positive else 'a <= b, both finite'
        raise SpecError(f'{path}: must be [a, b] with {rule}, got {value!r}')
    return float(value[0]), float(value[1])


def _grid_values(path: str, value: Any) -> list:
    """The list of values of one grid axis."""
    if isinstance(value, Mapping):
        if len(value) != 1 or next(iter(value)) not in _GRID_KINDS:
            raise SpecError(f'{path}: must be a list or one of {{linspace: [a, b, n]}}, '
                            f'{{logspace: [a, b, n]}}, got {value!r}')
        kind, args = next(iter(value.items()))
        ok = (isinstance(args, (list, tuple)) and len(args) == 3
              and not isinstance(args[2], bool) and isinstance(args[2], int) and args[2] >= 1)
        if not ok:
            raise SpecError(f'{path}.{kind}: must be [a, b, n] with n >= 1, got {args!r}')
        ends = list(args[:2])
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in ends):
            ends = sorted(ends)
        lo, hi = _pair(f'{path}.{kind}', ends, positive=kind == 'logspace')
        a, b = (lo, hi) if args[0] <= args[1] else (hi, lo)    # a descending axis is allowed
        pts = (np.linspace(a, b, args[2]) if kind == 'linspace'
               else np.geomspace(a, b, args[2]))
        return [float(x) for x in pts]
    if not isinstance(value, (list, tuple)) or len(value) == 0:
        raise SpecError(f'{path}: must be a non-empty list of values or {{linspace: [a, b, n]}}, '
                        f'got {value!r}')
    return list(value)


def _check_draw(path: str, value: Any) -> tuple[str, Any]:
    if not isinstance(value, Mapping) or len(value) != 1 or next(iter(value)) not in _RANDOM_KINDS:
        raise SpecError(f'{path}: must be one of {{uniform: [a, b]}}, {{loguniform: [a, b]}}, '
                        f'{{integers: [a, b]}}, {{choice: [...]}}, got {value!r}')
    kind, args = next(iter(value.items()))
    if kind == 'choice':
        if not isinstance(args, (list, tuple)) or not args:
            raise SpecError(f'{path}.choice: must be a non-empty list, got {args!r}')
        return kind, list(args)
    a, b = _pair(f'{path}.{kind}', args, positive=kind == 'loguniform')
    if kind == 'integers' and (a != int(a) or b != int(b)):
        raise SpecError(f'{path}.integers: must be two integers [a, b], got {args!r}')
    return kind, (a, b)


def _draw(rng: np.random.Generator, kind: str, args: Any) -> Any:
    if kind == 'uniform':
        return float(rng.uniform(args[0], args[1]))
    if kind == 'loguniform':
        return float(math.exp(rng.uniform(math.log(args[0]), math.log(args[1]))))
    if kind == 'integers':
        return int(rng.integers(int(args[0]), int(args[1]), endpoint=True))
    return _plain(args[int(rng.integers(len(args)))])


def apply_params(base: Mapping, params: Mapping[str, Any]) -> dict:
    """A deep copy of the scene dict ``base`` with ``params`` (dotted path -> value) set."""
    scene = copy.deepcopy(dict(base))
    if 'bodies' in params:
        p = int(params['bodies'])
        crawler = scene.setdefault('crawler', {})
        for key in _PER_BODY:
            if key in crawler:
                first = crawler[key][0] if isinstance(crawler[key], list) else crawler[key]
                crawler[key] = [first] * p if key == 'masses' else first
    for path, value in params.items():
        if path == 'bodies':
            continue
        section, key = path.split('.', 1)
        target = scene.setdefault(section, {})
        m = re.match(r'^(\w+)\[(\d+)\]$', key)
        if m:
            name, index = m.group(1), int(m.group(2))
            current = target.get(name)
            masses = scene.get('crawler', {}).get('masses')
            if section == 'crawler' and name in _PER_BODY and isinstance(masses, list) and \
                    not isinstance(current, (list, type(None))):
                current = target[name] = [current] * len(masses)    # one entry per body
            if not isinstance(current, list) or index >= len(current):
                raise SpecError(f'{path}: the base scene has no list {section}.{name} with an '
                                f'entry {index}')
            current[index] = _plain(value)
        else:
            target[key] = _plain(value)
    return scene


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the base scene dict, the parameters and how long each scene runs.

    ``periods`` gait periods are simulated per scene with ``samples_per_period`` uniform samples
    each (plus the event times). ``chunk_size`` scenes make one task (a local process job or a
    Dask task) and one resumable checkpoint.
    """

    name: str
    base: dict
    periods: int = 20
    samples_per_period: int = 50
    grid: dict = field(default_factory=dict)
    random: dict = field(default_factory=dict)
    chunk_size: int = 250
    description: str = ''

    @property
    def params(self) -> tuple[str, ...]:
        """The swept parameter names, in column order."""
        return tuple(self.grid) if self.grid else tuple(self.random.get('params', {}))

    def __len__(self) -> int:
        if self.grid:
            return math.prod(len(v) for v in self.grid.values())
        return int(self.random.get('n', 1)) if self.random else 1

    def param_sets(self) -> Iterator[dict]:
        """Every scene's parameter values (dotted path -> value), in a fixed order."""
        if self.grid:
            keys = list(self.grid)
            for combo in itertools.product(*(self.grid[k] for k in keys)):
                yield {k: _plain(v) for k, v in zip(keys, combo)}
        elif self.random:
            rng = np.random.Generator(np.random.PCG64(self.random['seed']))
            draws = self.random['params']
            for _ in range(self.random['n']):
                yield {k: _draw(rng, kind, args) for k, (kind, args) in draws.items()}
        else:
            yield {}

    def scene(self, params: Mapping[str, Any]) -> Scene:
        """The validated scene of one parameter set (raises SceneError for a bad combination)."""
        return scene_from_dict(apply_params(self.base, params), name=self.name)

    def to_dict(self) -> dict:
        """Plain data that `spec_from_dict` turns back into an equal spec (grid axes expanded)."""
        out: dict[str, Any] = {'name': self.name, 'base': copy.deepcopy(self.base),
                               'periods': self.periods,
                               'samples_per_period': self.samples_per_period,
                               'chunk_size': self.chunk_size}
        if self.description:
            out['description'] = self.description
        if self.grid:
            out['grid'] = {k: list(v) for k, v in self.grid.items()}
        if self.random:
            out['random'] = {'n': self.random['n'], 'seed': self.random['seed'],
                             'params': {k: {kind: list(args)} for k, (kind, args)
                                        in self.random['params'].items()}}
        return out


def spec_from_dict(data: Any, *, name: str = 'sweep') -> SweepSpec:
    """Build and check a `SweepSpec` from the mapping under ``sweep:``.

    The base scene and the first scene of the sweep are validated here, so a typo fails before
    any work starts; later scenes that are invalid become rows with an ``error``.
    """
    if isinstance(data, Mapping) and set(data) == {'sweep'}:
        data = data['sweep']
    if not isinstance(data, Mapping):
        raise SpecError(f'sweep: must be a mapping with keys {", ".join(_SPEC_KEYS)}, '
                        f'got {type(data).__name__}')
    for key in data:
        if key not in _SPEC_KEYS:
            raise SpecError(f'sweep: unknown key {key!r}; allowed: {", ".join(_SPEC_KEYS)}')
    if 'base' not in data or not isinstance(data['base'], Mapping):
        raise SpecError('sweep.base: missing or not a mapping (a scene: crawler, gait, run)')
    base = dict(data['base'])
    if isinstance(base.get('scene'), Mapping) and len(base) == 1:
        base = dict(base['scene'])
    name = data.get('name', name)
    if not isinstance(name, str):
        raise SpecError(f'sweep.name: must be a string, got {name!r}')
    if 'grid' in data and 'random' in data:
        raise SpecError('sweep: give grid or random, not both')
    grid: dict[str, list] = {}
    if 'grid' in data:
        if not isinstance(data['grid'], Mapping) or not data['grid']:
            raise SpecError('sweep.grid: must map parameter paths to values')
        for path, values in data['grid'].items():
            _check_path(f'sweep.grid.{path}', path)
            grid[path] = _grid_values(f'sweep.grid.{path}', values)
    random: dict[str, Any] = {}
    if 'random' in data:
        r = data['random']
        if not isinstance(r, Mapping) or set(r) - {'n', 'seed', 'params'} or 'params' not in r:
            raise SpecError('sweep.random: must be a mapping with n, seed and params')
        if not isinstance(r['params'], Mapping) or not r['params']:
            raise SpecError('sweep.random.params: must map parameter paths to distributions')
        params = {}
        for path, dist in r['params'].items():
            _check_path(f'sweep.random.params.{path}', path)
            params[path] = _check_draw(f'sweep.random.params.{path}', dist)
        random = {'n': _int('sweep.random.n', r.get('n', 1), 1),
                  'seed': _int('sweep.random.seed', r.get('seed', 0), 0), 'params': params}
    spec = SweepSpec(name=name, base=base,
                     periods=_int('sweep.periods', data.get('periods', 20), 4),
                     samples_per_period=_int('sweep.samples_per_period',
                                             data.get('samples_per_period', 50), 4),
                     grid=grid, random=random,
                     chunk_size=_int('sweep.chunk_size', data.get('chunk_size', 250), 1),
                     description=str(data.get('description', '')))
    try:
        scene_from_dict(base, name=name)
    except SceneError as exc:
        raise SpecError(f'sweep.base: {exc}') from None
    first = next(spec.param_sets())
    try:
        scene = spec.scene(first)
    except SceneError as exc:
        raise SpecError(f'sweep: the first scene {first} is invalid: {exc}') from None
    if not scene.gait.period:
        raise SpecError(f'sweep.base.gait: must be periodic (the figures are per period), got '
                        f'type {scene.gait_spec["type"]!r} without a period')
    return spec


def _check_path(where: str, path: Any) -> None:
    if not isinstance(path, str) or not _PATH.match(path):
        raise SpecError(f'{where}: a parameter must be "bodies" or a dotted path like '
                        f'crawler.mu, gait.asymmetry or crawler.masses[1], got {path!r}')


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep YAML file (OSError if unreadable, SpecError if invalid)."""
    path = Path(path)
    section = read_section(path, 'sweep', 'a sweep', SpecError)
    try:
        return spec_from_dict(section, name=path.stem)
    except SpecError as exc:
        raise SpecError(f'{path}: {exc}') from None
