"""crawler_sim: exact simulation of friction-based crawling locomotion.

The core (this package's ``model``, ``gaits``, ``solvers``, ``stepper``, ``trajectory``,
``verify``) imports no ROS; the ROS node, bags and command line sit around it.
"""
from . import gaits
from .model import Crawler
from .solvers.implicit import ImplicitBatch
from .solvers.penalty import penalty_bound
from .stepper import METHODS, Stepper, simulate
from .trajectory import Event, State, Trajectory
from .verify import VerifyReport, verify

__version__ = '0.1.0'

__all__ = ['Crawler', 'Event', 'ImplicitBatch', 'METHODS', 'State', 'Stepper', 'Trajectory',
           'VerifyReport', 'gaits', 'penalty_bound', 'simulate', 'verify', '__version__']
