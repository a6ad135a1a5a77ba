"""The one way crawler_sim writes a file: bags' metadata, tables and their sidecars, checkpoint
chunks, specs, gait files and figures all go through :func:`write_atomically`; what is written
as it happens (a recording, a process's log) is created by :func:`open_new`; a command checks
all its outputs before the first is written with :func:`check_outputs`.

Rules (docs/bags.md, "Outputs"):

* **Never an input.** :func:`reading` names the inputs of the command that runs (scene, spec,
  bag); while it is active, an output that is one of them (the same file by identity, also
  through a hard or symbolic link, not by name) or lies inside an input bag folder is refused
  with :class:`OutputRefused` (the command line's exit 2), before anything is written.
* **A file, in a folder that exists.** An output that is a directory (or a link to one), a
  FIFO or a device, or whose folder does not exist, is refused the same way.
* **Never through a link.** The new content goes to a temporary file created exclusively
  (``O_CREAT | O_EXCL | O_NOFOLLOW``) under a name nobody can guess
  (``.<name>.<16 random hex digits>.tmp``) in the output's folder, opened by a descriptor of
  that folder; the caller writes to the open file object, never to a path, so a link planted
  under any name is neither followed nor truncated. The folder the user names is followed as
  given (a ``runs`` that is a link to scratch space).
* **Atomic.** Once complete (flushed and ``fsync``-ed) the temporary file is renamed over the
  output: a reader sees the old file or the new one, never half of one; a failure or an
  interruption removes the temporary file and leaves the old output as it was. An output that
  was a link is replaced by the file (its target is not written).

Re-running a command over its own earlier output file replaces it (the README's commands rerun);
bag folders are never overwritten (:func:`check_new_folder`).

POSIX only (descriptors of folders, ``O_NOFOLLOW``), as the rest of the bag layer.
"""
from __future__ import annotations

from contextlib import contextmanager
import errno
import os
from pathlib import Path
import re
import secrets
import stat
import threading
from typing import IO, Any, Callable, Iterator

from .errors import BagError

__all__ = ['OutputRefused', 'reading', 'check_output', 'check_outputs', 'check_new_folder',
           'write_atomically', 'write_text', 'open_new', 'temporary_target', 'OPEN_NEW']

#: flags of every file crawler_sim creates: a new file, never an existing one, never a link
OPEN_NEW = (os.O_CREAT | os.O_EXCL | getattr(os, 'O_NOFOLLOW', 0)
            | getattr(os, 'O_CLOEXEC', 0))
_TEMPORARY = re.compile(r'^\.(?P<target>.+)\.[0-9a-f]{16}\.tmp$')
_NAME_ROOM = 200          # bytes of the output's name kept in its temporary's (NAME_MAX 255)


class OutputRefused(BagError, ValueError):
    """An output crawler_sim will not write (one of the inputs, inside an input bag folder, a
    directory, a folder that does not exist, a bag folder that exists): a user's mistake, the
    command line's exit 2. The message is one line naming the output. A ValueError too: a bad
    argument (STYLE: bad arguments give ValueError)."""


# -------------------------------------------------------------------- the command's inputs

