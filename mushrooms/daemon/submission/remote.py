"""HTTP clients of the two neighbours that put a plan in ZTF's ToO queue.

* :class:`KowalskiQueue`: ``PUT/DELETE/GET {url}/api/triggers/ztf`` with
  ``Authorization: Bearer <token>`` (skyportal/kowalski
  ``kowalski/api/handlers/ztf.py``, ``ZTFTriggerHandler``);
* :class:`SkyPortalPlans`: ``POST {url}/api/observation_plan/manual``,
  ``DELETE {url}/api/observation_plan/<id>`` and ``GET
  {url}/api/observation_plan/plan_names?name=...`` with ``Authorization:
  token <token>`` (skyportal/skyportal ``skyportal/handlers/api/observation_plan.py``).

What Kowalski answers to each, re-read from its source, is (Y0) of ``docs/design/submission.md``.

The contracts, with the commits they were read from, are in
``docs/design/submission.md``.  The token is sent only in the header, never
logged, and blanked out of any server text we keep.

What the HTTP library does and what is ours.  The connection, TLS (with
certificate and host name checks on by default) and the parsing of the
answer are urllib3's (:class:`urllib3.connection.HTTPConnection` /
``HTTPSConnection``, one connection per request, no pool).  A connection
never follows a redirect: a 3xx is an :class:`Answer` like any other and is
classified as a refusal with its ``Location`` (never followed, so the
token never goes to another host).  Written here, because urllib3 does not
give them: (1) a wall-clock *deadline* per request, ``timeout_s`` for
connect, send and the whole answer: urllib3's timeouts bound each socket
operation only (``urllib3/util/timeout.py`` @ urllib3 2.x: "if a server
streams one byte every fifteen seconds, a timeout of 20 seconds will not
trigger"), so a watchdog timer shuts the socket down at the deadline and the
blocked read returns; (2) a cap on the answer (:data:`ANSWER_BYTES`): the
body is read in pieces and the connection dropped once the cap is passed;
(3) every way an answer can be broken (cut, not HTTP, not JSON, too large,
past the deadline) is one of two outcomes, :class:`Unreachable` or an
:class:`Answer` with its :attr:`Answer.problem`, never another exception.
"""

from __future__ import annotations

import http.client
import json
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote, urlsplit

import urllib3
from urllib3.connection import HTTPConnection, HTTPSConnection

from ...handlers.secret_text import redact

__all__ = ["Answer", "Unreachable", "Request", "KowalskiQueue", "SkyPortalPlans", "make_client",
           "KOWALSKI_PATH", "SKYPORTAL_MANUAL_PATH", "ANSWER_BYTES"]

KOWALSKI_PATH = "/api/triggers/ztf"
SKYPORTAL_MANUAL_PATH = "/api/observation_plan/manual"
#: Characters of a server's answer kept (store, log, status document).
ANSWER_CHARS = 2000
#: Most bytes of an answer read (a queue list of the whole mountain fits; a 1.5 GB answer is cut).
ANSWER_BYTES = 4 * 2**20
_PIECE = 65536


class Unreachable(Exception):
    """No (usable) HTTP answer: refused or reset, DNS failure, the deadline, a cut or non-HTTP answer."""


@dataclass(frozen=True)
class Request:
    """One HTTP request, as it would go out (for ``--dry-run`` and logs the token is redacted)."""

    method: str
    url: str
    body: Any = None
    auth_scheme: str = "Bearer"

    def describe(self) -> dict[str, Any]:
        """Method, URL, headers with the token as ``***`` and the JSON body."""
        return {"method": self.method, "url": self.url,
                "headers": {"Authorization": f"{self.auth_scheme} ***", "Content-Type": "application/json"},
                "body": self.body}


@dataclass(frozen=True)
class Answer:
    """An HTTP answer: status, the text (token blanked, truncated), its JSON when it parses, and what is wrong.

    ``problem`` is None for a usable answer, else one line: a redirect (with
    its target), a body that is not JSON, or one larger than
    :data:`ANSWER_BYTES` (not read further).
    """

    status: int
    text: str
    data: Any = field(default=None, compare=False)
    problem: str | None = None

    @property
    def ok(self) -> bool:
        return 200 <= self.status < 300

    @property
    def redirected(self) -> bool:
        return 300 <= self.status < 400

    @property
    def refused(self) -> bool:
        """3xx or 4xx: the server read the request and did not take it (never retried blindly)."""
        return 300 <= self.status < 500

    def message(self) -> str:
        """The server's own message (``{"message": ...}``) when it gave one, else what is wrong, else its text."""
        if isinstance(self.data, dict) and isinstance(self.data.get("message"), str) and self.data["message"]:
            return self.data["message"][:ANSWER_CHARS]
        return self.problem or self.text


