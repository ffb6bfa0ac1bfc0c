"""Manual triggers: ``mushrooms trigger NOTICE.json | SKYMAP.fits | SUPEREVENT_ID``.

With a daemon running (it holds an exclusive lock on its pid file), the
target is written atomically into the daemon's trigger directory and the
daemon is woken with SIGUSR1; it stores the trigger like a received notice
and plans it.  Without a daemon the command does the job itself, with the
same store and a directory sink.

Trigger files: ``<time>-<pid>-<kind>.<ext>`` where kind is ``notice``
(the notice bytes), ``skymap`` (the FITS bytes), ``superevent`` (the id,
UTF-8) or ``closure`` (``mushrooms trigger SUPEREVENT --closed-until TIME``:
``{"superevent_id": ..., "closed_until": ...}``, JSON; the event is re-planned
from the reopening, :meth:`~mushrooms.daemon.intake.pipeline.NoticePipeline.replan_closure`).  The daemon deletes a file only after its outcome is stored.

The answer is truthful: the daemon writes the outcome next to the trigger
(``.<name>.result``, JSON: the decision, its reason and, for a planning job,
the outcome of the job's first plan) and the command prints it and exits 2
for a refusal (an unknown superevent, a sky map the planner cannot read),
1 for a failure on our side, 0 otherwise; it only says "queued" when no
answer came within :data:`RESULT_WAIT_S`.

No symbolic link is ever followed (a link planted in the trigger directory
would otherwise put a protected file's bytes into the state), nor anything
but a regular file read; the directory is created 0700 and the files 0600.

This module holds the trigger files, the pid lock and the dispatch the
daemon runs; the command's side (hand over, or plan here) is
:mod:`~mushrooms.daemon.intake.trigger_command`.
"""

from __future__ import annotations

import fcntl
import logging
import os
import re
import stat
import time
from pathlib import Path
from typing import Any, IO

from ... import inputs
from ...scheduler_core.errors import InputError
from ...scheduler_core.sky.sniff import is_fits

__all__ = [
    "PidLock", "daemon_pid", "classify", "write_trigger", "pending_triggers", "read_trigger", "read_result",
    "write_result", "outcome_result", "dispatch", "DaemonRunning", "closure_payload", "closure_of", "RESULT_WAIT_S",
]

log = logging.getLogger("mushrooms.daemon.trigger")

SUPEREVENT_RE = re.compile(r"^[MTS][A-Z]?\d{6}[a-z]{1,3}$")
KINDS = {"notice": "json", "skymap": "fits", "superevent": "txt", "closure": "json"}
#: How long (s) ``mushrooms trigger`` waits for the daemon's answer (the decision and the job's first plan).
RESULT_WAIT_S = 180.0
#: Largest trigger file read (bytes): a sky map is at most 4 x the 8 MiB notice limit.
MAX_TRIGGER_BYTES = 64 * 1024 * 1024


def read_regular_file(path: Path, max_bytes: int = MAX_TRIGGER_BYTES) -> bytes:
    """A trigger file's bytes: :func:`mushrooms.inputs.read_regular_file`, never through a symbolic link.

    Raises
    ------
    InputError
        A symbolic link, not a regular file, larger than ``max_bytes``, or unreadable.
    """
    return inputs.read_regular_file(path, max_bytes, follow_symlinks=False)


class DaemonRunning(RuntimeError):
    """Another daemon already holds the pid file lock."""


