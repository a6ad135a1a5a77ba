"""Scenes: a crawler, a gait and run options described in YAML.

(About 480 lines: the field checks, their ranges and the error messages belong together so
that every message names its field the same way.)

A scene file has one top-level key ``scene``::

    scene:
      name: scallop_2body                 # optional; defaults to the file name
      description: Two bodies, fast extension, slow contraction.
      crawler:
        masses: [1.0, 1.0]                # kg, p >= 2 entries, each > 0
        mu: 0.3                           # friction coefficients (one, or one per body) ...
        mu_backward: [0.6, 0.6]           # ... optional, defaults to mu
        # friction: [2.9, 2.9]            # ... or friction forces [N] instead of mu
        # friction_backward: [5.9, 5.9]
        mu_static: 0.5                    # optional static (stiction) bounds, >= the kinetic
        mu_static_backward: 0.7           # ones: defaults in crawler_sim.Crawler (no stiction);
        # static_friction: [4.9, 4.9]     # ... forces [N] with friction, coefficients with mu
        # static_friction_backward: [6.9, 6.9]
        slope: 0.0                        # rad, uphill is +x (or slope_deg: degrees)
        gravity: 9.81                     # m/s^2
      gait:
        type: scallop                     # sinusoid, fourier, scallop, piecewise_parabolic,
        mean: 0.1                         # stroke (PiecewiseParabolic.stroke) or spline;
        amplitude: 0.02                   # the other keys are the constructor's parameters
        frequency: 1.0                    # (crawler_sim.core.gaits), e.g. fourier: mean,
        asymmetry: 0.25                   # coefficients: [cos, sin], frequency
      run:                                # every key optional
        t_end: 20.0                       # s
        method: exact                     # exact, implicit or penalty
        dt: null                          # s (implicit, penalty; default 1e-3)
        penalty: null                     # N s/m (penalty), one or one per body
        tol: 1.0e-13                      # s (exact)
        max_step: null                    # s (exact)
        x0: 0.0                           # m, body 0
        v0: 0.0                           # m/s, body 0
        stiction_rule: incumbent          # incumbent or margin (crawler_sim.core.friction)
        initial_stuck: null               # a body at rest at t = 0 counted as stuck before it
      bench: {}                           # optional, options of crawler_sim.bench (not read here)

Every invalid value raises :class:`SceneError` with one line naming the field and the allowed
range, e.g. ``scene.crawler.masses[1]: must be finite and > 0, got -1.0``. Unknown keys are
errors too (a typo must not silently fall back to a default).

Besides sign and finiteness, a scene's values must lie in physical ranges (``LIMITS``) wide
enough for any crawler and narrow enough that no value reaches the solvers as a degenerate case
(a 1e-30 s run, a 1e-12 asymmetry, a tolerance of 1 s): masses in [1e-9, 1e9] kg, mu in [0,
1e3], friction forces in [0, 1e12] N (static ones too), gravity in [0, 1e3] m/s^2, gait
lengths, rates, accelerations and coefficients within 1e6 in magnitude, frequency in [1e-3,
1e4] Hz, asymmetry in [1e-3, 0.999], gait times within [-1e7, 1e7] s at least 1e-6 s apart,
t_end in [1e-6, 1e7] s, tol in [1e-15, 1e-6] s, max_step >= max(1e-6 s, t_end / 1e7), dt >=
max(1e-9 s, t_end / 1e8), x0 and v0 within 1e6, penalty in [1e-6, 1e15] N s/m. Derived
quantities (the sum of the masses, the total friction, the weight) are checked by `Crawler` and
reported under scene.crawler.

:func:`scene_to_dict` gives the plain-data form written into bags (friction as forces, so the
crawler is rebuilt bit for bit); :func:`scene_from_dict` reads it back.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
from pathlib import Path
import re
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray
import yaml

from . import gaits
from .model import Crawler
from .friction import DEFAULT_RULE, RULES
from .stepper import (METHODS, GaitLengthError, check_initial_stuck, check_lengths,
                      check_stiction, simulate)
from .trajectory import Trajectory

__all__ = ['SceneError', 'RunOptions', 'Scene', 'GAIT_TYPES', 'LIMITS', 'load_scene',
           'scene_from_dict', 'scene_to_dict', 'crawler_from_mapping', 'MAX_SCENE_BODIES',
           'MAX_ENTRIES', 'MAX_SCENE_BYTES', 'YamlLoader', 'FRICTION_KEYS']


class SceneError(ValueError):
    """A scene is missing, malformed or out of range; the message is one line for the user."""


#: the most bodies of a scene (a sweep's ``bodies`` too). Checked on the list's length before
#: any array is built from it: a 1e6-body scene reached optimize's first allocation of 3.8 GiB
#: (issue 38). 1000 bodies run 2 s in 2.5 s with the implicit method (its arrays are a few MB a
#: second); sim_node takes at most 64 (`core.plant.config.MAX_BODIES`).
MAX_SCENE_BODIES = 1000
#: the most numbers in one array field of a gait (a table of times and lengths, coefficients)
MAX_ENTRIES = 1_000_000
#: the largest scene file read, as a sweep spec's (a 1000-body scene with every per-body list
#: is ~30 kB). Checked before parsing: YAML is slow to parse (a 2 MB list of a million bodies:
#: 51 s and 790 MB with PyYAML's pure-Python loader, 10 s with libyaml's; 256 KiB: 5.3 s / 1.9 s)
MAX_SCENE_BYTES = 256 * 1024


def _short(value: Any) -> str:
    """``value`` in a message: bounded whatever its size."""
    import reprlib
    return reprlib.repr(value)


class YamlLoader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):     # type: ignore[misc]
    """The YAML loader of scene and sweep files: safe (libyaml's when PyYAML has it: 3x
    faster), and reads ``1e-3`` as a float (YAML 1.2; PyYAML's 1.1 needs ``1.0e-3``)."""


YamlLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'''^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                   |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                   |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                   |[-+]?\.(?:inf|Inf|INF)
                   |\.(?:nan|NaN|NAN))$''', re.X),
    list('-+0123456789.'))


