"""Bag names: confined to the recording directory and unique per process.

A record name is one path component made of ``[A-Za-z0-9._-]`` (not ``.`` or ``..``), so a bag
can only be created directly inside ``record_dir``. The default name carries the wall time and
the process id (``crawler_sim_20260101-120000_1234``); when a folder of that name exists
already (two runs in the same second, a restarted node) ``_2``, ``_3``... is appended. The folder
is created with ``mkdir`` (atomic), so two writers racing for a name never share a folder.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import time

from .errors import BagError

ALLOWED = 'A-Z a-z 0-9 . _ -'
_NAME = re.compile(r'[A-Za-z0-9._-]+')
MAX_NAME = 200                  # bytes; the file name adds '_0.mcap' within NAME_MAX (255)
MAX_SUFFIX = 10_000             # _2 .. _9999: beyond this something else is wrong


def check_record_name(name: str) -> str:
    """``name`` if it is a valid record name, else ``ValueError`` naming the field.

    Valid: 1 to 200 characters of ``[A-Za-z0-9._-]``, not ``.`` or ``..`` (so no separators,
    no absolute paths and no parent references). The empty string is *not* valid here; callers
    treat '' as "use :func:`default_name`".
    """
    if not isinstance(name, str):
        raise ValueError(f'record_name must be a string, got {type(name).__name__}')
    if (not _NAME.fullmatch(name) or name in ('.', '..')
            or len(name.encode()) > MAX_NAME):
        raise ValueError(f'record_name {name!r} is not allowed: use 1 to {MAX_NAME} characters '
                         f'from [{ALLOWED}] (one folder inside record_dir; not "." or "..", '
                         'no "/" or absolute path)')
    return name


def default_name(prefix: str = 'crawler_sim', now: float | None = None) -> str:
    """``<prefix>_<YYYYmmdd-HHMMSS>_<pid>`` in local wall time."""
    stamp = time.strftime('%Y%m%d-%H%M%S', time.localtime(now))
    return check_record_name(f'{prefix}_{stamp}_{os.getpid()}')


def claim_directory(record_dir: os.PathLike | str, record_name: str | None = None) -> Path:
    """Create and return a new, empty bag folder inside ``record_dir``.

    ``record_name`` ('' or None: :func:`default_name`) is checked with
    :func:`check_record_name`; if the folder exists, ``_2``, ``_3``... is appended. ``record_dir``
    itself is created when missing. Raises ``ValueError`` for a bad name and :class:`BagError`
    when the folder cannot be created.
    """
    base = check_record_name(record_name) if record_name else default_name()
    root = Path(record_dir)
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BagError(f'cannot create record_dir {root}: {exc.strerror or exc}') from None
    if not root.is_dir():
        raise BagError(f'record_dir {root} is not a directory')
    for k in range(1, MAX_SUFFIX):
        candidate = root / (base if k == 1 else f'{base}_{k}')
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
        except OSError as exc:
            raise BagError(f'cannot create bag directory {candidate}: '
                           f'{exc.strerror or exc}') from None
    raise BagError(f'{root}: {MAX_SUFFIX} bags named {base}_N exist already')


__all__ = ['ALLOWED', 'check_record_name', 'claim_directory', 'default_name']
