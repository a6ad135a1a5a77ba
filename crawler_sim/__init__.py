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
import sys as _sys

from .core import (Crawler, Event, ImplicitBatch, METHODS, State, Stepper, Trajectory,
                   VerifyReport, gaits, penalty_bound, simulate, verify)

# `import crawler_sim.gaits` and `from crawler_sim.gaits import X` keep working (public API).
_sys.modules[__name__ + '.gaits'] = gaits

__version__ = '0.1.0'

__all__ = ['Crawler', 'Event', 'ImplicitBatch', 'METHODS', 'State', 'Stepper', 'Trajectory',
           'VerifyReport', 'gaits', 'penalty_bound', 'simulate', 'verify', '__version__']
