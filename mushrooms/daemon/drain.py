"""A thread that drains a queue kept in the state file, backing off while its far end fails.

Two drains run in the daemon: the outbox (plans and withdrawals to the sink)
and, with ``[submit]``, the submitter (plans to ZTF's queue).  Planning
threads only :meth:`~OutboxDrain.kick` them, so a slow or dead broker or
queue server never holds a planning worker.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any, Callable

__all__ = ["OutboxDrain"]

log = logging.getLogger("mushrooms.daemon.jobs")


class OutboxDrain:
    """Publish the outbox from a thread of its own; back off while the broker fails.

    Planning threads only call :meth:`kick` after queueing a message; the
    drain thread calls ``flush()`` (which publishes pending rows in order and
    returns how many are still pending, or raises).  After a failure it
    waits ``initial_s``, doubling up to ``max_s``, before the next attempt;
    a kick during the back-off does not shorten it (a dead broker is not
    hammered), except that :meth:`kick` with ``now=True`` does, also when it
    arrives during a pass that then fails (the next pass runs at once: a
    retraction's DELETE does not wait for another event's back-off).

    Parameters
    ----------
    flush : callable
        ``flush() -> int`` messages still pending (or raises).
    initial_s, max_s : float
        First and largest back-off delay (s).
    name : str
        Thread name, and the ``event=<name>_failed`` of the back-off log line
        (``outbox``: ``publish_failed``); the submitter's drain is ``submit``.
    """

    def __init__(self, flush: Callable[[], Any], initial_s: float = 2.0, max_s: float = 300.0,
                 name: str = "outbox") -> None:
        self._flush = flush
        self._event = "publish_failed" if name == "outbox" else f"{name}_failed"
        self._initial_s = float(initial_s)
        self._max_s = float(max_s)
        self._delay_s = self._initial_s
        self._cv = threading.Condition()
        self._pending = False
        self._retry_at: float | None = None
        self._urgent = False  # a kick(now=True) came during the pass in progress
        self._closed = False
        self.attempts = 0
        self.failures = 0
        self.delays: list[float] = []  # back-off delays chosen, in order (for operators and tests)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def kick(self, now: bool = False) -> None:
        """Something was queued: publish it (after the current back-off unless ``now``)."""
        with self._cv:
            self._pending = True
            if now:
                self._retry_at = None
                self._urgent = True
            self._cv.notify()

    # the service's previous name for "try now"
    drain = kick

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._closed:
                    if self._retry_at is not None:
                        left = self._retry_at - time.monotonic()
                        if left <= 0:
                            break
                        self._cv.wait(left)
                    elif self._pending:
                        break
                    else:
                        self._cv.wait()
                if self._closed:
                    return
                self._pending = False
                self._retry_at = None
                self._urgent = False
            self.attempts += 1
            try:
                left = self._flush()
                ok = not (isinstance(left, int) and not isinstance(left, bool) and left > 0)
                error = None if ok else f"{left} message(s) still pending"
            except Exception as exc:
                ok, error = False, f"{type(exc).__name__}: {exc}"
            with self._cv:
                if ok:
                    self._delay_s = self._initial_s
                    continue
                self.failures += 1
                delay = self._delay_s
                self.delays.append(delay)
                self._delay_s = min(self._delay_s * 2.0, self._max_s)
                if self._urgent:  # asked for at once while this pass ran: no back-off before the next
                    self._urgent = False
                    delay = 0.0
                self._retry_at = time.monotonic() + delay
            log.warning("event=%s error=%r retry_in_s=%.1f", self._event, error, delay)

    @property
    def retry_scheduled(self) -> bool:
        """True while a failed publish waits for its back-off to pass."""
        with self._cv:
            return self._retry_at is not None

    def idle(self) -> bool:
        """Nothing waiting: no kick to serve and no retry scheduled."""
        with self._cv:
            return not self._pending and self._retry_at is None

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the drain thread (a publish in progress is finished, up to ``timeout_s``)."""
        with self._cv:
            self._closed = True
            self._cv.notify_all()
        self._thread.join(timeout_s)
