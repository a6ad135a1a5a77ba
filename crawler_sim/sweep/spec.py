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
special name ``bodies`` (number of bodies p: the masses, and per-body friction lists, kinetic
and static, are the base's first entry repeated p times). The static (stiction) bounds are axes
like any key of the crawler: ``crawler.mu_static``, ``crawler.mu_static_backward`` (with mu),
``crawler.static_friction``, ``crawler.static_friction_backward`` (with friction), and
``run.stiction_rule``. Grid values are a list or ``{linspace: [a, b, n]}`` /
``{logspace: [a, b, n]}`` (a, b the end values, not exponents). Random draws are
``{uniform: [a, b]}``, ``{loguniform: [a, b]}``, ``{integers: [a, b]}`` (both ends included) or
``{choice: [...]}``. Scene k draws from its own generator: numpy's PCG64 seeded with the k-th
child of ``SeedSequence(seed)`` (``SeedSequence(seed).spawn(k + 1)[k]``), so a spec gives the
same scenes on every machine and whatever the chunk size.

Scene k of a spec is computed from k alone (`SweepSpec.param_set`: the digits of k in the grid's
mixed radix, or scene k's own generator), so a chunk is planned in time proportional to its size
wherever it lies, and a spec of a billion scenes starts at once.

Every invalid value raises :class:`SpecError` naming the field, e.g.
``sweep.grid.gait.asymmetry.linspace: must be [a, b, n] with n >= 1, got [0.1, 0.9]``.

Sizes are limited before anything is expanded (`LIMITS`): the scenes of a spec, the values of a
grid axis or a choice, periods and samples, the spec file, and the spec itself with every YAML
alias counted once per use, so a "billion laughs" file is refused while it is a few hundred
bytes of text and a few hundred objects in memory.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
import math
from pathlib import Path
import re
import reprlib
from typing import Any, Iterator, Mapping

import numpy as np
import yaml

from ..core.scene import (FRICTION_KEYS, MAX_SCENE_BODIES, Scene, SceneError, YamlLoader,
                          read_text, scene_from_dict)

__all__ = ['SpecError', 'SweepSpec', 'LIMITS', 'load_spec', 'spec_from_dict', 'apply_params']

#: The largest accepted sizes. Checked before anything is expanded; each refusal is one line
#: naming the field and the allowed range.
LIMITS = {
    'scenes': 1_000_000_000,      # scenes of one spec (grid product or random.n)
    'axis': 10_000,               # values of one grid axis (list or linspace/logspace n), choice
    'values': 100_000,            # values in the whole spec, each use of a YAML alias counted
    'text': 1_000_000,            # characters of all strings, each use of an alias counted
    'depth': 32,                  # nesting levels of the spec
    'file_bytes': 256 * 1024,     # size of a spec file [bytes]
    'periods': 10_000,            # gait periods per scene
    'samples_per_period': 10_000,
    'samples': 1_000_000,         # periods x samples_per_period: one scene's samples
    'chunk_size': 100_000,        # scenes per task
    'seed': 2**64 - 1,
    'name': 100,                  # characters of the name (it becomes part of file names)
}

_SPEC_KEYS = ('name', 'description', 'base', 'periods', 'samples_per_period', 'grid', 'random',
              'chunk_size')
_GRID_KINDS = ('linspace', 'logspace')
_RANDOM_KINDS = ('uniform', 'loguniform', 'integers', 'choice')
_PATH = re.compile(r'^(bodies|(crawler|gait|run)\.[A-Za-z_]+(\[\d+\])?)$')
_PER_BODY = ('masses', *FRICTION_KEYS['mu'], *FRICTION_KEYS['friction'])


class SpecError(ValueError):
    """A sweep spec is malformed or out of range; the message is one line naming the field."""


# a value in a message: bounded whatever its size (reprlib looks at a few items of a few levels,
# never at the whole of a shared, alias-expanded structure)
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict = 3, 6, 6, 4
_REPR.maxstring = _REPR.maxother = 60


def _show(value: Any) -> str:
    """A short one-line repr of ``value`` for an error message."""
    try:
        return _REPR.repr(value).replace('\n', ' ')
    except ValueError:          # an int of more digits than Python converts to text
        return f'a {type(value).__name__} too large to show'


def _clip(text: str, limit: int = 300) -> str:
    """The first line of ``text``, at most ``limit`` characters."""
    line = text.splitlines()[0] if text else ''
    return line if len(line) <= limit else line[:limit] + '...'


def _parts(obj: Any) -> tuple[list | None, int]:
    """(children as (key label or None, child), characters of text) of a YAML node or of plain
    data; children is None for a scalar."""
    if isinstance(obj, yaml.MappingNode):
        return [item for k, v in obj.value for item in ((None, k), (_node_label(k), v))], 0
    if isinstance(obj, yaml.SequenceNode):
        return [(None, c) for c in obj.value], 0
    if isinstance(obj, yaml.ScalarNode):
        return None, len(obj.value)
    if isinstance(obj, Mapping):
        return [item for k, v in obj.items() for item in ((None, k), (k, v))], 0
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [(None, c) for c in obj], 0
    if isinstance(obj, (str, bytes)):
        return None, len(obj)
    return None, 0


def _node_label(key: yaml.Node) -> str | None:
    """The field name a mapping key node gives its value; None for a merge key ``<<`` (its
    keys become the mapping's own)."""
    if key.tag == 'tag:yaml.org,2002:merge':
        return None
    return key.value if isinstance(key, yaml.ScalarNode) else '?'


def _check_size(root: Any, prefix: str = 'sweep') -> None:
    """Refuse ``root`` (plain data or a composed YAML node) whose expanded size is over `LIMITS`.

    An alias, or an object shared in several places, counts once per use, but each shared
    object is measured once (memoised by identity), so the check costs the number of distinct
    objects, not the expanded size: a spec that would take hours to expand is refused at once.
    A structure that contains itself is refused too. Raises SpecError naming the innermost
    field (dotted keys after ``prefix``, the name of ``root``) where a limit was crossed.
    """
    memo: dict[int, tuple[int, int]] = {}
    active: set[int] = set()
    most, most_text, deepest = LIMITS['values'], LIMITS['text'], LIMITS['depth']

    def walk(obj: Any, path: str, depth: int) -> tuple[int, int]:
        children, chars = _parts(obj)
        if children is None:
            return 1, chars
        key = id(obj)
        if key in memo:
            return memo[key]
        where = path or 'the document'
        if key in active:
            raise SpecError(f'{where}: contains itself (a recursive YAML alias); a spec must be '
                            'a tree')
        if depth >= deepest:
            raise SpecError(f'{where}: nested more than {deepest} levels deep; allowed 1 to '
                            f'{deepest}')
        active.add(key)
        values = 1
        for label, child in children:
            sub = path if label is None else f'{path}.{_label(label)}' if path else _label(label)
            v, c = walk(child, sub, depth + 1)
            values, chars = values + v, chars + c
            if values > most:
                raise SpecError(f'{where}: expands to more than {most} values (a YAML alias '
                                f'counts once per use); allowed 1 to {most} in a spec')
            if chars > most_text:
                raise SpecError(f'{where}: expands to more than {most_text} characters of text '
                                f'(a YAML alias counts once per use); allowed 0 to {most_text} '
                                'in a spec')
        active.discard(key)
        memo[key] = (values, chars)
        return values, chars

    walk(root, prefix, 0)


def _label(key: Any) -> str:
    """A mapping key as a part of a dotted field name (short)."""
    text = key if isinstance(key, str) else _show(key)
    return text if len(text) <= 60 else text[:60] + '...'


def _plain(value: Any) -> Any:
    """numpy scalars to Python numbers (so scene dicts and metadata are plain YAML/JSON)."""
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


def _int(path: str, value: Any, lo: int, hi: int) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
            or not lo <= value <= hi):
        raise SpecError(f'{path}: must be an integer from {lo} to {hi}, got {_show(value)}')
    return int(value)


def _pair(path: str, value: Any, *, positive: bool = False) -> tuple[float, float]:
    ok = (isinstance(value, (list, tuple)) and len(value) == 2
          and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                  and math.isfinite(v) for v in value))
    if not ok or value[1] < value[0] or (positive and value[0] <= 0):
        rule = '0 < a <= b' if positive else 'a <= b, both finite'
        raise SpecError(f'{path}: must be [a, b] with {rule}, got {_show(value)}')
    return float(value[0]), float(value[1])


