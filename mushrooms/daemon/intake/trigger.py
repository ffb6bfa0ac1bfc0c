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
"""

from __future__ import annotations

import fcntl
import logging
import os
import re
import signal
import stat
import time
from pathlib import Path
from typing import Any, IO, Protocol

from ... import inputs
from ...scheduler_core.errors import InputError
from ...scheduler_core.sky.sniff import is_fits
from ..sections import ServiceConfig
from ..settings import RuntimePaths

__all__ = [
    "run_trigger", "TriggerConsole", "LogConsole", "PidLock", "daemon_pid", "classify", "write_trigger", "pending_triggers",
    "read_trigger", "dispatch", "DaemonRunning", "closure_payload", "closure_of",
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


class TriggerConsole(Protocol):
    """Where :func:`run_trigger` says what happened: the tool prints (``mushrooms trigger: ...``)."""

    def result(self, text: str) -> None:
        """The outcome (stdout)."""

    def note(self, text: str) -> None:
        """Where the work is done, what ``--force`` did (stderr)."""

    def warning(self, text: str) -> None:
        """Something the operator should know (stderr, ``warning:``)."""

    def error(self, text: str) -> None:
        """The trigger failed or was refused (stderr, ``error:``)."""


class LogConsole:
    """A :class:`TriggerConsole` for library callers: every message to this module's log."""

    def result(self, text: str) -> None:
        log.info("trigger: %s", text)

    def note(self, text: str) -> None:
        log.info("trigger: %s", text)

    def warning(self, text: str) -> None:
        log.warning("trigger: %s", text)

    def error(self, text: str) -> None:
        log.error("trigger: %s", text)


def run_trigger(target: str, kind: str, payload: bytes, config: ServiceConfig, paths: RuntimePaths,
                force: bool = False, console: TriggerConsole | None = None) -> int:
    """``mushrooms trigger``: hand work to the daemon, or do it here; the exit status.

    Parameters
    ----------
    target : str
        What was named on the command line (for messages and the origin).
    kind, payload : str, bytes
        The target as :func:`classify` read it.
    config : ServiceConfig
        The assembled configuration, command-line overrides included.
    paths : RuntimePaths
        The runtime paths resolved from ``config.daemon`` (the daemon's pid
        file and trigger directory, the state file).
    force : bool
        ``--force``: plan even when the policy would not (needs no daemon running).
    console : TriggerConsole, optional
        Told the outcome and the notes on the way (default: :class:`LogConsole`).

    Returns
    -------
    int
        0 done or handed over, 1 a job failed, 2 refused.
    """
    from ..wiring import open_pipeline

    console = console or LogConsole()

    pid = daemon_pid(paths.pid_file)
    if pid is not None and force:
        raise InputError(f"--force plans here, but a daemon runs (pid {pid}); stop it, or trigger without --force")
    if pid is not None:
        written = write_trigger(paths.trigger_dir, kind, payload, config.daemon.group_readable)
        try:
            os.kill(pid, signal.SIGUSR1)
        except ProcessLookupError:
            pid = None  # died between the check and the signal: do it ourselves below
            written.unlink(missing_ok=True)
        else:
            # wait for the daemon's answer (its decision, and a planning job's first plan), to report honestly
            result = read_result(written, RESULT_WAIT_S)
            if result is None:
                left = written.exists()
                console.result(f"{kind} {target} handed to the daemon (pid {pid}): "
                               + ("queued (the daemon will take it at its next scan)" if left else
                                  "taken; no answer yet (see the daemon's log)"))
                return 0
            decision, reason = result.get("decision", "?"), result.get("reason", "")
            plan = f"; plan {result['plan_id']}" if result.get("plan_id") else ""
            status = {"rejected": 2, "failed": 1}.get(str(decision), 0)
            text = f"{kind} {target} handed to the daemon (pid {pid}): {decision} ({reason}){plan}"
            if status:
                console.error(text)
            else:
                console.result(text)
            return status
    # no daemon: do the job here
    outbox = config.outbound.directory if config.outbound.sink == "directory" else f"kafka:{config.outbound.topic}"
    console.note(f"no daemon running: planning here; state {paths.state}, outbox "
                 f"{Path(outbox).resolve() if config.outbound.sink == 'directory' else outbox}")
    pipeline, close = open_pipeline(config, paths)
    try:
        _warn_if_retracted(pipeline, kind, payload, force, console)
        decision = dispatch(pipeline, kind, payload, origin=f"trigger:{kind}:{target}")
        if force:
            decision = _forced(pipeline, decision, kind, payload, target, console)
        log.info("event=trigger_accepted kind=%s target=%s decision=%s", kind, target,
                 _decision_text(decision))
        if getattr(decision, "action", None) == "rejected":
            console.error(f"{target}: {getattr(decision, 'reason', 'rejected')}")
            return 2
        from ..planning.jobs import describe_outcome

        done, status, info = 0, 0, {}
        job = getattr(decision, "job", None)
        if job is not None:  # only this trigger's job: leftovers wait for the daemon
            outcome = pipeline.run_job(job, None)
            info = describe_outcome(outcome)
            log.info("event=job_done superevent_id=%s job=%s %s", job.superevent_id, job.job_id,
                     " ".join(f"{k}={v}" for k, v in info.items()))
            done = 1
            status = {"rejected": 2, "failed": 1}.get(str(info.get("decision")), 0)
            if status:
                console.error(f"{target}: job {info.get('decision')}: {info.get('reason', '')}")
        pipeline.flush_outbox()
        result = f": {info.get('decision')}: {info.get('reason', '')}" if done else ""
        console.result(f"no daemon running; {kind} {target}: "
                       f"{_decision_text(decision)}, {done} job(s) run here{result}")
    finally:
        close()
    return status


