"""Contract servers of the executed-observation sources, on loopback (pytest-httpserver), written from their sources.

SkyPortal (skyportal/skyportal @ 8bd346c, BSD-3-Clause):
``skyportal/handlers/api/observation.py`` ``ObservationHandler.get``: query
``telescopeName``, ``instrumentName``, ``startDate``, ``endDate`` (required;
``Missing start_date``), ``numPerPage`` (default 100, at most
``MAX_OBSERVATIONS`` = 1000: ``numPerPage should be no larger than 1000.``),
``pageNumber`` (from 1); ``get_observations`` keeps ``startDate <= obstime <=
endDate`` and answers ``{"status": "success", "data": {"observations":
[...], "totalMatches": n}}``; ``auth_or_token`` (baselayer) reads
``Authorization: token <token>`` and answers 401 without one.  The
observations served are those of ``tests/data/executed/skyportal_observation_answer.json``.

ZTF's depot (IPAC): ``<depot>/<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json`` behind
HTTP basic auth (nuztf's ``download_depot_log`` and SkyPortal's
``fetch_depot_observations``, which HEADs then GETs), 404 for a night without
a file.  Every request is appended to ``log``.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path
from typing import Any

from pytest_httpserver import HTTPServer
from werkzeug.wrappers import Request, Response

EXECUTED = Path(__file__).resolve().parents[1] / "data" / "executed"
MAX_OBSERVATIONS = 1000


def _json(status: int, doc: Any) -> Response:
    return Response(json.dumps(doc), status=status, content_type="application/json")


def _error(message: str, status: int = 400) -> Response:
    return _json(status, {"status": "error", "message": message})


class SkyPortalObservations:
    """``GET /api/observation`` of one SkyPortal (see the module docstring)."""

    def __init__(self, server: HTTPServer, token: str, observations: list[dict[str, Any]] | None = None) -> None:
        self.server, self.token = server, token
        doc = json.loads((EXECUTED / "skyportal_observation_answer.json").read_text())
        self.observations = observations if observations is not None else doc["data"]["observations"]
        self.log: list[dict[str, Any]] = []
        server.expect_request("/api/observation", method="GET").respond_with_handler(self._handle)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server.port}"

    def _handle(self, request: Request) -> Response:
        args = request.args
        self.log.append({"args": dict(args), "authorization": request.headers.get("Authorization", "")})
        header = request.headers.get("Authorization", "")
        if header != f"token {self.token}":
            return _error("Unauthorized", 401)
        for name in ("startDate", "endDate"):
            if not args.get(name):
                return _error(f"Missing {name[:-4]}_date")
        try:
            page, n = int(args.get("pageNumber", 1)), int(args.get("numPerPage", 100))
        except ValueError:
            return _error("Invalid page number value.")
        if n > MAX_OBSERVATIONS:
            return _error(f"numPerPage should be no larger than {MAX_OBSERVATIONS}.")
        lo, hi = args["startDate"].strip(), args["endDate"].strip()
        inside = [o for o in self.observations if lo <= o["obstime"] <= hi]  # ISO strings order as times
        return _json(200, {"status": "success", "data": {"observations": inside[(page - 1) * n:page * n],
                                                         "totalMatches": len(inside)}})


class Depot:
    """IPAC's depot of ``ztf_recentproc`` files (see the module docstring)."""

    def __init__(self, server: HTTPServer, user: str, password: str, files: dict[str, bytes]) -> None:
        self.server, self.files = server, files
        self.credentials = "Basic " + base64.b64encode(f"{user}:{password}".encode()).decode()
        self.log: list[str] = []
        server.expect_request(re.compile(r"/ztf/depot/.*")).respond_with_handler(self._handle)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server.port}/ztf/depot"

    def _handle(self, request: Request) -> Response:
        self.log.append(f"{request.method} {request.path}")
        if request.headers.get("Authorization", "") != self.credentials:
            return Response("401 Unauthorized", status=401, headers={"WWW-Authenticate": 'Basic realm="depot"'})
        name = request.path[len("/ztf/depot/"):]
        if name not in self.files:
            return Response("404 Not Found", status=404)
        return Response(self.files[name], status=200, content_type="application/json")
