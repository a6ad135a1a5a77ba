"""One crawler of an environment, driven through sim_node's plant (``core.plant.Engine``).

``CrawlPlant`` holds what the single environment (``CrawlEnv``) and the vector environment
(``CrawlVectorEnv``) share: the configuration (the crawler as in scene files, the actuator,
the tick grid), the seeded reset (domain randomisation), the step (``Engine.command`` and
``Engine.run_to`` a control period, then the state read) and the observation. Its episode's
numbers are a row of ``_rows.EnvRows``, whose compiled step (the plant's own compiled step,
``core/plant/_batch``, then the reward and the observation) both environments run: a single
env its own row, the vector env all its rows in one call. So env i of a vector reset with
seed s is, bit for bit, a single env reset with seed s + i.

No gymnasium and no ROS here (only the core): the observation and reward rules have one home
(``_rows``).

Choices (docs/gym.md):

- action: one number per linkage in [-1, 1] (clipped), the target length
  ``min_length + (a + 1) / 2 (max_length - min_length)`` [m] sent as sim_node's
  ``linkage_cmd`` at the start of the control period (``Engine.command``);
- observation (float64), for p bodies and n = p - 1 linkages: lengths l [m] (n), rates l'
  [m/s] (n), actuator accelerations l'' [m/s^2] (n), the commanded targets [m] (n), body
  velocities v [m/s] (p), contact states (p; +1 sliding forward, 0 stuck, -1 backward): the
  plant's whole state but the absolute position, which is in ``info`` (as Swimmer does);
- reward: ``forward_reward_weight`` x the centre of mass's mean forward speed over the
  period [m/s] minus ``ctrl_cost_weight`` x sum(action^2);
- the plant's grid: ticks at ``integration_rate`` [Hz], the state integrated exactly once a
  control period (the publish grid of a sim_node with ``publish_rate = 1 / control_period``).
"""
from __future__ import annotations

from dataclasses import replace
import math
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

from ..core.actuator import ActuatorLimits
from ..core.plant.config import PARAMETERS, PlantConfig, as_float
from ..core.plant.engine import Engine, Journal
from ..core.scene import crawler_from_mapping
from ._rows import EnvRows

__all__ = ['CrawlPlant', 'SEED_CRAWLER', 'check_action']

#: the seed's crawler: sim_node's default parameters (config/scenes/scallop_2body.yaml's too)
SEED_CRAWLER: dict[str, Any] = {name: PARAMETERS[name][0]
                                for name in ('masses', 'mu', 'mu_backward')}

#: keys of a crawler mapping drawn again under domain randomisation: the masses and every
#: friction entry (coefficients or forces, sliding or static: each a per-body quantity > 0)
_RANDOMISED = ('masses', 'mu', 'friction', 'static')


def _randomised(key: str) -> bool:
    return key == 'masses' or any(word in key for word in _RANDOMISED[1:])


#: actions of up to this many numbers are checked and clipped in Python floats
_SMALL = 16