def _superevent_of(kind: str, payload: bytes) -> str | None:
    """The superevent a trigger concerns (None for a bare sky map or an unreadable notice)."""
    if kind == "superevent":
        return payload.decode().strip()
    if kind == "closure":
        return closure_of(payload)[0]
    if kind == "notice":
        from ...handlers.alert import NoticeError, parse_notice

        try:
            return parse_notice(payload).superevent_id
        except NoticeError:
            return None
    return None


def _warn_if_retracted(pipeline: Any, kind: str, payload: bytes, force: bool, console: TriggerConsole) -> None:
    """Warn (the console and the log) when the trigger concerns a retracted superevent."""
    sid = _superevent_of(kind, payload)
    state = pipeline.store.event_state(sid) if sid else None
    if state is not None and state.retracted:
        what = ("planning it anyway (--force)" if force else "re-planning it as asked") \
            if force or kind == "superevent" else "the policy decides (a notice after a retraction may plan it again)"
        log.warning("event=trigger_retracted superevent_id=%s: the event was retracted; %s", sid, what)
        console.warning(f"{sid} was retracted; {what}")


def _forced(pipeline: Any, decision: Any, kind: str, payload: bytes, target: str, console: TriggerConsole) -> Any:
    """``--force``: when the policy did not plan a notice (ignored or duplicate), re-plan its superevent.

    The re-plan uses the stored notice (the one just recorded, or the newest
    planned one) and supersedes the event's latest plan; the policy's reason
    is logged.
    """
    action = getattr(decision, "action", None)
    if kind != "notice" or action in ("plan", "rerun", "rejected", "withdraw"):
        return decision
    if getattr(decision, "alert_type", None) == "RETRACTION":
        console.note("--force does not apply to a retraction (nothing to plan)")
        return decision
    sid = getattr(decision, "superevent_id", None)
    log.warning("event=trigger_forced superevent_id=%s target=%s policy_decision=%s policy_reason=%r: "
                "planning anyway (--force)", sid, target, action, getattr(decision, "reason", ""))
    console.note(f"--force: the policy said {action} ({getattr(decision, 'reason', '')}); planning anyway")
    forced = pipeline.force_plan(payload, origin=f"trigger:force:{target}")
    return forced


def _decision_text(decision: Any) -> str:
    for name in ("action", "kind", "decision"):
        value = getattr(decision, name, None)
        if value is not None:
            value = getattr(value, "value", value)
            reason = getattr(decision, "reason", None)
            return f"{value}" + (f" ({reason})" if reason else "")
    return str(decision)
