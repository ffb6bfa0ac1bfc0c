"""What the observer on call is told, and when: one short message per thing that happens.

:class:`NotifyingSink` wraps the outbound sink: once a message is published
(never before, never instead), a one-paragraph text goes to the webhook
(:class:`~mushrooms.daemon.ops.webhook.Webhook`): a plan published (or superseding an older one), a
``plan_final`` verdict, an event not observable, a withdrawal, a submission's
state change.  :func:`job_failed` and :func:`submission_trouble` are the two
hooks the service calls for what is not an outbound message.  Posting only
queues (:meth:`~mushrooms.daemon.ops.webhook.Webhook.post`): nothing here waits for the network.
"""

from __future__ import annotations

import logging
from typing import Any, Callable, Mapping, Sequence

from .webhook import Webhook

__all__ = ["announcement", "NotifyingSink", "open_webhook", "webhook_of", "job_failed", "submission_trouble"]

log = logging.getLogger("mushrooms.daemon.webhook")


def _plan_text(m: Mapping[str, Any]) -> tuple[str, str]:
    from ...report.summary import answer_line

    sid = (m.get("event") or {}).get("superevent_id") or "a sky map"
    revision = m.get("revision")
    head = f"{sid}: new ZTF plan" + (f", revision {revision}" if revision else "")
    kind = "plan_superseded" if m.get("supersedes") else "plan_published"
    if m.get("supersedes"):
        head += f" (replaces {m['supersedes']})"
    tail = "; final" if m.get("final") else "; an optimised plan may follow" if m.get("final") is False else ""
    return kind, f"{head}: {answer_line(m)}{tail}."


def announcement(message: Mapping[str, Any]) -> tuple[str, str] | None:
    """(kind, text) of an outbound message, or None when it is not worth a message."""
    kind = message.get("type")
    sid = message.get("superevent_id") or (message.get("event") or {}).get("superevent_id") or "-"
    if kind == "plan":
        return _plan_text(message)
    if kind == "not_observable":
        from ...report.summary import answer_line

        return "not_observable", f"{sid}: {answer_line(message)}"
    if kind == "plan_final":
        return "plan_final", f"{sid}: plan {message.get('plan_id')} is final. {message.get('reason', '')}".strip()
    if kind == "withdrawal":
        return "withdrawn", (f"{sid} was retracted: {len(message.get('plan_ids') or [])} plan(s) withdrawn "
                             f"({message.get('reason', '')}).")
    if kind == "submission":
        state = message.get("state")
        what = {"submitted": "is in ZTF's queue", "replaced": "was replaced by a newer revision",
                "deleted": "was deleted from the queue", "rejected": "was REJECTED",
                "failed": "FAILED to reach the queue"}.get(str(state), f"is {state}")
        reason = f": {message['reason']}" if message.get("reason") else ""
        return f"submission_{state}", (f"{sid}: {_queues(message.get('queue_names') or message.get('queue_name'))} "
                                       f"({message.get('target', '')}) {what}{reason}.")
    return None


def _queues(names: Any) -> str:
    """``queue A`` or ``queues A, B, C +N more``: the names submitted (:func:`~..submission.names.queues_phrase`)."""
    from ..submission.names import queues_phrase

    return queues_phrase(names if isinstance(names, (list, tuple, str)) else None)


class NotifyingSink:
    """The outbound sink, telling the webhook about each message it published.

    Parameters
    ----------
    sink : Sink
        Publishes (its failure is raised as before, and nothing is posted).
    webhook : Webhook
    """

    def __init__(self, sink: Any, webhook: Webhook, parts: Callable[[str | None], list[dict[str, Any]]] | None = None):
        self.sink = sink
        self.webhook = webhook
        self.parts = parts  # plan_id -> the other telescopes' parts of its revision (issue 53), or None

    def __getattr__(self, name: str) -> Any:  # path_for, directory, ... of the wrapped sink
        return getattr(self.sink, name)

    def publish(self, message: dict[str, Any]) -> None:
        self.sink.publish(message)
        try:
            said = announcement(message)
        except Exception:
            log.exception("event=notify_text_failed type=%s", message.get("type"))
            return
        if said is not None:
            kind, text = said
            details = _details(message)
            if self.parts is not None:
                text, details = self._with_parts(message, text, details)
            self.webhook.post(kind, text, details)

    def _with_parts(self, message: Mapping[str, Any], text: str, details: dict[str, Any]
                    ) -> tuple[str, dict[str, Any]]:
        """The announcement naming every other telescope's part of the revision (or withdrawn with the event)."""
        from ..planning.parts import parts_words

        kind = message.get("type")
        if kind == "withdrawal":
            ids = [i for i in (message.get("plan_ids") or []) if isinstance(i, str)]
            names = sorted({p["telescope"] for i in ids for p in self.parts(i)})
            return (text + f" Every telescope's part withdrawn too ({', '.join(names)})." if names else text), details
        if kind not in ("plan", "not_observable"):
            return text, details
        parts = self.parts(message.get("plan_id"))
        if not parts:
            return text, details
        listed = [f"{p['telescope']} {p['queue']} {p['state']}" for p in sorted(parts, key=lambda p: p["telescope"])]
        from ...report.site import site_words
        from ...report.sky import area_words, plan_area_deg2

        said = f"{text} ZTF{site_words('ztf')}: this plan{area_words(plan_area_deg2(dict(message)))}"
        return f"{said}; {parts_words(parts)}.", {**details, "telescope_parts": listed}

    def close(self) -> None:
        self.webhook.close()
        close = getattr(self.sink, "close", None)
        if close is not None:
            close()

    def __repr__(self) -> str:
        return f"NotifyingSink({self.sink!r}, {self.webhook!r})"