def _grid_values(path: str, value: Any) -> list:
    """The list of values of one grid axis (at most LIMITS['axis'], checked before expanding)."""
    most = LIMITS['axis']
    if isinstance(value, Mapping):
        if len(value) != 1 or next(iter(value)) not in _GRID_KINDS:
            raise SpecError(f'{path}: must be a list or one of {{linspace: [a, b, n]}}, '
                            f'{{logspace: [a, b, n]}}, got {_show(value)}')
        kind, args = next(iter(value.items()))
        ok = (isinstance(args, (list, tuple)) and len(args) == 3
              and not isinstance(args[2], bool) and isinstance(args[2], int) and args[2] >= 1)
        if not ok:
            raise SpecError(f'{path}.{kind}: must be [a, b, n] with n >= 1, got {_show(args)}')
        if args[2] > most:
            raise SpecError(f'{path}.{kind}: n must be from 1 to {most} (values of one axis), '
                            f'got {args[2]}')
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
                        f'got {_show(value)}')
    if len(value) > most:
        raise SpecError(f'{path}: must have 1 to {most} values, got {len(value)}')
    return list(value)


def _check_draw(path: str, value: Any) -> tuple[str, Any]:
    if not isinstance(value, Mapping) or len(value) != 1 or next(iter(value)) not in _RANDOM_KINDS:
        raise SpecError(f'{path}: must be one of {{uniform: [a, b]}}, {{loguniform: [a, b]}}, '
                        f'{{integers: [a, b]}}, {{choice: [...]}}, got {_show(value)}')
    kind, args = next(iter(value.items()))
    if kind == 'choice':
        if not isinstance(args, (list, tuple)) or not args or len(args) > LIMITS['axis']:
            size = f'{len(args)} values' if isinstance(args, (list, tuple)) else _show(args)
            raise SpecError(f'{path}.choice: must be a list of 1 to {LIMITS["axis"]} values, '
                            f'got {size}')
        return kind, list(args)
    a, b = _pair(f'{path}.{kind}', args, positive=kind == 'loguniform')
    if kind == 'integers' and (a != int(a) or b != int(b)):
        raise SpecError(f'{path}.integers: must be two integers [a, b], got {_show(args)}')
    return kind, (a, b)


