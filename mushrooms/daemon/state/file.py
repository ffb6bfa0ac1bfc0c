"""The state file on disk: creating it with its mode, refusing what cannot be used, one daemon per file.

:func:`lock_state` holds an exclusive ``flock`` on the database file itself
(SQLite's own locks are POSIX record locks, which ``flock`` does not touch);
:func:`create_or_check_file` creates a missing file 0600 (or 0640) whatever
the umask and refuses an empty file or a symbolic link.  :class:`~mushrooms.daemon.state.store.Store`
checks the rest (a SQLite database passing ``PRAGMA quick_check``, a schema
not newer than this program's).
"""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

__all__ = ["StoreError", "StateInUse", "StateLock", "lock_state", "create_or_check_file"]


class StoreError(RuntimeError):
    """The state file cannot be used (newer schema, not a database, empty, damaged ...)."""


class StateInUse(StoreError):
    """Another process holds the state file's lock (a second daemon)."""


class StateLock:
    """An exclusive ``flock`` on the state database file, held while a daemon runs."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd: int | None = fd

    def release(self) -> None:
        """Drop the lock (closing our descriptor of the file)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def lock_state(path: str | Path) -> StateLock:
    """Take the single-instance lock of a state file, whatever the pid file.

    Call it after :class:`Store` has opened (or created) the file, and keep
    the returned lock until the store is closed.

    Raises
    ------
    StateInUse
        Another process holds it (its pid in the message when known).
    StoreError
        The file cannot be opened.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        raise StoreError(f"{p}: cannot open the state file to lock it ({exc.strerror or exc})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise StoreError(f"{p}: cannot lock the state file ({exc.strerror or exc})") from None
        raise StateInUse(f"state file {p} is in use by another mushrooms daemon{_holder(p)}") from None
    return StateLock(p, fd)


def _holder(path: Path) -> str:
    """`` (pid N)`` of the process holding ``path``'s flock, from /proc/locks, or ``""``."""
    try:
        st = path.stat()
        with open("/proc/locks") as fh:
            for line in fh:
                f = line.split()
                if len(f) >= 6 and f[1] == "FLOCK" and f[5].endswith(f":{st.st_ino}"):
                    dev = f[5].split(":")
                    if int(dev[0], 16) == os.major(st.st_dev) and int(dev[1], 16) == os.minor(st.st_dev):
                        return f" (pid {f[4]})"
    except (OSError, ValueError, IndexError):
        pass
    return ""


def create_or_check_file(path: Path, mode: int) -> None:
    """Create a missing state file with ``mode``; refuse an existing empty one or a link."""
    if path.is_symlink():
        raise StoreError(f"{path}: the state file is a symbolic link; give the real path")
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
    except FileExistsError:
        from ...inputs import state_file_problem

        if (problem := state_file_problem(path)) is not None:
            raise StoreError(problem) from None
        if path.is_file() and path.stat().st_size == 0:
            raise StoreError(f"{path}: the state file exists but is empty (0 bytes); refusing to start "
                             "from nothing: restore it, or remove it to start a new history") from None
        return
    except OSError as exc:
        raise StoreError(f"{path}: cannot create the state file ({exc.strerror or exc})") from None
    os.fchmod(fd, mode)  # whatever the umask
    os.close(fd)
