"""Output files: refused before any work when they cannot be written, then written atomically.

An output goes only to a regular file or a new path: never onto a device
node, a FIFO or a directory (``os.replace`` would turn a device node into a
regular file), never onto one of the command's inputs (``plan MAP -o MAP``
would destroy the sky map), never twice in one command.  A symbolic link
to a regular file is written through: its target is replaced, the link
stays.  The file appears whole or not at all (temporary file, fsync,
rename) with the mode an editor would give it: an existing file keeps its
mode, a new one gets ``0666 & ~umask`` (not ``mkstemp``'s 0600).
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path
from typing import Any, Iterable

from .scheduler_core.plan import strict_json

__all__ = ["check_output_path", "check_outputs", "write_json_atomic", "write_bytes_atomic"]


def _target(path: Path) -> Path:
    """Where writing ``path`` lands: the target of a symbolic link, else the path."""
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output_path(path: str | Path, what: str, inputs: Iterable[str | Path] = ()) -> Path:
    """Refuse, before any work, an output file that could not or must not be written.

    Parameters
    ----------
    path : str or pathlib.Path
        The output file.
    what : str
        The option that named it (``-o/--output``), for the message.
    inputs : iterable of paths
        The command's input files: the output must be none of them.

    Returns
    -------
    pathlib.Path
        Where the file will be written (a symbolic link's target).

    Raises
    ------
    InputError
        One line naming the option and the reason: a directory, a device
        node or FIFO, a symbolic link to a missing file or a non-regular
        one, one of the inputs, a missing or unwritable directory.
    """
    from .scheduler_core.errors import InputError

    p = Path(path)
    if not str(path).strip():
        raise InputError(f"{what}: an empty file name")
    if p.is_symlink() and not p.exists():
        raise InputError(f"{what} {path}: a symbolic link to a missing file ({os.readlink(p)})")
    target = _target(p)
    if target.is_dir():
        raise InputError(f"{what} {path}: is a directory")
    if target.exists() and not stat.S_ISREG(target.stat().st_mode):
        raise InputError(f"{what} {path}: not a regular file (a device, FIFO or socket): refused")
    for source in inputs:
        if source and Path(source).exists() and target.exists() and _same_file(target, Path(source)):
            raise InputError(f"{what} {path}: is the input {source}; it would be overwritten: give another file")
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{what} {path}: directory {parent} does not exist")
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{target.name}.", suffix=".probe")
    except OSError as exc:
        raise InputError(f"{what} {path}: cannot write in {parent}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)
    return target


def check_outputs(outputs: dict[str, str | Path | None], inputs: Iterable[str | Path] = ()) -> None:
    """:func:`check_output_path` for each given output, and no two outputs the same file.

    Parameters
    ----------
    outputs : dict
        Option -> path (None or empty: not asked for).
    inputs : iterable of paths
        The command's input files.
    """
    from .scheduler_core.errors import InputError

    inputs = [i for i in inputs if i]
    seen: dict[str, str] = {}
    for what, path in outputs.items():
        if not path:
            continue
        target = os.path.realpath(check_output_path(path, what, inputs))
        if target in seen:
            raise InputError(f"{what} {path}: the same file as {seen[target]}: give each output its own file")
        seen[target] = what


def _umask() -> int:
    """The process's umask, read without changing it (Linux ``/proc``), else by setting and restoring it."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write bytes so that readers see the old file or the whole new one.

    A symbolic link is written through (its target replaced); the new file
    keeps the old one's mode, or gets ``0666 & ~umask``.  The directory is
    not created: :func:`check_output_path` refused a missing one before.
    """
    target = _target(Path(path))
    try:
        mode = stat.S_IMODE(target.stat().st_mode)
    except FileNotFoundError:
        mode = 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fchmod(fh.fileno(), mode)
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json_atomic(path: str | Path, obj: Any) -> None:
    """Write a JSON document (never NaN nor infinity: :mod:`~mushrooms.scheduler_core.plan.strict_json`) atomically."""
    write_bytes_atomic(path, (strict_json.dumps(obj, indent=1) + "\n").encode())

