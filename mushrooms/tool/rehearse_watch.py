"""What a rehearsal sees of the service: its log lines and its outbox, told in words.

The service is watched from the outside, as an operator would: its log (one
``event=NAME key=value ...`` line per thing that happens, the format of
``docs/operations.md``) and the documents it publishes into the outbox
directory.  :func:`log_words` turns the log lines that matter into a sentence
(warnings and errors are always told); :class:`OutboxWatch` reads each new
document once; :func:`document_words` tells it.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

__all__ = ["LogLine", "parse_log_line", "log_words", "queues_of", "LogTail", "OutboxWatch", "document_words",
           "is_final"]

_LINE = re.compile(r"^(?:\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d+ )?(?P<level>[A-Z]+) (?P<name>[\w.]+): (?P<message>.*)$")
_PAIR = re.compile(r"""(\w+)=('(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*"|\S+)""")


@dataclass(frozen=True)
class LogLine:
    """One line of the service's log."""

    level: str
    logger: str
    message: str
    event: str | None
    fields: dict[str, str]


def _unquote(value: str) -> str:
    if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":
        return value[1:-1].replace("\\'", "'").replace('\\"', '"')
    return value


def parse_log_line(text: str) -> LogLine | None:
    """A service log line as level, logger, message, ``event`` and its ``key=value`` fields; None otherwise."""
    m = _LINE.match(text.rstrip("\n"))
    if m is None:
        return None
    message = m["message"]
    fields = {k: _unquote(v) for k, v in _PAIR.findall(message)}
    return LogLine(m["level"], m["name"], message, fields.pop("event", None), fields)


def _submission(f: Mapping[str, str], state: str) -> str:
    what = {"pending": "waits to be sent", "submitted": "is in the queue", "replaced": "replaced an older revision",
            "deleted": "was deleted", "rejected": "was REJECTED", "failed": "FAILED",
            "expired": "expired (its window is over)"}.get(state, state)
    reason = f": {f['reason']}" if f.get("reason") else ""
    return f"submission of {f.get('plan_id', '-')} ({queues_of(f)}) to {f.get('target', '-')} {what}{reason}"


def queues_of(f: Mapping[str, str]) -> str:
    """The queues a submission line names: ``queue A`` or ``queues A, B, C +N more`` (the service's ``queues``
    field), else the name base of an older service's line (``queues <base>_<k>``)."""
    if f.get("queues"):
        return ("queue " if f.get("queue_count") == "1" else "queues ") + f["queues"]
    return f"queues {f.get('queue_name', '-')}_<k>"


#: event -> its sentence (from the line's fields).
_WORDS: dict[str, Callable[[Mapping[str, str]], str]] = {
    "service_starting": lambda f: f"service starting (pid {f.get('pid', '?')}), state {f.get('state', '-')}",
    "submit_enabled": lambda f: (f"submission on: {f.get('target')} at {f.get('url')}"
                                 + (" (DRY RUN: requests are logged, not sent)" if f.get("dry_run") == "True" else "")),
    "notify_on": lambda f: f"notifications on: {f.get('target')} webhook (URL from {f.get('url_source', '?')})",
    "executed_loop": lambda f: f"loop on: executed exposures read from {f.get('source')} every "
                               f"{f.get('poll_interval_s')} s",
    "warm_up": lambda f: f"service warmed up in {f.get('total_s', '?')} s (fields, footprints, tonight's sky)",
    "consuming": lambda f: f"service consuming {f.get('partitions', '-')}",
    "service_ready": lambda f: f"service ready after {f.get('startup_s', '?')} s",
    "notice": lambda f: (f"notice {f.get('superevent_id', '-')} {f.get('alert_type', '')} received: "
                         f"{f.get('decision') or f.get('action') or '?'}"
                         + (f" ({f['reason']})" if f.get("reason") else "")),
    "job_started": lambda f: f"planning {f.get('superevent_id', '-')}: the quick first plan",
    "job_optimising": lambda f: f"optimising {f.get('superevent_id', '-')} (the configured solver)",
    "job_failed": lambda f: (f"planning {f.get('superevent_id', '-')} FAILED at {f.get('stage', '?')}: "
                             f"{f.get('error', '')}"),
    "job_deadline": lambda f: f"planning {f.get('superevent_id', '-')} hit its deadline ({f.get('deadline_s')} s)",
    "submission_dry_run": lambda f: f"submission (dry run) of {f.get('plan_id', '-')} as {f.get('queue_name', '-')}: "
                                    "the request is logged, not sent",  # queue_name: this line's one queue
    "submission_skipped": lambda f: f"submission of {f.get('plan_id', '-')} skipped: {f.get('reason', '')}",
    "submission_retry": lambda f: (f"submission of {f.get('plan_id', '-')} to be retried (attempt "
                                   f"{f.get('attempts', '?')}): "
                                   f"{f.get('error') or f.get('reason') or f.get('state', '')}"),
    "notify_sent": lambda f: f"webhook told: {f.get('kind', '-')} (HTTP {f.get('http_status', '?')})",
    "notify_failed": lambda f: f"webhook FAILED for {f.get('kind', '-')}: {f.get('error', '')}",
    "notify_dropped": lambda f: f"webhook message {f.get('kind', '-')} dropped: too many waiting",
    "start_refused": lambda f: f"the service REFUSED to start: {f.get('reason', '')}",
    "broker_unreachable": lambda f: f"broker unreachable ({f.get('client', '-')}): {f.get('error', '')}",
    "service_stopping": lambda f: "service stopping",
    "jobs_left_pending": lambda f: "a job was still running at the stop: it resumes at the next start",
}
for _state in ("pending", "submitted", "replaced", "deleted", "rejected", "failed", "expired"):
    _WORDS[f"submission_{_state}"] = lambda f, s=_state: _submission(f, s)


def log_words(line: LogLine) -> str | None:
    """What the line says in words, or None for a line a rehearsal does not tell (heartbeats, details).

    Warnings and errors are always told: their own sentence, else
    ``WARNING: <the message>``.
    """
    words = _WORDS.get(line.event or "")
    if words is not None:
        return words(line.fields)
    if line.level in ("WARNING", "ERROR", "CRITICAL"):
        flat = " ".join(line.message.split())
        return f"{line.level}: {flat[:300]}" + ("..." if len(flat) > 300 else "")
    return None


class LogTail:
    """The complete lines appended to a log file since the last read."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._offset = 0
        self._partial = b""
        self.lines: list[str] = []

    def read(self) -> list[str]:
        """The new complete lines (also kept in :attr:`lines`)."""
        try:
            with open(self.path, "rb") as fh:
                fh.seek(self._offset)
                data = fh.read()
        except FileNotFoundError:
            return []
        self._offset += len(data)
        chunks = (self._partial + data).split(b"\n")
        self._partial = chunks.pop()
        new = [c.decode(errors="replace") for c in chunks]
        self.lines += new
        return new


class OutboxWatch:
    """Each new document of the outbox directory, once, in the order they appear."""

    def __init__(self, directory: Path) -> None:
        self.directory = Path(directory)
        self._seen: set[str] = set()
        self.documents: dict[str, dict[str, Any]] = {}

    def read(self) -> list[dict[str, Any]]:
        """The documents published since the last read (oldest file first)."""
        if not self.directory.is_dir():
            return []
        fresh = [p for p in self.directory.glob("*.json") if not p.name.startswith(".") and p.name not in self._seen]
        out = []
        for p in sorted(fresh, key=lambda q: q.stat().st_mtime_ns):
            try:
                doc = json.loads(p.read_text())
            except (OSError, ValueError):
                continue  # written atomically, so this is a foreign file: skip it for good
            finally:
                self._seen.add(p.name)
            if isinstance(doc, dict):
                self.documents[p.stem] = doc
                out.append(doc)
        return out


def is_final(doc: Mapping[str, Any]) -> bool:
    """The document ends the event's planning: a final plan, a ``plan_final`` verdict or a final not_observable."""
    kind = doc.get("type")
    return kind == "plan_final" or (kind in ("plan", "not_observable") and doc.get("final") is not False)


def document_words(doc: Mapping[str, Any]) -> str | None:
    """A published document in one line (None for kinds the log already tells, like submissions)."""
    from ..report.summary import answer_line

    kind = doc.get("type")
    sid = (doc.get("event") or {}).get("superevent_id") or doc.get("superevent_id") or "-"
    if kind == "plan":
        state = "final" if doc.get("final") else "an optimised plan may follow" if doc.get("final") is False else ""
        replaces = f", replaces {doc['supersedes']}" if doc.get("supersedes") else ""
        return (f"revision {doc.get('revision', '?')} of {sid} published ({doc.get('plan_id')}{replaces}; {state}): "
                f"{answer_line(doc)}")
    if kind == "plan_final":
        return f"{sid}: the optimisation found nothing better; {doc.get('plan_id')} is final: {doc.get('reason', '')}"
    if kind == "not_observable":
        return f"{sid}: {answer_line(doc)}"
    if kind == "withdrawal":
        return f"{sid} withdrawn: {doc.get('reason', '')}"
    return None