def _scene_rng(seed: int, k: int) -> np.random.Generator:
    """The generator of random scene ``k``: PCG64 seeded with the k-th child of
    ``SeedSequence(seed)``. Independent streams per scene (numpy's documented way to split a
    seed), so scene k needs neither the draws of scenes 0..k-1 nor the chunk size."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(k,))))


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

    @property
    def n_chunks(self) -> int:
        """Number of chunks of ``chunk_size`` scenes in spec order (the last may be short)."""
        return max(1, -(-len(self) // self.chunk_size))

    def chunk_scenes(self, index: int) -> range:
        """The scene indices of chunk ``index``: ``chunk_size`` of them from
        ``index * chunk_size`` (fewer in the last chunk, none past it)."""
        start = index * self.chunk_size
        return range(start, max(start, min(start + self.chunk_size, len(self))))

    def param_set(self, k: int) -> dict:
        """The parameter values (dotted path -> value) of scene ``k``, 0 <= k < len(self),
        computed from k alone: O(number of parameters) whatever k."""
        if not 0 <= k < len(self):
            raise IndexError(f'scene {k} of a sweep of {len(self)} scenes')
        if self.grid:
            digits = {}
            for key in reversed(self.grid):        # the last axis varies fastest
                k, j = divmod(k, len(self.grid[key]))
                digits[key] = _plain(self.grid[key][j])
            return {key: digits[key] for key in self.grid}
        if self.random:
            rng = _scene_rng(self.random['seed'], k)
            return {key: _draw(rng, kind, args)
                    for key, (kind, args) in self.random['params'].items()}
        return {}

    def param_sets(self) -> Iterator[dict]:
        """Every scene's parameter values (dotted path -> value), in a fixed order: a grid's
        combinations with the last axis fastest, or the random scenes 0, 1, ..."""
        for k in range(len(self)):
            yield self.param_set(k)

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

    Sizes are checked first (`LIMITS`, shared objects counted once per use), before anything is
    expanded. The base scene and the first scene of the sweep are validated here, so a typo
    fails before any work starts; later scenes that are invalid become rows with an ``error``.
    """
    if isinstance(data, Mapping) and set(data) == {'sweep'}:
        data = data['sweep']
    if not isinstance(data, Mapping):
        raise SpecError(f'sweep: must be a mapping with keys {", ".join(_SPEC_KEYS)}, '
                        f'got {type(data).__name__}')
    _check_size(data)
    for key in data:
        if key not in _SPEC_KEYS:
            raise SpecError(f'sweep: unknown key {_show(key)}; allowed: {", ".join(_SPEC_KEYS)}')
    if 'base' not in data or not isinstance(data['base'], Mapping):
        raise SpecError('sweep.base: missing or not a mapping (a scene: crawler, gait, run)')
    base = dict(data['base'])
    if isinstance(base.get('scene'), Mapping) and len(base) == 1:
        base = dict(base['scene'])
    name = _name(data.get('name', name))
    description = data.get('description', '')
    if not isinstance(description, str):
        raise SpecError(f'sweep.description: must be a string, got {_show(description)}')
    if 'grid' in data and 'random' in data:
        raise SpecError('sweep: give grid or random, not both')
    grid = _grid(data['grid']) if 'grid' in data else {}
    random = _random(data['random']) if 'random' in data else {}
    periods = _int('sweep.periods', data.get('periods', 20), 4, LIMITS['periods'])
    samples = _int('sweep.samples_per_period', data.get('samples_per_period', 50), 4,
                   LIMITS['samples_per_period'])
    if periods * samples > LIMITS['samples']:
        raise SpecError(f'sweep.samples_per_period: periods x samples_per_period must be from 16 '
                        f'to {LIMITS["samples"]} (samples of one scene), got {periods} x '
                        f'{samples}')
    spec = SweepSpec(name=name, base=base, periods=periods, samples_per_period=samples,
                     grid=grid, random=random,
                     chunk_size=_int('sweep.chunk_size', data.get('chunk_size', 250), 1,
                                     LIMITS['chunk_size']),
                     description=description)
    _check_first_scene(spec)
    return spec


