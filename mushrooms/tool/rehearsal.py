"""The rehearsal's run: the service as a process of its own, watched until its plan is final, then stopped.

:class:`Rehearsal` starts ``mushrooms run`` (its log in ``DIR/service.log``),
waits until it consumes, lets the caller send the notice, tells each log
line and each published document in words, and ends when the plan is final
(then it waits a little for the submission's and the webhook's outcome), when
the service fails, or at the timeout.  It always stops the service.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

from .rehearse_watch import LogTail, OutboxWatch, document_words, is_final, log_words, parse_log_line, queues_of

__all__ = ["Rehearsal", "RehearsalFailed", "say"]

#: Seconds between two looks at the log and the outbox.
TICK_S = 0.1
#: Environment the service must not inherit from a rehearsal run under systemd.
_SYSTEMD_ENV = ("NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID", "JOURNAL_STREAM")
#: Submission events that end a submission attempt (the rehearsal waits for one of the final plan).
_SUBMISSION_OUTCOMES = {f"submission_{s}" for s in ("submitted", "failed", "rejected", "dry_run", "skipped",
                                                     "retry", "replaced", "expired")}
_NOTIFY_OUTCOMES = {"notify_sent", "notify_failed", "notify_dropped"}
#: Submission events that mean the plan did not reach the queue (yet).
_FAILED_SUBMISSION = {"submission_failed", "submission_rejected", "submission_retry"}
_ANNOUNCED = ("plan", "plan_final", "not_observable", "withdrawal", "submission")
#: A job's decisions that mean its planning failed (``event=job_done decision=...``).
_FAILED_JOB = ("failed", "rejected")


def say(text: str, t0: float) -> None:
    """One line of the rehearsal, with the seconds since it started (``t0``, ``time.monotonic()``)."""
    print(f"[{time.monotonic() - t0:6.1f} s] {text}", flush=True)


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


class RehearsalFailed(Exception):
    """The rehearsal cannot go on; ``str()`` is the one line to print."""


class Rehearsal:
    """The service under rehearsal.

    Parameters
    ----------
    command : list of str
        ``mushrooms run ...`` (:func:`~.rehearse.service_command`).
    out : Path
        The rehearsal's directory (``service.log``, ``outbox/``, the state).
    t0 : float
        ``time.monotonic()`` at the rehearsal's start (the lines' clock).
    timeout_s : float
        The plan must be final this long after the service was started.
    config : Config
        The effective configuration (what to wait for after the plan: a
        submission, a webhook message; how long the service may take to stop).
    temporary : bool
        ``out`` is a temporary directory, removed when the rehearsal passes.
    """

    def __init__(self, command: list[str], out: Path, t0: float, timeout_s: float, config: Any,
                 temporary: bool = False) -> None:
        self.command, self.out, self.t0, self.timeout_s, self.config = command, Path(out), t0, timeout_s, config
        self.temporary = temporary  # the directory goes when the rehearsal passes: say so, not where its files are
        self.log = LogTail(self.out / "service.log")
        self.outbox = OutboxWatch(self.out / "outbox")
        self.proc: subprocess.Popen | None = None
        self.sent_at: float | None = None
        self.final: dict[str, Any] | None = None
        self.final_after_s = 0.0
        self.answer = ""
        self.events: list[Any] = []

    def say(self, text: str) -> None:
        say(text, self.t0)

    def run(self, send: Callable[[], None]) -> int:
        """Start the service, ``send()`` once it consumes, watch until final; the exit status."""
        env = {k: v for k, v in os.environ.items() if k not in _SYSTEMD_ENV}
        with open(self.out / "service.log", "wb") as fh:
            # a session of its own: Ctrl-C reaches the rehearsal, which stops the service in order
            self.proc = subprocess.Popen(self.command, stdout=fh, stderr=subprocess.STDOUT, env=env,
                                         start_new_session=True)
        previous = signal.signal(signal.SIGTERM, _interrupt)  # a SIGTERM stops the service too
        self.say(f"service started (pid {self.proc.pid}); its log: {self.out / 'service.log'}")
        self.deadline = time.monotonic() + self.timeout_s
        try:
            self._until(lambda: any(e.event == "consuming" for e in self.events), "the service to consume")
            send()
            self.sent_at = time.monotonic()
            self._until(lambda: self.final is not None, "the final plan")
            self._linger()
            self._summary()
            self._judge_outcomes()
        except RehearsalFailed as exc:
            self._stop(ok=False)
            print(f"mushrooms rehearse: error: {exc}", file=sys.stderr, flush=True)
            return 1
        except KeyboardInterrupt:
            self._stop(ok=False)
            print("mushrooms rehearse: interrupted", file=sys.stderr, flush=True)
            return 130
        finally:
            signal.signal(signal.SIGTERM, previous)
        return self._stop()

    # ------------------------------------------------------------ watching
    def _look(self) -> None:
        """Tell the new log lines and published documents; raise :class:`RehearsalFailed` on a failure."""
        for text in self.log.read():
            line = parse_log_line(text)
            if line is None:
                continue
            self.events.append(line)
            words = log_words(line)
            if words:
                self.say(words)
            self._judge(line)
        for doc in self.outbox.read():
            words = document_words(doc)
            if words:
                after = f" [{time.monotonic() - self.sent_at:.1f} s after the notice]" if self.sent_at else ""
                self.say(words + after)
            if is_final(doc) and self.final is None:
                self.final = doc
                self.final_after_s = time.monotonic() - (self.sent_at or self.t0)

    def _judge(self, line: Any) -> None:
        f = line.fields
        decision = f.get("decision") or f.get("action")
        if line.event == "notice" and decision not in ("plan", "rerun"):
            raise RehearsalFailed(f"the service did not plan the notice: {decision} ({f.get('reason', '')})")
        if line.event == "job_failed":
            raise RehearsalFailed(f"planning failed at {f.get('stage', '?')}: {f.get('error', '')}")
        if line.event == "job_done" and decision in _FAILED_JOB:  # a job whose stage failed ends so (no job_failed)
            raise RehearsalFailed(f"planning {f.get('superevent_id', '-')} failed ({decision}): "
                                  f"{' '.join(f.get('reason', '').split())[:300]}")
        if line.event == "warm_up_plan_failed":
            raise RehearsalFailed(f"the service is not ready: its warm-up plan failed: {f.get('error', '')}")
        if line.event == "start_refused":
            raise RehearsalFailed(f"the service refused to start: {f.get('reason', '')}")

    def _until(self, done: Callable[[], bool], what: str) -> None:
        while True:
            self._look()
            if done():
                return
            assert self.proc is not None
            if self.proc.poll() is not None:
                self._look()
                if done():
                    return
                raise RehearsalFailed(f"the service exited (status {self.proc.returncode}) while waiting for {what}"
                                      f"{self._last_error()}; the service's log: {self.out / 'service.log'}")
            if time.monotonic() > self.deadline:
                raise RehearsalFailed(f"gave up waiting for {what}: --timeout {self.timeout_s:g} s is over"
                                      f"{self._last_error()}; the service's log: {self.out / 'service.log'}")
            time.sleep(TICK_S)

    def _last_error(self) -> str:
        for line in reversed(self.events):
            if line.level in ("ERROR", "CRITICAL"):
                return f"; its last error: {' '.join(line.message.split())[:200]}"
        for text in reversed(self.log.lines[-20:]):
            if text.strip() and parse_log_line(text) is None:
                return f"; it said: {text.strip()[:200]}"
        return ""

    def _linger(self) -> None:
        """After the final plan: wait (a little) for its submission's outcome and the webhook's answers."""
        submit, notify = self.config.submit, self.config.notify
        wait = max(submit.timeout_s + 5.0 if submit.enabled else 0.0, notify.timeout_s + 2.0 if notify.enabled else 0.0)
        plan_id = (self.final or {}).get("plan_id")
        end = time.monotonic() + wait

        def settled() -> bool:
            submitted = not submit.enabled or any(
                e.event in _SUBMISSION_OUTCOMES and e.fields.get("plan_id") == plan_id for e in self.events)
            announced = sum(1 for d in self.outbox.documents.values() if d.get("type") in _ANNOUNCED)
            told = sum(1 for e in self.events if e.event in _NOTIFY_OUTCOMES)
            return submitted and (not notify.enabled or told >= announced)

        while time.monotonic() < end and not settled():
            self._look()
            time.sleep(TICK_S)
        if not settled():
            self.say(f"(stopped waiting for the submission and webhook outcomes after {wait:.0f} s)")

    def _judge_outcomes(self) -> None:
        """The plan is final; a submission or a webhook message that failed still fails the rehearsal."""
        problems: list[str] = []
        for e in self.events:
            if e.event in _FAILED_SUBMISSION and not any(p.startswith("submission") for p in problems):
                why = e.fields.get("error") or e.fields.get("reason") or e.fields.get("state", "")
                what = {"submission_retry": "did not reach the queue (the service retries)",
                        "submission_failed": "FAILED", "submission_rejected": "was REJECTED"}[e.event]
                problems.append(f"submission of {e.fields.get('plan_id', '-')} ({queues_of(e.fields)}) "
                                f"{what}: {why[:200]}")
            if e.event in ("notify_failed", "notify_dropped") and not any(p.startswith("webhook") for p in problems):
                detail = e.message.split("error=", 1)[1] if "error=" in e.message else e.message
                what = "failed" if e.event == "notify_failed" else "dropped"
                problems.append(f"webhook message {e.fields.get('kind', '-')} {what}: {' '.join(detail.split())[:200]}")
        if problems:
            raise RehearsalFailed("the plan is final, but " + "; ".join(problems))

    def _summary(self) -> None:
        from ..report.summary import summary_text

        from ..report.files import revision_in_force

        doc = self.final or {}
        if doc.get("type") == "plan_final":  # the verdict makes the revision it names final
            doc = revision_in_force(self.outbox.documents.values()) or doc
        if doc.get("type") not in ("plan", "not_observable"):
            return
        from ..report.summary import answer_line

        sid = (doc.get("event") or {}).get("superevent_id") or "-"
        self.answer = (f"{sid} revision {doc.get('revision', 1)} final {self.final_after_s:.1f} s after the "
                       f"notice: {answer_line(doc)}")
        print("", flush=True)
        print(summary_text(doc, rows=False), flush=True)
        stem = self.out / "outbox" / str(doc.get("plan_id"))
        if not self.temporary:
            self.say(f"the plan: {stem}.json, its summary {stem}.txt (one row per exposure) and page {stem}.html")
        self._parts(sid)

    def _parts(self, sid: str) -> None:
        """Every other telescope's part of the event (issue 53: ``[scheduler] telescopes`` after ztf), one line each."""
        import json

        from ..daemon.state.parts import part_line

        for path in sorted((self.out / "outbox" / "telescopes").glob("*/*/*/part.json")):
            try:
                doc = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if doc.get("superevent_id") == sid:
                self.say("telescope part: " + part_line({**doc, "folder": str(path.parent)}))

    # ------------------------------------------------------------ stopping
    def _stop(self, ok: bool = True) -> int:
        """SIGTERM the service and wait for it; 0 when it stopped cleanly (``ok``: the rehearsal went well)."""
        proc = self.proc
        if proc is None:
            return 1
        if proc.poll() is None:
            self.say("stopping the service (SIGTERM)")
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(self.config.daemon.stop_grace_s + 30.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
                self._look_quietly()
                print("mushrooms rehearse: error: the service did not stop within its grace; killed", file=sys.stderr,
                      flush=True)
                return 1
        self._look_quietly()
        if proc.returncode != 0:
            if ok:
                print(f"mushrooms rehearse: error: the service ended with status {proc.returncode}"
                      f"{self._last_error()}", file=sys.stderr, flush=True)
            return 1
        self.say("service stopped cleanly (exit 0)")
        if ok:
            where = "" if self.temporary else f"; everything in {self.out}"
            self.say(f"rehearsal passed: {self.answer or 'the plan is final'}{where}")
        return 0

    def _look_quietly(self) -> None:
        """Tell the last lines; a failure seen now is already being handled."""
        try:
            self._look()
        except RehearsalFailed:
            pass
