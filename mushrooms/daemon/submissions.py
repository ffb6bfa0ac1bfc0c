"""Plans into ZTF's ToO queue, idempotently across crashes (``[submit]``).

One row per plan id in the store's ``submissions`` table::

    pending ─► submitted ─► replaced   (a newer revision of the event was accepted)
       │           └──────► deleted    (the event was retracted)
       ├─► rejected  (the server refused it: 4xx, or 409 with other content; never retried)
       ├─► failed    (no queue could be built, the validity window ended before it was
       │              accepted, or a DELETE was refused: the operator must look)
       └─► skipped   (gates, dry run, or superseded/withdrawn before it was sent)

How it works: the store is the wanted state, the server is made to match.
For every event, the wanted queue is its latest plan (when it passes the
gates); :meth:`Submitter.step` (run by its own thread, kicked after a plan is
stored or a withdrawal recorded) first ``PUT``\\s the wanted queue and only
once it was accepted ``DELETE``\\s the event's older queues, so the telescope
is never left with nothing; a retraction deletes every queue of the event.

Crash safety: a queue's name and body are stored before anything is sent,
and the attempt is committed *before* the HTTP call.  After a kill -9
between the call and the commit the restart sends the same name and body
again: Kowalski answers 409 and the queue list (``GET``) shows the same
content, which counts as accepted; a DELETE repeated after a crash finds
the queue gone (400, not in the list), which counts as done.  So no queue is
sent twice nor left orphaned.  SkyPortal's import is not keyed by name: an
interrupted POST is looked up by plan name (``plan_names?name=``) before
it is repeated.

Queue names: ``ToO_<subprogram_name>_<superevent>_r<n>``, ``n`` counting the
event's submitted revisions from 1 (stored with the row: stable across restarts).
The planning workers never wait on HTTP: they only kick this thread.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Callable

from ..handlers.instants import now_iso_z
from .remote import Answer, KowalskiQueue, SkyPortalPlans, Unreachable
from .store import Store

if TYPE_CHECKING:
    from ..scheduler_core.plan.exports import ExportConfig
    from .submit_settings import SubmitConfig

__all__ = ["Submission", "Submitter", "Verdict", "send_queue", "queue_name", "gate", "build_body", "same_content",
           "status_document", "open_submitter", "submissions", "STATES", "OPEN"]

log = logging.getLogger("mushrooms.daemon.submit")

STATES = ("pending", "submitted", "replaced", "deleted", "rejected", "failed", "skipped")
#: States whose queue may be on the server (the submitter still has work with them).
OPEN = ("pending", "submitted")
#: Transitions that are published as a ``submission`` status document.
_PUBLISHED = ("submitted", "replaced", "deleted", "rejected", "failed")


@dataclass(frozen=True)
class Submission:
    """One row of the ``submissions`` table."""

    plan_id: str
    superevent_id: str
    target: str
    revision: int | None
    queue_name: str | None
    state: str
    reason: str | None
    body: dict[str, Any] | None
    remote_id: str | None
    http_status: int | None
    answer: str | None
    attempts: int
    created_at: str
    attempted_at: str | None
    submitted_at: str | None
    finished_at: str | None


def _row(r: Any) -> Submission:
    return Submission(r["plan_id"], r["superevent_id"], r["target"], r["revision"], r["queue_name"], r["state"],
                      r["reason"], json.loads(r["body"]) if r["body"] else None, r["remote_id"], r["http_status"],
                      r["answer"], r["attempts"], r["created_at"], r["attempted_at"], r["submitted_at"],
                      r["finished_at"])


def submissions(store: Store, superevent_id: str | None = None) -> list[Submission]:
    """Every submission (of one event), oldest first: for operators and tests."""
    q, args = "SELECT * FROM submissions", ()
    if superevent_id is not None:
        q, args = q + " WHERE superevent_id=?", (superevent_id,)
    return [_row(r) for r in store.connection().execute(q + " ORDER BY created_at, rowid", args)]


def _now_iso() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def _unix(iso: str) -> float:
    return datetime.fromisoformat(iso.replace("Z", "+00:00")).timestamp()


def queue_name(subprogram_name: str, superevent_id: str, revision: int) -> str:
    """``ToO_<subprogram_name>_<superevent>_r<revision>``: the queue of an event's ``revision``-th submission."""
    return f"ToO_{subprogram_name}_{superevent_id}_r{int(revision)}"


