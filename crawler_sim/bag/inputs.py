"""The plant inputs a sim_node bag recorded, as ``crawler_sim.core.plant.replay.Input``.

sim_node records each input its engine took on ``~/plant_inputs`` (``std_msgs/msg/String``,
JSON ``{"seq", "kind", ...}`` at the sim time it took effect, see ``SimNode._journal``); the
points of an applied trajectory are the ``linkage_trajectory`` message recorded at the same
time, in the same order. Bags written before that journal existed hold only ``linkage_cmd`` and
``linkage_trajectory``: :func:`load_inputs` then returns those (``journaled`` False), and a run
with parameter changes or resets cannot be repeated from them.

Every journal entry is checked before it is used (a bag is a file anyone can write): a JSON
object, ``kind`` one of ``KINDS``, ``seq`` an integer >= 0, and the field its kind needs
(``lengths`` a list, ``values`` an object, ``points`` an integer >= -1, with the trajectory it
names readable on ``linkage_trajectory``); the values in them are checked where they are applied
(``crawler_sim.core.plant.replay``). A malformed entry raises ``JournalError``: one line naming
the bag, the message (its index in the journal, in log-time order, and its sim time) and the
field.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from crawler_sim.core.plant.config import _short
from crawler_sim.core.plant.replay import Input, input_name, JournalError, KINDS
from . import journal, trajarrays
from .mcapfile import Batch, scan
from .reader import bag_files
from .topics import LINKAGE_CMD, LINKAGE_TRAJECTORY, PLANT_INPUTS, normalize_namespace
from crawler_sim.core.simtime import to_seconds

__all__ = ['RecordedInputs', 'load_inputs', 'PLANT_INPUTS_SUFFIX', 'TRAJECTORY_SUFFIX']

PLANT_INPUTS_SUFFIX = PLANT_INPUTS.leaf        # <node>/plant_inputs, the node's ~/plant_inputs
TRAJECTORY_SUFFIX = LINKAGE_TRAJECTORY.suffix


class RecordedInputs(NamedTuple):
    """The inputs in the order they took effect, and whether the bag held the journal."""

    inputs: list[Input]
    journaled: bool


def _raw(path: Path, keep) -> dict[str, list[tuple[int, bytes]]]:
    """Raw messages (log time [ns], CDR) of the topics ``keep(topic)`` accepts, per topic."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    for file in bag_files(path):
        found: dict[str, list[tuple[int, bytes]]] = {}

        def want(channel, schema, found=found):
            if not keep(channel.topic):
                return None
            rows = found[channel.topic] = []      # a re-read replaces a first attempt

            def sink(batch: Batch) -> None:
                rows.extend((int(batch.log_times[i]), batch.data(i)) for i in range(len(batch)))
            return sink
        scan(file, want)
        for topic, rows in found.items():
            out.setdefault(topic, []).extend(rows)
    return out


def load_inputs(path: os.PathLike | str, namespace: str = '') -> RecordedInputs:
    """The plant inputs recorded in the bag at ``path`` for the robot in ``namespace``.

    Raises ``JournalError`` (a ValueError) naming the message and the field when a journal
    entry or a trajectory cannot be decoded or is malformed, or when the journal names a
    trajectory that was not recorded; :class:`BagError` when the file cannot be read.
    """
    ns = normalize_namespace(namespace)

    def journal_topic(t: str) -> bool:
        return t.startswith(ns + '/') and t.endswith('/' + PLANT_INPUTS_SUFFIX)
    traj = f'{ns}/{TRAJECTORY_SUFFIX}'
    cmd = LINKAGE_CMD.name(ns)
    raw = _raw(Path(path), lambda t: journal_topic(t) or t in (traj, cmd))
    trajectories = sorted(raw.get(traj, []), key=lambda r: r[0])
    journal = [row for topic, rows in raw.items() if journal_topic(topic) for row in rows]
    if journal:
        return RecordedInputs(_from_journal(path, journal, trajectories), True)
    return RecordedInputs(_from_topics(path, raw.get(cmd, []), trajectories), False)


def _string(data: bytes) -> str:
    """The ``data`` of a CDR ``std_msgs/msg/String``."""
    n = int.from_bytes(data[4:8], 'little')
    return data[8:8 + n - 1].decode('utf-8')