class PidLock:
    """The daemon's pid file, held with an exclusive ``flock`` while it runs.

    A stale file left by a killed daemon is not locked, so it never blocks
    a restart nor fools ``mushrooms trigger``.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._fh: IO[str] | None = None

    def acquire(self) -> None:
        """Take the lock and write our pid; raises :class:`DaemonRunning`.

        Raises
        ------
        InputError
            The pid file cannot be created or written (e.g. a read-only
            state directory): one line and exit 2, which the unit's
            ``RestartPreventExitStatus=`` does not restart on (a restart
            cannot make the directory writable).
        """
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fh = open(self.path, "a+")
        except OSError as exc:
            raise InputError(f"{self.path}: cannot write the pid file ({exc.strerror or exc}); the state "
                             "directory must be writable by the service") from None
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            other = fh.read().strip() or "?"
            fh.close()
            raise DaemonRunning(f"another mushrooms daemon runs (pid {other}, {self.path})") from None
        try:
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
            fh.flush()
            os.fsync(fh.fileno())
        except OSError as exc:
            fh.close()
            raise InputError(f"{self.path}: cannot write the pid file ({exc.strerror or exc})") from None
        self._fh = fh

    def release(self) -> None:
        """Remove the pid file and drop the lock."""
        if self._fh is None:
            return
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        self._fh.close()
        self._fh = None


def daemon_pid(pid_file: Path) -> int | None:
    """Pid of the running daemon, or None when no daemon holds the lock."""
    try:
        fh = open(pid_file)
    except FileNotFoundError:
        return None
    with fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            text = fh.read().strip()
            return int(text) if text.isdigit() else None
        fcntl.flock(fh, fcntl.LOCK_UN)
        return None


def classify(target: str) -> tuple[str, bytes]:
    """Tell a notice file, a sky map file and a superevent id apart.

    Returns
    -------
    kind : str
        ``notice``, ``skymap`` or ``superevent``.
    payload : bytes
        The file's bytes, or the id.

    Raises
    ------
    InputError
        When the target is none of the three.
    """
    path = Path(target)
    if path.is_symlink():
        raise InputError(f"{target}: is a symbolic link; give the file itself")
    if path.is_file():
        data = read_regular_file(path)
        if is_fits(data):
            return "skymap", data
        head = data[:80].lstrip()
        if head.startswith(b"{") or data[:4] == b"Obj\x01" or path.suffix.lower() in (".json", ".avro"):
            return "notice", data
        raise InputError(f"{target}: neither a notice (JSON/Avro) nor a sky map (FITS)")
    if SUPEREVENT_RE.match(target):
        return "superevent", target.encode()
    raise InputError(f"{target}: no such file, and not a superevent id (like S250101ab)")


def write_trigger(trigger_dir: Path, kind: str, payload: bytes, group_readable: bool = False) -> Path:
    """Write a trigger file atomically (temporary name, fsync, rename), 0600 (0640 group readable)."""
    if not trigger_dir.is_dir():
        trigger_dir.mkdir(parents=True, exist_ok=True)
        trigger_dir.chmod(0o750 if group_readable else 0o700)
    name = f"{time.time_ns():020d}-{os.getpid()}-{kind}.{KINDS[kind]}"
    tmp = trigger_dir / f".{name}.tmp"
    mode = 0o640 if group_readable else 0o600
    with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, mode), "wb") as fh:
        fh.write(payload)
        fh.flush()
        os.fsync(fh.fileno())
    final = trigger_dir / name
    os.replace(tmp, final)
    dfd = os.open(trigger_dir, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)
    return final


def result_path(trigger: Path) -> Path:
    """Where the daemon answers a trigger file (a dot file: never taken for a trigger)."""
    return trigger.with_name(f".{trigger.name}.result")


def write_result(trigger: Path, result: dict[str, Any], group_readable: bool = False) -> None:
    """The daemon's answer to a trigger, written atomically (never raises: the answer is a courtesy)."""
    import json

    final = result_path(trigger)
    tmp = final.with_name(final.name + ".tmp")
    try:
        with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW,
                          0o640 if group_readable else 0o600), "w") as fh:
            json.dump(result, fh)
        os.replace(tmp, final)
    except OSError as exc:
        log.warning("event=trigger_result_not_written file=%s error=%r", trigger.name, str(exc))


