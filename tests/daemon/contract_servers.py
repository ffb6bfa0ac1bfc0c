"""Contract servers of the two neighbours, on loopback (pytest-httpserver), written from their sources.

Kowalski (skyportal/kowalski @ 51d0078, MIT): ``kowalski/api/handlers/ztf.py``
``ZTFTriggerHandler`` behind ``/api/triggers/ztf`` (``kowalski/api/api.py``),
``admin_required`` and ``auth_middleware`` (``kowalski/api/middlewares.py``),
``BaseHandler.success/error`` (``kowalski/api/handlers/base.py``):

* auth: ``Authorization: Bearer <jwt>`` (or the bare token); none -> 401
  ``auth required``; undecodable -> 400 ``token is invalid``; not the admin
  -> 403 ``admin rights required``;
* PUT: the body is validated as ``ZTFTriggerPut`` (``queue_name: str,
  validity_window_mjd: List[float], targets: List[dict], queue_type: str,
  user: str``); a validation error becomes 400 ``<ExceptionName>: ...``
  (``error_middleware``); the mountain's 201 -> 200 ``{"status": "success",
  "message": "submitted"}``; its 200 (the queue exists) -> 409 ``Submitted
  queue <name> already exists``; anything else -> 400 ``ZTF trigger attempt
  rejected: ...``.  The targets' keys are the OpenAPI ``required`` list of
  the same handler;
* DELETE: ``ZTFTriggerDelete`` (``queue_name: str, user: str``); 200
  ``deleted``, else 400 ``ZTF queue delete attempt rejected: ...``;
* GET: ``{"status": "success", "message": "retrieved", "data": [...]}``, the
  mountain's list: ``queue_name``, ``validity_window_mjd`` and ``queue`` (the
  targets as JSON text), as SkyPortal's ``ZTFMMAAPI.queued`` /
  ``fetch_queued_observations`` read it.

SkyPortal (skyportal/skyportal @ 8bd346c, BSD-3-Clause):
``skyportal/handlers/api/observation_plan.py`` ``ObservationPlanManualRequestHandler.post``
(``/api/observation_plan/manual``), ``ObservationPlanRequestHandler.delete``,
``ObservationPlanNameHandler.get``; auth ``Authorization: token <token>``;
errors are 400 ``{"status": "error", "message": ...}``.

Faults for the tests: :attr:`KowalskiContract.faults` maps a method to a
list of answers for its next requests (a status code; ``"hang"``: the
request is applied to nothing and answered only after :attr:`release` is set
or ``hang_s`` passed; ``"drip"``: applied to nothing, answered 200 with a
body of one byte every 0.1 s for ``hang_s``; ``"late"``: held unanswered until :attr:`land`
is set, *then applied* (a slow mountain link: Kowalski applies a PUT after the client's
deadline; :attr:`late_held` is set while one is held, :attr:`landed` once applied);
``"mountain-timeout"``: answered at once with Kowalski's own 400 ``TimeoutError: `` (its 10 s to the
mountain ran out: ``error_middleware``'s text for the handler's exception), and applied by the mountain
only once :attr:`land` is set (:attr:`late_held`, :attr:`landed` as for ``"late"``); ``None``:
no fault).  :attr:`faults_by_name` maps ``(method, queue name)`` to such a list for the requests
of that method naming that queue (taken before the method's faults).  :attr:`KowalskiContract.block_after` holds a method
*after* applying it, until :attr:`release` (a request that reached the
server while the client dies).  Every request is appended to :attr:`log`.
"""

from __future__ import annotations

import fnmatch
import json
import threading
import time
from typing import Any

from pytest_httpserver import HTTPServer
from werkzeug.wrappers import Request, Response

KOWALSKI_PATH = "/api/triggers/ztf"

PUT_FIELDS = {"queue_name": str, "validity_window_mjd": list, "targets": list, "queue_type": str, "user": str}
TARGET_FIELDS = ("request_id", "program_id", "field_id", "ra", "dec", "filter_id", "exposure_time", "program_pi",
                 "subprogram_name")

