"""Post short messages to a webhook (Slack incoming webhook, or a generic JSON one), off the service's path.

:class:`Webhook` is one sender thread and a bounded queue, whatever the
webhook does: :meth:`Webhook.post` only queues the message (never blocks;
when the queue is full the *oldest* waiting message makes room, with a log
line and the ``dropped`` count), and the thread POSTs one message at a time
(:func:`~.webhook_post.post_once`: a hard deadline of ``[notify] timeout_s``
for the whole exchange, the socket closed at it however slowly the answer
trickles; a redirect never followed).  A webhook that hangs, trickles or
fails therefore never delays planning, publishing or submission, and never
holds more than one thread and one socket.  Each message is sent inside its
own ``try``: one that cannot be sent is counted and logged, and the next one
goes out.  Failures are logged as one word, never with the URL (the URL is
the secret of a Slack webhook) nor with an exception's text.

Bodies: ``slack`` posts ``{"text": TEXT}`` (Slack's incoming-webhook format,
https://api.slack.com/messaging/webhooks); ``json`` posts
``{"event": KIND, "text": TEXT, "source": "mushrooms", ...details}``.  Every
string in a body first goes through :func:`~mushrooms.handlers.chat_text.chat_safe`
(chat markup, control and bidi characters neutralised; text from Kowalski,
an error or a notice reaches the chat as plain words).
"""

from __future__ import annotations

import collections
import json
import logging
import ssl
import threading
import time
from typing import Any, Mapping

from ...handlers.chat_text import chat_safe
from .webhook_post import PostFailed, post_once
from .webhook_url import parse_webhook_url

__all__ = ["Webhook", "webhook_body"]

log = logging.getLogger("mushrooms.daemon.webhook")

#: The longest identifier or number said in a JSON body's extra keys (characters).
DETAIL_LIMIT = 200


#: The most items of a list said in a JSON body's extra keys (``queue_names``).
DETAIL_ITEMS = 50


def _detail(value: Any) -> Any:
    """A JSON body's extra value: numbers and booleans as they are, a list as a list of at most
    :data:`DETAIL_ITEMS` neutralised texts, anything else as neutralised text."""
    if value is None or isinstance(value, (bool, int, float)):
        return value
    if isinstance(value, (list, tuple)):
        return [chat_safe(v, DETAIL_LIMIT) for v in value[:DETAIL_ITEMS]]
    return chat_safe(value, DETAIL_LIMIT)


def webhook_body(target: str, kind: str, text: str, details: Mapping[str, Any] | None = None) -> bytes:
    """The POST body of one message for ``target`` ``slack`` or ``json`` (every string neutralised for a chat)."""
    if target == "slack":
        return json.dumps({"text": chat_safe(text)}).encode()
    body: dict[str, Any] = {"event": chat_safe(kind, DETAIL_LIMIT), "text": chat_safe(text), "source": "mushrooms",
                            "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    body.update({str(k): _detail(v) for k, v in (details or {}).items() if k not in body})
    return json.dumps(body).encode()


class Webhook:
    """A bounded queue of messages and the one thread that posts them.

    Parameters
    ----------
    url : str
        The webhook (a secret: never logged, never in an error). A URL that
        cannot be used raises :class:`~.webhook_url.WebhookURLError` here.
    target : str
        ``slack`` or ``json`` (:func:`webhook_body`).
    timeout_s : float
        Hard deadline of one POST (s), connect to answer.
    max_pending : int
        Messages waiting at most; beyond, the oldest is dropped.
    source : str
        Where the URL came from (said in errors instead of the URL).
    """

    def __init__(self, url: str, target: str, timeout_s: float = 5.0, max_pending: int = 100,
                 source: str = "the webhook setting"):
        self._address = parse_webhook_url(url, source)
        self.target = target
        self.timeout_s = float(timeout_s)
        self.max_pending = int(max_pending)
        self._pending: collections.deque[tuple[str, str, dict[str, Any]]] = collections.deque()
        self._cv = threading.Condition()
        self._closing = False
        self._busy = False
        self._context: ssl.SSLContext | None = None
        self.sent = 0
        self.failed = 0
        self.dropped = 0
        self._thread = threading.Thread(target=self._run, name="mushrooms-webhook", daemon=True)
        self._thread.start()

    def post(self, kind: str, text: str, details: Mapping[str, Any] | None = None) -> bool:
        """Queue one message (the oldest waiting one dropped when full); False once closed. Never blocks."""
        with self._cv:
            if self._closing:
                self.dropped += 1
                log.warning("event=notify_dropped kind=%s reason='the notifier is stopping'", chat_safe(kind, 60))
                return False
            if len(self._pending) >= self.max_pending:
                oldest = self._pending.popleft()
                self.dropped += 1
                log.warning("event=notify_dropped kind=%s reason='%d messages already wait for the webhook; the "
                            "oldest made room'", chat_safe(oldest[0], 60), self.max_pending)
            self._pending.append((kind, text, dict(details or {})))
            self._cv.notify()
        return True

    def counts(self) -> dict[str, int]:
        """Messages ``sent``, ``failed``, ``dropped`` since start, and ``pending`` now (the metrics' source)."""
        with self._cv:
            return {"sent": self.sent, "failed": self.failed, "dropped": self.dropped, "pending": len(self._pending)}

    @property
    def alive(self) -> bool:
        """The sender thread runs (or has stopped because it was closed)."""
        return self._thread.is_alive() or self._closing

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._pending and not self._closing:
                    self._cv.wait()
                if not self._pending:
                    return
                kind, text, details = self._pending.popleft()
                self._busy = True
            try:
                self._send(kind, text, details)
            except Exception as exc:  # one message never kills the sender; its text may hold anything: not logged
                self._failed(kind, None, type(exc).__name__)
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()

    def _send(self, kind: str, text: str, details: dict[str, Any]) -> None:
        """One POST within the deadline; the outcome counted and logged (status or one word, never the URL)."""
        body = webhook_body(self.target, kind, text, details)
        if self._address.scheme == "https" and self._context is None:
            self._context = ssl.create_default_context()
        try:
            status = post_once(self._address, body, self.timeout_s, self._context)
        except PostFailed as exc:
            self._failed(kind, None, exc.reason)
            return
        if 200 <= status < 300:
            with self._cv:
                self.sent += 1
            log.info("event=notify_sent kind=%s http_status=%d", chat_safe(kind, 60), status)
        else:
            self._failed(kind, status, "redirect_not_followed" if 300 <= status < 400 else "http_status")

    def _failed(self, kind: str, status: int | None, error: str) -> None:
        with self._cv:
            self.failed += 1
        log.warning("event=notify_failed kind=%s http_status=%s error=%s", chat_safe(kind, 60),
                    status if status is not None else "-", error)

    def close(self, timeout_s: float = 5.0) -> None:
        """Post what waits for at most ``timeout_s``, then stop the thread (what is left is dropped, and said)."""
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while (self._pending or self._busy) and self._thread.is_alive():
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cv.wait(left)
            left_behind = len(self._pending)
            self._pending.clear()
            self.dropped += left_behind
            self._closing = True
            self._cv.notify_all()
        if left_behind:
            log.warning("event=notify_dropped count=%d reason='the notifier stopped before the webhook took them'",
                        left_behind)
        self._thread.join(max(0.0, deadline - time.monotonic()))

    def __repr__(self) -> str:  # never the URL
        return f"Webhook(target={self.target!r}, timeout_s={self.timeout_s:g})"