class _Deadline:
    """Shuts a connection's socket down when the request's time is up (the blocked read then returns)."""

    def __init__(self, seconds: float) -> None:
        self.at = time.monotonic() + seconds
        self.fired = False
        self._sock: socket.socket | None = None
        self._lock = threading.Lock()
        self._timer = threading.Timer(seconds, self._fire)
        self._timer.daemon = True

    def watch(self, conn: HTTPConnection) -> None:
        with self._lock:
            self._sock = conn.sock
        self._timer.start()

    def left(self) -> float:
        return self.at - time.monotonic()

    def _fire(self) -> None:
        with self._lock:
            self.fired = True
            if self._sock is not None:
                try:
                    self._sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass

    def cancel(self) -> None:
        self._timer.cancel()


#: What a broken connection or answer raises inside http.client and urllib3.
_BROKEN = (OSError, http.client.HTTPException, urllib3.exceptions.HTTPError, ValueError)


class _Client:
    auth_scheme = "Bearer"

    def __init__(self, url: str, token: str | None, timeout_s: float = 10.0) -> None:
        self.base = url.rstrip("/")
        self._token = token
        self.timeout_s = float(timeout_s)

    def __repr__(self) -> str:  # never the token
        return f"{type(self).__name__}({self.base!r}, token=***)"

    def send(self, req: Request) -> Answer:
        """Send one request within ``timeout_s`` in all; an HTTP status of any value is an :class:`Answer`.

        Raises
        ------
        Unreachable
            No usable answer (refused, reset, the deadline, a cut or non-HTTP answer).
        """
        data = None if req.body is None else json.dumps(req.body).encode()
        headers = {"Accept": "application/json", "Connection": "close"}
        if data is not None:
            headers["Content-Type"] = "application/json"
        if self._token:
            headers["Authorization"] = f"{self.auth_scheme} {self._token}"
        deadline = _Deadline(self.timeout_s)
        try:
            status, location, raw, cut = self._exchange(req, data, headers, deadline)
        except _BROKEN as exc:
            why = (f"no complete answer within the {self.timeout_s:g} s deadline" if deadline.fired
                   else f"{type(exc).__name__}: {exc}")
            raise Unreachable(_line(f"{req.method} {req.url}: {redact(why, self._token)}")) from None
        finally:
            deadline.cancel()
        text = redact(raw.decode("utf-8", "replace"), self._token)
        parsed, problem = None, None
        if cut:
            problem = f"the answer is larger than {ANSWER_BYTES} bytes (not read further)"
        elif 300 <= status < 400:
            problem = f"redirected to {redact(location or '(no Location)', self._token)} (redirects are not followed)"
        elif not text.strip():
            problem = "the answer is empty, not JSON"
        else:
            try:
                parsed = json.loads(text)
            except ValueError:
                problem = "the answer is not JSON"
        return Answer(status, text[:ANSWER_CHARS], parsed, problem)

    def _exchange(self, req: Request, data: bytes | None, headers: dict[str, str],
                  deadline: _Deadline) -> tuple[int, str | None, bytes, bool]:
        """(status, Location, body up to the cap, whether it was cut) of one request on a new connection."""
        parts = urlsplit(req.url)
        cls = HTTPSConnection if parts.scheme == "https" else HTTPConnection
        conn = cls(parts.hostname or "", parts.port, timeout=max(0.01, deadline.left()))
        try:
            conn.connect()
            deadline.watch(conn)
            path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
            conn.request(req.method, path, body=data, headers=headers, preload_content=False)
            resp = conn.getresponse()
            body = bytearray()
            while len(body) <= ANSWER_BYTES:
                piece = resp.read(_PIECE)
                if not piece:
                    break
                body += piece
            if deadline.fired:
                raise TimeoutError("deadline")
            cut = len(body) > ANSWER_BYTES
            return resp.status, resp.headers.get("Location"), bytes(body[:ANSWER_BYTES]), cut
        finally:
            conn.close()


def _line(text: str, limit: int = 500) -> str:
    """One line of at most ``limit`` characters (a server's text can hold anything)."""
    flat = " ".join(text.split())
    return flat if len(flat) <= limit else flat[:limit] + "..."