MANUAL_REQUIRED = ("payload", "status", "allocation_id", "plan_name", "observation_plans")
PLANNED_REQUIRED = ("dateobs", "field_id", "exposure_time", "weight", "filt", "planned_observation_id",
                    "overhead_per_exposure")


def _json(status: int, doc: dict[str, Any]) -> Response:
    return Response(json.dumps(doc), status=status, content_type="application/json")


def _error(message: str, status: int = 400) -> Response:
    return _json(status, {"status": "error", "message": message})


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def loopback_server() -> HTTPServer:
    """A started threaded pytest-httpserver on 127.0.0.1 (a hanging request does not block the others)."""
    server = HTTPServer(host="127.0.0.1", port=0, threaded=True)
    server.start()
    return server


class _Contract:
    scheme = "Bearer"

    def __init__(self, server: HTTPServer, token: str) -> None:
        self.server = server
        self.token = token
        self.log: list[dict[str, Any]] = []
        self.faults: dict[str, list[Any]] = {}
        self.faults_by_name: dict[tuple[str, str], list[Any]] = {}
        self.land = threading.Event()  # a "late" request is applied once this is set
        self.late_held = threading.Event()  # a "late" request is held
        self.landed = threading.Event()  # a "late" request was applied
        self.block_after: set[str] = set()
        self.release = threading.Event()
        self.hang_s = 60.0
        self.blocked = threading.Event()  # set while a request is held by block_after
        self.hanging = 0  # requests held unanswered by a "hang" fault right now
        self.drip_s = 0.1  # seconds per byte of a "drip" answer
        self.delay_s = 0.0  # every request is applied only after this (a slow but working server)
        self._lock = threading.Lock()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server.port}"

    def _auth(self, request: Request) -> Response | None:
        header = request.headers.get("Authorization")
        if not header:
            return _error("auth required", 401)
        parts = header.split()
        value = parts[1] if len(parts) == 2 and parts[0].lower() == self.scheme.lower() else header
        if value != self.token:
            return _error("token is invalid", 400)
        return None

    def _next_fault(self, method: str, body: Any) -> Any:
        name = (body.get("queue_name") or body.get("plan_name")) if isinstance(body, dict) else None
        with self._lock:  # a name, or a pattern of names (fnmatch: a plan's queue is named after its plan id)
            queue = next((q for (m, pattern), q in self.faults_by_name.items()
                          if m == method and name and fnmatch.fnmatchcase(name, pattern)), None)
            if not queue:
                queue = self.faults.get(method)
            return queue.pop(0) if queue else None

    def _late(self, request: Request, body: Any) -> Response:
        """Hold the request past the client's deadline until :attr:`land`, then apply it (answered to no one)."""
        self.late_held.set()
        self.land.wait(self.hang_s)
        response = self._apply(request, body)
        self._record(request, response.status_code, body, late=True)
        self.landed.set()
        return response

    def _mountain_timeout(self, request: Request, body: Any) -> Response:
        """Kowalski's 400 ``TimeoutError: `` now; the mountain applies the request once :attr:`land` is set."""
        method = request.method

        def apply_later() -> None:
            self.land.wait(self.hang_s)
            done = self._apply(type("Late", (), {"method": method})(), body)  # type: ignore[arg-type]
            self._record(request, done.status_code, body, late=True)
            self.landed.set()

        self.late_held.set()
        threading.Thread(target=apply_later, daemon=True).start()
        response = _error("TimeoutError: ")
        self._record(request, response.status_code, body)
        return response

    def _fault(self, fault: Any) -> Response | None:
        if fault is None:
            return None
        if fault == "drip":  # a 200 whose body comes one byte every 0.1 s for hang_s: no recv ever times out
            n, step = max(1, int(self.hang_s / self.drip_s)), self.drip_s

            def trickle():
                for _ in range(n):
                    time.sleep(step)
                    yield b" "

            return Response(trickle(), status=200, content_type="application/json")
        if fault == "hang":
            with self._lock:
                self.hanging += 1
            self.release.wait(self.hang_s)
            with self._lock:
                self.hanging -= 1
            return _error("hung", 504)
        return _error(f"injected {fault}", int(fault))

    def _handle(self, request: Request) -> Response:
        """Auth, then an injected fault, then the contract (:meth:`_apply`); every request logged."""
        try:
            body = json.loads(request.get_data() or b"null")
        except ValueError:
            body = None
        if self.delay_s:
            time.sleep(self.delay_s)
        response = self._auth(request)
        if response is None:
            fault = self._next_fault(request.method, body)
            if fault == "late":
                return self._late(request, body)
            if fault == "mountain-timeout":
                return self._mountain_timeout(request, body)
            response = self._fault(fault) or self._apply(request, body)
        self._record(request, response.status_code, body)
        if request.method in self.block_after and response.status_code == 200:
            self.blocked.set()
            self.release.wait(self.hang_s)
        return response

    def _apply(self, request: Request, body: Any) -> Response:
        raise NotImplementedError

    def _record(self, request: Request, status: int, body: Any, late: bool = False) -> None:
        entry = {"t": round(time.time(), 3), "method": request.method, "path": request.path, "status": status,
                 "authorization": request.headers.get("Authorization", "")}
        if late:
            entry["late"] = True
        if isinstance(body, dict):
            for k in ("queue_name", "plan_name", "user"):
                if k in body:
                    entry[k] = body[k]
        with self._lock:
            self.log.append(entry)

    def lines(self) -> list[str]:
        """The request log as ``METHOD path name -> status`` lines (for reports)."""
        return [f"{e['method']} {e['path']} {e.get('queue_name') or e.get('plan_name') or ''} -> {e['status']}"
                + (" (applied after the client's deadline)" if e.get("late") else "") for e in self.log]