def _name(name: Any) -> str:
    """The sweep's name: it becomes part of file names and task keys, so no path separators."""
    most = LIMITS['name']
    if (not isinstance(name, str) or not 1 <= len(name) <= most or name in ('.', '..')
            or any(c in name for c in '/\\') or not name.isprintable()):
        raise SpecError(f'sweep.name: must be a string of 1 to {most} printable characters '
                        f'without / or \\, got {_show(name)}')
    return name


def _grid(data: Any) -> dict[str, list]:
    """The grid axes, refused when their product is over LIMITS['scenes'] (before expanding)."""
    if not isinstance(data, Mapping) or not data:
        raise SpecError('sweep.grid: must map parameter paths to values')
    grid: dict[str, list] = {}
    for path, values in data.items():
        _check_path(f'sweep.grid.{_label(path)}', path)
        grid[path] = _grid_values(f'sweep.grid.{path}', values)     # each at most LIMITS['axis']
        if path == 'bodies':
            _check_bodies(f'sweep.grid.{path}', grid[path])
    scenes = math.prod(len(v) for v in grid.values())
    if scenes > LIMITS['scenes']:
        sizes = ' x '.join(str(len(v)) for v in grid.values())
        raise SpecError(_clip(f'sweep.grid: must give 1 to {LIMITS["scenes"]} scenes (the product '
                              f'of the axis lengths), got {scenes} = {sizes}'))
    return grid


