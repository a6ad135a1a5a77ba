"""``sim_node``: kept as the entry point ``crawler_sim.ros.sim_node:main`` and the import path
of ``SimNode``; the node itself lives in :mod:`crawler_sim.ros.sim` (one module per
responsibility)."""
from crawler_sim.ros.sim import (LoopTakenGroup, OUTPUTS, PARAMETERS, SimConfig, SimNode, main,
                                 check_command)

__all__ = ['SimNode', 'SimConfig', 'PARAMETERS', 'OUTPUTS', 'main', 'check_command',
           'LoopTakenGroup']

if __name__ == '__main__':
    main()