# ---------------------------------------------------------------------------------------------
# Field checks. Each takes the dotted path of the field for the error message.

def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


def _number(path: str, value: Any, rule: str = 'finite', *, lo: float | None = None,
            lo_open: bool = False) -> float:
    """A finite float, optionally > lo (``lo_open``) or >= lo."""
    if not _is_number(value):
        raise SceneError(f'{path}: must be a number ({rule}), got {value!r}')
    x = float(value)
    if not math.isfinite(x) or (lo is not None and (x <= lo if lo_open else x < lo)):
        raise SceneError(f'{path}: must be {rule}, got {value!r}')
    return x


def _optional(path: str, value: Any, rule: str, **kw: Any) -> float | None:
    return None if value is None else _number(path, value, rule, **kw)


#: field -> (lowest, highest, unit) allowed in a scene (see the module docstring)
LIMITS: dict[str, tuple[float, float, str]] = {
    'masses': (1e-9, 1e9, 'kg'), 'mu': (0.0, 1e3, ''), 'mu_backward': (0.0, 1e3, ''),
    'friction': (0.0, 1e12, 'N'), 'friction_backward': (0.0, 1e12, 'N'),
    'mu_static': (0.0, 1e3, ''), 'mu_static_backward': (0.0, 1e3, ''),
    'static_friction': (0.0, 1e12, 'N'), 'static_friction_backward': (0.0, 1e12, 'N'),
    'gravity': (0.0, 1e3, 'm/s^2'),
    'mean': (-1e6, 1e6, 'm'), 'amplitude': (-1e6, 1e6, 'm'), 'l0': (-1e6, 1e6, 'm'),
    'v0_gait': (-1e6, 1e6, 'm/s'), 'lengths': (-1e6, 1e6, 'm'),
    'coefficients': (-1e6, 1e6, 'm'), 'accelerations': (-1e6, 1e6, 'm/s^2'),
    'phase': (-1e6, 1e6, 'rad'), 'times': (-1e7, 1e7, 's'),
    'frequency': (1e-3, 1e4, 'Hz'), 'asymmetry': (1e-3, 1.0 - 1e-3, ''),
    't_end': (1e-6, 1e7, 's'), 'tol': (1e-15, 1e-6, 's'), 'x0': (-1e6, 1e6, 'm'),
    'v0': (-1e6, 1e6, 'm/s'), 'penalty': (1e-6, 1e15, 'N s/m'),
}
_MIN_GAIT_SPACING = 1e-6     # s, between consecutive gait times