def _details(message: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON webhook's extra keys: ids and the headline numbers."""
    event = message.get("event") or {}
    metrics = message.get("metrics") or {}
    out = {"type": message.get("type"), "superevent_id": message.get("superevent_id") or event.get("superevent_id"),
           "plan_id": message.get("plan_id"), "revision": message.get("revision"),
           "coverage": metrics.get("coverage"), "state": message.get("state"),
           "queue_name": message.get("queue_name"), "queue_names": _listed(message.get("queue_names"))}
    return {k: v for k, v in out.items() if v is not None}


def _listed(names: Any) -> list[str] | None:
    """The JSON webhook's ``queue_names`` (the webhook keeps the first 50: a bounded message), None without any."""
    if not isinstance(names, (list, tuple)) or not names:
        return None
    return [str(n) for n in names]


def open_webhook(notify: Any, environ: Mapping[str, str] | None = None) -> Webhook | None:
    """The webhook of ``[notify]`` (the URL from the credential ``notify_url`` or ``$MUSHROOMS_NOTIFY_URL``).

    None when ``[notify]`` is off.  Raises
    :class:`~.credentials.CredentialsError` when it is on and the URL is missing
    or cannot be used (:class:`~.webhook_url.WebhookURLError`: one line, never the URL).
    """
    if notify is None or not notify.enabled:
        return None
    from .webhook_url import checked_notify_url

    url, source, _ = checked_notify_url(environ)
    log.info("event=notify_on target=%s url_source=%s timeout_s=%g max_pending=%d", notify.target, source,
             notify.timeout_s, notify.max_pending)
    return Webhook(url, notify.target, notify.timeout_s, notify.max_pending, source=source)


def webhook_of(sink: Any) -> Webhook | None:
    """The webhook of a :class:`NotifyingSink`, however many wrappers (``inner``, ``sink``) lie around it."""
    for _ in range(8):
        if isinstance(sink, NotifyingSink):
            return sink.webhook
        sink = getattr(sink, "inner", None) or (getattr(sink, "sink", None) if not isinstance(sink, type) else None)
        if sink is None:
            return None
    return None


def close_outbound(sink: Any) -> None:
    """Close a sink the service no longer publishes to, but not the webhook it tells (a reload keeps that one).

    Goes through the service's wrappers (``inner``: the metrics' ``ObservedSink``; a :class:`NotifyingSink`'s
    ``sink``), whose ``close`` would reach the webhook, to the sink itself (a Kafka sink: its producer is
    flushed and closed; a directory sink: its page-drawing thread ends).
    """
    for _ in range(8):
        if isinstance(sink, NotifyingSink):
            sink = sink.sink
            break
        inner = vars(sink).get("inner") if hasattr(sink, "__dict__") else None
        if inner is None:
            break
        sink = inner
    close = getattr(sink, "close", None)
    if close is not None:
        close()


def job_failed(sink: Any, superevent_id: str | None, reason: str) -> None:
    """Hook: a planning job failed (nothing was published for it)."""
    hook = webhook_of(sink)
    if hook is not None:
        hook.post("job_failed", f"{superevent_id or '-'}: planning FAILED: {reason}",
                  {"superevent_id": superevent_id})


def submission_trouble(sink: Any, superevent_id: str | None, queue_names: Sequence[str] | str | None,
                       attempts: int, error: str, action: str = "submitted") -> None:
    """Hook: a submission's first failure to be ``submitted`` (a PUT) or ``removed`` (a DELETE): retried, said once.

    ``queue_names``: the names of the row's queues (:meth:`~..submission.rows.Submission.queue_names`), a few
    of them in the text, the first 50 in the JSON webhook's ``queue_names``.
    """
    hook = webhook_of(sink)
    if hook is not None:
        names = [queue_names] if isinstance(queue_names, str) else list(queue_names or ())
        why = f"attempt {attempts}: {error}" if action == "submitted" else error
        hook.post("submission_failing", f"{superevent_id or '-'}: {_queues(names)} could not be "
                  f"{action} ({why}); retrying", {"superevent_id": superevent_id,
                                                  "queue_name": names[0] if len(names) == 1 else None,
                                                  "queue_names": _listed(names), "action": action})
