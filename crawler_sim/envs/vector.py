"""``CrawlVectorEnv``: N crawlers of ``crawler_sim/Crawl-v0`` stepped together (its registered
``vector_entry_point``).

Each sub-environment is the single environment's ``CrawlPlant``, seeded as a single env would
be: reset with seed s, env i draws from ``seeding.np_random(s + i)``, so it behaves bit for bit
like ``CrawlEnv`` reset with seed s + i until its first termination or truncation (then it is
reset from its own generator, as a single env reset without a seed). Gymnasium 1.x autoreset,
``NEXT_STEP``: the step after an episode ended resets that env, ignores its action and returns
its first observation with reward 0, not terminated, not truncated.

The plants are rows of one ``_rows.EnvRows``: the step is one compiled loop over them, each
through its engine's compiled step (``core/plant/_batch``, sim_node's plant), the same code a
single env's step runs (docs/gym.md, Speed).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
import numpy as np
from numpy.typing import NDArray

from . import MAX_EPISODE_STEPS
from .plant import CrawlPlant, check_action
from .render import draw

__all__ = ['CrawlVectorEnv']


class CrawlVectorEnv(VectorEnv):
    """``num_envs`` crawlers with the keyword arguments of ``CrawlEnv`` (the same for all;
    ``randomize`` draws each env's crawler from its own seed), truncated after
    ``max_episode_steps`` control periods (the registered id's: 1000)."""

    metadata = {'render_modes': ['rgb_array'], 'autoreset_mode': AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, crawler: Mapping[str, Any] | None = None, *,
                 max_episode_steps: int | None = MAX_EPISODE_STEPS,
                 render_mode: str | None = None, **plant: Any) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) \
                or not 1 <= num_envs <= 1_000_000:
            raise ValueError(f'num_envs must be an integer in [1, 1000000], got {num_envs!r}')
        if max_episode_steps is not None and (
                isinstance(max_episode_steps, bool)
                or not isinstance(max_episode_steps, (int, np.integer)) or max_episode_steps < 1):
            raise ValueError(f'max_episode_steps must be an integer >= 1 or None, got '
                             f'{max_episode_steps!r}')
        if render_mode not in (None, 'rgb_array'):
            raise ValueError(f'render_mode must be None or "rgb_array", got {render_mode!r}')
        self.num_envs = int(num_envs)
        self.render_mode = render_mode
        self.max_episode_steps = max_episode_steps
        first = CrawlPlant(crawler, **plant)      # checks the arguments once
        self.plants = [first] + [CrawlPlant(crawler, **plant) for _ in range(num_envs - 1)]
        self._rows = first.rows(self.num_envs)
        for i, pl in enumerate(self.plants):
            pl.bind(self._rows, i)
        n = first.n_links
        self.control_period = first.control_period
        self.single_action_space = spaces.Box(-1.0, 1.0, (n,), np.float64)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (first.obs_size,),
                                                   np.float64)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.metadata = {**self.metadata, 'render_fps': 1.0 / self.control_period}
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._rngs: list[np.random.Generator] = [seeding.np_random()[0]
                                                  for _ in range(self.num_envs)]
        for pl in self.plants:
            pl.reset(None)

    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float64], dict]:
        """Every env at rest; ``seed`` s seeds env i with s + i (a list: one seed each)."""
        if seed is None:
            seeds: Sequence[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f'seed must be an int, None or {self.num_envs} seeds, got '
                                 f'{len(seeds)}')
        for i, s in enumerate(seeds):
            if s is not None:
                self._rngs[i] = seeding.np_random(s)[0]
            self.plants[i].reset(self._rngs[i])
        self._steps[:] = 0
        self._autoreset[:] = False
        return self._rows.obs.copy(), self._infos(np.zeros(self.num_envs))

    def step(self, actions: Any) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                          NDArray[np.bool_], NDArray[np.bool_], dict]:
        """One control period of every env (NEXT_STEP autoreset, module doc)."""
        acts = check_action(actions, (self.num_envs, self.plants[0].n_links))
        rows = self._rows
        resets = self._autoreset.nonzero()[0].tolist()
        engines = [pl.engine for pl in self.plants]
        for i in resets:
            engines[i] = None            # not stepped: reset below
        rows.step(engines, np.ascontiguousarray(acts))
        rewards, speeds = rows.reward.copy(), rows.speed.copy()
        terminated = rows.failed.copy()
        for i in resets:
            self.plants[i].reset(self._rngs[i])
        rewards[resets] = 0.0
        speeds[resets] = 0.0
        terminated[resets] = False
        self._steps[resets] = -1
        self._steps += 1
        truncated = (self._steps >= self.max_episode_steps) if self.max_episode_steps \
            else np.zeros(self.num_envs, dtype=bool)
        truncated &= ~self._autoreset
        self._autoreset = terminated | truncated
        return rows.obs.copy(), rewards, terminated, truncated, self._infos(speeds)

    def _infos(self, speeds: NDArray[np.float64]) -> dict[str, Any]:
        mask = np.ones(self.num_envs, dtype=bool)
        return {'x_position': self._rows.com.copy(), '_x_position': mask,
                'x_velocity': speeds, '_x_velocity': mask}

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """rgb_array: one image per env (``render.draw``)."""
        if self.render_mode != 'rgb_array':
            return None
        return tuple(draw(pl.x, pl.contact, pl.masses, 2.0 * pl.max_length * pl.p)
                     for pl in self.plants)
