"""Input files: only regular files are read, by one reader for every command.

``mushrooms plan /dev/zero`` once grew to 5.5 GB, and ``plan FIFO`` or
``check PLAN FIFO`` waited forever for a writer.  Every file a command reads
(sky maps, plan documents, notices, trigger files, the configuration) is
opened here without blocking (``O_NONBLOCK``: opening a FIFO returns at
once), checked with ``fstat`` to be a regular file, and read up to a bound.

:func:`read_regular_file` returns the bytes; :func:`open_regular_file` the
open file, for readers that stream it line by line (executed records);
:func:`regular_file` only checks and hands the path on, for readers that
stream a large file themselves (the sky map reader).  The trigger directory also refuses
symbolic links (``follow_symlinks=False``): a link planted there would put a
protected file's bytes into the state.  A user's own input may be a link to
a regular file.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import BinaryIO

from .scheduler_core.errors import InputError

__all__ = ["read_regular_file", "open_regular_file", "regular_file", "MAX_INPUT_BYTES", "file_kind", "state_file_problem"]

#: Default bound (bytes) of a file read whole: 64 MiB (a notice is at most 8 MiB, a plan < 1 MiB).
MAX_INPUT_BYTES = 64 * 1024 * 1024


def _open(path: str | Path, what: str, follow_symlinks: bool) -> int:
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow_symlinks else os.O_NOFOLLOW)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if exc.errno == errno.ELOOP and not follow_symlinks:
            raise InputError(f"{what}{path}: is a symbolic link; give the file itself") from None
        if exc.errno == errno.ENOENT:
            raise InputError(f"{what.strip() or 'file'} not found: {path}") from None
        raise InputError(f"{what}{path}: cannot read ({exc.strerror or exc})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise InputError(f"{what}{path}: {_kind(st.st_mode)}, not a regular file: refused")
    return fd


def _kind(mode: int) -> str:
    """What a file that is not a regular file is, in words."""
    return ("a directory" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
            else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def file_kind(path: str | Path) -> str | None:
    """What ``path`` is when it exists and is not a regular file (``a directory``, ``a FIFO``, ``a device``,
    ``a socket``), following links; None when it is a regular file or does not exist (or cannot be looked at)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    return None if stat.S_ISREG(mode) else _kind(mode)


def state_file_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be a state file (``X: a FIFO, not a state file ...``), or None.

    A missing file is no problem here (the service creates it); a directory,
    FIFO, device or socket is, before SQLite opens it (a FIFO or a device
    gave ``disk I/O error`` and a ``-journal`` file created beside it).
    """
    kind = file_kind(path)
    return None if kind is None else f"{path}: {kind}, not a state file (an SQLite file the service creates)"


def _prefix(what: str) -> str:
    return f"{what} " if what else ""


def regular_file(path: str | Path, what: str = "", follow_symlinks: bool = True) -> Path:
    """The path, after checking that it names a readable regular file.

    Parameters
    ----------
    path : str or pathlib.Path
        The input.
    what : str
        What it is (``sky map``), for the message.
    follow_symlinks : bool
        Accept a symbolic link to a regular file.

    Raises
    ------
    InputError
        Missing, unreadable, a directory, FIFO, device or socket (or a link
        when ``follow_symlinks`` is False).
    """
    os.close(_open(path, _prefix(what), follow_symlinks))
    return Path(path)


def read_regular_file(path: str | Path, max_bytes: int = MAX_INPUT_BYTES, what: str = "",
                      follow_symlinks: bool = True) -> bytes:
    """A regular file's bytes, never from a FIFO or device, at most ``max_bytes``.

    Parameters
    ----------
    path : str or pathlib.Path
        The input.
    max_bytes : int
        Larger files are refused (by their size, before reading).
    what : str
        What it is (``plan``, ``config``), for the message.
    follow_symlinks : bool
        Accept a symbolic link to a regular file (False for the trigger
        directory).

    Raises
    ------
    InputError
        Not a regular file, larger than ``max_bytes``, or unreadable.
    """
    with open_regular_file(path, max_bytes, what, follow_symlinks) as fh:
        try:
            return fh.read(max_bytes + 1)[:max_bytes]
        except OSError as exc:
            raise InputError(f"{_prefix(what)}{path}: cannot read ({exc.strerror or exc})") from None


def open_regular_file(path: str | Path, max_bytes: int = MAX_INPUT_BYTES, what: str = "",
                      follow_symlinks: bool = True) -> BinaryIO:
    """A regular file opened for reading (binary), never a FIFO or device, refused when over ``max_bytes``.

    Parameters and errors as :func:`read_regular_file`; the caller reads (and closes) it.
    """
    fd = _open(path, _prefix(what), follow_symlinks)
    fh = os.fdopen(fd, "rb")
    size = os.fstat(fd).st_size
    if size > max_bytes:
        fh.close()
        raise InputError(f"{_prefix(what)}{path}: {size} bytes is more than the {max_bytes}-byte limit")
    return fh
