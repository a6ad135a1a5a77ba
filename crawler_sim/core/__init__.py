"""The simulator's core: model, gaits, solvers, stepper, trajectory, verify (no ROS import).

Nothing under ``crawler_sim.core`` imports rclpy, message packages or anything from
``crawler_sim.ros``, ``crawler_sim.bag``, ``benchmarks.solvers`` or ``crawler_sim.cli``
(test/core/test_layers.py enforces it); those layers import the core, never the other way.
"""
from . import friction, gaits
from .model import Crawler
from .solvers.implicit import ImplicitBatch
from .solvers.penalty import penalty_bound
from .stepper import METHODS, Stepper, simulate
from .trajectory import Event, State, Trajectory
from .verify import VerifyReport, verify

__all__ = ['Crawler', 'Event', 'friction', 'ImplicitBatch', 'METHODS', 'State', 'Stepper',
           'Trajectory', 'VerifyReport', 'gaits', 'penalty_bound', 'simulate', 'verify']