def gate(document: dict[str, Any], sub: SubmitConfig, now: float | None = None) -> str | None:
    """Why a plan document is not submitted (None: it is).

    Gates of ``[submit]``: only plans (not ``not_observable`` answers) with
    observations, of an alert type in ``alert_types``, covering at least
    ``min_coverage``, with at most ``max_exposures`` exposures (0: any), whose
    validity window has not ended.
    """
    if document.get("type") != "plan":
        return f"a {document.get('type')} document, not a plan"
    if not document.get("observations"):
        return "no observations"
    alert_type = (document.get("event") or {}).get("alert_type")
    if alert_type not in sub.alert_types:
        return f"alert type {alert_type} not in [submit] alert_types"
    metrics = document.get("metrics") or {}
    coverage = float(metrics.get("coverage") or 0.0)
    if coverage < sub.min_coverage:
        return f"coverage {coverage:.4f} below [submit] min_coverage {sub.min_coverage:g}"
    n = int(metrics.get("n_exposures") or len(document["observations"]))
    if sub.max_exposures and n > sub.max_exposures:
        return f"{n} exposures, more than [submit] max_exposures {sub.max_exposures}"
    if _unix(document["end"]) <= (time.time() if now is None else now):
        return f"validity window ended at {document['end']}"
    return None


def build_body(document: dict[str, Any], submit: SubmitConfig, export: ExportConfig, name: str) -> dict[str, Any]:
    """The request body of a plan for ``[submit] target`` under queue name ``name``.

    Kowalski: :func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queue`
    (``plan --queue``); SkyPortal: :func:`~...exports.to_skyportal` (``plan
    --skyportal``) with ``plan_name`` and ``payload.queue_name`` = ``name``
    without its ``ToO_`` (SkyPortal's ZTF API puts it back when it queues the plan).

    Raises
    ------
    ValueError
        The plan cannot be expressed (no observations, a non-ZTF filter,
        SkyPortal without allocation id or event time).
    """
    from ..scheduler_core import Plan
    from ..scheduler_core.plan.exports import to_skyportal, to_trigger_queue

    plan = Plan.from_document(document)
    if submit.target == "kowalski":
        return to_trigger_queue(plan, export, queue_name=name)
    body = to_skyportal(plan, export)
    short = name.removeprefix("ToO_")
    body["plan_name"] = short
    body["payload"]["queue_name"] = short
    return body


def _targets_key(targets: Any) -> list[tuple[int, int, float]]:
    if isinstance(targets, str):
        targets = json.loads(targets)
    return sorted((int(t["field_id"]), int(t["filter_id"]), round(float(t["exposure_time"]), 3)) for t in targets)


def same_content(body: dict[str, Any], listed: dict[str, Any]) -> bool:
    """Whether a queue listed by ``GET /api/triggers/ztf`` is ``body``: same validity window, fields, filters, exposures."""
    try:
        mine, theirs = body["validity_window_mjd"], listed.get("validity_window_mjd")
        if theirs is None or len(theirs) != 2 or any(abs(float(a) - float(b)) > 1e-6 for a, b in zip(mine, theirs)):
            return False
        return _targets_key(body["targets"]) == _targets_key(listed.get("queue", listed.get("targets", [])))
    except (KeyError, TypeError, ValueError):
        return False


@dataclass(frozen=True)
class Verdict:
    """What one PUT/POST of a queue came to: ``submitted``, ``rejected`` or ``retry`` (5xx, timeout, unreachable)."""

    state: str
    answer: Answer | None
    reason: str | None = None
    remote_id: str | None = None


def send_queue(client: KowalskiQueue | SkyPortalPlans, body: dict[str, Any], name: str) -> Verdict:
    """Send one queue (Kowalski ``PUT``) or plan (SkyPortal ``POST``) and classify the answer.

    200: submitted.  Kowalski's 409 (a queue of that name exists) counts as
    submitted when ``GET`` lists the queue with the same content (a repeat
    after a crash), else rejected.  Other 4xx: rejected (the server's text
    kept).  5xx, a timeout, no connection: retry.  The daemon's submitter
    and ``mushrooms submit`` both use it.
    """
    try:
        answer = client.put(body) if isinstance(client, KowalskiQueue) else client.post(body)
    except Unreachable as exc:
        return Verdict("retry", None, str(exc))
    if answer.ok:
        remote = None
        if isinstance(answer.data, dict) and isinstance(answer.data.get("data"), dict):
            remote = answer.data["data"].get("id")
        return Verdict("submitted", answer, None, None if remote is None else str(remote))
    if answer.status == 409 and isinstance(client, KowalskiQueue):
        try:
            listed = [q for q in client.queues() if q.get("queue_name") == name]
        except (Unreachable, RuntimeError) as exc:
            return Verdict("retry", answer, f"409, and the queue list could not be read: {exc}")
        if listed and same_content(body, listed[0]):
            return Verdict("submitted", answer, "409: already queued with the same content (accepted)")
        return Verdict("rejected", answer, "409: a queue of that name exists with other content" if listed
                       else "409, but the queue list does not show it")
    if answer.refused:
        return Verdict("rejected", answer)
    return Verdict("retry", answer, answer.message())


