"""``/metrics``, ``/healthz`` and ``/readyz`` on one HTTP listener (``[daemon] metrics_address``).

``/metrics`` is prometheus-client's own WSGI app (:func:`prometheus_client.make_wsgi_app`,
content negotiation and gzip included) over the daemon's registry.  The
library's ``start_http_server`` answers every path with the metrics, so the
two health paths need a listener of our own: a small threaded WSGI server
from the standard library that sends ``/healthz`` and ``/readyz`` here and
everything else to the metrics app.

``/healthz`` (liveness): 200 while the consume loop turned within the
watchdog interval (systemd's ``WatchdogSec``, else 60 s), 503 otherwise.
During start-up and warm-up it answers 200 (``"phase": "starting"``): the
process is alive, just not consuming yet.

``/readyz`` (readiness): 200 only when every check passes, else 503; the
JSON body names each check, whether it passed and why.  Checks: ``warm_up``
(the caches and the throw-away plan are done, and the plan did not fail), ``partitions`` (the consumer
has partitions assigned), ``store`` (the state file takes a write lock and
its disk has room), ``broker`` (the input cluster answers), ``outbound``
(the outbox is being published: no failed publish waiting for its back-off,
no message older than the sink's delivery timeout + 10 s, the outbound
broker not known down), ``submission`` when ``[submit]`` is on
(:func:`submission_check`: no submission failing and waiting for its
back-off, none pending longer than ``[submit] max_pending_s``), and
whatever :meth:`HealthServer.add_check` added.

The listener (:class:`~.http_front.Front`) reads request heads in one thread
without blocking and answers complete ones in :data:`MAX_CONNECTIONS` worker
threads; a connection has :data:`CONNECTION_TIMEOUT_S` to send its head, and
at most :data:`~.http_front.MAX_OPEN` are kept open (a new one closes the
oldest idle one), so idle or dripping clients never silence ``/healthz``
nor take the unit's ``TasksMax`` threads.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable

from prometheus_client import make_wsgi_app

from .http_front import Front
from .metrics import ServiceMetrics
from ..state.views import connect_readonly, outbox_backlog

__all__ = ["HealthServer", "service_checks", "liveness", "Check", "LIVENESS_DEFAULT_S", "MIN_FREE_BYTES"]

log = logging.getLogger("mushrooms.daemon.health")

#: A check: ``() -> (passed, one-line detail)``.
Check = Callable[[], "tuple[bool, str]"]

#: Liveness limit (s) on the consume loop's age when systemd sets no watchdog (the unit's WatchdogSec).
LIVENESS_DEFAULT_S = 60.0
#: The store check fails when the state file's file system has less than this free (bytes).
MIN_FREE_BYTES = 64 * 2**20


#: Threads that answer complete requests (idle connections take none; threads are the unit's TasksMax).
MAX_CONNECTIONS = 4
#: Time (s) a connection has to send its request head: an idle or dripping client is dropped after it.
CONNECTION_TIMEOUT_S = 10.0


class HealthServer:
    """The listener.

    Parameters
    ----------
    host, port : str, int
        Where to listen (port 0: any free port; see :attr:`address`).
    metrics : ServiceMetrics
    alive : callable
        ``() -> (alive, detail dict)`` for ``/healthz``.
    checks : dict
        Readiness checks by name.
    max_connections : int
        Requests answered at once (a worker thread each); connections still sending their
        request head take no thread.
    connection_timeout_s : float
        Time (s) a connection has to send its request head (and the socket timeout of the answer).
    """

    def __init__(self, host: str, port: int, metrics: ServiceMetrics, alive: Callable[[], tuple[bool, dict]],
                 checks: dict[str, Check] | None = None, max_connections: int = MAX_CONNECTIONS,
                 connection_timeout_s: float = CONNECTION_TIMEOUT_S) -> None:
        self._alive = alive
        self._checks: dict[str, Check] = dict(checks or {})
        self._metrics_app = make_wsgi_app(metrics.registry)
        self._server = Front(host, port, self._app, workers=max_connections, timeout_s=connection_timeout_s)
        self.address = self._server.address
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.5},
                                        name="metrics-http", daemon=True)

    def start(self) -> "HealthServer":
        self._thread.start()
        return self

    def add_check(self, name: str, check: Check) -> None:
        """Hook: one more readiness check (e.g. ``submission``: the telescope queue answers)."""
        self._checks[name] = check

    def readiness(self) -> tuple[bool, dict[str, Any]]:
        """(ready, body): every check's verdict; a check that raises fails with its error."""
        results = {}
        for name, check in list(self._checks.items()):
            try:
                ok, detail = check()
            except Exception as exc:
                ok, detail = False, f"check failed: {type(exc).__name__}: {exc}"
            results[name] = {"ok": bool(ok), "detail": detail}
        failed = [n for n, r in results.items() if not r["ok"]]
        return not failed, {"ready": not failed, "failed": failed, "checks": results}

    def _app(self, environ: dict[str, Any], start_response: Callable[..., Any]) -> Iterable[bytes]:
        path = environ.get("PATH_INFO", "")
        if path in ("/healthz", "/readyz"):
            if environ.get("REQUEST_METHOD") not in ("GET", "HEAD"):
                start_response("405 Method Not Allowed", [("Allow", "GET, HEAD")])
                return [b""]
            if path == "/healthz":
                ok, body = self._alive()
                body = {"alive": ok, **body}
            else:
                ok, body = self.readiness()
            data = (json.dumps(body, sort_keys=True) + "\n").encode()
            start_response("200 OK" if ok else "503 Service Unavailable",
                           [("Content-Type", "application/json"), ("Content-Length", str(len(data))),
                            ("Cache-Control", "no-store")])
            return [data]
        if path in ("/metrics", "/"):
            return self._metrics_app(environ, start_response)
        start_response("404 Not Found", [("Content-Type", "text/plain")])
        return [b"not found: try /metrics, /healthz or /readyz\n"]

    def close(self) -> None:
        """Stop listening."""
        self._server.close()
        if self._thread.is_alive():
            self._thread.join(5.0)


