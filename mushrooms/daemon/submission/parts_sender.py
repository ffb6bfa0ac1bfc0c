"""Send the other telescopes' SkyPortal parts (``[submit_parts]``, issue 53 item 4).

Every part the service exported (``telescope_parts``, state ``exported``) of a
telescope whose description says ``queue = "skyportal"`` becomes one SkyPortal
observation plan request: the ``skyportal_request.json`` of its folder with
the telescope's allocation, POSTed to ``/api/observation_plan/manual``.  The
lifecycle is the ``part_requests`` table's (:mod:`~mushrooms.daemon.state.part_requests`).
Level-triggered, like the ZTF submitter: each :meth:`PartSender.step` adopts the
parts not yet seen, sends what is pending, and DELETEs (``DELETE
/api/observation_plan/<id>``) the requests whose part no longer stands: a
retraction's (``withdrawn``) at once, a superseded one once the telescope's
newer part is not pending any more (sent, refused or never to be sent).
A part is one round of a job (docs/design/telescopes.md J9): when ZTF's
revision 2 re-plans the job's parts, ``telescope_parts`` keeps round 2's row
only, and round 1's request counts as superseded by it (a request is keyed by
(job, telescope, round), so round 2's is adopted and sent like a newer map's).

Crash safety: a row is marked ``tried`` in its own transaction before its
POST.  A tried row still ``pending`` (a kill -9 between the POST and its
record, the deadline, a 5xx, an answer that is not SkyPortal's) is looked up
by its name (:meth:`~.remote.SkyPortalPlans.find`) before anything else: found,
it is ``sent`` with the id SkyPortal gave it; not found, POSTed again; the
lookup unanswered, it waits.  So a request is never imported twice while
SkyPortal answers its list.

Hostile answers are :mod:`.remote`'s (a hard deadline per request, 4 MiB,
no redirect followed); a 3xx or 4xx to a POST is ``rejected``, never retried,
and since SkyPortal stores the request before it checks filters and fields
(observation_plan.py lines 1430-1485), a request of that name it kept is
looked up and DELETEd.
"""

from __future__ import annotations

import datetime as dt
import json
import logging
from pathlib import Path
from typing import Any, Callable

from ..state.part_requests import add_request, requests, update_request
from .part_request import manual_body, request_name
from .remote import Answer, Unreachable

__all__ = ["PartSender", "REQUEST_FILE"]

log = logging.getLogger("mushrooms.daemon.submit_parts")

#: The request a part's folder holds (written by :mod:`~mushrooms.daemon.planning.parts`).
REQUEST_FILE = "skyportal_request.json"
#: Largest request file read (bytes).
MAX_REQUEST_BYTES = 64 * 2**20


class _Wait(Exception):
    """The far end did not answer usably: the row stays as it is, the pass counts it waiting."""


class _Closed(Exception):
    """The row was closed on the way (nothing more to do in this pass)."""


