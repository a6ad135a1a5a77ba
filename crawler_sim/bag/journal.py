"""The plant journal's format on ``~/plant_inputs``: one owner for the writer and the reader.

sim_node records every input its engine took (``crawler_sim.core.plant.Engine``'s journal) as
one ``std_msgs/msg/String`` per input, at the sim time it took effect: a JSON object
``{"seq": n, "kind": k, <field>: ...}``. ``seq`` counts the entries from 1 (it orders entries
of one sim time); ``kind`` is one of ``crawler_sim.core.plant.replay.KINDS``; :data:`FIELDS`
names the one field a kind carries (the others carry none). The node writes entries with
:func:`encode` (``ros/sim/node.py``), the bag reads them back with its checks in
``bag/inputs.py`` (every field through :data:`FIELDS`).
"""
from __future__ import annotations

import json
from typing import Any, Callable

__all__ = ['FIELDS', 'encode', 'NOT_RECORDED']

#: the field each kind of entry carries: (name, what it must be, check of a read value)
FIELDS: dict[str, tuple[str, str, Callable[[Any], bool]]] = {
    'command': ('lengths', 'a list of lengths [m]', lambda x: isinstance(x, list)),
    'configure': ('values', 'an object of parameter values', lambda x: isinstance(x, dict)),
    'reset': ('values', 'an object of parameter values', lambda x: isinstance(x, dict)),
    'trajectory': ('points', 'an integer >= -1 (-1: not recorded)',
                   lambda x: isinstance(x, int) and not isinstance(x, bool) and x >= -1),
}
#: ``points`` of a trajectory given in Python (not a message: its points are not in the bag)
NOT_RECORDED = -1


def encode(seq: int, kind: str, payload: Any = None) -> str:
    """The JSON text of entry ``seq`` of ``kind``; ``payload`` is the engine's: the target
    lengths (command), a config with ``values`` (configure, reset), or the number of points
    (trajectory; :data:`NOT_RECORDED`); the other kinds carry nothing."""
    entry: dict[str, Any] = {'seq': seq, 'kind': kind}
    if kind in FIELDS:
        field = FIELDS[kind][0]
        if kind in ('configure', 'reset'):
            payload = {k: (list(v) if isinstance(v, (list, tuple)) else v)
                       for k, v in payload.values.items()}
        entry[field] = payload
    return json.dumps(entry)
