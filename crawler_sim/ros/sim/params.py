"""sim_node parameters: declarations, descriptors, validation to a :class:`SimConfig`.

The defaults are the seed's crawler: two bodies (a 0.5 kg head and a 1 kg tail, friction
coefficient 0.3, i.e. friction forces proportional to weight) joined by one linkage, so
``linkage_cmd`` takes ONE length. Every per-body or per-linkage list accepts one
entry meaning "the same for all", so changing the number of bodies at run time is a single
``masses`` change (``ros2 param set /crawler_sim masses "[1.0, 1.0, 1.0]"``).

Validation covers single values (ranges in the descriptors, enforced by rclpy) and derived
quantities (list lengths against ``masses``, sums and products that could overflow), so a
configuration that is accepted never gives non-finite outputs.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from crawler_sim.bag.naming import check_record_name
from crawler_sim.core.actuator import ActuatorLimits
from crawler_sim.core.engine import EngineConfig
from crawler_sim.core.model import Crawler
from crawler_sim.core.stepper import METHODS

__all__ = ['PARAMETERS', 'OUTPUTS', 'SimConfig', 'descriptor', 'declare_all']

#: largest body mass, friction force and sum of them accepted [kg, N]: far beyond any crawler,
#: far below float overflow (a sum of p such values times g stays finite)
MAX_VALUE = 1e9

#: name -> (default, description, range or None, read_only)
PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None, bool]] = {
    'masses': ([0.5, 1.0], 'Body masses [kg], p >= 2 entries, each in (0, 1e9]; p sets the '
               'number of bodies (a change of p resets the simulation; the seed: 2 bodies)',
               None, False),
    'mu': ([0.3], 'Coulomb friction coefficient against forward sliding, one entry for all '
           'bodies or one per body, each in [0, 1e3]: friction force = mu m g cos(slope) '
           '(unless friction is set)', None, False),
    'mu_backward': ([0.3], 'Coulomb friction coefficient against backward sliding (as mu)',
                    None, False),
    'friction': ((), 'Friction force resisting forward sliding [N], one entry for all bodies '
                 'or one per body, each in [0, 1e9]; when set (non-empty) it replaces mu',
                 None, False),
    'friction_backward': ((), 'Friction force resisting backward sliding [N] (as friction); '
                          'when set it replaces mu_backward', None, False),
    'slope': (0.0, 'Incline [rad], uphill is +x', (-1.5, 1.5), False),
    'gravity': (9.81, 'Gravitational acceleration [m/s^2] (acts through the slope)',
                (0.0, 100.0), False),
    'initial_lengths': ([0.1], 'Linkage lengths at start and after reset [m], one entry for '
                        'all linkages or p-1 entries, within [min_length, max_length]',
                        None, False),
    'initial_position': (0.0, 'Position of body 0 at start and after reset [m]',
                         (-1e6, 1e6), False),
    'integration_rate': (1000.0, 'Ticks per simulated second [Hz]; dt = 1/integration_rate',
                         (1.0, 100000.0), False),
    'publish_rate': (100.0, 'Output (and /clock) rate [Hz] in sim time, <= integration_rate; '
                     'outputs go out every round(integration_rate/publish_rate) ticks',
                     (0.1, 100000.0), False),
    'method': ('exact', 'Solver: exact (event driven), implicit (Moreau-Jean) or penalty',
               None, False),
    'penalty': ([10000.0], 'Method penalty only: the regularisation n [N s/m] of the seed, one '
                'entry for all bodies or one per body, each in (0, 1e9] '
                '(error ~ sqrt(t f^2 / (M n)))', None, False),
    'actuator_bandwidth': (5.0, 'Actuator -3 dB bandwidth [Hz] (critically damped 3rd order)',
                           (0.01, 1000.0), False),
    'actuator_max_speed': (0.5, 'Largest |l\'| of a linkage [m/s]', (1e-6, 100.0), False),
    'actuator_max_acceleration': (5.0, 'Largest |l\'\'| of a linkage [m/s^2]',
                                  (1e-6, 1e5), False),
    'min_length': (0.02, 'Shortest commandable linkage length [m]', (0.0, 100.0), False),
    'max_length': (0.5, 'Longest commandable linkage length [m]', (0.0, 100.0), False),
    'real_time_factor': (1.0, 'Sim seconds per wall second: 1 real time, 10 ten times faster, '
                         '0 as fast as possible', (0.0, 1000.0), False),
    'publish_clock': (True, 'Publish /clock (sim time, every publish tick) so that other '
                      'nodes, RViz and Foxglove can use_sim_time (as Gazebo does)', None, False),
    'publish_joint_states': (True, 'Publish joint_states', None, False),
    'publish_body_states': (True, 'Publish body_states', None, False),
    'publish_contact_states': (True, 'Publish contact_states (std_msgs/Int8MultiArray)',
                               None, False),
    'publish_contacts_stamped': (True, 'Publish contacts (sensor_msgs/JointState, stamped: '
                                 'name body_i, position = contact state -1/0/+1, effort = '
                                 'friction force [N])', None, False),
    'publish_odom': (True, 'Publish odom', None, False),
    'publish_markers': (True, 'Publish markers', None, False),
    'publish_diagnostics': (True, 'Publish /diagnostics', None, False),
    'diagnostics_period': (1.0, 'Wall seconds between /diagnostics messages',
                           (0.05, 3600.0), False),
    'max_trajectory_lead': (3600.0, 'A stamped linkage_trajectory must start within this many '
                            'seconds of the current sim time [s] (a wall-clock stamp on sim '
                            'time is rejected, not held for decades)', (0.0, 1e6), False),
    'start_paused': (False, 'Start paused (~/pause false starts the clock), so that controllers '
                     'and recorders can connect first', None, True),
    'record': (False, 'Record inputs and outputs to an MCAP bag (crawler_sim.bag)', None, True),
    'record_dir': ('runs', 'Directory for new bags', None, True),
    'record_name': ('', 'Bag name under record_dir (empty: crawler_sim_<date>-<time>)',
                    None, True),
}
#: the outputs in publishing order (diagnostics last: it is not on the publish grid)
OUTPUTS = ('joint_states', 'body_states', 'contact_states', 'contacts_stamped', 'odom',
           'markers', 'diagnostics')


def descriptor(name: str):
    """The ParameterDescriptor of parameter ``name`` (description, range, read-only)."""
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
    default, desc, rng, ro = PARAMETERS[name]
    d = ParameterDescriptor(description=desc, read_only=ro)
    if rng is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(rng[0]),
                                                     to_value=float(rng[1]), step=0.0)]
    if name == 'method':
        d.additional_constraints = 'one of: ' + ', '.join(METHODS)
    return d


def declare_all(node) -> dict[str, Any]:
    """Declare every parameter on ``node``; return the values (overrides applied)."""
    from rclpy.parameter import Parameter
    for name, (default, *_rest) in PARAMETERS.items():
        if default == ():         # a double array without a value until it is set
            default = Parameter.Type.DOUBLE_ARRAY
        node.declare_parameter(name, default, descriptor(name))
    return {name: node.get_parameter_or(name).value for name in PARAMETERS}


def _per_body(name: str, values, p: int, lo: float, hi: float, lo_open: bool = False
              ) -> list[float]:
    vals = [float(x) for x in values]
    if len(vals) not in (1, p):
        raise ValueError(f'{name} must have 1 or {p} entries (one per body, p = {p} from '
                         f'masses), got {len(vals)}')
    for i, x in enumerate(vals):
        ok = math.isfinite(x) and (lo < x if lo_open else lo <= x) and x <= hi
        if not ok:
            bracket = '(' if lo_open else '['
            raise ValueError(f'{name}[{i}] = {x!r} outside {bracket}{lo:g}, {hi:g}]')
    return vals


@dataclass(frozen=True)
class SimConfig:
    """The node's parameters, validated and turned into core objects (the one place that reads
    parameter values). Every parameter value is also a plain attribute (``cfg.publish_rate``)."""

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
        return [float(n) for n in self.values['penalty']] if self.method == 'penalty' else None

    def engine_config(self) -> EngineConfig:
        """The part of the configuration the integration loop (``engine.Engine``) uses."""
        return EngineConfig(self.crawler, self.method, self.dt_ns, self.publish_every,
                            self.initial_lengths, self.initial_position, self.limits,
                            self.penalty_n)

    def __post_init__(self) -> None:
        for name, value in self.values.items():
            if name not in self.__dict__ and not hasattr(type(self), name):
                object.__setattr__(self, name, value)

    @classmethod
    def from_values(cls, values: dict) -> SimConfig:
        """Validate a full set of parameter values; raise ValueError naming the field and the
        allowed range."""
        v = dict(values)
        for name, (default, _, rng, _) in PARAMETERS.items():
            if name not in v:
                raise ValueError(f'missing parameter {name}')
            if rng is not None:
                x = v[name]
                if not (isinstance(x, float) and math.isfinite(x) and rng[0] <= x <= rng[1]):
                    raise ValueError(f'{name} must be a float in [{rng[0]}, {rng[1]}], got {x!r}')
        p = len(v['masses'])
        if p < 2:
            raise ValueError(f'masses must list p >= 2 bodies, got {p}')
        masses = _per_body('masses', v['masses'], p, 0.0, MAX_VALUE, lo_open=True)
        weight = [m * v['gravity'] * math.cos(v['slope']) for m in masses]
        forces = []
        for force, coeff in (('friction', 'mu'), ('friction_backward', 'mu_backward')):
            if v[force]:
                forces.append(_per_body(force, v[force], p, 0.0, MAX_VALUE))
            else:
                mu = _per_body(coeff, v[coeff], p, 0.0, 1e3)
                mu = mu * p if len(mu) == 1 else mu
                forces.append([mu_i * w for mu_i, w in zip(mu, weight)])
        fwd, bwd = forces
        # derived quantities: the total mass and the largest weight component must be finite
        # (each value being finite is not enough once they are summed and multiplied)
        if not math.isfinite(sum(masses) * max(v['gravity'], 1.0)):
            raise ValueError(f'masses sum to {sum(masses)!r} kg: the total weight overflows')
        _per_body('penalty', v['penalty'], p, 0.0, MAX_VALUE, lo_open=True)
        if v['method'] not in METHODS:
            raise ValueError(f'method must be one of {", ".join(METHODS)}, got {v["method"]!r}')
        if v['record_name']:      # a bag name stays inside record_dir: refused before the run
            check_record_name(v['record_name'])
        crawler = Crawler(masses, fwd, bwd, v['slope'], v['gravity'])
        lo, hi = v['min_length'], v['max_length']
        if not lo < hi:
            raise ValueError(f'min_length ({lo}) must be < max_length ({hi})')
        lengths = [float(x) for x in v['initial_lengths']]
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
                                v['actuator_max_acceleration'])
        return cls(v, crawler, tuple(lengths), limits, max(1, round(1e9 / rate)),
                   max(1, round(rate / pub)))
