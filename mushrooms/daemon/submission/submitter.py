"""Plans into ZTF's ToO queue, idempotently across crashes (``[submit]``).

One row per plan id in the store's ``submissions`` table::

    pending ─► submitted ─► replaced   (a newer revision of the event was accepted)
       │           └──────► deleted    (the event was retracted)
       ├─► rejected  (the server refused it: 4xx, or 409 on a queue not ours; never retried)
       ├─► failed    (no queue could be built, the validity window ended before it was
       │              accepted, or a DELETE was refused: the operator must look)
       └─► skipped   (gates, dry run, or superseded/withdrawn before it was sent)

How it works: the store is the wanted state, the server is made to match.
For every event, the wanted queue set is its latest plan (when it passes
the gates): to Kowalski a revision is the ordered list of queues of
:func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queues`.
:meth:`Submitter.step` (run by its own thread, kicked after a plan is
stored or a withdrawal recorded) first ``PUT``\\s every queue of the wanted
set and only once all were accepted ``DELETE``\\s the queues of the event's
older sets that may be live (accepted, or sent without an answer: never one
that was not sent), so the telescope is never left with nothing; a
retraction does so for every revision.  The row's ``progress`` records each
queue sent, accepted or removed (an interrupted pass goes on where it
stopped).  A queue sent without an answer (the deadline, a cut, a 5xx) may
still be applied by Kowalski later: when its revision is settled and the
list does not show it, it is watched for until its window ends and deleted
when it appears; the row says ``replaced``/``deleted`` only after that
(:mod:`~mushrooms.daemon.submission.removal`).

Crash safety: a queue's name and body are stored before anything is sent,
and the attempt (with the name, ``progress.tried``) is committed *before*
the HTTP call.  After a kill -9 between the call and the commit the restart
sends the same name and body again: Kowalski answers 409, and the queue is
ours when the list (``GET``) shows it with our window and a sub-multiset of
our targets (the telescope may have observed some meanwhile), or, the name
having been sent by this revision, when the list no longer shows it: that
counts as accepted; a DELETE repeated after a crash finds the queue gone
(400, not in the list), which counts as done.  So no queue is sent twice
nor left orphaned.  To SkyPortal a revision is the ordered list
of observation plans of :func:`~mushrooms.scheduler_core.plan.exports.to_skyportal_plans`
(one per filter pass), POSTed in order and DELETEd by request id; its import
is not keyed by name, so each plan is marked ``tried`` before its POST and a
tried plan is looked up by name (``plan_names?name=``) before it is sent again.

Queue names: ``<base>_<k>``, ``k`` the queue of the set, the base
:func:`~mushrooms.scheduler_core.plan.exports.queue_name_base` of the plan (the row's
``queue_name``, stored with the row: stable across restarts); ``revision``
counts the event's submitted revisions from 1.  A request has a wall-clock deadline (``[submit]
timeout_s``), so one stuck event costs the others at most that per pass.
A submitted set whose window ended is closed (``finished_at``).  Planning
workers only kick this thread.  Pure rules: :mod:`~mushrooms.daemon.submission.rules`.
"""

from __future__ import annotations

import json
import logging
import time
from typing import TYPE_CHECKING, Any, Callable

from ..state import current_event
from ..state.records import now_iso as _now_iso
from ..state.store import Store
from .removal import DONE, RETRY, WATCH, Removal
from .remote import Answer, KowalskiQueue, SkyPortalPlans, Unreachable
from .rows import OPEN, PUBLISHED, STATES, Submission, status_document, submission_from_row, submissions
from .rows import SubmissionState as State
from .names import few_names
from .rules import Verdict, build_body, gate, name_of, queue_name_base, same_content, send_queue, set_of
from .rules import unix as _unix

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from .settings import SubmitConfig

__all__ = ["Submission", "Submitter", "Verdict", "send_queue", "queue_name_base", "gate", "build_body", "same_content",
           "status_document", "submissions", "STATES", "OPEN"]