def _random(r: Any) -> dict[str, Any]:
    """The random sample: n, seed and the distribution of each parameter."""
    if not isinstance(r, Mapping) or set(r) - {'n', 'seed', 'params'} or 'params' not in r:
        raise SpecError('sweep.random: must be a mapping with n, seed and params')
    if not isinstance(r['params'], Mapping) or not r['params']:
        raise SpecError('sweep.random.params: must map parameter paths to distributions')
    params = {}
    for path, dist in r['params'].items():
        _check_path(f'sweep.random.params.{_label(path)}', path)
        params[path] = _check_draw(f'sweep.random.params.{path}', dist)
        if path == 'bodies':
            kind, args = params[path]
            if kind not in ('integers', 'choice'):
                raise SpecError(f'sweep.random.params.bodies: must be {{integers: [a, b]}} or '
                                f'{{choice: [...]}} (a number of bodies), got {kind}')
            _check_bodies(f'sweep.random.params.bodies.{kind}', args)
    return {'n': _int('sweep.random.n', r.get('n', 1), 1, LIMITS['scenes']),
            'seed': _int('sweep.random.seed', r.get('seed', 0), 0, LIMITS['seed']),
            'params': params}


def _check_bodies(where: str, values: Any) -> None:
    """Every number of bodies the spec can give is an integer in [2, MAX_SCENE_BODIES],
    checked on the spec: a scene's lists are made ``bodies`` long before the scene is
    validated, so a billion would be allocated first."""
    for value in values:
        whole = isinstance(value, (int, float)) and not isinstance(value, bool) and \
            float(value).is_integer()
        if not whole or not 2 <= value <= MAX_SCENE_BODIES:
            raise SpecError(f'{where}: numbers of bodies must be integers from 2 to '
                            f'{MAX_SCENE_BODIES}, got {_show(value)}')


def _check_first_scene(spec: SweepSpec) -> None:
    """The base scene and the sweep's first scene are valid, and the gait is periodic."""
    try:
        scene_from_dict(spec.base, name=spec.name)
    except SceneError as exc:
        raise SpecError(f'sweep.base: {_clip(str(exc))}') from None
    first = next(spec.param_sets())
    try:
        scene = spec.scene(first)
    except SceneError as exc:
        raise SpecError(f'sweep: the first scene {_show(first)} is invalid: '
                        f'{_clip(str(exc))}') from None
    if not scene.gait.period:
        raise SpecError(f'sweep.base.gait: must be periodic (the figures are per period), got '
                        f'type {_show(scene.gait_spec["type"])} without a period')


def _check_path(where: str, path: Any) -> None:
    if not isinstance(path, str) or not _PATH.match(path):
        raise SpecError(f'{where}: a parameter must be "bodies" or a dotted path like '
                        f'crawler.mu, gait.asymmetry or crawler.masses[1], got {_show(path)}')


def _read_yaml(path: Path) -> Any:
    """The YAML document of ``path``, its size checked (`_check_size`) on the composed nodes,
    before the constructor builds anything: whatever a PyYAML release does with aliases and
    merge keys ``<<`` (releases before 6.0.4 copy merged keys once per use), nothing has been
    expanded when a bomb is refused."""
    text = read_text(path, LIMITS['file_bytes'], 'a sweep spec file', SpecError)
    loader = YamlLoader(text)        # the scene files' loader, composing first
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_size(node, prefix='')
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or str(exc)
        raise SpecError(f'{path}: invalid YAML{where}: {_clip(problem)}') from None
    except RecursionError:
        raise SpecError(f'{path}: invalid YAML: nested too deeply; allowed 1 to '
                        f'{LIMITS["depth"]} levels') from None
    except SpecError:
        raise
    except ValueError as exc:     # e.g. an integer of more digits than Python converts
        raise SpecError(f'{path}: invalid YAML: {_clip(str(exc))}') from None
    finally:
        loader.dispose()


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep YAML file (OSError if unreadable, SpecError if invalid or over
    `LIMITS`)."""
    path = Path(path)
    try:
        data = _read_yaml(path)
        if not isinstance(data, Mapping) or 'sweep' not in data:
            raise SpecError('not a sweep file (no top-level "sweep:" key)')
        return spec_from_dict(data['sweep'], name=path.stem[:LIMITS['name']])
    except SpecError as exc:
        message = str(exc)
        raise SpecError(message if message.startswith(f'{path}: ') else f'{path}: {message}'
                        ) from None