def check_action(action: Any, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """``action`` as float64 of ``shape``, clipped to [-1, 1]; ValueError naming the field for a
    wrong shape or a value that is not finite (NaN would reach the plant as a NaN length)."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f'action must be numbers in [-1, 1] of shape {shape}, got '
                         f'{action!r:.80}') from None
    if a.shape != shape:
        if a.size == math.prod(shape):
            a = a.reshape(shape)
        else:
            raise ValueError(f'action must have shape {shape} (values in [-1, 1]), got shape '
                             f'{a.shape}')
    if a.size <= _SMALL:
        # a single env's action: clipped in Python floats (np.isfinite and np.clip cost more
        # than the step's plant work on a few numbers; the same values, bit for bit)
        vals = a.ravel().tolist()
        if all(map(math.isfinite, vals)):
            out = np.array([-1.0 if x < -1.0 else 1.0 if x > 1.0 else x for x in vals])
            return out if len(shape) == 1 else out.reshape(shape)
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f'action{list(bad.tolist())} must be finite, in [-1, 1], got '
                         f'{a[tuple(bad)]!r}')
    return np.clip(a, -1.0, 1.0)


class CrawlPlant:
    """One crawler on sim_node's plant, stepped one control period at a time.

    Parameters (checked here; ValueError naming the field and its allowed range):
    ``crawler``: a crawler mapping as in scene files (``scene.crawler_from_mapping``: masses,
    mu or friction, their backward and static variants, slope, gravity); default the seed's.
    ``control_period`` [s]: a whole number of ticks in [1/integration_rate, 10].
    ``min_length``, ``max_length`` [m]: the action's range (and the actuator's limits).
    ``initial_lengths`` [m]: one or one per linkage (default the middle of the range).
    ``integration_rate`` [Hz], ``actuator_bandwidth`` [Hz], ``actuator_max_speed`` [m/s],
    ``actuator_max_acceleration`` [m/s^2]: sim_node's parameters of the same names.
    ``randomize``: the relative spread r in [0, 0.9] of domain randomisation: at each reset
    each body's mass, and all its friction entries together, are multiplied by factors drawn
    uniformly in [1 - r, 1 + r] from the reset's generator (0: the crawler as given).
    ``journal``: sim_node's journal callback, handed to each episode's Engine.
    """

    #: whether each episode's Engine keeps its contact events (``Engine.pop_events``): off,
    #: since the env never pops them and an episode without end would keep them all; set it
    #: on a plant before a reset to inspect them
    keep_events = False

    def __init__(self, crawler: Mapping[str, Any] | None = None, *,
                 control_period: float = 0.04, min_length: float = 0.05,
                 max_length: float = 0.15, initial_lengths: Any = None,
                 integration_rate: float = 1000.0, actuator_bandwidth: float = 5.0,
                 actuator_max_speed: float = 0.5, actuator_max_acceleration: float = 5.0,
                 forward_reward_weight: float = 1.0, ctrl_cost_weight: float = 1e-4,
                 randomize: float = 0.0, journal: Journal | None = None) -> None:
        self.spec = dict(SEED_CRAWLER if crawler is None else crawler)
        self.base = crawler_from_mapping(self.spec, 'crawler')
        self.p = self.base.p
        self.n_links = self.p - 1
        rate = as_float('integration_rate', integration_rate, (1.0, 100000.0))
        period = as_float('control_period', control_period, (1.0 / rate, 10.0))
        ticks = round(period * rate)
        if abs(ticks / rate - period) > 1e-9 * period:
            raise ValueError(f'control_period must be a whole number of ticks of 1/'
                             f'integration_rate = {1.0 / rate:g} s, in [{1.0 / rate:g}, 10] s, '
                             f'got {control_period!r}')
        self.control_period = ticks / rate
        lo = as_float('min_length', min_length, (0.0, 100.0))
        hi = as_float('max_length', max_length, (0.0, 100.0))
        if not lo < hi:
            raise ValueError(f'min_length ({lo}) must be < max_length ({hi})')
        self.min_length, self.max_length = lo, hi
        if initial_lengths is None:
            initial_lengths = 0.5 * (lo + hi)
        lengths = np.atleast_1d(np.asarray(initial_lengths, dtype=float)).ravel().tolist()
        if len(lengths) == 1:
            lengths = lengths * self.n_links
        if len(lengths) != self.n_links:
            raise ValueError(f'initial_lengths must have 1 or {self.n_links} entries, got '
                             f'{len(lengths)}')
        limits = ActuatorLimits(actuator_bandwidth, actuator_max_speed,
                                actuator_max_acceleration, lo, hi)
        # the plant of a sim_node with these parameters (PlantConfig validates them as the
        # node does; its publish grid is the control period), running OUR crawler: the one of
        # the mapping, with every key it knows (stiction included)
        self.plant_config = PlantConfig.for_crawler(
            self.base, lengths, limits, min_length=lo, max_length=hi, integration_rate=rate,
            publish_rate=rate / ticks)
        self.engine_config = replace(self.plant_config.engine_config(), crawler=self.base)
        self.ticks = ticks
        self.period_ns = ticks * self.engine_config.dt_ns
        self.forward_reward_weight = as_float('forward_reward_weight', forward_reward_weight,
                                              (-1e9, 1e9))
        self.ctrl_cost_weight = as_float('ctrl_cost_weight', ctrl_cost_weight, (0.0, 1e9))
        self.randomize = as_float('randomize', randomize, (0.0, 0.9))
        self.journal = journal
        self.masses = self.base.masses
        self.mass = float(self.base.total_mass)
        self.engine: Engine | None = None
        # the episode's numbers: a row of compiled rows (``_rows.EnvRows``: the step, the
        # reward and the observation), its own or a vector env's (``bind``)
        self.bind(self.rows(1), 0)
        self.targets = lengths

    def rows(self, n: int) -> EnvRows:
        """New rows for ``n`` crawlers of this configuration (a vector env's, ``bind``)."""
        return EnvRows(n, self.p, self.min_length, 0.5 * (self.max_length - self.min_length),
                       self.period_ns, self.control_period, self.forward_reward_weight,
                       self.ctrl_cost_weight)

    def bind(self, rows: EnvRows, i: int) -> None:
        """Keep this crawler's numbers in row ``i`` of ``rows`` from now on (reset next)."""
        self._rows, self._i = rows, i
        # views of the row: the plant's x [m], v [m/s] and contact, refilled in place
        self.x, self.v, self.contact = rows.x[i], rows.v[i], rows.contact[i]

    @property
    def targets(self) -> list[float]:
        """The commanded target lengths [m] (the observation's)."""
        return self._rows.targets[self._i].tolist()

    @targets.setter
    def targets(self, lengths: Any) -> None:
        self._rows.targets[self._i] = lengths

    @property
    def com(self) -> float:
        """The centre of mass's position [m] after the last step (or reset)."""
        return float(self._rows.com[self._i])

    @property
    def failures(self) -> int:
        """The engine's failures counted by the last step (or reset)."""
        return int(self._rows.failures[self._i])

    @property
    def obs_size(self) -> int:
        """Length of the observation: 4 n + 2 p."""
        return 4 * self.n_links + 2 * self.p

    def crawler_for(self, rng: np.random.Generator | None) -> Any:
        """The crawler of an episode: the base one, or (``randomize`` = r > 0) its masses
        scaled by one factor per body and every friction entry of a body (forward, backward,
        static, coefficients or forces) by another, both drawn uniformly in [1 - r, 1 + r] from
        ``rng`` (masses first): one factor for all of a body's friction keeps their ratios
        (static >= sliding, forward / backward). Validated as a scene's crawler."""
        if not self.randomize or rng is None:
            return self.base
        r = self.randomize
        mass_f = rng.uniform(1.0 - r, 1.0 + r, self.p)
        friction_f = rng.uniform(1.0 - r, 1.0 + r, self.p)
        spec = {}
        for key, value in self.spec.items():
            if _randomised(key):
                arr = np.asarray(value, dtype=float)
                arr = np.broadcast_to(arr, (self.p,)) if arr.size == 1 else arr
                spec[key] = (arr * (mass_f if key == 'masses' else friction_f)).tolist()
            else:
                spec[key] = value
        return crawler_from_mapping(spec, 'crawler')

    def reset(self, rng: np.random.Generator | None) -> None:
        """A new episode: a new Engine at sim time 0, at rest (history never leaks in)."""
        crawler = self.crawler_for(rng)
        cfg = self.engine_config if crawler is self.base else replace(self.engine_config,
                                                                      crawler=crawler)
        self.masses = crawler.masses
        self.mass = float(crawler.total_mass)
        self.engine = Engine(cfg, 0, self.journal, keep_events=self.keep_events)
        rows, i = self._rows, self._i
        rows.masses[i] = self.masses
        rows.mass[i] = self.mass
        rows.targets[i] = cfg.initial_lengths
        rows.failures[i] = 0
        st = self.engine.state
        # the row's arrays, refilled in place each step (``Engine.read_state``)
        self.x[:] = st.x
        self.v[:] = st.v
        self.contact[:] = st.contact
        rows.com[i] = float(self.masses @ st.x) / self.mass
        rows.observe(i, self.engine)

    def lengths_of(self, action: NDArray[np.float64]) -> NDArray[np.float64]:
        """Target lengths [m] of a checked action in [-1, 1] (shape (n_links,)):
        min_length + (a + 1) (max_length - min_length) / 2 per linkage (``_rows``)."""
        return self._rows.lengths_of(action)

    def step(self, action: NDArray[np.float64]) -> tuple[float, float, bool]:
        """One control period with the checked ``action``: (reward, forward speed of the centre
        of mass [m/s], terminated). Terminated when the plant had to contain a solver failure
        (it restarts at rest, ``Engine._contain``): that episode's physics ended. The
        compiled step of the row (``_rows.EnvRows``; the vector env steps all its rows in
        one call of it)."""
        return self._rows.step_row(self._i, self.engine, action)

    def observe(self, out: NDArray[np.float64]) -> NDArray[np.float64]:
        """The observation (module doc) written into ``out`` (shape (obs_size,))."""
        out[:] = self._rows.obs[self._i]
        return out

    def observation(self) -> NDArray[np.float64]:
        """The observation (module doc) as a new array."""
        return self._rows.obs[self._i].copy()

    def info(self) -> dict[str, Any]:
        """What a policy must not see but a user wants: positions, time, failures."""
        return {'x_position': self.com, 'x': self.x.copy(), 't': self.engine.t,
                'failures': list(self.engine.failures)}