class _Inputs:
    """The identities of the running command's inputs (process-wide: the command's writes may
    come from any thread, e.g. a sweep's chunks)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.files: dict[tuple[int, int], str] = {}      # (st_dev, st_ino) -> the input's name
        self.folders: dict[tuple[int, int], str] = {}    # input bag folders


_INPUTS = _Inputs()


def _identity(st: os.stat_result) -> tuple[int, int]:
    return st.st_dev, st.st_ino


def _bag_folder(path: Path, st: os.stat_result) -> Path | None:
    """The bag folder of an input: the input itself if it is a directory, else the folder of an
    ``.mcap`` file when that folder is a bag (it holds metadata.yaml)."""
    if stat.S_ISDIR(st.st_mode):
        return path
    if path.suffix == '.mcap' and (path.parent / 'metadata.yaml').is_file():
        return path.parent
    return None


@contextmanager
def reading(*inputs: os.PathLike | str) -> Iterator[None]:
    """Within the block, :func:`check_output` (so every write of the package) refuses an output
    that is one of ``inputs`` or lies inside an input bag folder. Inputs that do not exist are
    skipped (the command reports them itself). Blocks nest."""
    added_files: list[tuple[int, int]] = []
    added_folders: list[tuple[int, int]] = []

    def add(table: dict, added: list, key: tuple[int, int], name: str) -> None:
        with _INPUTS.lock:
            if key not in table:
                table[key] = name
                added.append(key)

    for item in inputs:
        path = Path(item)
        try:
            st = os.stat(path)
        except (OSError, ValueError):
            continue
        add(_INPUTS.files, added_files, _identity(st), str(path))
        folder = _bag_folder(path, st)
        if folder is None:
            continue
        try:
            add(_INPUTS.folders, added_folders, _identity(os.stat(folder)), str(folder))
            # the bag's files too: a hard link to one of them elsewhere is that input
            with os.scandir(folder) as entries:
                for entry in entries:
                    if entry.is_file(follow_symlinks=False):
                        add(_INPUTS.files, added_files, _identity(entry.stat()),
                            str(folder / entry.name))
        except OSError:
            continue
    try:
        yield
    finally:
        with _INPUTS.lock:
            for key in added_files:
                _INPUTS.files.pop(key, None)
            for key in added_folders:
                _INPUTS.folders.pop(key, None)


def _input_named(path: Path) -> str | None:
    """The input ``path`` is (by identity, through a link too), if any."""
    with _INPUTS.lock:
        files = dict(_INPUTS.files)
    if not files:
        return None
    for follow in (False, True):
        try:
            st = os.stat(path, follow_symlinks=follow)
        except OSError:
            continue
        if _identity(st) in files:
            return files[_identity(st)]
    return None


def _input_folder_around(folder: Path) -> str | None:
    """The input bag folder that ``folder`` is or lies inside (by identity), if any."""
    with _INPUTS.lock:
        folders = dict(_INPUTS.folders)
    if not folders:
        return None
    here = Path(os.path.realpath(folder))
    for candidate in (here, *here.parents):
        try:
            key = _identity(os.stat(candidate))
        except OSError:
            continue
        if key in folders:
            return folders[key]
    return None


# -------------------------------------------------------------------- checks

def _check_not_input(path: Path) -> None:
    source = _input_named(path)
    if source is not None:
        same = '' if os.path.abspath(source) == os.path.abspath(path) else f' ({source})'
        raise OutputRefused(f'{path}: is an input of this command{same}; not overwriting it '
                            '(write the output elsewhere)')
    bag = _input_folder_around(path.parent)
    if bag is not None:
        raise OutputRefused(f'{path}: lies inside the input bag folder {bag}; a bag is never '
                            'written into (write the output elsewhere)')


def check_output(path: os.PathLike | str) -> Path:
    """``Path(path)`` if a file may be written there, else :class:`OutputRefused` naming it:
    one of the inputs (:func:`reading`) or inside an input bag folder, a directory (or a link
    to one), a FIFO, device or socket, or in a folder that does not exist. A regular file (an
    earlier output) or a link (replaced, not followed) may be written over."""
    path = Path(path)
    if not path.name or path.name in ('.', '..'):
        raise OutputRefused(f'{path}: is a directory, not a file name')
    _check_not_input(path)
    try:
        st = os.stat(path)                       # through a link: a link to a folder is refused
    except FileNotFoundError:
        st = None                                # new, or a dangling link (replaced)
    except OSError as exc:
        if exc.errno == errno.ENOTDIR:
            raise OutputRefused(f'{path}: the folder {path.parent} is not a folder') from None
        st = None                                # e.g. a link loop: replaced like a link
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputRefused(f'{path}: is a directory; give a file name')
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise OutputRefused(f'{path}: is not a regular file (a FIFO, device or socket); not '
                            'writing to it')
    folder = path.parent
    if not folder.is_dir():
        what = 'is not a folder' if os.path.lexists(folder) else 'does not exist'
        raise OutputRefused(f'{path}: the folder {folder} {what}')
    return path


def check_outputs(*paths: os.PathLike | str) -> list[Path]:
    """:func:`check_output` of every file a command is about to write, before the first is
    written; also :class:`OutputRefused` if two of them are the same file (one would replace
    the other)."""
    seen: dict[str, Path] = {}
    checked = []
    for item in paths:
        path = check_output(item)
        key = os.path.join(os.path.realpath(path.parent), path.name)
        if key in seen:
            raise OutputRefused(f'{path}: named for two outputs of this command (also as '
                                f'{seen[key]}); give them different names')
        seen[key] = path
        checked.append(path)
    return checked


def check_new_folder(path: os.PathLike | str) -> Path:
    """``Path(path)`` if a new folder (a bag) may be made there, else :class:`OutputRefused`:
    one of the inputs or inside an input bag folder, or anything (a folder, a file, a link,
    even a dangling one) already there, which is never overwritten."""
    path = Path(path)
    _check_not_input(path)
    if os.path.lexists(path):
        raise OutputRefused(f'{path} exists already, not overwriting')
    return path


# -------------------------------------------------------------------- writing

def temporary_target(name: str) -> str | None:
    """The output name (cut to 200 bytes) a temporary file named ``name`` was written for, or
    None if ``name`` is not one of :func:`write_atomically`'s temporaries (e.g. left behind by
    a killed process: any later write of that output leaves its own, and removes only its
    own)."""
    m = _TEMPORARY.match(name)
    return m.group('target') if m else None


def _temporary(folder_fd: int, name: str) -> tuple[str, int, tuple[int, int]]:
    """A new temporary file for output ``name`` inside the folder of ``folder_fd``: its name, a
    write descriptor and its identity. Exclusive (never an existing file, never through a
    link); a name already taken (planted) is skipped for another."""
    base = os.fsencode(name)[:_NAME_ROOM].decode(errors='ignore')
    for _ in range(100):
        tmp = f'.{base}.{secrets.token_hex(8)}.tmp'
        try:
            fd = os.open(tmp, os.O_WRONLY | OPEN_NEW, 0o666, dir_fd=folder_fd)
        except FileExistsError:
            continue
        return tmp, fd, _identity(os.fstat(fd))
    raise FileExistsError(errno.EEXIST, 'no free temporary name', name)


def write_atomically(path: os.PathLike | str, write: Callable[[IO[bytes]], Any]) -> Path:
    """Write the file ``path`` through ``write(fh)``, ``fh`` a binary file object open on a new
    temporary file beside it (see the module doc), then rename that over ``path``.

    ``write`` writes to ``fh`` (pyarrow, pandas and matplotlib take it as they take a path);
    it may close it. Checks ``path`` with :func:`check_output` first (:class:`OutputRefused`).
    If ``write`` or the rename fails, or is interrupted, the temporary file is removed and the
    old ``path`` stays as it was; an OSError (a full disk, an unwritable folder) is raised
    again as an OSError of the same errno whose ``filename`` is ``path`` and whose message is
    ``cannot write: <reason>``. Returns ``Path(path)``.
    """
    path = check_output(path)
    try:
        folder_fd = os.open(path.parent, os.O_RDONLY | getattr(os, 'O_DIRECTORY', 0)
                            | getattr(os, 'O_CLOEXEC', 0))
    except OSError as exc:
        raise _naming(exc, path) from exc
    try:
        _write_in(folder_fd, path, write)
    finally:
        os.close(folder_fd)
    return path


def _write_in(folder_fd: int, path: Path, write: Callable[[IO[bytes]], Any]) -> None:
    tmp = fd = None
    made = (-1, -1)
    try:
        tmp, fd, made = _temporary(folder_fd, path.name)
        with open(fd, 'wb', closefd=False) as fh:
            write(fh)
        os.fsync(fd)
        # the name must still lead to the file made (not one swapped in meanwhile) when renamed
        if not _leads_to(folder_fd, tmp, made):
            raise OSError(errno.EEXIST, 'the temporary file was replaced by another one')
        os.replace(tmp, path.name, src_dir_fd=folder_fd, dst_dir_fd=folder_fd)
        tmp = None
        _fsync_folder(folder_fd)
    except BaseException as exc:
        if tmp is not None and _leads_to(folder_fd, tmp, made):
            try:
                os.unlink(tmp, dir_fd=folder_fd)
            except OSError:
                pass
        if isinstance(exc, OSError) and not isinstance(exc, BagError):
            raise _naming(exc, path) from exc
        raise
    finally:
        if fd is not None:
            os.close(fd)


def open_new(path: os.PathLike | str, *, readable: bool = False) -> IO[bytes]:
    """A new file at ``path`` opened for writing (and reading with ``readable``), for what is
    written as it happens and cannot wait for a rename (a recording, a process's log): created
    exclusively, never an existing file and never through a link (FileExistsError), checked
    with :func:`check_output` first."""
    path = check_output(path)
    fd = os.open(path, (os.O_RDWR if readable else os.O_WRONLY) | OPEN_NEW, 0o666)
    return open(fd, 'wb')


def write_text(path: os.PathLike | str, text: str) -> Path:
    """:func:`write_atomically` of ``text`` (UTF-8)."""
    data = text.encode('utf-8')
    return write_atomically(path, lambda fh: fh.write(data))


def _leads_to(folder_fd: int, name: str, identity: tuple[int, int]) -> bool:
    """True if ``name`` in the folder of ``folder_fd`` is (not links to) the file ``identity``."""
    try:
        return _identity(os.stat(name, dir_fd=folder_fd, follow_symlinks=False)) == identity
    except OSError:
        return False


def _fsync_folder(folder_fd: int) -> None:
    """The rename on disk too (some file systems refuse to sync a folder: nothing to do)."""
    try:
        os.fsync(folder_fd)
    except OSError:
        pass


def _naming(exc: OSError, path: Path) -> OSError:
    """An OSError like ``exc`` (same errno, so the same subclass) that names ``path``
    (pyarrow's errors name neither the file nor the cause plainly)."""
    code = exc.errno or errno.EIO
    reason = os.strerror(exc.errno) if exc.errno else str(exc).splitlines()[0]
    return OSError(code, f'cannot write: {reason}', str(path))
