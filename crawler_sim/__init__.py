"""crawler_sim: exact simulation of friction-based crawling locomotion.

Layers (docs/ARCHITECTURE.md), dependencies pointing one way, cli/ros/bench -> bag -> core:

- ``crawler_sim.core``: model, gaits, solvers, stepper, trajectory, verify; no ROS import.
- ``crawler_sim.bag``: rosbag2-compatible MCAP recording, loading, recovery (message classes, no
  node).
- ``crawler_sim.ros``: the nodes (sim_node, gait_node, replay_node), their messages and the demo.
- ``benchmarks.solvers``: work-precision benchmark and stress suite.
- ``crawler_sim.cli``: the ``crawler-sim`` command.

The public API is the core's, re-exported here: ``crawler_sim.Crawler``, ``simulate``, ``gaits``...
"""
from pathlib import Path as _Path
import sys as _sys

#: the compiled modules of the core (Cython, built by ``pip install`` or ``make build``)
_COMPILED = ('core/solvers/_gait', 'core/solvers/_exact', 'core/solvers/_stepping',
            'core/_actuator')


def _unbuilt() -> list[str]:
    """The compiled modules whose ``.pyx`` source lies here without a built extension next to
    it: this is a source checkout nobody built (``import crawler_sim`` from its root picks it
    up before the installed package, the current directory being first on ``sys.path``)."""
    from importlib.machinery import EXTENSION_SUFFIXES
    here = _Path(__file__).resolve().parent
    return [name for name in _COMPILED if (here / f'{name}.pyx').is_file() and not any(
        (here / f'{name}{suffix}').is_file() for suffix in EXTENSION_SUFFIXES)]


try:
    from .core import (Crawler, Event, ImplicitBatch, METHODS, State, Stepper, Trajectory,
                       VerifyReport, gaits, penalty_bound, simulate, verify)
except ImportError as _exc:      # only on failure: an import that works costs nothing here
    _missing = _unbuilt()
    if not _missing:
        raise
    _root = _Path(__file__).resolve().parent.parent
    raise ImportError(
        f'crawler_sim is imported from the source checkout {_root}, whose compiled core is '
        f'not built ({", ".join(m.rsplit("/", 1)[1] for m in _missing)} missing): run '
        f'`pip install -e .` (or `make build`) in {_root}, or run Python from another '
        'directory to import the installed crawler_sim') from _exc

# `import crawler_sim.gaits` and `from crawler_sim.gaits import X` keep working (public API).
_sys.modules[__name__ + '.gaits'] = gaits

# gymnasium's `crawler_sim/Crawl-v0`, registered once gymnasium is imported (not imported here)
from .envs import register_when_imported as _register_envs   # noqa: E402
_register_envs()

__version__ = '0.1.0'

__all__ = ['Crawler', 'Event', 'ImplicitBatch', 'METHODS', 'State', 'Stepper', 'Trajectory',
           'VerifyReport', 'gaits', 'penalty_bound', 'simulate', 'verify', '__version__']
