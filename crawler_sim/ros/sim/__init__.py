"""sim_node, split along its responsibilities (docs/ARCHITECTURE.md):

- :mod:`.params`: parameter declarations, descriptors, validation to a ``SimConfig``;
- :mod:`.intake`: ``linkage_cmd`` / ``linkage_trajectory`` validation, queueing, cheap rejection;
- :mod:`.trajarrays`: trajectories parsed from CDR into numpy arrays (point limit);
- :mod:`.outputs`: publishers and CDR encoders of the outputs;
- :mod:`.recording`: the bag; :mod:`.diagnostics`: ``/diagnostics``;
- :mod:`.loop`: the real-time loop; :mod:`.node`: ``SimNode``; :mod:`.main`: the entry point.

Everything but ``node``, ``outputs``, ``diagnostics`` and ``main`` works without DDS.
"""
from .intake import validate_command
from .main import main
from .node import LoopTakenGroup, NODE_NAME, SimNode
from .params import OUTPUTS, PARAMETERS, SimConfig

__all__ = ['SimNode', 'SimConfig', 'PARAMETERS', 'OUTPUTS', 'main', 'validate_command',
           'LoopTakenGroup', 'NODE_NAME']