class Submitter:
    """The submission lifecycle over the store (see the module docstring); :meth:`step` does one pass.

    Parameters
    ----------
    store : Store
        The daemon's state (plans and the ``submissions`` table).
    submit : SubmitConfig
        The ``[submit]`` section (target, gates, dry run, back-off).
    export : ExportConfig
        The ``[export]`` section (the queue's and SkyPortal's program fields).
    client : KowalskiQueue or SkyPortalPlans or None
        The target's HTTP client (None only with ``dry_run``).
    on_outbox : callable, optional
        Called after a ``submission`` status document was queued (the outbox drain's kick).
    on_result : callable, optional
        ``on_result(state, target)`` after every transition (metrics: counts by result).
    """

    #: ``on_trouble(submission, error)`` after a first attempt fails (the service's [notify] hook); None: nothing
    on_trouble: Callable[[Submission, str], None] | None = None

    def __init__(self, store: Store, submit: SubmitConfig, export: ExportConfig,
                 client: KowalskiQueue | SkyPortalPlans | None,
                 on_outbox: Callable[[], None] | None = None,
                 on_result: Callable[[str, str], None] | None = None) -> None:
        self.store = store
        self.submit = submit
        self.export = export
        self.client = client
        self._on_outbox = on_outbox
        self._on_result = on_result
        self.results: dict[str, int] = {s: 0 for s in STATES}

    @property
    def target(self) -> str:
        return self.submit.target

    # ------------------------------------------------------------ one pass
    def step(self) -> int:
        """Adopt new plans, then bring every open event's queues to the wanted state.

        Returns
        -------
        int
            Submissions left waiting for a retry (a 5xx, a timeout, an
            unreachable server): the caller backs off before the next pass.
        """
        self.adopt()
        if self.submit.dry_run:
            return 0  # a dry run sends nothing, not even the DELETEs of queues an earlier run submitted
        waiting = 0
        for sid in self._open_events():
            try:
                waiting += self._settle(sid)
            except Exception:  # one event's bug must not stop the others' submissions
                log.exception("event=submission_error superevent_id=%s", sid)
                waiting += 1
        return waiting

    def adopt(self) -> list[Submission]:
        """Give every stored plan without a submission row one: ``pending`` or ``skipped`` (returns the new rows)."""
        created: list[Submission] = []
        failed: list[tuple[Submission, str]] = []
        with self.store.transaction() as c:
            rows = c.execute("SELECT p.plan_id, COALESCE(p.superevent_id, p.plan_id) AS sid, p.withdrawn,"
                             " p.document FROM plans p LEFT JOIN submissions s USING(plan_id)"
                             " WHERE s.plan_id IS NULL ORDER BY p.seq").fetchall()
            for r in rows:
                plan_id, sid, doc = r["plan_id"], r["sid"], json.loads(r["document"])
                latest = c.execute("SELECT plan_id FROM plans WHERE COALESCE(superevent_id, plan_id)=? AND"
                                   " withdrawn=0 ORDER BY seq DESC LIMIT 1", (sid,)).fetchone()
                if r["withdrawn"]:
                    reason: str | None = "withdrawn before it was submitted"
                elif latest is None or latest[0] != plan_id:
                    reason = "superseded before it was submitted"
                else:
                    try:
                        reason = gate(doc, self.submit)
                    except (KeyError, TypeError, ValueError) as exc:
                        reason = f"unreadable plan document: {type(exc).__name__}: {exc}"
                name = body = None
                state = "skipped"
                if reason is None:
                    revision = c.execute("SELECT COALESCE(MAX(revision), 0) + 1 FROM submissions WHERE"
                                         " superevent_id=?", (sid,)).fetchone()[0]
                    name = queue_name(self.export.subprogram_name, sid, revision)
                    try:
                        body = build_body(doc, self.submit, self.export, name)
                    except (KeyError, TypeError, ValueError) as exc:
                        reason, state = f"no request could be built: {exc}", "failed"
                    else:
                        if self.submit.dry_run:
                            reason = "dry run"
                            log.info("event=submission_dry_run superevent_id=%s plan_id=%s queue_name=%s request=%s",
                                     sid, plan_id, name, json.dumps(self._request(body).describe()))
                        else:
                            state = "pending"
                else:
                    revision = None
                c.execute("INSERT INTO submissions(plan_id, superevent_id, target, revision, queue_name, state,"
                          " reason, body, created_at, finished_at) VALUES (?,?,?,?,?,?,?,?,?,?)",
                          (plan_id, sid, self.target, revision if state != "skipped" else None,
                           name if state != "skipped" else None, state, reason,
                           json.dumps(body) if body is not None and state == "pending" else None,
                           _now_iso(), None if state == "pending" else _now_iso()))
                sub = _row(c.execute("SELECT * FROM submissions WHERE plan_id=?", (plan_id,)).fetchone())
                created.append(sub)
                if state == "failed":
                    failed.append((sub, reason or ""))
                    self._queue_document(c, sub)
        for sub in created:
            if sub.state == "pending":
                log.info("event=submission_pending superevent_id=%s plan_id=%s queue_name=%s target=%s",
                         sub.superevent_id, sub.plan_id, sub.queue_name, sub.target)
            elif sub.state == "skipped":
                log.info("event=submission_skipped superevent_id=%s plan_id=%s reason=%r", sub.superevent_id,
                         sub.plan_id, sub.reason)
            self._count(sub.state)
        for sub, why in failed:
            log.error("event=submission_failed superevent_id=%s plan_id=%s target=%s reason=%r",
                      sub.superevent_id, sub.plan_id, sub.target, why)
        if failed and self._on_outbox is not None:
            self._on_outbox()
        return created

    def _open_events(self) -> list[str]:
        rows = self.store.connection().execute(
            "SELECT superevent_id, MIN(created_at) FROM submissions WHERE state IN ('pending','submitted')"
            " GROUP BY superevent_id ORDER BY 2").fetchall()
        return [r[0] for r in rows]

    def _settle(self, sid: str) -> int:
        conn = self.store.connection()
        rows = [_row(r) for r in conn.execute(
            "SELECT * FROM submissions WHERE superevent_id=? AND state IN ('pending','submitted')"
            " ORDER BY revision", (sid,))]
        latest = conn.execute("SELECT plan_id FROM plans WHERE COALESCE(superevent_id, plan_id)=? AND withdrawn=0"
                              " ORDER BY seq DESC LIMIT 1", (sid,)).fetchone()
        latest_id = latest[0] if latest else None
        wanted = next((r for r in rows if r.plan_id == latest_id), None)
        if wanted is not None and wanted.state == "pending":
            wanted = self._submit(wanted)
            if wanted is None:
                return 1  # not accepted yet: the older queue stays
        retracted = latest_id is None
        may_remove = retracted or (wanted is not None and wanted.state == "submitted")
        waiting = 0
        for r in rows:
            if wanted is not None and r.plan_id == wanted.plan_id:
                continue
            if r.state == "pending" and r.attempts == 0:
                self._finish(r, "skipped", reason="withdrawn before it was sent" if retracted
                             else "superseded before it was sent")
                continue
            if not may_remove:
                continue  # kept until the newer queue is accepted
            if not self._remove(r, "deleted" if retracted else "replaced"):
                waiting += 1
        return waiting

    # ------------------------------------------------------------ submit
    def _request(self, body: dict[str, Any]) -> Any:
        if isinstance(self.client, SkyPortalPlans) or (self.client is None and self.target == "skyportal"):
            return (self.client or SkyPortalPlans(self.submit.url, None)).post_request(body)
        return (self.client or KowalskiQueue(self.submit.url, None)).put_request(body)

    def _submit(self, sub: Submission) -> Submission | None:
        """PUT/POST the wanted queue; the row afterwards, or None when it waits for a retry."""
        assert sub.body is not None and self.client is not None
        plan_end = self._plan_end(sub.plan_id)
        if plan_end is not None and plan_end <= time.time():
            return self._finish(sub, "failed", reason=f"validity window ended before the queue was accepted "
                                f"({sub.attempts} attempt(s); last: {sub.answer or '-'})")
        if isinstance(self.client, SkyPortalPlans) and sub.attempts > 0:
            try:  # an import interrupted by a crash may have happened: look before posting again
                if self.client.exists(sub.body["plan_name"]):
                    return self._finish(sub, "submitted", reason="found by plan name after an interrupted POST "
                                        "(request id unknown)")
            except (Unreachable, RuntimeError) as exc:
                return self._retry(sub, None, str(exc))
        sub = self._mark_attempt(sub)
        verdict = send_queue(self.client, sub.body, str(sub.queue_name))
        if verdict.state == "retry":
            return self._retry(sub, verdict.answer.status if verdict.answer else None, verdict.reason or "")
        return self._finish(sub, verdict.state, verdict.answer, reason=verdict.reason, remote_id=verdict.remote_id)

    def _remove(self, sub: Submission, end_state: str) -> bool:
        """DELETE an older (or retracted) queue; True when settled (removed, gone, or failed for good)."""
        assert self.client is not None
        if isinstance(self.client, SkyPortalPlans):
            if not sub.remote_id:
                self._finish(sub, "failed", reason="SkyPortal request id unknown (interrupted POST): remove "
                             f"plan {sub.queue_name} by hand")
                return True
            try:
                answer = self.client.delete(sub.remote_id)
            except Unreachable as exc:
                self._retry(sub, None, str(exc))
                return False
            if answer.ok:
                self._finish(sub, end_state, answer)
            elif answer.refused:
                self._finish(sub, "failed", answer, reason=f"DELETE refused: {answer.message()}")
            else:
                self._retry(sub, answer.status, answer.message())
                return False
            return True
        user = self.export.user
        try:
            answer = self.client.delete(str(sub.queue_name), user)
        except Unreachable as exc:
            self._retry(sub, None, str(exc))
            return False
        if answer.ok:
            self._finish(sub, end_state, answer)
            return True
        if not answer.refused:
            self._retry(sub, answer.status, answer.message())
            return False
        try:
            names = {q.get("queue_name") for q in self.client.queues()}
        except (Unreachable, RuntimeError) as exc:
            self._retry(sub, answer.status, f"DELETE refused and the queue list could not be read: {exc}")
            return False
        if sub.queue_name not in names:
            self._finish(sub, end_state, answer, reason="not on the server (already removed)")
        else:
            self._finish(sub, "failed", answer, reason=f"DELETE refused: {answer.message()}")
        return True

    # ------------------------------------------------------------ rows
    def _plan_end(self, plan_id: str) -> float | None:
        row = self.store.connection().execute("SELECT document FROM plans WHERE plan_id=?", (plan_id,)).fetchone()
        if row is None:
            return None
        try:
            return _unix(json.loads(row[0])["end"])
        except (KeyError, ValueError):
            return None

    def _mark_attempt(self, sub: Submission) -> Submission:
        """Count the attempt durably *before* the HTTP call (a crash after it is then known to the restart)."""
        with self.store.transaction() as c:
            c.execute("UPDATE submissions SET attempts=attempts+1, attempted_at=? WHERE plan_id=?",
                      (_now_iso(), sub.plan_id))
            return _row(c.execute("SELECT * FROM submissions WHERE plan_id=?", (sub.plan_id,)).fetchone())

    def _retry(self, sub: Submission, status: int | None, error: str) -> None:
        with self.store.transaction() as c:
            c.execute("UPDATE submissions SET http_status=?, answer=? WHERE plan_id=?",
                      (status, error[:2000], sub.plan_id))
        log.warning("event=submission_retry superevent_id=%s plan_id=%s queue_name=%s state=%s attempts=%d "
                    "http_status=%s error=%r", sub.superevent_id, sub.plan_id, sub.queue_name, sub.state,
                    sub.attempts, status if status is not None else "-", error)
        if self.on_trouble is not None and sub.attempts <= 1:  # [notify]: the first failure, said once
            self.on_trouble(sub, error)
        return None

    def _finish(self, sub: Submission, state: str, answer: Answer | None = None, reason: str | None = None,
                remote_id: str | None = None) -> Submission | None:
        """Move a row from its state to ``state`` (and queue its status document), atomically."""
        now = _now_iso()
        terminal = state not in OPEN
        with self.store.transaction() as c:
            cur = c.execute(
                "UPDATE submissions SET state=?, reason=?, http_status=COALESCE(?, http_status),"
                " answer=COALESCE(?, answer), remote_id=COALESCE(?, remote_id),"
                " submitted_at=CASE WHEN ?='submitted' THEN ? ELSE submitted_at END,"
                " finished_at=CASE WHEN ? THEN ? ELSE finished_at END WHERE plan_id=? AND state=?",
                (state, reason if reason is not None else (answer.message()[:500] if answer and not answer.ok
                                                           else None),
                 answer.status if answer else None, answer.text if answer else None, remote_id, state, now,
                 int(terminal), now, sub.plan_id, sub.state))
            if not cur.rowcount:
                return None  # another pass moved it meanwhile
            new = _row(c.execute("SELECT * FROM submissions WHERE plan_id=?", (sub.plan_id,)).fetchone())
            if state in _PUBLISHED:
                self._queue_document(c, new)
        fields = (f"superevent_id={new.superevent_id} plan_id={new.plan_id} queue_name={new.queue_name} "
                  f"target={new.target} state={state} http_status={new.http_status if answer else '-'} "
                  f"attempts={new.attempts}")
        if state in ("rejected", "failed"):
            log.error("event=submission_%s %s reason=%r", state, fields, new.reason)
        else:
            log.info("event=submission_%s %s%s", state, fields, f" reason={new.reason!r}" if new.reason else "")
        self._count(state)
        if state in _PUBLISHED and self._on_outbox is not None:
            self._on_outbox()
        return new

    def _queue_document(self, c: Any, sub: Submission) -> None:
        doc = status_document(sub)
        Store._insert_outbox(c, doc["submission_id"], "submission", doc)

    def _count(self, state: str) -> None:
        self.results[state] = self.results.get(state, 0) + 1
        if self._on_result is not None:
            try:
                self._on_result(state, self.target)
            except Exception:
                log.exception("event=submission_callback_failed")