log = logging.getLogger("mushrooms.daemon.submit")
FOUND_BY_NAME = "found by plan name after an interrupted POST (request id unknown)"


class Submitter(Removal):
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

    #: ``on_trouble(submission, error, action)`` the first time a row's submission (``action`` ``submitted``) or
    #: its removal (``removed``) fails: once per row and action, kept in its ``progress`` (the service's [notify]
    #: hook); None: nothing
    on_trouble: Callable[[Submission, str, str], None] | None = None

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
        #: Rows of the last pass watching for a queue sent without an answer (not a failure: no back-off,
        #: but the list must be read again; the submitter's thread passes again later)
        self.watching = 0

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
        self.watching = 0
        if self.submit.dry_run:
            return 0  # a dry run sends nothing, not even the DELETEs of queues an earlier run submitted
        waiting = 0
        for sid in self.open_events():
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
                latest = current_event.latest_plan_id(c, sid)
                if r["withdrawn"]:
                    reason: str | None = "withdrawn before it was submitted"
                elif latest != plan_id:
                    reason = "superseded before it was submitted"
                else:
                    try:
                        reason = gate(doc, self.submit)
                    except (KeyError, TypeError, ValueError) as exc:
                        reason = f"unreadable plan document: {type(exc).__name__}: {exc}"
                name = body = None
                state = State.SKIPPED
                if reason is None:
                    revision = c.execute("SELECT COALESCE(MAX(revision), 0) + 1 FROM submissions WHERE"
                                         " superevent_id=?", (sid,)).fetchone()[0]
                    name = queue_name_base(self.export.subprogram_name, plan_id, (doc.get("event") or {}).get("superevent_id"))
                    try:
                        body = build_body(doc, self.submit, self.export, name)
                    except (KeyError, TypeError, ValueError) as exc:
                        reason, state = f"no request could be built: {exc}", State.FAILED
                    else:
                        if self.submit.dry_run:
                            reason = "dry run"
                            for one in set_of(body) if isinstance(body, list) else [body]:
                                log.info("event=submission_dry_run superevent_id=%s plan_id=%s queue_name=%s "
                                         "request=%s", sid, plan_id, name_of(one),
                                         json.dumps(self._request(one).describe()))
                        else:
                            state = State.PENDING
                else:
                    revision = None
                c.execute("INSERT INTO submissions(plan_id, superevent_id, target, revision, queue_name, state,"
                          " reason, body, created_at, finished_at) VALUES (?,?,?,?,?,?,?,?,?,?)",
                          (plan_id, sid, self.target, revision if state != State.SKIPPED else None,
                           name if state != State.SKIPPED else None, state, reason,
                           json.dumps(body) if body is not None and state == State.PENDING else None,
                           _now_iso(), None if state == State.PENDING else _now_iso()))
                sub = _row(c, plan_id)
                created.append(sub)
                if state == State.FAILED:
                    failed.append((sub, reason or ""))
                    self._queue_document(c, sub)
        for sub in created:
            if sub.state == State.PENDING:
                log.info("event=submission_pending superevent_id=%s plan_id=%s queue_name=%s %s target=%s",
                         sub.superevent_id, sub.plan_id, sub.queue_name, _queues_field(sub), sub.target)
            elif sub.state == State.SKIPPED:
                log.info("event=submission_skipped superevent_id=%s plan_id=%s reason=%r", sub.superevent_id,
                         sub.plan_id, sub.reason)
            self._count(sub.state)
        for sub, why in failed:
            log.error("event=submission_failed superevent_id=%s plan_id=%s target=%s reason=%r",
                      sub.superevent_id, sub.plan_id, sub.target, why)
        if failed and self._on_outbox is not None:
            self._on_outbox()
        return created

    def open_events(self) -> list[str]:
        """Events with rows still to bring to their wanted state (pending, or submitted and not closed)."""
        rows = self.store.connection().execute(
            "SELECT superevent_id, MIN(created_at) FROM submissions WHERE state='pending' OR"
            " (state='submitted' AND finished_at IS NULL) GROUP BY superevent_id ORDER BY 2").fetchall()
        return [r[0] for r in rows]

    def _latest(self, sid: str) -> str | None:
        return current_event.latest_plan_id(self.store.connection(), sid)

    def _settle(self, sid: str, again: bool = True) -> int:
        """Bring one event's queues to its wanted state; the number of rows left waiting for a retry."""
        conn = self.store.connection()
        rows = [submission_from_row(r) for r in conn.execute(
            "SELECT * FROM submissions WHERE superevent_id=? AND (state='pending' OR (state='submitted' AND"
            " finished_at IS NULL)) ORDER BY revision", (sid,))]
        rows = [r for r in rows if not self._close_if_expired(r)]
        latest_id = self._latest(sid)
        wanted = next((r for r in rows if r.plan_id == latest_id), None)
        if wanted is not None and wanted.state == State.PENDING:
            accepted = self._submit(wanted)
            if accepted is None:  # not accepted yet: the older queues stay (those being watched are looked for)
                return 1 + self._settle_rows([r for r in rows if r.progress.get("watch")], wanted, False, True)
            wanted = accepted
            if again and self._latest(sid) != latest_id:  # retracted or replaced while the PUT was in flight
                return self._settle(sid, again=False)
        retracted = latest_id is None
        newest = None
        if wanted is None and latest_id is not None:
            found = conn.execute("SELECT * FROM submissions WHERE plan_id=?", (latest_id,)).fetchone()
            newest = submission_from_row(found) if found is not None else None
        given_up = newest is not None and newest.state not in OPEN  # the newest plan is not submitted
        may_remove = retracted or (wanted is not None and wanted.state == State.SUBMITTED)
        why = f"by a plan not submitted ({newest.reason})" if given_up and newest is not None else None
        return self._settle_rows(rows, wanted, retracted, may_remove, why)

    def _settle_rows(self, rows: list[Submission], wanted: Submission | None, retracted: bool, may_remove: bool,
                     given_up: str | None = None) -> int:
        """Settle an event's rows other than ``wanted``; the number left waiting for a retry.

        ``given_up``: why the newest plan is not submitted (its older pending rows are then skipped).
        """
        waiting = 0
        for r in rows:
            if wanted is not None and r.plan_id == wanted.plan_id:
                continue
            if r.state == State.PENDING and r.attempts == 0:
                self._finish(r, State.SKIPPED, reason="withdrawn before it was sent" if retracted
                             else "superseded before it was sent")
                continue
            if r.state == State.PENDING and given_up and not retracted:
                outcome = self._remove(r, State.SKIPPED, f"superseded after {r.attempts} attempt(s) {given_up}")
            elif may_remove:
                outcome = self._remove(r, State.DELETED if retracted else State.REPLACED)
            else:
                continue  # kept until the newer queues are accepted
            waiting += outcome == RETRY
            self.watching += outcome == WATCH
        return waiting

    def _close_if_expired(self, sub: Submission) -> bool:
        """A submitted set whose validity window ended is closed: nothing is left to do with it."""
        end = self._plan_end(sub.plan_id)
        if sub.state != State.SUBMITTED or end is None or end > time.time():
            return False
        with self.store.transaction() as c:
            c.execute("UPDATE submissions SET finished_at=? WHERE plan_id=? AND state='submitted'",
                      (_now_iso(), sub.plan_id))
        log.info("event=submission_expired superevent_id=%s plan_id=%s queue_name=%s", sub.superevent_id,
                 sub.plan_id, sub.queue_name)
        return True

    # ------------------------------------------------------------ submit
    def _request(self, body: dict[str, Any]) -> Any:
        if isinstance(self.client, SkyPortalPlans) or (self.client is None and self.target == "skyportal"):
            return (self.client or SkyPortalPlans(self.submit.url, None)).post_request(body)
        return (self.client or KowalskiQueue(self.submit.url, None)).put_request(body)

    def _submit(self, sub: Submission) -> Submission | None:
        """PUT every queue (or POST every SkyPortal plan, (T2)) of the set not yet accepted; the row, or None."""
        assert sub.body is not None and self.client is not None
        plan_end = self._plan_end(sub.plan_id)
        if plan_end is not None and plan_end <= time.time():
            if sub.to_settle() and self._remove_all(sub, State.FAILED, "validity window ended") != DONE:
                return None
            return self._finish(sub, State.FAILED, reason=f"validity window ended before the queue was accepted "
                                f"({sub.attempts} attempt(s); last: {sub.answer or '-'})")
        if sub.progress.get("rejected"):  # a request of the set was refused: take the accepted ones back first
            return self._finish_rejection(sub)
        last: Verdict | None = None
        found, sky = None, isinstance(self.client, SkyPortalPlans)
        for part in set_of(sub.body):
            name = name_of(part)
            if name in sub.progress.get("put", ()):
                continue
            posted = self._posted_before(sub, name) if sky else False
            if posted is None:
                return None
            if posted:  # SkyPortal's import is not keyed by name: found by it after an interrupted POST
                sub, found = self._note(sub, "put", name), FOUND_BY_NAME
                continue
            sent_before = name in sub.maybe_sent()  # a 409 on it may be our own queue (a lost answer)
            sub = self._mark_attempt(sub, tried=name)
            last = send_queue(self.client, part, name, sent_before=sent_before)
            if last.state == "retry":
                return self._retry(sub, last.answer.status if last.answer else None, last.reason or "")
            if last.state == "rejected":
                reason = f"{name}: {last.reason or (last.answer.message() if last.answer else '-')}"
                sub = self._note(sub, "refused", name)
                sub = self._note(sub, "rejected", reason, last.answer)
                return self._finish_rejection(sub)
            sub = self._note(sub, "put", name, remote_id=last.remote_id)
        return self._finish(sub, State.SUBMITTED, last.answer if last else None,
                            reason=(last.reason if last else None) or found, remote_id=sub.request_ids())

    def _posted_before(self, sub: Submission, name: str) -> bool | None:
        """SkyPortal: whether plan ``name``, POSTed before a crash, was imported (T3) (None: unknown yet, retry)."""
        assert isinstance(self.client, SkyPortalPlans)
        if name not in sub.maybe_sent():
            return False
        try:
            return self.client.exists(name)
        except (Unreachable, RuntimeError) as exc:
            return self._retry(sub, None, str(exc))

    def _finish_rejection(self, sub: Submission) -> Submission | None:
        """A set with a refused queue: remove its accepted queues, then the row is ``rejected``."""
        if sub.to_settle() and self._remove_all(sub, State.REJECTED, "a queue of the set was refused") != DONE:
            return None
        return self._finish(sub, State.REJECTED, reason=str(sub.progress["rejected"]))

    def _note(self, sub: Submission, key: str, value: str, answer: Answer | None = None,
              absent: bool = False, remote_id: str | None = None, reason: str | None = None) -> Submission:
        """Record durably what became of queue ``value``: ``put`` (with its SkyPortal id), ``gone``, ``refused``,
        ``watch``, ``expired`` (or the set's ``rejected`` reason); ``reason`` replaces the row's."""
        progress = dict(sub.progress)
        if remote_id is not None:
            progress["ids"] = {**progress.get("ids", {}), value: remote_id}
        if key == "rejected":
            progress["rejected"] = value
        else:
            progress[key] = sorted(set(progress.get(key, [])) | {value})
        if absent:
            progress["absent"] = True
        with self.store.transaction() as c:
            c.execute("UPDATE submissions SET progress=?, http_status=COALESCE(?, http_status),"
                      " answer=COALESCE(?, answer), reason=COALESCE(?, reason) WHERE plan_id=?",
                      (json.dumps(progress), answer.status if answer else None, answer.text if answer else None,
                       reason, sub.plan_id))
            return _row(c, sub.plan_id)

    # ------------------------------------------------------------ rows
    def _current(self, plan_id: str) -> Submission:
        return _row(self.store.connection(), plan_id)

    def _plan_end(self, plan_id: str) -> float | None:
        row = self.store.connection().execute("SELECT document FROM plans WHERE plan_id=?", (plan_id,)).fetchone()
        if row is None:
            return None
        try:
            return _unix(json.loads(row[0])["end"])
        except (KeyError, ValueError):
            return None

    def _mark_attempt(self, sub: Submission, tried: str | None = None) -> Submission:
        """Count the attempt (and the queue or plan ``tried``) durably *before* the HTTP call (known to a restart)."""
        progress = dict(sub.progress)
        if tried is not None:
            progress["tried"] = sorted(set(progress.get("tried", [])) | {tried})
        with self.store.transaction() as c:
            c.execute("UPDATE submissions SET attempts=attempts+1, attempted_at=?, progress=? WHERE plan_id=?",
                      (_now_iso(), json.dumps(progress), sub.plan_id))
            return _row(c, sub.plan_id)

    def _retry(self, sub: Submission, status: int | None, error: str, action: str = "submitted") -> None:
        """Keep the answer; the row is retried after the back-off.  The first failure of each ``action``
        (``submitted``: a PUT/POST; ``removed``: a DELETE) of a row goes to :attr:`on_trouble`, once
        (``progress.told``, in the state file: not again at every pass, nor after a restart)."""
        with self.store.transaction() as c:
            progress = dict(_row(c, sub.plan_id).progress)
            first = action not in progress.get("told", ())
            if first:
                progress["told"] = sorted({*progress.get("told", ()), action})
            c.execute("UPDATE submissions SET http_status=?, answer=?, progress=? WHERE plan_id=?",
                      (status, error[:2000], json.dumps(progress), sub.plan_id))
        log.warning("event=submission_retry superevent_id=%s plan_id=%s queue_name=%s %s state=%s attempts=%d "
                    "http_status=%s error=%r", sub.superevent_id, sub.plan_id, sub.queue_name, _queues_field(sub),
                    sub.state, sub.attempts, status if status is not None else "-", error)
        if self.on_trouble is not None and first:  # [notify]: each trouble said once
            self.on_trouble(sub, error, action)
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
            new = _row(c, sub.plan_id)
            if state in PUBLISHED:
                self._queue_document(c, new)
        fields = (f"superevent_id={new.superevent_id} plan_id={new.plan_id} queue_name={new.queue_name} "
                  f"{_queues_field(new)} "
                  f"target={new.target} state={state} http_status={new.http_status if answer else '-'} "
                  f"attempts={new.attempts}")
        if state in (State.REJECTED, State.FAILED):
            log.error("event=submission_%s %s reason=%r", state, fields, new.reason)
        else:
            log.info("event=submission_%s %s%s", state, fields, f" reason={new.reason!r}" if new.reason else "")
        self._count(state)
        if state in PUBLISHED and self._on_outbox is not None:
            self._on_outbox()
        return new

    def _queue_document(self, c: Any, sub: Submission) -> None:
        doc = status_document(sub)
        Store.insert_outbox(c, doc["submission_id"], "submission", doc)

    def _count(self, state: str) -> None:
        self.results[state] = self.results.get(state, 0) + 1
        if self._on_result is not None:
            try:
                self._on_result(state, self.target)
            except Exception:
                log.exception("event=submission_callback_failed")


def _queues_field(sub: Submission) -> str:
    """A log line's ``queue_count=K queues='A, B, C +N more'``: the queues themselves (``queue_name`` is their base)."""
    names = sub.queue_names()
    return f"queue_count={len(names)} queues={few_names(names)!r}"


def _row(c: Any, plan_id: str) -> Submission:
    """The ``submissions`` row of ``plan_id`` (connection or transaction ``c``)."""
    return submission_from_row(c.execute("SELECT * FROM submissions WHERE plan_id=?", (plan_id,)).fetchone())
