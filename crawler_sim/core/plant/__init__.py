"""The simulated plant as the node runs it: the crawler, its actuator and the tick grid.

- ``engine``: ``Engine``, the one owner of the plant (inputs: command, trajectory,
  reconfigure, reset, pause, resume), and ``EngineConfig``;
- ``config``: the plant's parameters (``PARAMETERS``) and their validation (``PlantConfig``);
- ``inputs``: the rules a command or a trajectory must meet (``check_command``,
  ``check_trajectory``) and a trajectory ready to apply (``PreparedTrajectory``);
- ``replay``: a recorded journal of inputs run again through an engine;
- ``streams``: the command streams a gait_node sends for a gait (set-points, trajectories),
  and a run of them offline "as the node runs it".
"""
from .config import PARAMETERS, PlantConfig
from .engine import Engine, EngineConfig
from .inputs import PreparedTrajectory, TrajectoryArrays, check_command, check_trajectory

__all__ = ['Engine', 'EngineConfig', 'PARAMETERS', 'PlantConfig', 'PreparedTrajectory',
           'TrajectoryArrays', 'check_command', 'check_trajectory']