#: the field each kind of journal entry needs: (name, what it must be, check); the format's
#: owner is .journal (the node writes with it)
_FIELDS = journal.FIELDS


def _entry(path, name: str, data: bytes) -> dict:
    """The journal entry in the CDR ``data`` of the message ``name``, its fields checked."""
    try:
        entry = json.loads(_string(data))
    except (ValueError, RecursionError) as exc:      # UnicodeDecodeError is a ValueError
        raise JournalError(f'{path}: {name} is not a JSON journal entry ({exc})') from None
    if not isinstance(entry, dict):
        raise JournalError(f'{path}: {name} must be a JSON object, got {_short(entry)}')
    kind = entry.get('kind')
    if not isinstance(kind, str) or kind not in KINDS:
        raise JournalError(f'{path}: {name}: kind must be one of {", ".join(KINDS)}, got '
                           f'{_short(kind)}')
    seq = entry.setdefault('seq', 0)
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise JournalError(f'{path}: {name}: seq must be an integer >= 0, got {_short(seq)}')
    if kind in _FIELDS:
        field, what, ok = _FIELDS[kind]
        if field not in entry:
            raise JournalError(f'{path}: {name}: a {kind} entry needs {field} ({what})')
        if not ok(entry[field]):
            raise JournalError(f'{path}: {name}: {field} must be {what}, got '
                               f'{_short(entry[field])}')
    return entry


def _from_journal(path, journal: list[tuple[int, bytes]],
                  trajectories: list[tuple[int, bytes]]) -> list[Input]:
    journal = sorted(journal, key=lambda row: row[0])     # stable: file order within a time
    entries = []
    for index, (t_ns, data) in enumerate(journal):
        entry = _entry(path, input_name(index, t_ns), data)
        entries.append((t_ns, entry['seq'], index, entry))
    entries.sort(key=lambda e: (e[0], e[1]))
    out: list[Input] = []
    k = 0
    for t_ns, _seq, index, entry in entries:
        kind = entry['kind']
        name = input_name(index, t_ns)
        payload = None
        if kind == 'command':
            payload = entry['lengths']           # its numbers are checked where applied
        elif kind in ('configure', 'reset'):
            payload = entry['values']
        elif kind == 'trajectory':
            if entry['points'] < 0:
                raise JournalError(f'{path}: {name}: the trajectory applied then was not '
                                   'recorded (points -1: given in Python, not as a message)')
            while k < len(trajectories) and trajectories[k][0] < t_ns:
                k += 1              # a message without a journal entry: not applied
            if k >= len(trajectories) or trajectories[k][0] != t_ns:
                raise JournalError(f'{path}: {name}: the trajectory applied then is missing '
                                   'from linkage_trajectory')
            payload = _trajectory(path, name, trajectories[k][1])
            k += 1
        out.append(Input(t_ns, kind, payload, index))
    return out


def _trajectory(path, name: str, data: bytes):
    try:
        return trajarrays.parse(data)
    except trajarrays.TrajectoryFormatError as exc:
        raise JournalError(f'{path}: {name}: its linkage_trajectory message cannot be read '
                           f'({exc})') from None


def _from_topics(path, commands: list[tuple[int, bytes]],
                 trajectories: list[tuple[int, bytes]]) -> list[Input]:
    """Inputs of a bag without the journal: commands and trajectories at their log times."""
    from .cdr import Decoder
    out: list[Input] = []
    if commands:
        dec = Decoder(LINKAGE_CMD.type, ('data',))
        buf = np.frombuffer(b''.join(d for _, d in commands), dtype=np.uint8)
        lengths = np.array([len(d) for _, d in commands], dtype=np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        dec.add(buf, starts, lengths)
        values = dec.columns()['data']
        for (t_ns, _), row in zip(commands, values):
            out.append(Input(t_ns, 'command', [float(x) for x in row if not np.isnan(x)]))
    out.extend(Input(t_ns, 'trajectory',
                     _trajectory(path, f'linkage_trajectory message #{k} (t = '
                                 f'{to_seconds(t_ns):.9f} s)', data))
               for k, (t_ns, data) in enumerate(trajectories))
    out.sort(key=lambda e: e.t_ns)
    return out