class KowalskiContract(_Contract):
    """Kowalski's ``/api/triggers/ztf`` (see the module docstring)."""

    def __init__(self, server: HTTPServer, token: str) -> None:
        super().__init__(server, token)
        self.queues: dict[str, dict[str, Any]] = {}
        #: name prefixes whose first queue exists already with other content (its first PUT gets 409)
        self.taken: set[str] = set()
        for method in ("PUT", "DELETE", "GET"):
            server.expect_request(KOWALSKI_PATH, method=method).respond_with_handler(self._handle)

    def _apply(self, request: Request, body: Any) -> Response:
        if request.method == "GET":
            data = [{"queue_name": n, "validity_window_mjd": q["validity_window_mjd"],
                     "queue": json.dumps(q["targets"])} for n, q in self.queues.items()]
            return _json(200, {"status": "success", "message": "retrieved", "data": data})
        if not isinstance(body, dict):
            return _error("JSONDecodeError: the body is not a JSON object")
        if request.method == "DELETE":
            missing = [k for k in ("queue_name", "user") if not isinstance(body.get(k), str)]
            if missing:
                return _error(f"ValidationError: {', '.join(missing)}: field required (str)")
            with self._lock:
                gone = self.queues.pop(body["queue_name"], None)
            if gone is None:
                return _error(f"ZTF queue delete attempt rejected: queue {body['queue_name']} not found")
            return _json(200, {"status": "success", "message": "deleted", "data": {}})
        problem = self._put_problem(body)
        if problem:
            return _error(f"ValidationError: {problem}")
        with self._lock:
            name = body["queue_name"]
            for prefix in [p for p in self.taken if name.startswith(p) and name.endswith("_1")]:
                self.taken.discard(prefix)
                self.queues[name] = {"queue_name": name, "validity_window_mjd": [1.0, 2.0], "targets": []}
            if body["queue_name"] in self.queues:
                return _error(f"Submitted queue {body['queue_name']} already exists", 409)
            self.queues[body["queue_name"]] = body
        return _json(200, {"status": "success", "message": "submitted", "data": {}})

    @staticmethod
    def _put_problem(body: dict[str, Any]) -> str | None:
        for key, kind in PUT_FIELDS.items():
            if key not in body:
                return f"{key}: field required"
            if not isinstance(body[key], kind):
                return f"{key}: expected {kind.__name__}, got {type(body[key]).__name__}"
        if len(body["validity_window_mjd"]) != 2 or not all(map(_is_number, body["validity_window_mjd"])):
            return "validity_window_mjd: expected [start, end] numbers"
        if body["queue_type"] != "list":
            return f"queue_type {body['queue_type']!r}: the mountain takes list queues"
        if not body["targets"]:
            return "targets: empty queue"
        for i, t in enumerate(body["targets"]):
            if not isinstance(t, dict):
                return f"targets[{i}]: expected dict"
            lacking = [k for k in TARGET_FIELDS if k not in t]
            if lacking:
                return f"targets[{i}]: lacks {', '.join(lacking)}"
            if not all(_is_number(t[k]) for k in ("ra", "dec", "exposure_time")):
                return f"targets[{i}]: ra, dec, exposure_time must be numbers"
            if not isinstance(t["filter_id"], int) or t["filter_id"] not in (1, 2, 3):
                return f"targets[{i}]: filter_id must be 1, 2 or 3"
            if not all(isinstance(t[k], (int, str)) and not isinstance(t[k], bool)
                       for k in ("request_id", "program_id", "field_id")):
                return f"targets[{i}]: request_id, program_id, field_id must be integers or strings"
            if not all(isinstance(t[k], str) for k in ("program_pi", "subprogram_name")):
                return f"targets[{i}]: program_pi, subprogram_name must be strings"
        return None