class PartSender:
    """Sends, finds again and deletes the SkyPortal requests of the other telescopes' parts.

    Parameters
    ----------
    store : Store
        The state file.
    settings : PartSubmitConfig
    client : SkyPortalPlans
        The HTTP client (its token in the header only).
    on_result : callable, optional
        ``on_result(state, telescope)`` after every transition (metrics).
    clock : callable, optional
        The time (UTC ``datetime``) of a pass without ``now``; default the system clock.
    """

    def __init__(self, store: Any, settings: Any, client: Any,
                 on_result: Callable[[str, str], None] | None = None,
                 clock: Callable[[], dt.datetime] | None = None) -> None:
        self.store, self.settings, self.client = store, settings, client
        self.on_result = on_result
        self.clock = clock or (lambda: dt.datetime.now(dt.timezone.utc))

    def step(self, now: dt.datetime | None = None) -> int:
        """One pass: adopt, send, settle.  The number of requests still waiting on SkyPortal."""
        now = now or self.clock()
        self._adopt(now)
        parts = {(p["job_id"], p["telescope"]): p for p in _parts(self.store)}  # each job's latest round
        waiting = 0
        for stage in ("pending", "sent"):  # send first: an old request goes once the newer one is in
            rows = requests(self.store)
            for row in [r for r in rows if r["state"] == stage]:
                part = _part_of(row, parts)
                try:
                    if stage == "pending":
                        self._pending(row, part, now)
                    elif part.get("state") in ("withdrawn", "superseded") and not _newer_pending(row, rows, part):
                        self._settle(row, "deleted" if part["state"] == "withdrawn" else "replaced", now)
                except _Closed:
                    continue
                except (_Wait, Unreachable, RuntimeError) as exc:
                    waiting += 1
                    log.warning("event=part_request_waiting superevent_id=%s telescope=%s job=%s plan_name=%s "
                                "error=%r", row["superevent_id"], row["telescope"], row["job_id"], row["plan_name"],
                                str(exc)[:500])
        return waiting

    # ------------------------------------------------------------ adopting parts
    def _adopt(self, now: dt.datetime) -> None:
        """A row for every exported ``skyportal`` part without one: pending, or why it is not sent."""
        cur = self.store.connection().execute(
            "SELECT p.job_id, p.telescope, p.round, p.superevent_id, p.plan_id, p.folder, j.alert_type"
            " FROM telescope_parts p LEFT JOIN jobs j USING (job_id) WHERE p.queue='skyportal' AND p.state='exported'"
            " AND NOT EXISTS (SELECT 1 FROM part_requests r WHERE r.job_id=p.job_id AND r.telescope=p.telescope"
            " AND r.round=p.round)")
        for part in [dict(r) for r in cur]:
            state, reason, body, name = self._first_state(part, now)
            if add_request(self.store, {"job_id": part["job_id"], "telescope": part["telescope"],
                                        "round": int(part["round"] or 1),
                                        "superevent_id": part["superevent_id"], "plan_id": part["plan_id"],
                                        "plan_name": name, "state": state, "reason": reason,
                                        "body": None if body is None else json.dumps(body)}):
                self._told(part, name, state, reason, body)

    def _first_state(self, part: dict[str, Any], now: dt.datetime) -> tuple[str, str, Any, str]:
        """(state, reason, body, plan name) of a part just adopted."""
        s = self.settings
        name = request_name(part["telescope"], part["superevent_id"], part["plan_id"] or "")
        try:
            request = _read_request(Path(part["folder"] or "") / REQUEST_FILE)
            name = request.get("plan_name") or name
            body = manual_body(request, s.allocations.get(part["telescope"], 1), s.status)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            return "failed", f"no request to send: {type(exc).__name__}: {exc}"[:500], None, name
        if part["alert_type"] not in s.alert_types:
            return "skipped", f"alert type {part['alert_type']} is not in [submit_parts] alert_types", None, name
        if part["telescope"] not in s.allocations:
            return "failed", f"no SkyPortal allocation for {part['telescope']} in [submit_parts] allocations", None, name
        if _window_end(body) <= now:
            return "failed", "its validity window ended before it was sent", body, name
        if s.dry_run:
            return "skipped", "dry run", body, name
        return "pending", "", body, name

    def _told(self, part: dict[str, Any], name: str, state: str, reason: str, body: Any) -> None:
        if self.settings.dry_run and body is not None and state == "skipped":
            log.info("event=part_request_dry_run superevent_id=%s telescope=%s request=%s", part["superevent_id"],
                     part["telescope"], json.dumps(self.client.post_request(body).describe())[:4000])
        if state != "pending":
            self._result(state, part["telescope"], part["superevent_id"], part["job_id"], name, reason)

    # ------------------------------------------------------------ sending
    def _pending(self, row: dict[str, Any], part: dict[str, Any], now: dt.datetime) -> None:
        """Send a pending request, find one that may have been sent, or close it."""
        body = json.loads(row["body"])
        if part.get("state") != "exported" or _window_end(body) <= now:
            found = self._found_at_the_end(row, body, now) if row["tried"] else None
            if found is not None and part.get("state") == "exported":  # it did reach SkyPortal (its window is over)
                return self._close(row, "sent", f"found in SkyPortal after an unanswered POST (request {found})",
                                   remote_id=str(found))
            if found is not None:  # it did reach SkyPortal: take it back like a sent one
                update_request(self.store, row, state="sent", remote_id=str(found))
                return self._settle({**row, "remote_id": str(found)}, _closing_state(part), now)
            why = ("its validity window ended before it was sent" if part.get("state") == "exported"
                   else f"{part.get('state', 'gone')} before it was sent")
            return self._close(row, "failed" if part.get("state") == "exported" else "skipped", why)
        if row["tried"]:
            found = self.client.find(row["plan_name"], body["dateobs"])
            if found is not None:
                return self._close(row, "sent", f"found in SkyPortal after an unanswered POST (request {found})",
                                   remote_id=str(found))
        update_request(self.store, row, tried=1, attempts=row["attempts"] + 1)
        answer = self.client.post(body)
        found = _request_id(answer)
        if found is not None:
            return self._close(row, "sent", "", remote_id=str(found), http_status=answer.status, answer=answer.text)
        if answer.refused:
            return self._close(row, "rejected", f"SkyPortal refused it ({answer.status}): {answer.message()}"
                               + self._kept(row, body), http_status=answer.status, answer=answer.text)
        update_request(self.store, row, http_status=answer.status, answer=answer.text)
        raise _Wait(f"POST answered {answer.status}: {answer.message()}"[:500])

    def _found_at_the_end(self, row: dict[str, Any], body: dict[str, Any], now: dt.datetime) -> int | None:
        """The id of a tried request whose part is over; unknown past its window: ``failed``, remove by hand."""
        try:
            return self.client.find(row["plan_name"], body["dateobs"])
        except (Unreachable, RuntimeError) as exc:
            if _window_end(body) > now:
                raise
            self._close(row, "failed", f"whether SkyPortal holds {row['plan_name']} is unknown at the end of its "
                        f"window ({exc}); remove it by hand if it is there")
            raise _Closed() from None

    def _kept(self, row: dict[str, Any], body: dict[str, Any]) -> str:
        """After a refusal: DELETE a request of that name SkyPortal stored anyway; a few words on it."""
        try:
            found = self.client.find(row["plan_name"], body["dateobs"])
            if found is None:
                return ""
            gone = self.client.delete(str(found))
        except (Unreachable, RuntimeError) as exc:
            return f"; whether SkyPortal kept a request of that name is unknown ({exc})"[:300]
        if gone.ok:
            return f"; SkyPortal had kept request {found} of that name: deleted"
        return f"; SkyPortal kept request {found} of that name and refused to delete it: remove it by hand"

    # ------------------------------------------------------------ taking back
    def _settle(self, row: dict[str, Any], final: str, now: dt.datetime) -> None:
        """DELETE a sent request whose part no longer stands; ``final`` once it is gone.

        A DELETE that keeps failing (5xx, no answer: e.g. an instrument without an
        observation plan API, whose ``api_class_obsplan`` SkyPortal cannot resolve)
        is retried until the request's window ends, then ``failed``: remove it by hand.
        """
        if not row.get("remote_id"):
            return self._close(row, "failed", "sent, but its SkyPortal id is unknown: remove it by hand")
        answer = self.client.delete(row["remote_id"])
        if answer.ok and not answer.problem:
            return self._close(row, final, f"request {row['remote_id']} deleted")
        body = json.loads(row["body"])
        if not answer.refused and _window_end(body) > now:
            raise _Wait(f"DELETE answered {answer.status}: {answer.message()}"[:500])
        if not answer.refused:
            return self._close(row, "failed", f"SkyPortal did not delete request {row['remote_id']} before its window "
                               f"ended ({answer.status}: {answer.message()}); remove it by hand",
                               http_status=answer.status, answer=answer.text)
        if self.client.find(row["plan_name"], body["dateobs"]) is None:
            return self._close(row, final, f"request {row['remote_id']} no longer in SkyPortal")
        self._close(row, "failed", f"SkyPortal refused to delete request {row['remote_id']} ({answer.status}): "
                    f"{answer.message()}; remove it by hand", http_status=answer.status, answer=answer.text)

    def _close(self, row: dict[str, Any], state: str, reason: str, **values: Any) -> None:
        update_request(self.store, row, state=state, reason=reason[:1000], **values)
        self._result(state, row["telescope"], row["superevent_id"], row["job_id"], row["plan_name"], reason,
                     values.get("remote_id") or row.get("remote_id"))

    def _result(self, state: str, telescope: str, sid: str, job: int, name: str, reason: str,
                remote_id: Any = None) -> None:
        level = logging.ERROR if state in ("rejected", "failed") else logging.INFO
        log.log(level, "event=part_request_%s superevent_id=%s telescope=%s job=%s plan_name=%s remote_id=%s "
                "reason=%r", state, sid, telescope, job, name, remote_id or "-", reason[:500])
        if self.on_result is not None:
            self.on_result(state, telescope)


