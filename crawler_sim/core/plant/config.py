"""The plant's parameters (the crawler, its actuator, the integration grid) and their validation.

``PARAMETERS`` are the node's physical parameters (sim_node declares them, adding its own for
outputs and recording); ``PlantConfig.from_values`` validates a full set of their values and
turns it into core objects. It is the one reader of these values: sim_node on every parameter
change, ``crawler-sim replay`` on a bag's recorded parameters, offline runs "as the node runs
them". The crawler itself is validated by ``scene.crawler_from_mapping``, as in scenes.

The defaults are the seed's crawler: two bodies (a 0.5 kg head and a 1 kg tail, friction
coefficient 0.3, i.e. friction forces proportional to weight) joined by one linkage. Every
per-body or per-linkage list accepts one entry meaning "the same for all".
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping, Sequence

from ..actuator import ActuatorLimits
from ..friction import DEFAULT_RULE, RULES, check_rule
from ..model import Crawler
from ..scene import FRICTION_KEYS, LIMITS, crawler_from_mapping
from ..stepper import METHODS, check_stiction
from ..simtime import NS_PER_S
from .engine import EngineConfig

__all__ = ['PARAMETERS', 'PlantConfig', 'MAX_BODIES', 'LATER_PARAMETERS', 'as_float']

#: the most bodies the live node takes, chosen from measurement: at p = 64 sim_node (exact,
#: 1 kHz ticks, every output at 100 Hz with a subscriber) keeps a real-time factor of 1.000 on
#: 21 % of one core and runs 9.6x real time flat out (`python -m benchmarks.node --bodies 64
#: --only realtime,flat`); each tick's work grows with p, so the limit keeps one message or
#: parameter from freezing the node. Offline runs take any p.
MAX_BODIES = 64

#: name -> (default, description, range of a float or None)
PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None]] = {
    'masses': ([0.5, 1.0], f'Body masses [kg], 2 to {MAX_BODIES} entries, each in [1e-9, 1e9]; '
               'p sets the number of bodies (a change of p resets the simulation; the seed: '
               '2 bodies)', None),
    'mu': ([0.3], 'Coulomb friction coefficient against forward sliding, one entry for all '
           'bodies or one per body, each in [0, 1e3]: friction force = mu m g cos(slope) '
           '(unless friction is set)', None),
    'mu_backward': ([0.3], 'Coulomb friction coefficient against backward sliding (as mu)',
                    None),
    'friction': ([], 'Friction force resisting forward sliding [N], one entry for all bodies '
                 'or one per body, each in [0, 1e12]; empty (the default): from mu; when set '
                 'it replaces mu', None),
    'friction_backward': ([], 'Friction force resisting backward sliding [N] (as friction); '
                          'empty: from mu_backward', None),
    'mu_static': ([], 'Static (stiction) coefficient against forward sliding: a stuck body '
                  'holds while the force it needs is within it (as mu; each >= its mu); empty '
                  '(the default): mu, no stiction', None),
    'mu_static_backward': ([], 'Static coefficient against backward sliding (as mu_static, '
                           '>= mu_backward); empty: mu_backward', None),
    'static_friction': ([], 'Static friction force against forward sliding [N] (as friction, '
                        '>= the forward kinetic force); empty: from mu_static; when set it '
                        'replaces mu_static', None),
    'static_friction_backward': ([], 'Static friction force against backward sliding [N] (as '
                                 'static_friction); empty: from mu_static_backward', None),
    'stiction_rule': (DEFAULT_RULE, 'With static friction above kinetic: who holds when several '
                      'parts of the crawler come to rest at once, one of ' + ', '.join(RULES)
                      + ' (incumbent: the part stuck before holds first, then the largest '
                      'static margin; margin: the largest margin alone)', None),
    'slope': (0.0, 'Incline [rad], uphill is +x', (-1.5, 1.5)),
    'gravity': (9.81, 'Gravitational acceleration [m/s^2] (acts through the slope)',
                (0.0, 100.0)),
    'initial_lengths': ([0.1], 'Linkage lengths at start and after reset [m], one entry for '
                        'all linkages or p-1 entries, within [min_length, max_length]', None),
    'initial_position': (0.0, 'Position of body 0 at start and after reset [m]',
                         (-1e6, 1e6)),
    'integration_rate': (1000.0, 'Ticks per simulated second [Hz]; dt = 1/integration_rate',
                         (1.0, 100000.0)),
    'publish_rate': (100.0, 'Output (and /clock) rate [Hz] in sim time, <= integration_rate; '
                     'outputs go out every round(integration_rate/publish_rate) ticks',
                     (0.1, 100000.0)),
    'method': ('exact', 'Solver: exact (event driven), implicit (Moreau-Jean) or penalty',
               None),
    'penalty': ([10000.0], 'Method penalty only: the regularisation n [N s/m] of the seed, one '
                'entry for all bodies or one per body, each in [1e-6, 1e15] '
                '(error ~ sqrt(t f^2 / (M n)))', None),
    'actuator_bandwidth': (5.0, 'Actuator -3 dB bandwidth [Hz] (critically damped 3rd order)',
                           (0.01, 1000.0)),
    'actuator_max_speed': (0.5, 'Largest |l\'| of a linkage [m/s]', (1e-6, 100.0)),
    'actuator_max_acceleration': (5.0, 'Largest |l\'\'| of a linkage [m/s^2]', (1e-6, 1e5)),
    'min_length': (0.02, 'Shortest linkage length [m]: commands and trajectory points outside '
                   '[min_length, max_length] are rejected, and the actuator keeps the length '
                   'inside it', (0.0, 100.0)),
    'max_length': (0.5, 'Longest linkage length [m]', (0.0, 100.0)),
    'max_trajectory_lead': (3600.0, 'A stamped linkage_trajectory must start within this many '
                            'seconds of the current sim time [s] (a wall-clock stamp on sim '
                            'time is rejected, not held for decades)', (0.0, 1e6)),
}


def as_float(name: str, value: Any, rng: tuple[float, float]) -> float:
    """A number (an int is a number too) in ``rng``; ValueError naming ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f'{name} must be a number in [{rng[0]:g}, {rng[1]:g}], got '
                         f'{_short(value)}')
    x = float(value)
    if not (math.isfinite(x) and rng[0] <= x <= rng[1]):
        raise ValueError(f'{name} must be in [{rng[0]:g}, {rng[1]:g}], got {value!r}')
    return x


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters (a 10^6-entry list is not a message)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 5] + ' ...' + text[-1]