def read_result(trigger: Path, timeout_s: float) -> dict[str, Any] | None:
    """Wait up to ``timeout_s`` (s) for the daemon's answer to ``trigger``; consume it."""
    import json

    path = result_path(trigger)
    end = time.monotonic() + timeout_s
    while True:
        try:
            data = json.loads(read_regular_file(path, 1 << 20))
        except InputError:
            data = None
        except ValueError:  # half written by an old daemon: wait for the rename
            data = None
        if isinstance(data, dict):
            path.unlink(missing_ok=True)
            return data
        if time.monotonic() > end:
            return None
        time.sleep(0.1)


def outcome_result(decision: Any, outcome: Any = None) -> dict[str, Any]:
    """The answer to a trigger from its decision and (for a planning job) its first plan's outcome."""
    out = {"decision": str(getattr(decision, "action", "") or ""), "reason": str(getattr(decision, "reason", "")),
           "superevent_id": getattr(decision, "superevent_id", None)}
    if outcome is not None:
        inner = getattr(outcome, "outcome", outcome)  # a Staged first stage carries its Outcome
        out.update(decision=str(getattr(inner, "decision", out["decision"])),
                   reason=str(getattr(inner, "reason", "")), plan_id=getattr(inner, "plan_id", None))
    return out


def pending_triggers(trigger_dir: Path) -> list[Path]:
    """Trigger files waiting, oldest first (temporary files excluded).

    Only regular files count.  A symbolic link, FIFO or anything else with
    a trigger's name is renamed ``.NAME.refused`` (never opened) and
    logged once.
    """
    if not trigger_dir.is_dir():
        return []
    found = []
    for p in trigger_dir.iterdir():
        if p.name.startswith(".") or _kind_of(p) is None:
            continue
        if stat.S_ISREG(p.lstat().st_mode):
            found.append(p)
            continue
        log.warning("event=trigger_refused file=%s reason='not a regular file (symbolic link, FIFO, ...)'", p.name)
        try:
            os.replace(p, p.with_name(f".{p.name}.refused"))
        except OSError:
            pass
    return sorted(found)


def _kind_of(path: Path) -> str | None:
    stem = path.name.rsplit(".", 1)[0]
    kind = stem.rsplit("-", 1)[-1]
    return kind if kind in KINDS else None


def read_trigger(path: Path) -> tuple[str, bytes]:
    """Kind and payload of a trigger file."""
    kind = _kind_of(path)
    if kind is None:
        raise InputError(f"{path.name}: not a trigger file")
    return kind, read_regular_file(path)


def dispatch(pipeline: Any, kind: str, payload: bytes, origin: str) -> Any:
    """Store a trigger through the pipeline; returns its Decision.

    A notice goes through ``accept`` like one from Kafka.  A sky map and a
    superevent id use the pipeline's manual entry points.
    """
    if kind == "notice":
        return pipeline.accept(payload, origin)
    if kind == "skymap":
        return pipeline.accept_skymap(payload, origin)
    if kind == "superevent":
        return pipeline.rerun_superevent(payload.decode().strip(), origin)
    if kind == "closure":
        sid, until = closure_of(payload)
        return pipeline.replan_closure(sid, until, origin)
    raise InputError(f"unknown trigger kind {kind!r}")


def closure_payload(superevent_id: str, closed_until: str) -> bytes:
    """The payload of a ``closure`` trigger (``--closed-until``): JSON of the event and the reopening (ISO UTC)."""
    import json

    return json.dumps({"superevent_id": superevent_id, "closed_until": closed_until}).encode()


def closure_of(payload: bytes) -> tuple[str, str]:
    """The superevent and the reopening of a ``closure`` trigger's payload.

    Raises
    ------
    InputError
        Not the JSON :func:`closure_payload` writes.
    """
    import json

    try:
        doc = json.loads(payload)
        sid, until = doc["superevent_id"], doc["closed_until"]
    except (ValueError, KeyError, TypeError):
        raise InputError("a closure trigger is {\"superevent_id\": ..., \"closed_until\": ...}") from None
    if not isinstance(sid, str) or not isinstance(until, str):
        raise InputError("a closure trigger's superevent_id and closed_until are strings")
    return sid, until
