"""HTTP clients of the two neighbours that put a plan in ZTF's ToO queue.

* :class:`KowalskiQueue`: ``PUT/DELETE/GET {url}/api/triggers/ztf`` with
  ``Authorization: Bearer <token>`` (skyportal/kowalski
  ``kowalski/api/handlers/ztf.py``, ``ZTFTriggerHandler``);
* :class:`SkyPortalPlans`: ``POST {url}/api/observation_plan/manual``,
  ``DELETE {url}/api/observation_plan/<id>`` and ``GET
  {url}/api/observation_plan/plan_names?name=...`` with ``Authorization:
  token <token>`` (skyportal/skyportal ``skyportal/handlers/api/observation_plan.py``).

The contracts, with the commits they were read from, are in
``docs/design/submission.md``.  The standard library's ``urllib.request``
is enough for three JSON calls (no new dependency); the token is sent
only in the header, never logged, and blanked out of any server text we keep.
"""

from __future__ import annotations

import json
import socket
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import quote

__all__ = ["Answer", "Unreachable", "Request", "KowalskiQueue", "SkyPortalPlans", "make_client", "redact",
           "KOWALSKI_PATH", "SKYPORTAL_MANUAL_PATH"]

KOWALSKI_PATH = "/api/triggers/ztf"
SKYPORTAL_MANUAL_PATH = "/api/observation_plan/manual"
#: Characters of a server's answer kept (store, log, status document).
ANSWER_CHARS = 2000


class Unreachable(Exception):
    """No HTTP answer: connection refused or reset, DNS failure, timeout."""


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
    """An HTTP answer: status, the text (token blanked, truncated) and its JSON when it parses."""

    status: int
    text: str
    data: Any = field(default=None, compare=False)

    @property
    def ok(self) -> bool:
        return 200 <= self.status < 300

    @property
    def refused(self) -> bool:
        """4xx: the server read the request and said no (never retried blindly)."""
        return 400 <= self.status < 500

    def message(self) -> str:
        """The server's own message (``{"message": ...}``) when it gave one, else its text."""
        if isinstance(self.data, dict) and isinstance(self.data.get("message"), str) and self.data["message"]:
            return self.data["message"][:ANSWER_CHARS]
        return self.text


def redact(text: str, token: str | None) -> str:
    """``text`` with every occurrence of ``token`` replaced by ``***``."""
    return text.replace(token, "***") if token else text


class _Client:
    auth_scheme = "Bearer"

    def __init__(self, url: str, token: str | None, timeout_s: float = 10.0) -> None:
        self.base = url.rstrip("/")
        self._token = token
        self.timeout_s = float(timeout_s)

    def __repr__(self) -> str:  # never the token
        return f"{type(self).__name__}({self.base!r}, token=***)"

    def send(self, req: Request) -> Answer:
        """Send one request; an HTTP status of any value is an :class:`Answer`.

        Raises
        ------
        Unreachable
            No answer (refused, reset, timeout).
        """
        data = None if req.body is None else json.dumps(req.body).encode()
        headers = {"Accept": "application/json"}
        if data is not None:
            headers["Content-Type"] = "application/json"
        if self._token:
            headers["Authorization"] = f"{self.auth_scheme} {self._token}"
        r = urllib.request.Request(req.url, data=data, method=req.method, headers=headers)
        try:
            with urllib.request.urlopen(r, timeout=self.timeout_s) as resp:
                status, raw = resp.status, resp.read()
        except urllib.error.HTTPError as exc:
            status = exc.code
            try:
                raw = exc.read()
            except (OSError, socket.timeout) as inner:
                raise Unreachable(f"{req.method} {req.url}: answer {status} cut off ({inner})") from None
        except (urllib.error.URLError, OSError, socket.timeout) as exc:
            reason = getattr(exc, "reason", exc)
            raise Unreachable(f"{req.method} {req.url}: {redact(str(reason), self._token)}") from None
        text = redact(raw.decode("utf-8", "replace"), self._token)
        try:
            parsed = json.loads(text) if text.strip() else None
        except ValueError:
            parsed = None
        return Answer(status, text[:ANSWER_CHARS], parsed)


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
            raise RuntimeError(f"GET {KOWALSKI_PATH} answered {answer.status}: {answer.message()}")
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
            raise RuntimeError(f"GET plan_names answered {answer.status}: {answer.message()}")
        return bool(data.get("exists"))


def make_client(target: str, url: str, token: str | None, timeout_s: float) -> KowalskiQueue | SkyPortalPlans:
    """The client of a ``[submit] target``."""
    if target == "kowalski":
        return KowalskiQueue(url, token, timeout_s)
    if target == "skyportal":
        return SkyPortalPlans(url, token, timeout_s)
    raise ValueError(f"no submission client for target {target!r}")