def _as_list(name: str, value: Any, n_max: float) -> list[float]:
    """A number or a list of numbers as a list of floats (at most ``n_max`` entries)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return [float(value)]
    try:
        out = list(value)
    except TypeError:
        raise ValueError(f'{name} must be a number or a list of numbers, got '
                         f'{_short(value)}') from None
    if len(out) > n_max:
        raise ValueError(f'{name} must have at most {n_max} entries, got {len(out)}')
    if any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in out):
        raise ValueError(f'{name} must be a list of numbers, got {_short(value)}')
    return [float(x) for x in out]


#: the friction parameters, as (coefficients, forces [N]) per bound: kinetic forward, kinetic
#: backward, static forward, static backward (``scene.FRICTION_KEYS``)
_BOUNDS = tuple(zip(FRICTION_KEYS['mu'], FRICTION_KEYS['friction']))
#: the parameters added after sim_node bags began: a bag recorded without them ran with these
#: values (their defaults: no stiction), so its journal still replays
LATER_PARAMETERS = ('mu_static', 'mu_static_backward', 'static_friction',
                    'static_friction_backward', 'stiction_rule')


def _crawler(v: Mapping[str, Any]) -> Crawler:
    """The crawler of the node's parameters (``scene.crawler_from_mapping``): each bound
    (kinetic and static, forward and backward) as forces where they are set, else from its
    coefficients; an empty static bound is `Crawler`'s default (its kinetic bound)."""
    masses = _as_list('masses', v['masses'], math.inf)
    if not 2 <= len(masses) <= MAX_BODIES:
        raise ValueError(f'masses must list 2 to {MAX_BODIES} bodies (the live node\'s limit; '
                         f'offline runs take any number), got {len(masses)}')
    spec: dict[str, Any] = {'masses': masses, 'slope': v['slope'], 'gravity': v['gravity']}
    coeffs = {mu: _as_list(mu, v[mu], MAX_BODIES) for mu, _ in _BOUNDS}
    forces = {f: _as_list(f, v[f], MAX_BODIES) for _, f in _BOUNDS}
    if not any(forces.values()):
        return crawler_from_mapping({**spec, **{mu: c for mu, c in coeffs.items()
                                                if c or mu in ('mu', 'mu_backward')}}, '')
    # some bounds as forces: the others' forces first, from their coefficients (a bound given
    # as a force is 0 here, so the static >= kinetic check sees only coefficients given)
    need = {mu: coeffs[mu] for mu, f in _BOUNDS
            if not forces[f] and (coeffs[mu] or mu in ('mu', 'mu_backward'))}
    if need:
        kinetic = {mu: need.get(mu, 0.0) for mu in ('mu', 'mu_backward')}
        coeff = crawler_from_mapping({**spec, **kinetic, **{mu: c for mu, c in need.items()
                                                            if mu not in kinetic}}, '')
        of = {'mu': coeff.friction, 'mu_backward': coeff.friction_backward,
              'mu_static': coeff.static_friction,
              'mu_static_backward': coeff.static_friction_backward}
        for mu, f in _BOUNDS:
            if mu in need:
                forces[f] = of[mu].tolist()
    try:
        return crawler_from_mapping({**spec, **{f: x for f, x in forces.items() if x}}, '')
    except ValueError as exc:       # a bound converted from a coefficient: name that one
        field = str(exc).split('[')[0].split(':')[0].split(' ')[0]      # the field it names
        mu = next((mu for mu, f in _BOUNDS if mu in need and field == f), None)
        if mu is None:
            raise
        raise ValueError(f'{mu} (as forces, {mu} m g cos(slope)): {exc}') from None


