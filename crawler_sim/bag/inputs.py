"""The plant inputs a sim_node bag recorded, as ``crawler_sim.core.plant.replay.Input``.

sim_node records each input its engine took on ``~/plant_inputs`` (``std_msgs/msg/String``,
JSON ``{"seq", "kind", ...}`` at the sim time it took effect, see ``SimNode._journal``); the
points of an applied trajectory are the ``linkage_trajectory`` message recorded at the same
time, in the same order. Bags written before that journal existed hold only ``linkage_cmd`` and
``linkage_trajectory``: :func:`load_inputs` then returns those (``journaled`` False), and a run
with parameter changes or resets cannot be repeated from them.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from crawler_sim.core.plant.replay import Input, KINDS
from . import trajarrays
from .errors import BagError
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

    Raises :class:`BagError` naming the message when a journal entry or a trajectory cannot be
    decoded, or when the journal names more trajectories than were recorded.
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


def _from_journal(path, journal: list[tuple[int, bytes]],
                  trajectories: list[tuple[int, bytes]]) -> list[Input]:
    entries = []
    for t_ns, data in journal:
        try:
            entry = json.loads(_string(data))
            kind = entry['kind']
            seq = int(entry.get('seq', 0))
        except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
            raise BagError(f'{path}: plant_inputs message at t = {to_seconds(t_ns)} s cannot be '
                           'read '
                           f'({exc})') from None
        if kind not in KINDS:
            raise BagError(f'{path}: plant_inputs message at t = {to_seconds(t_ns)} s has kind '
                           f'{kind!r} (expected one of {", ".join(KINDS)})')
        entries.append((t_ns, seq, kind, entry))
    entries.sort(key=lambda e: (e[0], e[1]))
    out: list[Input] = []
    k = 0
    for t_ns, _seq, kind, entry in entries:
        payload = None
        if kind == 'command':
            payload = [float(x) for x in entry['lengths']]
        elif kind in ('configure', 'reset'):
            payload = entry['values']
        elif kind == 'trajectory':
            if entry.get('points', 0) < 0:
                raise BagError(f'{path}: the trajectory applied at t = {to_seconds(t_ns)} s was '
                               'not '
                               'recorded (given in Python, not as a message)')
            while k < len(trajectories) and trajectories[k][0] < t_ns:
                k += 1              # a message without a journal entry: not applied
            if k >= len(trajectories) or trajectories[k][0] != t_ns:
                raise BagError(f'{path}: the trajectory applied at t = {to_seconds(t_ns)} s is '
                               'missing from linkage_trajectory')
            payload = _trajectory(path, *trajectories[k])
            k += 1
        out.append(Input(t_ns, kind, payload))
    return out


def _trajectory(path, t_ns: int, data: bytes):
    try:
        return trajarrays.parse(data)
    except trajarrays.TrajectoryFormatError as exc:
        raise BagError(f'{path}: linkage_trajectory at t = {to_seconds(t_ns)} s cannot be read '
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
    out.extend(Input(t_ns, 'trajectory', _trajectory(path, t_ns, data))
               for t_ns, data in trajectories)
    out.sort(key=lambda e: e.t_ns)
    return out
