"""ROS domain ids for the tests that no other test session on this host can hold at once.

``pid % 100 + 1`` alone let two sessions meet (issue 38 item 8: a fresh clone's ``make test``
shared a domain with a session running hostile-message tests). Each id is claimed here with an
exclusive, non-blocking ``flock`` on ``<tempdir>/crawler_sim_ros_domain_<id>.lock``, held open
for the life of the process (the kernel drops it when the process ends, also on SIGKILL, so a
crashed session never leaves an id taken). Ids are tried in turn from ``pid % 100 + 1``.

Fast DDS opens its default ports for domain ids 0 to 101 on Linux; tests keep to 1 to 100 (0 is
every user's default domain, where a developer's own nodes run), and the domain the developer's
shell names in ``ROS_DOMAIN_ID`` is skipped too. No ROS import here: the session's id must be
set before any test module imports rclpy.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path
import tempfile
from typing import IO

__all__ = ['FIRST', 'LAST', 'POOL', 'claim', 'session_domain_id', 'next_domain_id']

FIRST, LAST = 1, 100      # usable ids (Fast DDS: 0-101 with default ports on Linux)
POOL = 4                  # ids an in-process test cycles through, besides the session's

_held: dict[int, IO[bytes]] = {}      # id -> its open, locked file (kept for the process's life)
_pool: list[int] = []
_turn = [0]


def _lock_path(domain: int) -> Path:
    return Path(tempfile.gettempdir()) / f'crawler_sim_ros_domain_{domain}.lock'


def _try(domain: int) -> bool:
    """Lock ``domain``'s file without waiting; True when this process now holds it."""
    if domain in _held:
        return False
    try:
        fd = os.open(_lock_path(domain), os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        try:                    # another user's file: a read-only descriptor locks as well
            fd = os.open(_lock_path(domain), os.O_RDONLY)
        except OSError:
            return False
    handle = os.fdopen(fd, 'rb')
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        return False
    _held[domain] = handle
    return True


def claim(start: int | None = None, avoid: tuple[int, ...] = ()) -> int:
    """Claim a domain id no other process on this host holds, trying ids in turn from
    ``start`` (default ``pid % 100 + 1``) and skipping ``avoid``; RuntimeError when every id in
    [FIRST, LAST] is held."""
    n = LAST - FIRST + 1
    first = (os.getpid() % n) if start is None else start - FIRST
    for k in range(n):
        domain = FIRST + (first + k) % n
        if domain not in avoid and _try(domain):
            return domain
    raise RuntimeError(f'every ROS domain id in [{FIRST}, {LAST}] is held by another test '
                       f'session on this host (lock files {_lock_path(FIRST).parent}/'
                       'crawler_sim_ros_domain_*.lock)')


def _users_domain() -> tuple[int, ...]:
    text = os.environ.get('ROS_DOMAIN_ID', '')
    return (int(text),) if text.isdigit() else ()


_session: list[int] = []


def session_domain_id() -> int:
    """This process's session domain (claimed at the first call, skipping the domain the
    environment named before: a developer's own nodes may run there)."""
    if not _session:
        _session.append(claim(avoid=_users_domain()))
    return _session[0]


def next_domain_id() -> int:
    """A domain id for one in-process test: held by this process, never the session's, and
    different from the previous call's (the process claims up to :data:`POOL` ids and cycles
    through them, so a long session does not use up the host's ids)."""
    base = session_domain_id()
    if len(_pool) < POOL:
        _pool.append(claim(start=base % (LAST - FIRST + 1) + FIRST))
        return _pool[-1]
    _turn[0] += 1
    return _pool[_turn[0] % POOL]
