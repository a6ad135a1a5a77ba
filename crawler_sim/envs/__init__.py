"""Gymnasium environments of friction crawlers on sim_node's plant (no ROS import).

``crawler_sim/Crawl-v0``: ``CrawlEnv`` (``gymnasium.make``) and ``CrawlVectorEnv``, its
registered ``vector_entry_point`` (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``); docs/gym.md.

Importing crawler_sim does not import gymnasium (it would add ~35 ms to ~100 ms): it calls
``register_when_imported``, which registers the environment now if gymnasium is loaded, else
right after gymnasium's own import completes (a one-shot import hook). ``CrawlEnv`` and
``CrawlVectorEnv`` are imported from here on first use.
"""
from __future__ import annotations

import importlib.util
import sys
from typing import Any

__all__ = ['ENV_ID', 'CrawlEnv', 'CrawlVectorEnv', 'register_envs', 'register_when_imported']

ENV_ID = 'crawler_sim/Crawl-v0'
#: episode length [control periods] of the registered id (40 s at control_period = 0.04 s)
MAX_EPISODE_STEPS = 1000


def register_envs() -> None:
    """Register ``crawler_sim/Crawl-v0`` with gymnasium (once; entry points as strings, so
    nothing of the environment is imported until it is made)."""
    from gymnasium.envs.registration import register, registry
    if ENV_ID in registry:
        return
    register(id=ENV_ID, entry_point='crawler_sim.envs.crawl:CrawlEnv',
             vector_entry_point='crawler_sim.envs.vector:CrawlVectorEnv',
             max_episode_steps=MAX_EPISODE_STEPS)


class _AfterImport:
    """A meta path finder (not derived from importlib.abc.MetaPathFinder, whose import costs
    5-30 ms: importlib.resources, tempfile, random). Finds nothing itself: when ``gymnasium``
    is about to be imported, wraps its loader so that ``register_envs`` runs right after the
    module has executed, then removes itself."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != 'gymnasium':
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)       # the other finders (self removed)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        run = loader.exec_module

        def exec_module(module: Any) -> None:
            run(module)
            register_envs()
        loader.exec_module = exec_module          # (this loader object serves this import only)
        return spec


def register_when_imported() -> None:
    """Register now when gymnasium is imported, else when it is (no import of it here; a
    machine without gymnasium registers nothing)."""
    if 'gymnasium' in sys.modules:
        register_envs()
    elif not any(isinstance(f, _AfterImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport())


def __getattr__(name: str) -> Any:
    # CrawlEnv / CrawlVectorEnv on first use (they import gymnasium)
    if name == 'CrawlEnv':
        from .crawl import CrawlEnv
        return CrawlEnv
    if name == 'CrawlVectorEnv':
        from .vector import CrawlVectorEnv
        return CrawlVectorEnv
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