def liveness(phase: Callable[[], str], loop_age_s: Callable[[], float], limit_s: float) -> Callable[[], tuple[bool, dict]]:
    """The ``/healthz`` verdict: alive unless the consume loop is older than ``limit_s`` (s) while running."""

    def alive() -> tuple[bool, dict]:
        p, age = phase(), loop_age_s()
        ok = p != "running" or age <= limit_s
        return ok, {"phase": p, "loop_age_s": round(age, 3), "limit_s": limit_s}

    return alive


def store_check(path: Path, min_free_bytes: int = MIN_FREE_BYTES) -> Check:
    """The state file takes a write lock (``BEGIN IMMEDIATE``, rolled back) and its disk has room."""

    def check() -> tuple[bool, str]:
        st = os.statvfs(path.parent)
        free = st.f_bavail * st.f_frsize
        if free < min_free_bytes:
            return False, f"only {free / 2**20:.0f} MiB free on the state file's file system"
        try:
            conn = sqlite3.connect(path, timeout=1.0, isolation_level=None)
            try:
                conn.execute("BEGIN IMMEDIATE")
                conn.execute("ROLLBACK")
            finally:
                conn.close()
        except sqlite3.OperationalError as exc:
            if "locked" in str(exc) or "busy" in str(exc):
                return True, "writable (a write was in progress)"
            return False, f"not writable: {exc}"
        except sqlite3.Error as exc:
            return False, f"not writable: {exc}"
        return True, f"writable, {free / 2**30:.1f} GiB free"

    return check


def service_checks(service: Any) -> dict[str, Check]:
    """The readiness checks of a running :class:`~.service.Service`.

    Reads ``service.phase``, ``service.consumer`` (``assigned``, ``health``),
    ``service.outbox`` (``retry_scheduled``), ``service.pipeline.sink``
    (``health`` of a Kafka sink), ``service.paths.state`` and
    ``service.config``.
    """

    def warm_up() -> tuple[bool, str]:
        p = service.phase
        if p != "running":
            return False, f"not done ({p})"
        failure = getattr(getattr(service, "sky_cache", None), "plan_failure", None)
        if failure is not None:
            return False, (f"the warm-up plan failed: {failure}: every job may fail the same way (tried again "
                           f"every re-warm; the log's event=warm_up_plan_failed)")
        return True, "done"

    def partitions() -> tuple[bool, str]:
        c = service.consumer
        assigned = sorted(getattr(c, "assigned", ()) or ()) if c is not None else []
        if not assigned:
            since = getattr(c, "waiting_since", None)
            wait = f" for {time.monotonic() - since:.0f} s" if since else ""
            return False, f"no partitions assigned yet (waiting{wait})"
        return True, " ".join(f"{t}[{p}]" for t, p in assigned)

    def broker() -> tuple[bool, str]:
        c = service.consumer
        h = getattr(c, "health", None)
        if h is None:
            return False, "no consumer"
        return h.up is True, h.status_text()

    def outbound() -> tuple[bool, str]:
        sink = getattr(service.pipeline, "sink", None)
        h = getattr(sink, "health", None)
        conn = connect_readonly(service.paths.state, timeout_s=2.0)
        try:
            pending, age, error = outbox_backlog(conn)
        finally:
            conn.close()
        where = f"{pending} message(s) pending" + (f", the oldest {age:.0f} s old" if age is not None else "")
        if h is not None and h.up is False:
            return False, f"outbound {h.status_text()}; {where}"
        drain = getattr(service, "outbox", None)
        if drain is not None and drain.retry_scheduled:
            return False, f"publishing failed, retrying with back-off; {where}: {error or '-'}"
        limit = service.config.outbound.delivery_timeout_s + 10.0
        if age is not None and age > limit:
            return False, f"outbox not draining: {where} (limit {limit:.0f} s): {error or 'publish in progress'}"
        return True, where

    checks = {"warm_up": warm_up, "partitions": partitions, "store": store_check(service.paths.state),
              "broker": broker, "outbound": outbound}
    drain = getattr(service, "submit_drain", None)
    if drain is not None:
        checks["submission"] = submission_check(service.paths.state, drain, service.config.submit.max_pending_s)
    return checks


def submission_check(state: Path, drain: Any, max_pending_s: float) -> Check:
    """The plans reach the telescope: no submission failing (back-off), none pending longer than ``max_pending_s``."""
    from ..state.views import oldest_pending_submission
    from ..submission.names import pending_queue_names, queues_phrase

    def check() -> tuple[bool, str]:
        conn = connect_readonly(state, timeout_s=2.0)
        try:
            oldest = oldest_pending_submission(conn)
        finally:
            conn.close()
        where = "no submission pending" if oldest is None else (
            f"{queues_phrase(pending_queue_names(oldest))} pending for {oldest['age_s']:.0f} s: "
            f"{oldest['answer'] or '-'}")
        if drain.retry_scheduled:
            return False, f"submissions failing, retrying with back-off; {where}"
        if oldest is not None and oldest["age_s"] > max_pending_s:
            return False, f"{where} (limit [submit] max_pending_s = {max_pending_s:g} s)"
        return True, where

    return check
