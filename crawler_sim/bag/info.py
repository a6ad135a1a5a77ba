"""``info``: a short text summary of a bag (any MCAP file, crawler_sim or not)."""
from __future__ import annotations

from datetime import datetime, timezone
import json
import os
from pathlib import Path

from .clock import NS_PER_S
from .mcapfile import Scan, scan
from .reader import bag_files
from .topics import SCENE_METADATA

_EPOCH_2001_NS = 978_307_200 * NS_PER_S     # stamps after this are shown as dates too


def format_time(t_ns: int | None) -> str:
    """``12.345000000 s``; wall-clock stamps also as a UTC date."""
    if t_ns is None:
        return '-'
    text = f'{t_ns / NS_PER_S:.9f} s'
    if t_ns >= _EPOCH_2001_NS:
        date = datetime.fromtimestamp(t_ns / NS_PER_S, tz=timezone.utc)
        text += f' ({date.isoformat(timespec="milliseconds")})'
    return text


def _size(path: Path) -> str:
    size = float(path.stat().st_size)
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024 or unit == 'GiB':
            return f'{size:.0f} {unit}' if unit == 'B' else f'{size:.1f} {unit}'
        size /= 1024
    return ''


def _topic_lines(scans: list[Scan]) -> list[str]:
    rows: dict[str, list] = {}
    for sc in scans:
        for cid, channel in sorted(sc.channels.items()):
            schema = sc.schemas.get(channel.schema_id)
            row = rows.setdefault(channel.topic, [schema.name if schema else '?', 0,
                                                 channel.message_encoding])
            row[1] += sc.counts.get(cid, 0)
    if not rows:
        return ['topics:    none']
    width = max(len(t) for t in rows)
    type_width = max(len(r[0]) for r in rows.values())
    lines = [f'topics:    {len(rows)}']
    for topic, (type_name, count, encoding) in rows.items():
        lines.append(f'  {topic:<{width}}  {type_name:<{type_width}}  {count:>9} msgs  '
                     f'[{encoding}]')
    return lines


def _short(text: str, width: int = 40) -> str:
    """A JSON value for one line: strings unquoted, long values cut."""
    try:
        value = json.loads(text)
    except ValueError:
        value = text
    shown = value if isinstance(value, str) else text
    return shown if len(shown) <= width else shown[:width - 3] + '...'


def _scene_line(scans: list[Scan]) -> list[str]:
    for sc in scans:
        for record in sc.metadata:
            if record.name == SCENE_METADATA:
                return ['scene:     ' + ', '.join(
                    f'{key}={_short(text)}' for key, text in record.metadata.items())]
    return []


def _lost(sc: Scan) -> tuple[int, bool]:
    """Messages of ``sc``'s file lost to damage: exact when the file's statistics survived."""
    if sc.expected is not None and not sc.truncated:
        return max(sc.expected - sc.message_count, 0), False
    return sc.lost


def _status_lines(scans: list[Scan]) -> list[str]:
    """``status:`` (complete, DAMAGED or INCOMPLETE) and one ``damage:`` line per damaged
    part of a file (what was skipped, why, and the messages it cost)."""
    damaged = [sc for sc in scans if sc.damage]
    cut = [sc for sc in scans if sc.truncated]
    if not damaged and not cut:
        return ['status:    complete']
    lines = []
    if cut:
        lines.append('status:    INCOMPLETE - ' + '; '.join(
            f'{sc.path.name}: {sc.stop_reason}' for sc in cut)
            + ' (crawler_sim.bag.recover repairs it)')
    if damaged:
        lost = [_lost(sc) for sc in damaged]
        total, maybe = sum(n for n, _ in lost), any(m for _, m in lost)
        parts = sum(len(sc.damage) for sc in damaged)
        cost = (f'at least {total} messages lost' if maybe and total else
                'an unknown number of messages lost' if maybe else
                f'{total} messages lost' if total else 'no message lost')
        label = 'damage:' if cut else 'status:'
        lines.append(f'{label:<11}DAMAGED - {parts} damaged part{"s" if parts > 1 else ""} '
                     f'skipped, {cost} (crawler_sim.bag.recover writes a new bag of the '
                     'readable messages)')
        lines += [f'  {sc.path.name}: {d}' for sc in damaged for d in sc.damage]
    return lines


def info(path: os.PathLike | str) -> str:
    """Summary of a bag directory or .mcap file: files, status, times, topics and scene.

    Works for any MCAP file. Every chunk is read and checked, so the status is ``complete``
    only when every message is readable; otherwise it names each damaged part (which chunk,
    why, how many messages it cost) or where the file was cut. The message and topic counts
    are of the readable messages. Raises :class:`crawler_sim.bag.BagError` for a missing,
    empty or non-MCAP input.
    """
    path = Path(path)
    files = bag_files(path)
    scans = [scan(f, verify=True) for f in files]
    starts = [sc.start_ns for sc in scans if sc.start_ns is not None]
    ends = [sc.end_ns for sc in scans if sc.end_ns is not None]
    start = min(starts) if starts else None
    end = max(ends) if ends else None
    lines = [f'bag:       {path}']
    if path.is_dir():
        has_yaml = (path / 'metadata.yaml').is_file()
        lines.append(f'metadata:  {"metadata.yaml" if has_yaml else "no metadata.yaml"}')
    lines.append('files:     ' + ', '.join(f'{f.name} ({_size(f)})' for f in files))
    lines.append('writer:    ' + '; '.join(sorted({f'{sc.library} (profile {sc.profile or "-"})'
                                                  for sc in scans})))
    lines.extend(_status_lines(scans))
    readable = sum(sc.message_count for sc in scans)
    claimed = [sc.expected for sc in scans]
    note = ''
    if any(sc.damage for sc in scans) and None not in claimed and sum(claimed) != readable:
        note = f' readable (the files\' statistics list {sum(claimed)})'
    lines.append(f'messages:  {readable}{note}')
    lines.append(f'start:     {format_time(start)}')
    lines.append(f'end:       {format_time(end)}')
    duration = None if start is None or end is None else end - start
    lines.append(f'duration:  {format_time(duration)}')
    lines.extend(_topic_lines(scans))
    lines.extend(_scene_line(scans))
    return '\n'.join(lines)