def _parts(store: Any) -> list[dict[str, Any]]:
    """Every part; one of a retracted event counts as ``withdrawn`` (its request goes before the outbox is out)."""
    rows = store.connection().execute(
        "SELECT p.job_id, p.telescope, p.round, p.superevent_id, CASE WHEN e.retracted=1 THEN 'withdrawn'"
        " ELSE p.state END AS state FROM telescope_parts p LEFT JOIN events e USING (superevent_id)")
    return [dict(r) for r in rows]


def _part_of(row: dict[str, Any], parts: dict[tuple[int, str], dict[str, Any]]) -> dict[str, Any]:
    """The part a request was made for; ``superseded`` when its job's part is now of another round (J9).

    ``telescope_parts`` keeps a job's latest round per telescope: a request of
    an earlier round no longer stands (its folder is marked ``SUPERSEDED``), but
    a retraction still withdraws it.
    """
    part = parts.get((row["job_id"], row["telescope"]))
    if part is None:
        return {}
    if part["state"] != "withdrawn" and int(part.get("round") or 1) != int(row.get("round") or 1):
        return {**part, "state": "superseded"}
    return part


def _newer_pending(row: dict[str, Any], rows: list[dict[str, Any]], part: dict[str, Any]) -> bool:
    """A superseded part's request waits while the telescope's newer part (job, round) of the event is pending."""
    mine = (row["job_id"], int(row.get("round") or 1))
    return part.get("state") == "superseded" and any(
        r["state"] == "pending" and r["superevent_id"] == row["superevent_id"] and r["telescope"] == row["telescope"]
        and (r["job_id"], int(r.get("round") or 1)) > mine for r in rows)


