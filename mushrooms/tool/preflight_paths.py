"""The file checks of ``mushrooms preflight`` (:mod:`mushrooms.tool.preflight`): state file, directories, outbox.

Each returns one ``(status, name, reason)`` line.  Nothing is created or
changed: a missing path is checked for whether this user could create it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

__all__ = ["state_check", "directories_check", "outbox_directory_check"]

#: (status, name, reason); status is ``ok``, ``FAIL`` or ``skip``.
Result = tuple[str, str, str]


_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link"))


def _kind(mode: int) -> str:
    return next((what for test, what in _KINDS if test(mode)), "not a regular file")


def _creatable(path: Path) -> tuple[bool, str]:
    """Whether ``path`` can be created by this user: its nearest existing ancestor is a writable directory."""
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return False, f"{parent} is {_kind(parent.lstat().st_mode)}, not a directory"
    if not os.access(parent, os.W_OK | os.X_OK):
        return False, f"{parent} is not writable by this user ({_who()})"
    return True, f"will be created in {parent}"


def _who() -> str:
    import pwd

    try:
        return pwd.getpwuid(os.geteuid()).pw_name
    except KeyError:
        return f"uid {os.geteuid()}"


def state_check(config: Any) -> Result:
    from ..daemon.settings import resolve_paths

    path = resolve_paths(config.daemon).state
    base = ("" if Path(config.daemon.state_path).expanduser().is_absolute() else
            " ([daemon] state_path is relative: resolved against $STATE_DIRECTORY" if os.environ.get(
                "STATE_DIRECTORY") else " ([daemon] state_path is relative: resolved against the working directory, "
            "as the service does only when systemd sets no $STATE_DIRECTORY")
    base += ")" if base else ""
    try:
        st = path.lstat()
    except FileNotFoundError:
        ok, why = _creatable(path)
        return ("ok" if ok else "FAIL"), "state", f"{path}: not there yet, {why}{base}"
    if not stat.S_ISREG(st.st_mode):
        return "FAIL", "state", f"{path} is {_kind(st.st_mode)}, not a SQLite state file{base}"
    mode = stat.S_IMODE(st.st_mode)
    if not os.access(path, os.R_OK | os.W_OK):
        return "FAIL", "state", f"{path} (mode {mode:04o}) is not readable and writable by this user ({_who()})"
    if mode & 0o004:
        return "FAIL", "state", (f"{path} is world-readable (mode {mode:04o}): it keeps every notice, plan and "
                                 "answer of the submission target; chmod o-rwx it (the service makes it 0600, "
                                 "0640 with [daemon] group_readable)")
    problem = _sqlite_problem(path, st.st_size)
    if problem:
        return "FAIL", "state", f"{path}: {problem}"
    return "ok", "state", f"{path}: SQLite state file, mode {mode:04o}, writable by {_who()}{base}"


def _sqlite_problem(path: Path, size: int) -> str | None:
    """Why ``path`` is not a state file this program can run on, or None."""
    import sqlite3

    from ..daemon.state.schema import SCHEMA_VERSION
    from ..daemon.state.views import connect_readonly

    if size == 0:
        return "an empty file (0 bytes): the service refuses it; restore it, or remove it to start a new history"
    with open(path, "rb") as fh:
        if fh.read(16) != b"SQLite format 3\x00":
            return "not a SQLite file"
    try:
        conn = connect_readonly(path, timeout_s=2.0)
        try:
            version = conn.execute("PRAGMA user_version").fetchone()[0]
        finally:
            conn.close()
    except sqlite3.Error as exc:
        return f"not readable as SQLite ({exc})"
    if version > SCHEMA_VERSION:
        return f"schema {version}, newer than this program's {SCHEMA_VERSION}: use a newer mushrooms"
    return None


def _directory_problem(path: Path) -> str | None:
    try:
        st = path.lstat()
    except FileNotFoundError:
        ok, why = _creatable(path)
        return None if ok else f"{path}: {why}"
    if not stat.S_ISDIR(st.st_mode):
        return f"{path} is {_kind(st.st_mode)}, not a directory"
    if not os.access(path, os.W_OK | os.X_OK):
        return f"{path} is not writable by this user ({_who()})"
    return None


def directories_check(config: Any) -> Result:
    from ..daemon.settings import resolve_paths

    paths = resolve_paths(config.daemon)
    wanted = (paths.trigger_dir, paths.quarantine_dir, paths.pid_file.parent)
    problems = [p for p in map(_directory_problem, wanted) if p]
    if problems:
        return "FAIL", "directories", "; ".join(problems)
    return "ok", "directories", ", ".join(str(p) for p in wanted) + ": there or creatable, writable"


def outbox_directory_check(outbound: Any) -> Result:
    """The directory sink's directory: there and writable, or creatable; who can read the plans in it."""
    path = Path(outbound.directory).expanduser().absolute()
    relative = "" if Path(outbound.directory).expanduser().is_absolute() else \
        " ([outbound] directory is relative: resolved against the working directory, as the service does)"
    problem = _directory_problem(path)
    if problem:
        return "FAIL", "outbox", problem
    if not path.exists():
        return "ok", "outbox", f"{path}: not there yet, will be created by the service{relative}"
    mode = stat.S_IMODE(path.stat().st_mode)
    readers = "everyone" if mode & 0o005 == 0o005 else "its group" if mode & 0o050 == 0o050 else "its owner only"
    return "ok", "outbox", f"{path}: directory, mode {mode:04o} (plans readable by {readers}), writable{relative}"
