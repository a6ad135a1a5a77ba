"""sim_node, split along its responsibilities (docs/ARCHITECTURE.md):

- :mod:`.params`: the node's parameters (the plant's and its own), validation to a ``SimConfig``;
- :mod:`.intake`: raw ``linkage_trajectory`` to plant inputs, cheap rejection (the rules live
  with the plant, ``crawler_sim.core.plant.inputs``);
- :mod:`.outputs`: publishers and CDR encoders of the outputs; :mod:`.model`: the URDF
  (``robot_description``);
- :mod:`.recording`: the bag; :mod:`.diagnostics`: ``/diagnostics``; :mod:`.clock`: the
  ``/clock`` shared by the sims of a domain;
- :mod:`.loop`: the real-time loop; :mod:`.node`: ``SimNode``; :mod:`.main`: the entry point.

Everything but ``node``, ``outputs``, ``diagnostics`` and ``main`` works without DDS
(``model`` imports nothing of ROS).
"""
from .intake import check_command
from .main import main
from .node import LoopTakenGroup, NODE_NAME, SimNode
from .params import OUTPUTS, PARAMETERS, SimConfig

__all__ = ['SimNode', 'SimConfig', 'PARAMETERS', 'OUTPUTS', 'main', 'check_command',
           'LoopTakenGroup', 'NODE_NAME']