def status_document(sub: Submission) -> dict[str, Any]:
    """The ``submission`` status document of a row (published beside the plan; docs/design/plan-format.md)."""
    answer = sub.answer
    if answer is not None:
        try:
            parsed = json.loads(answer)
            if isinstance(parsed, dict) and isinstance(parsed.get("message"), str):
                answer = parsed["message"]
        except ValueError:
            pass
    return {
        "type": "submission",
        "submission_id": f"{sub.plan_id}-submission-{sub.state}",
        "plan_id": sub.plan_id,
        "superevent_id": sub.superevent_id,
        "target": sub.target,
        "queue_name": sub.queue_name,
        "state": sub.state,
        "http_status": sub.http_status,
        "answer": None if answer is None else answer[:2000],
        "reason": sub.reason,
        "attempts": int(sub.attempts),
        "created": now_iso_z(),
    }


def open_submitter(submit: SubmitConfig, export: ExportConfig, store: Store, token: str | None,
                   on_outbox: Callable[[], None] | None = None, on_result: Callable[[str, str], None] | None = None,
                   closing: Callable[[], bool] | None = None) -> tuple[Submitter, Any] | None:
    """The daemon's submitter and the thread that runs it (an :class:`~.jobs.OutboxDrain` named ``submit``).

    Returns None when ``[submit] target = "none"``.  ``kick()`` the drain
    after a plan is stored or a withdrawal recorded; it retries with the
    ``[submit]`` back-off while submissions wait (5xx, timeouts).
    ``closing()`` True makes passes do nothing (the store is being closed).
    """
    from .jobs import OutboxDrain
    from .remote import make_client

    sub = submit
    if not sub.enabled:
        return None
    client = make_client(sub.target, sub.url, token, sub.timeout_s)
    submitter = Submitter(store, sub, export, client, on_outbox=on_outbox, on_result=on_result)

    def one_pass() -> int:
        if closing is not None and closing():
            return 0
        return submitter.step()

    drain = OutboxDrain(one_pass, sub.retry_initial_s, sub.retry_max_s, name="submit")
    log.info("event=submit_enabled target=%s url=%s dry_run=%s alert_types=%s min_coverage=%g max_exposures=%d",
             sub.target, sub.url, str(sub.dry_run).lower(), ",".join(sub.alert_types), sub.min_coverage,
             sub.max_exposures)
    return submitter, drain
