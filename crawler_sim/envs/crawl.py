"""``CrawlEnv``: a Gymnasium environment of one friction crawler on sim_node's plant.

Registered as ``crawler_sim/Crawl-v0`` (``crawler_sim.envs.register_envs``; importing
crawler_sim registers it as soon as gymnasium is imported). The action, observation, reward
and plant grid are documented in ``crawler_sim.envs.plant`` and docs/gym.md; an episode ends by
truncation (``max_episode_steps``, 1000 control periods by default: 40 s at the default
``control_period`` of 0.04 s) or is terminated when the plant had to contain a solver failure.
"""
from __future__ import annotations

from typing import Any, Mapping

import gymnasium
from gymnasium import spaces
import numpy as np
from numpy.typing import NDArray

from .plant import CrawlPlant, check_action
from .render import draw

__all__ = ['CrawlEnv']


class CrawlEnv(gymnasium.Env):
    """p bodies on a line with exact Coulomb friction, linkage lengths commanded through the
    node's actuator. Keyword arguments: those of ``CrawlPlant`` (``crawler``, a scene file's
    crawler mapping; ``control_period`` [s], default 0.04; ``min_length``/``max_length`` [m],
    the action's range, default [0.05, 0.15]; ``initial_lengths``; ``integration_rate``;
    the actuator's limits; ``forward_reward_weight`` (default 1 per m/s);
    ``ctrl_cost_weight`` (default 1e-4); ``randomize``, the domain randomisation spread) and
    ``render_mode`` (None or "rgb_array")."""

    metadata = {'render_modes': ['rgb_array'], 'render_fps': 25}

    def __init__(self, crawler: Mapping[str, Any] | None = None, *,
                 render_mode: str | None = None, **plant: Any) -> None:
        if render_mode not in (None, 'rgb_array'):
            raise ValueError(f'render_mode must be None or "rgb_array", got {render_mode!r}')
        self.plant = CrawlPlant(crawler, **plant)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, 'render_fps': 1.0 / self.plant.control_period}
        n = self.plant.n_links
        self.action_space = spaces.Box(-1.0, 1.0, (n,), np.float64)
        self.observation_space = spaces.Box(-np.inf, np.inf, (self.plant.obs_size,),
                                            np.float64)
        self.plant.reset(None)

    @property
    def control_period(self) -> float:
        """Sim time of one step [s]."""
        return self.plant.control_period

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float64], dict]:
        """At rest with the initial lengths at sim time 0; the crawler drawn anew from the
        seeded generator when ``randomize`` > 0."""
        super().reset(seed=seed)
        self.plant.reset(self.np_random)
        return self.plant.observation(), self.plant.info()

    def step(self, action: Any) -> tuple[NDArray[np.float64], float, bool, bool, dict]:
        """One control period: the action's target lengths sent, the plant run to its end."""
        a = check_action(action, (self.plant.n_links,))
        reward, speed, failed = self.plant.step(a)
        info = self.plant.info()
        info['x_velocity'] = speed
        return self.plant.observation(), reward, failed, False, info

    def render(self) -> NDArray[np.uint8] | None:
        """rgb_array: the crawler now (``render.draw``); None without a render mode."""
        if self.render_mode != 'rgb_array':
            return None
        pl = self.plant
        return draw(pl.x, pl.contact, pl.masses, 2.0 * pl.max_length * pl.p)