def _in_range(path: str, value: Any, key: str) -> None:
    """Every entry of ``value`` (a number or an array) within LIMITS[key]."""
    lo, hi, unit = LIMITS[key]
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    bad = ~((arr >= lo) & (arr <= hi))
    if np.any(bad):
        where = '' if arr.size == 1 else f'[{int(np.argmax(bad))}]' if arr.ndim == 1 else ''
        got = float(arr.ravel()[int(np.argmax(bad.ravel()))])
        raise SceneError(f'{path}{where}: must be in [{lo:g}, {hi:g}]{" " + unit if unit else ""}'
                         f', got {got!r}')


def _array(path: str, value: Any, budget: list[int] | None = None) -> NDArray[np.float64]:
    """A finite float array of any rectangular shape, from numbers and (nested) lists, of at
    most ``MAX_ENTRIES`` entries: counted while they are read (``budget``: the entries still
    allowed), so a list too long, or nested YAML aliases that repeat a list a billion times,
    stop at the limit instead of being walked or built."""
    budget = [MAX_ENTRIES] if budget is None else budget
    if _is_number(value):
        arr = np.array(float(value))
    else:
        if not isinstance(value, (list, tuple)) or len(value) == 0:
            raise SceneError(f'{path}: must be a number or a non-empty list of numbers, '
                             f'got {_short(value)}')
        budget[0] -= len(value)         # its items (numbers or rows), before walking them
        if budget[0] < 0:
            root = path.split('[', 1)[0]
            raise SceneError(f'{root}: must have at most {MAX_ENTRIES} entries (its numbers '
                             'and rows, each use of a YAML alias counted)')
        rows = [_array(f'{path}[{i}]', v, budget) for i, v in enumerate(value)]
        if any(r.shape != rows[0].shape for r in rows):
            raise SceneError(f'{path}: rows must all have the same length, got '
                             f'{[len(r) if r.ndim else 1 for r in rows]}')
        return np.stack(rows)
    if not math.isfinite(float(arr)):
        raise SceneError(f'{path}: must be finite, got {value!r}')
    return arr


def _per_body(path: str, value: Any, p: int | None, *, positive: bool, limit: str = ''
              ) -> NDArray[np.float64]:
    """One number or a list of one number per body, each finite and > 0 (or >= 0); the
    message names the range ``LIMITS[limit]`` when given."""
    rule = 'finite and > 0' if positive else 'finite and >= 0'
    if limit:
        lo, hi, unit = LIMITS[limit]
        rule = f'in [{lo:g}, {hi:g}]{" " + unit if unit else ""}'
    scalar = _is_number(value)
    if not scalar and not isinstance(value, (list, tuple)):
        raise SceneError(f'{path}: must be a number or a list of numbers ({rule}), '
                         f'got {value!r}')
    values = [value] if scalar else list(value)
    if p is not None and len(values) not in (1, p):
        raise SceneError(f'{path}: must have 1 or {p} entries (one per body), '
                         f'got {len(values)}')
    for i, v in enumerate(values):
        _number(path if scalar else f'{path}[{i}]', v, rule, lo=0.0, lo_open=positive)
    arr = np.array(values, dtype=float)
    return np.full(p, arr[0]) if p is not None and arr.size == 1 else arr