@dataclass(frozen=True)
class PlantConfig:
    """The plant's parameters validated: the crawler, the actuator, the tick grid. Every
    parameter value is also a plain attribute (``cfg.publish_rate``); ``values`` holds them."""

    values: dict
    crawler: Crawler
    initial_lengths: tuple[float, ...]
    limits: ActuatorLimits
    dt_ns: int
    publish_every: int

    @property
    def p(self) -> int:
        """Number of bodies."""
        return self.crawler.p

    @property
    def n_links(self) -> int:
        """Number of linkages (p - 1)."""
        return self.crawler.p - 1

    @property
    def penalty_n(self) -> list[float] | None:
        """The ``penalty`` argument of ``Stepper`` (None unless method is penalty)."""
        if self.values['method'] != 'penalty':
            return None
        n = _as_list('penalty', self.values['penalty'], MAX_BODIES)
        return n * self.p if len(n) == 1 else n

    def engine_config(self) -> EngineConfig:
        """The part of the configuration the plant's engine uses."""
        v = self.values
        return EngineConfig(self.crawler, v['method'], self.dt_ns, self.publish_every,
                            self.initial_lengths, float(v['initial_position']), self.limits,
                            self.penalty_n, {name: v[name] for name in PARAMETERS},
                            v['stiction_rule'])

    def __post_init__(self) -> None:
        for name, value in self.values.items():
            if name not in self.__dict__ and not hasattr(type(self), name):
                object.__setattr__(self, name, value)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> PlantConfig:
        """Validate a full set of parameter values (at least every name of ``PARAMETERS``);
        raise ValueError naming the field and the allowed range."""
        v = dict(values)
        for name, (default, _, rng) in PARAMETERS.items():
            if name not in v:
                raise ValueError(f'missing parameter {name}')
            if rng is not None:
                v[name] = as_float(name, v[name], rng)
        crawler = _crawler(v)
        p = crawler.p
        pen = _as_list('penalty', v['penalty'], MAX_BODIES)
        lo_n, hi_n, _ = LIMITS['penalty']
        if len(pen) not in (1, p) or not all(lo_n <= n <= hi_n for n in pen):
            raise ValueError(f'penalty must have 1 or {p} entries, each in [{lo_n:g}, '
                             f'{hi_n:g}] N s/m, got {_short(pen)}')
        if not isinstance(v['method'], str) or v['method'] not in METHODS:   # (a recorded list)
            raise ValueError(f'method must be one of {", ".join(METHODS)}, got {v["method"]!r}')
        if not isinstance(v['stiction_rule'], str):       # (a list is unhashable)
            raise ValueError(f'stiction_rule must be one of {", ".join(RULES)}, got '
                             f'{_short(v["stiction_rule"])}')
        check_rule(v['stiction_rule'])
        check_stiction(crawler, v['method'])
        lo, hi = v['min_length'], v['max_length']
        if not lo < hi:
            raise ValueError(f'min_length ({lo}) must be < max_length ({hi})')
        lengths = _as_list('initial_lengths', v['initial_lengths'], MAX_BODIES)
        if len(lengths) == 1:
            lengths = lengths * (p - 1)
        if len(lengths) != p - 1:
            raise ValueError(f'initial_lengths must have 1 or {p - 1} entries (p-1 linkages), '
                             f'got {len(lengths)}')
        for j, x in enumerate(lengths):
            if not (math.isfinite(x) and lo <= x <= hi):
                raise ValueError(f'initial_lengths[{j}] = {x} outside [min_length, max_length]'
                                 f' = [{lo}, {hi}]')
        rate, pub = v['integration_rate'], v['publish_rate']
        if pub > rate:
            raise ValueError(f'publish_rate ({pub} Hz) must be <= integration_rate ({rate} Hz)')
        limits = ActuatorLimits(v['actuator_bandwidth'], v['actuator_max_speed'],
                                v['actuator_max_acceleration'], lo, hi)
        for name in ('masses', *(n for pair in _BOUNDS for n in pair), 'penalty',
                     'initial_lengths'):
            v[name] = _as_list(name, v[name], MAX_BODIES)
        return cls(v, crawler, tuple(lengths), limits, max(1, round(NS_PER_S / rate)),
                   max(1, round(rate / pub)))

    @classmethod
    def for_crawler(cls, crawler: Crawler, lengths: Sequence[float],
                    limits: ActuatorLimits | None = None, **overrides: Any) -> PlantConfig:
        """The plant of sim_node with this crawler (friction as forces [N]), at rest with
        linkage lengths ``lengths`` [m], the actuator ``limits`` (default: the node's), and
        the node's defaults for the rest (``overrides`` replace them). The length limits are
        widened, when needed, to [0.05, 2] x the given lengths (a stroke of the optimiser's
        families stays inside them)."""
        limits = limits or ActuatorLimits()
        lo, hi = PARAMETERS['min_length'][0], PARAMETERS['max_length'][0]
        values: dict[str, Any] = {
            'masses': crawler.masses.tolist(), 'friction': crawler.friction.tolist(),
            'friction_backward': crawler.friction_backward.tolist(),
            'static_friction': crawler.static_friction.tolist(),
            'static_friction_backward': crawler.static_friction_backward.tolist(),
            'slope': float(crawler.slope), 'gravity': float(crawler.gravity),
            'initial_lengths': [float(x) for x in lengths],
            'min_length': min(lo, 0.05 * min(lengths)), 'max_length': max(hi, 2 * max(lengths)),
            'actuator_bandwidth': float(limits.bandwidth),
            'actuator_max_speed': float(limits.max_speed),
            'actuator_max_acceleration': float(limits.max_acceleration)}
        values.update(overrides)
        return cls.defaults(**values)

    @classmethod
    def defaults(cls, **overrides: Any) -> PlantConfig:
        """The default parameters (the seed's crawler) with ``overrides``."""
        values = {name: default for name, (default, _, _) in PARAMETERS.items()}
        values.update(overrides)
        return cls.from_values(values)