class KowalskiQueue(_Client):
    """ZTF's ToO queue through Kowalski's ``/api/triggers/ztf``."""

    target = "kowalski"
    auth_scheme = "Bearer"

    def put_request(self, queue: dict[str, Any]) -> Request:
        return Request("PUT", self.base + KOWALSKI_PATH, queue, self.auth_scheme)

    def delete_request(self, queue_name: str, user: str) -> Request:
        return Request("DELETE", self.base + KOWALSKI_PATH, {"queue_name": queue_name, "user": user},
                       self.auth_scheme)

    def put(self, queue: dict[str, Any]) -> Answer:
        """Submit a queue: 200 accepted, 409 a queue of that name exists, 400/401/403 refused."""
        return self.send(self.put_request(queue))

    def delete(self, queue_name: str, user: str) -> Answer:
        """Remove a queue: 200 removed, 400 refused (also when the mountain does not know it)."""
        return self.send(self.delete_request(queue_name, user))

    def queues(self) -> list[dict[str, Any]]:
        """What is queued: ``[{queue_name, validity_window_mjd, queue}, ...]`` (``queue``: JSON text of the targets).

        Raises
        ------
        Unreachable
            No answer.
        RuntimeError
            The server answered, but not with a list.
        """
        answer = self.send(Request("GET", self.base + KOWALSKI_PATH, None, self.auth_scheme))
        data = answer.data.get("data") if isinstance(answer.data, dict) else None
        if not answer.ok or not isinstance(data, list):
            raise RuntimeError(_line(f"GET {KOWALSKI_PATH} answered {answer.status}: {answer.message()}"))
        return [q for q in data if isinstance(q, dict)]


class SkyPortalPlans(_Client):
    """SkyPortal's manual observation plans (``ObservationPlanManualRequestHandler``)."""

    target = "skyportal"
    auth_scheme = "token"

    def post_request(self, payload: dict[str, Any]) -> Request:
        return Request("POST", self.base + SKYPORTAL_MANUAL_PATH, payload, self.auth_scheme)

    def post(self, payload: dict[str, Any]) -> Answer:
        """Import a plan: 200 with ``data.id`` (the observation plan request), 400 refused."""
        return self.send(self.post_request(payload))

    def delete(self, request_id: str) -> Answer:
        """Delete an observation plan request by its id."""
        return self.send(Request("DELETE", f"{self.base}/api/observation_plan/{quote(str(request_id))}", None,
                                 self.auth_scheme))

    def exists(self, plan_name: str) -> bool:
        """Whether a plan of that name exists (``plan_names?name=``).

        Raises
        ------
        Unreachable, RuntimeError
        """
        answer = self.send(Request("GET", f"{self.base}/api/observation_plan/plan_names?name={quote(plan_name)}",
                                   None, self.auth_scheme))
        data = answer.data.get("data") if isinstance(answer.data, dict) else None
        if not answer.ok or not isinstance(data, dict):
            raise RuntimeError(_line(f"GET plan_names answered {answer.status}: {answer.message()}"))
        return bool(data.get("exists"))

    def find(self, plan_name: str, dateobs: str, pages: int = 20) -> int | None:
        """The id of the event's request named ``plan_name`` (``payload.queue_name``), None when there is none.

        ``GET /api/observation_plan?dateobs=...`` lists the event's requests
        with their ``payload`` (``ObservationPlanRequestHandler.get``,
        observation_plan.py lines 1246-1304), 100 a page; at most ``pages`` pages.

        Raises
        ------
        Unreachable, RuntimeError
            No answer, or not SkyPortal's list (then whether it exists is unknown).
        """
        for page in range(1, pages + 1):
            answer = self.send(Request("GET", f"{self.base}/api/observation_plan?dateobs={quote(dateobs)}"
                                       f"&numPerPage=100&pageNumber={page}", None, self.auth_scheme))
            data = answer.data.get("data") if isinstance(answer.data, dict) else None
            listed = data.get("requests") if isinstance(data, dict) else None
            if not answer.ok or answer.problem or not isinstance(listed, list):
                raise RuntimeError(_line(f"GET observation_plan answered {answer.status}: {answer.message()}"))
            for row in listed:
                payload = row.get("payload") if isinstance(row, dict) else None
                if isinstance(payload, dict) and payload.get("queue_name") == plan_name:
                    found = row.get("id")
                    if isinstance(found, int) and not isinstance(found, bool):
                        return found
                    raise RuntimeError(_line(f"request {plan_name} listed with id {found!r}"))
            total = data.get("totalMatches")
            if not listed or not isinstance(total, int) or page * 100 >= total:
                return None
        raise RuntimeError(f"more than {pages * 100} requests listed for the event: {plan_name} not found in them")


def make_client(target: str, url: str, token: str | None, timeout_s: float) -> KowalskiQueue | SkyPortalPlans:
    """The client of a ``[submit] target``."""
    if target == "kowalski":
        return KowalskiQueue(url, token, timeout_s)
    if target == "skyportal":
        return SkyPortalPlans(url, token, timeout_s)
    raise ValueError(f"no submission client for target {target!r}")