def _mapping(path: str, value: Any, allowed: tuple[str, ...], required: tuple[str, ...] = ()
             ) -> dict:
    """``value`` as a dict with only ``allowed`` keys and all ``required`` ones."""
    if not isinstance(value, Mapping):
        raise SceneError(f'{path}: must be a mapping with keys {", ".join(allowed)}, '
                         f'got {type(value).__name__}')
    for key in value:
        if key not in allowed:
            raise SceneError(f'{path}: unknown key {key!r}; allowed: {", ".join(allowed)}')
    for key in required:
        if key not in value:
            raise SceneError(f'{path}.{key}: missing (required)')
    return dict(value)


def _plain(value: Any) -> Any:
    """numpy values to plain Python lists and floats (for YAML, JSON and bags)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    return value


# ---------------------------------------------------------------------------------------------
# Crawler

#: the friction keys of a crawler: (kinetic forward, kinetic backward, static forward, static
#: backward), as coefficients or as forces [N]; a crawler takes one kind
FRICTION_KEYS = {'mu': ('mu', 'mu_backward', 'mu_static', 'mu_static_backward'),
                 'friction': ('friction', 'friction_backward', 'static_friction',
                              'static_friction_backward')}
_CRAWLER_KEYS = ('masses', *FRICTION_KEYS['mu'], *FRICTION_KEYS['friction'], 'slope',
                 'slope_deg', 'gravity')


def crawler_from_mapping(spec: Any, path: str = 'crawler') -> Crawler:
    """The one validator of a crawler description (scenes, sweeps, the bench, the node's
    parameters, replay): ``masses`` [kg], ``mu`` or ``friction`` [N] (one or one per body),
    optional ``mu_backward`` / ``friction_backward``, the static (stiction) bounds
    ``mu_static``, ``mu_static_backward`` / ``static_friction``, ``static_friction_backward``
    (of the same kind as the kinetic ones; each >= its kinetic bound; their defaults are
    `Crawler`'s: no stiction), ``slope`` [rad] or ``slope_deg``, ``gravity`` [m/s^2].
    SceneError (a ValueError) names the field under ``path`` and its allowed range."""
    def k(name: str) -> str:
        return f'{path}.{name}' if path else name
    d = _mapping(path or 'crawler', spec, _CRAWLER_KEYS, ('masses',))
    if isinstance(d['masses'], (list, tuple)) and len(d['masses']) > MAX_SCENE_BODIES:
        raise SceneError(f"{k('masses')}: must list 2 to {MAX_SCENE_BODIES} bodies, got "
                         f"{len(d['masses'])}")
    masses = _per_body(k('masses'), d['masses'], None, positive=True, limit='masses')
    _in_range(k('masses'), masses, 'masses')
    p = masses.size
    if p < 2:
        raise SceneError(f"{k('masses')}: must list p >= 2 bodies, got {p}")
    if 'slope' in d and 'slope_deg' in d:
        raise SceneError(f'{path or "crawler"}: give slope [rad] or slope_deg [deg], not both')
    if 'slope_deg' in d:
        slope = math.radians(_number(k('slope_deg'), d['slope_deg'],
                                     'finite, in (-90, 90) deg'))
        slope_path = k('slope_deg')
    else:
        slope = _number(k('slope'), d.get('slope', 0.0), 'finite, in (-pi/2, pi/2) rad')
        slope_path = k('slope')
    if not abs(slope) < math.pi / 2:
        raise SceneError(f'{slope_path}: must be in (-pi/2, pi/2) rad = (-90, 90) deg, '
                         f'got {d.get("slope", d.get("slope_deg"))!r}')
    gravity = _number(k('gravity'), d.get('gravity', 9.81), 'finite and >= 0 m/s^2', lo=0.0)
    _in_range(k('gravity'), gravity, 'gravity')
    has_mu, has_f = 'mu' in d, 'friction' in d
    if has_mu == has_f:
        raise SceneError(f'{path or "crawler"}: give exactly one of mu (coefficients) or '
                         f'friction (forces [N]), got {"both" if has_mu else "neither"}')
    # each given bound: one value or one per body, in range (absent ones: Crawler's defaults;
    # a coefficient mixed with forces is refused by Crawler, naming both)
    bounds = {}
    for key in FRICTION_KEYS['mu'] + FRICTION_KEYS['friction']:
        if key in d:
            bounds[key] = _per_body(k(key), d[key], p, positive=False, limit=key)
            _in_range(k(key), bounds[key], key)
    try:
        return Crawler(masses, slope=slope, gravity=gravity, **bounds)
    except ValueError as exc:     # derived quantities, static < kinetic; the message names them
        raise SceneError(f'{path}.{exc}' if path else str(exc)) from None


def _crawler(spec: Any) -> Crawler:
    return crawler_from_mapping(spec, 'scene.crawler')


# ---------------------------------------------------------------------------------------------
# Gaits: type -> (builder, required parameters, optional parameters with defaults)

def _stroke(mean, amplitude, frequency, asymmetry, phase=0.0, *, n_links=None):
    return gaits.PiecewiseParabolic.stroke(mean, amplitude, frequency, asymmetry, phase,
                                           n_links=n_links)


#: type name -> (builder, required keys, optional keys with defaults, takes n_links)
_GAITS: dict[str, tuple[Any, tuple[str, ...], dict[str, Any], bool]] = {
    'sinusoid': (gaits.Sinusoid, ('mean', 'amplitude', 'frequency'), {'phase': 0.0}, True),
    'fourier': (gaits.Fourier, ('mean', 'coefficients', 'frequency'), {}, True),
    'scallop': (gaits.Scallop, ('mean', 'amplitude', 'frequency', 'asymmetry'),
                {'phase': 0.0}, True),
    'piecewise_parabolic': (gaits.PiecewiseParabolic, ('times', 'accelerations', 'l0'),
                            {'v0': 0.0, 'periodic': True}, False),
    'stroke': (_stroke, ('mean', 'amplitude', 'frequency', 'asymmetry'), {'phase': 0.0}, True),
    'spline': (gaits.Spline, ('times', 'lengths'), {'periodic': False}, False),
}
GAIT_TYPES = tuple(_GAITS)
_BOOL_KEYS = ('periodic',)
_SCALAR_KEYS = ('frequency', 'asymmetry')
_PER_LINK_KEYS = ('mean', 'amplitude', 'phase', 'l0', 'v0')


def _gait_type(value: Any) -> str:
    names = {t.replace('_', ''): t for t in GAIT_TYPES}
    key = str(value).lower().replace('_', '').replace('-', '') if isinstance(value, str) else None
    if key not in names:
        raise SceneError(f'scene.gait.type: unknown gait {value!r}; expected one of '
                         f'{", ".join(GAIT_TYPES)}')
    return names[key]


def _gait(spec: Any, p: int) -> tuple[gaits.Gait, dict]:
    """The gait and its normalised description ({'type': ..., parameters as plain data})."""
    path = 'scene.gait'
    if not isinstance(spec, Mapping) or 'type' not in spec:
        raise SceneError(f'{path}: must be a mapping with a type ({", ".join(GAIT_TYPES)}) '
                         'and its parameters')
    kind = _gait_type(spec['type'])
    build, required, optional, takes_n = _GAITS[kind]
    d = _mapping(path, spec, ('type',) + required + tuple(optional), required)
    kwargs: dict[str, Any] = {}
    for key in required + tuple(optional):
        value = d.get(key, optional.get(key))
        if key in _BOOL_KEYS:
            if not isinstance(value, bool):
                raise SceneError(f'{path}.{key}: must be true or false, got {value!r}')
            kwargs[key] = value
        elif key in _SCALAR_KEYS:
            kwargs[key] = _number(f'{path}.{key}', value, 'finite')
            _in_range(f'{path}.{key}', kwargs[key], key)
        else:
            kwargs[key] = arr = _array(f'{path}.{key}', value)
            _in_range(f'{path}.{key}', arr, 'v0_gait' if key == 'v0' else key)
            if key == 'times' and arr.ndim == 1 and arr.size > 1 and np.all(np.diff(arr) > 0) \
                    and np.diff(arr).min() < _MIN_GAIT_SPACING:
                raise SceneError(f'{path}.times: consecutive times must be at least '
                                 f'{_MIN_GAIT_SPACING:g} s apart, got a gap of '
                                 f'{float(np.diff(arr).min())!r} s')
            if key in _PER_LINK_KEYS and arr.ndim == 1 and arr.size not in (1, p - 1):
                count = '1 entry' if p == 2 else f'1 or {p - 1} entries'
                raise SceneError(f'{path}.{key}: must have {count} (one per linkage; '
                                 f'scene.crawler.masses lists {p} bodies), got {arr.size}')
    if takes_n:
        kwargs['n_links'] = p - 1
    try:
        gait = build(**kwargs)
    except ValueError as exc:
        raise SceneError(f'{path} ({kind}): {exc}') from None
    if gait.n_links != p - 1:
        raise SceneError(f'{path} ({kind}): drives {gait.n_links} linkages, but '
                         f'scene.crawler.masses lists {p} bodies (needs p - 1 = {p - 1})')
    kwargs.pop('n_links', None)
    return gait, {'type': kind, **{k: _plain(v) for k, v in kwargs.items()}}


# ---------------------------------------------------------------------------------------------
# Run options

@dataclass(frozen=True)
class RunOptions:
    """How to simulate a scene (the keyword arguments of `crawler_sim.simulate`).

    t_end [s] > 0; method in METHODS; dt [s] > 0 or None; penalty [N s/m] one float or one per
    body (required for "penalty"); tol [s] > 0; max_step [s] > 0 or None; x0 [m], v0 [m/s];
    stiction_rule in ``core.friction.RULES``; initial_stuck None or the index of a body at
    rest at t = 0 whose cluster counts as stuck before it (``Stepper``).
    """

    t_end: float = 10.0
    method: str = 'exact'
    dt: float | None = None
    penalty: float | list[float] | None = None
    tol: float = 1e-13
    max_step: float | None = None
    x0: float = 0.0
    v0: float = 0.0
    stiction_rule: str = DEFAULT_RULE
    initial_stuck: int | None = None

    def to_dict(self) -> dict:
        return {'t_end': self.t_end, 'method': self.method, 'dt': self.dt,
                'penalty': self.penalty, 'tol': self.tol, 'max_step': self.max_step,
                'x0': self.x0, 'v0': self.v0, 'stiction_rule': self.stiction_rule,
                'initial_stuck': self.initial_stuck}


_RUN_KEYS = tuple(RunOptions().to_dict())


def _run(spec: Any, p: int) -> RunOptions:
    path = 'scene.run'
    d = _mapping(path, {} if spec is None else spec, _RUN_KEYS)
    method = d.get('method', 'exact')
    if not isinstance(method, str) or method not in METHODS:     # a list is unhashable
        raise SceneError(f'{path}.method: unknown method {method!r}; expected one of '
                         f'{", ".join(METHODS)}')
    penalty = d.get('penalty')
    if penalty is not None:
        arr = _per_body(f'{path}.penalty', penalty, None, positive=True)
        if arr.size not in (1, p):
            raise SceneError(f'{path}.penalty: must have 1 or {p} entries (one per body), '
                             f'got {arr.size}')
        penalty = float(arr[0]) if _is_number(penalty) else arr.tolist()
    elif method == 'penalty':
        raise SceneError(f'{path}.penalty: required for method penalty (the seed\'s n, '
                         'finite and > 0 N s/m)')
    rule = d.get('stiction_rule', DEFAULT_RULE)
    if not isinstance(rule, str) or rule not in RULES:
        raise SceneError(f'{path}.stiction_rule: unknown rule {rule!r}; expected one of '
                         f'{", ".join(RULES)}')
    stuck = d.get('initial_stuck')
    if stuck is not None and (isinstance(stuck, bool) or not isinstance(stuck, int)
                              or not 0 <= stuck < p):
        raise SceneError(f'{path}.initial_stuck: must be null or a body index in [0, {p - 1}], '
                         f'got {stuck!r}')
    pos = 'finite and > 0 s'
    opts = RunOptions(
        t_end=_number(f'{path}.t_end', d.get('t_end', 10.0), pos, lo=0.0, lo_open=True),
        method=method,
        dt=_optional(f'{path}.dt', d.get('dt'), pos, lo=0.0, lo_open=True),
        penalty=penalty,
        tol=_number(f'{path}.tol', d.get('tol', 1e-13), pos, lo=0.0, lo_open=True),
        max_step=_optional(f'{path}.max_step', d.get('max_step'), pos, lo=0.0, lo_open=True),
        x0=_number(f'{path}.x0', d.get('x0', 0.0), 'finite [m]'),
        v0=_number(f'{path}.v0', d.get('v0', 0.0), 'finite [m/s]'),
        stiction_rule=rule, initial_stuck=stuck)
    for key in ('t_end', 'tol', 'x0', 'v0'):
        _in_range(f'{path}.{key}', getattr(opts, key), key)
    if opts.penalty is not None:
        _in_range(f'{path}.penalty', opts.penalty, 'penalty')
    # steps: bounded in number (a run must end) and above the rounding of t
    if opts.max_step is not None and opts.max_step < max(1e-6, opts.t_end / 1e7):
        raise SceneError(f'{path}.max_step: must be >= max(1e-6 s, t_end / 1e7) = '
                         f'{max(1e-6, opts.t_end / 1e7):g} s, got {opts.max_step!r}')
    if opts.dt is not None and opts.dt < max(1e-9, opts.t_end / 1e8):
        raise SceneError(f'{path}.dt: must be >= max(1e-9 s, t_end / 1e8) = '
                         f'{max(1e-9, opts.t_end / 1e8):g} s, got {opts.dt!r}')
    return opts


# ---------------------------------------------------------------------------------------------
# Scene

@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene: what to simulate (crawler, gait) and how (run)."""

    name: str
    crawler: Crawler
    gait: gaits.Gait
    run: RunOptions
    gait_spec: dict
    description: str = ''
    bench: dict = field(default_factory=dict)

    def with_run(self, **changes: Any) -> Scene:
        """A copy with some run options replaced (None values are ignored), checked again."""
        changes = {k: v for k, v in changes.items() if v is not None}
        if not changes:
            return self
        merged = {**self.run.to_dict(), **changes}
        run = _run(merged, self.crawler.p)
        _check_run(self.crawler, self.gait, run)
        return replace(self, run=run)

    def simulate(self, **kwargs: Any) -> Trajectory:
        """Run `crawler_sim.simulate` with the scene's options (``kwargs`` go to simulate)."""
        r = self.run
        kwargs.setdefault('lengths_check', 'raise')    # a scene's gait: refused, not warned
        try:
            return simulate(self.crawler, self.gait, r.t_end, r.method, dt=r.dt, v0=r.v0,
                            x0=r.x0, penalty=r.penalty, tol=r.tol, max_step=r.max_step,
                            stiction_rule=r.stiction_rule, initial_stuck=r.initial_stuck,
                            **kwargs)
        except GaitLengthError as exc:      # the scene's gait field, one line, exit 2
            raise SceneError(f'scene.gait ({self.gait_spec["type"]}): {exc}') from None


def _check_run(crawler: Crawler, gait: gaits.Gait, run: RunOptions) -> None:
    """The run options that depend on the crawler and the gait: a method that can simulate
    its stiction, and an ``initial_stuck`` body at rest at t = 0 (``Stepper``'s checks, named
    under scene.run)."""
    try:
        check_stiction(crawler, run.method)
    except ValueError as exc:
        raise SceneError(f'scene.run.method: {exc}') from None
    try:
        check_initial_stuck(crawler, gait, 0.0, run.v0, run.initial_stuck)
    except ValueError as exc:
        raise SceneError(f'scene.run.{exc}') from None


_SCENE_KEYS = ('name', 'description', 'crawler', 'gait', 'run', 'bench')


def scene_from_dict(data: Any, *, name: str = 'scene') -> Scene:
    """Build a `Scene` from the mapping under ``scene:`` (or a mapping holding ``scene:``)."""
    if isinstance(data, Mapping) and set(data) == {'scene'}:
        data = data['scene']
    d = _mapping('scene', data, _SCENE_KEYS, ('crawler', 'gait'))
    name = d.get('name', name)
    description = d.get('description', '')
    for key, value in (('name', name), ('description', description)):
        if not isinstance(value, str):
            raise SceneError(f'scene.{key}: must be a string, got {value!r}')
    bench = d.get('bench') or {}
    if not isinstance(bench, Mapping):
        raise SceneError(f'scene.bench: must be a mapping (options of crawler_sim.bench), '
                         f'got {bench!r}')
    crawler = _crawler(d['crawler'])
    gait, gait_spec = _gait(d['gait'], crawler.p)
    run = _run(d.get('run'), crawler.p)
    try:
        # a length <= 0 within the run known from the gait's closed form: refused at load, so
        # every use of the scene (offline, --as-node, a sweep) says so before any work
        check_lengths(gait, 0.0, run.t_end)
    except GaitLengthError as exc:
        raise SceneError(f'scene.gait ({gait_spec["type"]}): {exc}') from None
    _check_run(crawler, gait, run)
    return Scene(name=name, crawler=crawler, gait=gait, run=run,
                 gait_spec=gait_spec, description=description, bench=dict(bench))


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene YAML file.

    Raises
    ------
    OSError
        The file cannot be read (missing, a directory, no permission).
    SceneError
        Malformed YAML, no top-level ``scene:`` key, or an invalid field; the message starts
        with the file name.
    """
    path = Path(path)
    section = read_section(path, 'scene', 'a scene', SceneError)
    try:
        return scene_from_dict(section, name=path.stem)
    except SceneError as exc:
        raise SceneError(f'{path}: {exc}') from None


def read_text(path: Path, most: int, what: str, error: type[Exception]) -> str:
    """The UTF-8 text of ``path``, reading at most ``most`` bytes (a huge file or a device is
    not read): more, or bytes that are not UTF-8, raise ``error`` naming the file (``what`` is
    the file's kind in the message, e.g. 'scene file')."""
    with open(path, 'rb') as fh:
        raw = fh.read(most + 1)
    if len(raw) > most:
        raise error(f'{path}: {what} must have at most {most} bytes, got more')
    try:
        return raw.decode('utf-8')
    except UnicodeDecodeError as exc:
        raise error(f'{path}: not UTF-8 text ({exc.reason} at byte {exc.start})') from None


def read_section(path: Path, key: str, kind: str, error: type[Exception]) -> Any:
    """The value under the top-level ``key`` of the YAML file ``path`` (safe loader, YAML 1.2
    floats). Malformed YAML or a missing key raise ``error`` naming the file, and the line
    and column where known (OSError if the file cannot be read).
    """
    text = read_text(path, MAX_SCENE_BYTES, f'{kind} file', error)
    try:
        data = yaml.load(text, Loader=YamlLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        problem = getattr(exc, 'problem', None) or str(exc).splitlines()[0]
        raise error(f'{path}: invalid YAML{where}: {problem}') from None
    if not isinstance(data, Mapping) or key not in data:
        raise error(f'{path}: not {kind} file (no top-level "{key}:" key)')
    return data[key]


def scene_to_dict(scene: Scene) -> dict:
    """Plain data (lists, floats, str, bool, None) that `scene_from_dict` turns back into an
    equal scene; friction is given as forces so the crawler is rebuilt bit for bit."""
    return {'name': scene.name, 'description': scene.description,
            'crawler': scene.crawler.to_dict(),
            'gait': dict(scene.gait_spec), 'run': scene.run.to_dict(),
            **({'bench': dict(scene.bench)} if scene.bench else {})}