def _closing_state(part: dict[str, Any]) -> str:
    return {"withdrawn": "deleted", "superseded": "replaced"}.get(part.get("state", ""), "skipped")


def _request_id(answer: Answer) -> int | None:
    """SkyPortal's id of an imported request (``{"data": {"id": N}}`` with a 2xx), else None."""
    data = answer.data.get("data") if answer.ok and not answer.problem and isinstance(answer.data, dict) else None
    found = data.get("id") if isinstance(data, dict) else None
    return found if isinstance(found, int) and not isinstance(found, bool) and found >= 0 else None


def _window_end(body: dict[str, Any]) -> dt.datetime:
    """The end of a request's validity window (UTC)."""
    end = dt.datetime.fromisoformat(str(body["observation_plans"][0]["validity_window_end"]).rstrip("Z"))
    return end.replace(tzinfo=dt.timezone.utc)


def _read_request(path: Path) -> dict[str, Any]:
    with path.open("rb") as f:
        raw = f.read(MAX_REQUEST_BYTES + 1)
    if len(raw) > MAX_REQUEST_BYTES:
        raise ValueError(f"{path.name} is larger than {MAX_REQUEST_BYTES} bytes")
    doc = json.loads(raw)
    if not isinstance(doc, dict):
        raise ValueError(f"{path.name} is not a JSON object")
    return doc