class SkyPortalContract(_Contract):
    """SkyPortal's manual observation plan import, plan deletion and plan-name lookup."""

    scheme = "token"

    def __init__(self, server: HTTPServer, token: str) -> None:
        super().__init__(server, token)
        self.plans: dict[int, dict[str, Any]] = {}
        self._next = 1
        server.expect_request("/api/observation_plan/manual", method="POST").respond_with_handler(self._handle)
        server.expect_request("/api/observation_plan/plan_names", method="GET").respond_with_handler(self._handle)
        import re

        server.expect_request(re.compile(r"^/api/observation_plan/[0-9]+$"), method="DELETE"
                              ).respond_with_handler(self._handle)

    def _apply(self, request: Request, body: Any) -> Response:
        if request.method == "GET":
            name = request.args.get("name")
            exists = any(p["plan_name"] == name or p["payload"].get("queue_name") == name for p in self.plans.values())
            return _json(200, {"status": "success", "data": {"exists": exists}})
        if request.method == "DELETE":
            pid = int(request.path.rsplit("/", 1)[1])
            if self.plans.pop(pid, None) is None:
                return _error(f"Cannot find ObservationPlanRequest with ID: {pid}")
            return _json(200, {"status": "success"})
        if not isinstance(body, dict):
            return _error("Invalid JSON")
        if "gcnevent_id" not in body and "dateobs" not in body:
            return _error("Need to specify either gcnevent_id or dateobs")
        if "localization_id" not in body and "localization_name" not in body:
            return _error("Need to specify either localization_id or localization_name")
        lacking = [k for k in MANUAL_REQUIRED if k not in body]
        if lacking:
            return _error(f"KeyError: {lacking[0]!r}")
        if not body["observation_plans"]:
            return _error("Observation plan request must have at least one observation plan")
        plan = body["observation_plans"][0]
        for k in ("validity_window_start", "validity_window_end", "status", "planned_observations"):
            if k not in plan:
                return _error(f"KeyError: {k!r}")
        for o in plan["planned_observations"]:
            lacking = [k for k in PLANNED_REQUIRED if k not in o]
            if lacking:
                return _error(f"KeyError: {lacking[0]!r}")
            if o["filt"] not in ("ztfg", "ztfr", "ztfi"):
                return _error("Planned observation filter(s) not in instrument's filter list")
        with self._lock:
            pid, self._next = self._next, self._next + 1
            self.plans[pid] = body
        return _json(200, {"status": "success", "data": {"id": pid}})
