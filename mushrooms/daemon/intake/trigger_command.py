"""``mushrooms trigger``: hand a notice, sky map, superevent or closure to the running daemon, or plan it here.

With a daemon running, the target goes into its trigger directory, the
daemon is woken with SIGUSR1 and its answer is waited for (at most
:data:`~mushrooms.daemon.intake.trigger.RESULT_WAIT_S`); without one, the
job is done here with the same store and sink.  The files, the pid lock and
the dispatch are :mod:`~mushrooms.daemon.intake.trigger`'s.
"""

from __future__ import annotations

import logging
import os
import signal
from pathlib import Path
from typing import Any, Protocol

from ...handlers.text import storable
from ...scheduler_core.errors import InputError
from ..sections import ServiceConfig
from ..settings import RuntimePaths
from .trigger import RESULT_WAIT_S, closure_of, daemon_pid, dispatch, read_result, write_trigger

__all__ = ["run_trigger", "TriggerConsole", "LogConsole"]

log = logging.getLogger("mushrooms.daemon.trigger")


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
    console = console or LogConsole()
    target = storable(target)  # shown and logged only: a file name's terminal escapes are shown escaped
    pid = daemon_pid(paths.pid_file)
    if pid is not None and force:
        raise InputError(f"--force plans here, but a daemon runs (pid {pid}); stop it, or trigger without --force")
    if pid is not None:
        status = _hand_to_daemon(pid, target, kind, payload, config, paths, console)
        if status is not None:
            return status
    return _plan_here(target, kind, payload, config, paths, force, console)


def _hand_to_daemon(pid: int, target: str, kind: str, payload: bytes, config: ServiceConfig, paths: RuntimePaths,
                    console: TriggerConsole) -> int | None:
    """Write the trigger, wake the daemon and report its answer; None when the daemon died meanwhile."""
    written = write_trigger(paths.trigger_dir, kind, payload, config.daemon.group_readable)
    try:
        os.kill(pid, signal.SIGUSR1)
    except ProcessLookupError:
        written.unlink(missing_ok=True)  # died between the check and the signal: the caller does it here
        return None
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


def _plan_here(target: str, kind: str, payload: bytes, config: ServiceConfig, paths: RuntimePaths, force: bool,
               console: TriggerConsole) -> int:
    """No daemon: decide and run this trigger's job here, then publish; the exit status."""
    from ..planning.jobs import describe_outcome
    from ..wiring import open_pipeline

    outbox = config.outbound.directory if config.outbound.sink == "directory" else f"kafka:{config.outbound.topic}"
    pipeline, close = open_pipeline(config, paths)  # a state file the store refuses: one line, before the note
    console.note(f"no daemon running: planning here; state {paths.state}, outbox "
                 f"{Path(outbox).resolve() if config.outbound.sink == 'directory' else outbox}")
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
