"""Post short messages to a webhook (Slack incoming webhook, or a generic JSON one), off the service's path.

:class:`Webhook` keeps a bounded queue and one thread of its own: :meth:`Webhook.post`
only puts the message in the queue (never blocks; a full queue drops the
message and logs it), and the thread POSTs each one with a deadline
(``[notify] timeout_s``).  A webhook that hangs or fails therefore never
delays planning, publishing or submission; its failures are logged without
the URL (the URL is the secret of a Slack webhook).

Bodies: ``slack`` posts ``{"text": TEXT}`` (Slack's incoming-webhook format,
https://api.slack.com/messaging/webhooks); ``json`` posts
``{"event": KIND, "text": TEXT, "source": "mushrooms", ...details}``.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
import urllib.error
import urllib.request
from typing import Any, Mapping

__all__ = ["Webhook", "webhook_body"]

log = logging.getLogger("mushrooms.daemon.webhook")


def webhook_body(target: str, kind: str, text: str, details: Mapping[str, Any] | None = None) -> bytes:
    """The POST body of one message for ``target`` ``slack`` or ``json``."""
    if target == "slack":
        return json.dumps({"text": text}).encode()
    body = {"event": kind, "text": text, "source": "mushrooms", "time": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                                                      time.gmtime())}
    body.update({k: v for k, v in (details or {}).items() if k not in body})
    return json.dumps(body, default=str).encode()


class Webhook:
    """A bounded queue of messages and the thread that posts them.

    Parameters
    ----------
    url : str
        The webhook (a secret: never logged).
    target : str
        ``slack`` or ``json`` (:func:`webhook_body`).
    timeout_s : float
        Deadline of one POST (s): the socket's timeout and the whole request's.
    max_pending : int
        Messages waiting at most; beyond, new ones are dropped.
    """

    def __init__(self, url: str, target: str, timeout_s: float = 5.0, max_pending: int = 100):
        self._url = url
        self.target = target
        self.timeout_s = float(timeout_s)
        self._queue: queue.Queue[tuple[str, str, dict[str, Any]] | None] = queue.Queue(int(max_pending))
        self.sent = 0
        self.failed = 0
        self.dropped = 0
        self._thread = threading.Thread(target=self._run, name="mushrooms-webhook", daemon=True)
        self._thread.start()

    def post(self, kind: str, text: str, details: Mapping[str, Any] | None = None) -> bool:
        """Queue one message; False (and a log line) when the queue is full. Never blocks."""
        try:
            self._queue.put_nowait((kind, text, dict(details or {})))
            return True
        except queue.Full:
            self.dropped += 1
            log.warning("event=notify_dropped kind=%s reason='%d messages already wait for the webhook'",
                        kind, self._queue.maxsize)
            return False

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            kind, text, details = item
            self._send(kind, webhook_body(self.target, kind, text, details))

    def _send(self, kind: str, body: bytes) -> None:
        """One POST within the deadline; a failure is logged (status or error, never the URL)."""
        request = urllib.request.Request(self._url, data=body, method="POST",
                                         headers={"Content-Type": "application/json",
                                                  "User-Agent": "mushrooms-notify"})
        done = threading.Event()
        outcome: dict[str, Any] = {}

        def attempt() -> None:
            try:
                with urllib.request.urlopen(request, timeout=self.timeout_s) as answer:
                    outcome["status"] = answer.status
            except urllib.error.HTTPError as exc:
                outcome["status"] = exc.code
            except Exception as exc:  # unreachable, refused, timed out, a bad answer
                outcome["error"] = type(exc).__name__
            finally:
                done.set()

        threading.Thread(target=attempt, name="mushrooms-webhook-post", daemon=True).start()
        if not done.wait(self.timeout_s + 0.5):  # the whole request's deadline, however slowly it trickles
            outcome = {"error": "deadline"}
        status = outcome.get("status")
        if status is not None and 200 <= status < 300:
            self.sent += 1
            log.info("event=notify_sent kind=%s http_status=%s", kind, status)
        else:
            self.failed += 1
            log.warning("event=notify_failed kind=%s http_status=%s error=%s", kind, status or "-",
                        outcome.get("error", "-"))

    def close(self, timeout_s: float = 5.0) -> None:
        """Post what waits for at most ``timeout_s``, then stop the thread (what is left is dropped)."""
        deadline = time.monotonic() + timeout_s
        while not self._queue.empty() and time.monotonic() < deadline:
            time.sleep(0.05)
        try:
            self._queue.put_nowait(None)
        except queue.Full:
            pass
        self._thread.join(max(0.0, deadline - time.monotonic()))

    def __repr__(self) -> str:  # never the URL
        return f"Webhook(target={self.target!r}, timeout_s={self.timeout_s:g})"
