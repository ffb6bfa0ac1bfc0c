"""The ``submissions`` table's rows as values, and the ``submission`` status document of a row.

One row per plan id (:mod:`~mushrooms.daemon.submission.submitter` owns the lifecycle; the states are
in its docstring).  ``progress`` records which queues of a revision's queue
set were sent (``tried``), accepted (``put``) or removed (``gone``), and a
refusal of one of them (``rejected``, the name ``refused``), so that a pass
interrupted between two queues goes on where it stopped.  A queue sent and
neither accepted nor refused may be live (:meth:`Submission.maybe_live`: its
answer was lost to the deadline, a cut or a kill); one that was not listed
when its revision was settled is watched for (``watch``) until its window ends.
"""

from __future__ import annotations

import enum
import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ...handlers.instants import now_iso_z
from .names import row_queues
from .rules import name_of, set_of

if TYPE_CHECKING:
    from ..state.store import Store

__all__ = ["Submission", "SubmissionState", "submissions", "submission_from_row", "status_document", "STATES",
           "OPEN", "PUBLISHED"]


class SubmissionState(enum.StrEnum):
    """A submission's ``state`` in the ``submissions`` table (the stored text is the value).

    ``pending`` -> ``submitted`` -> ``replaced`` | ``deleted``, or
    ``rejected`` | ``failed`` | ``skipped`` (the lifecycle:
    :mod:`~mushrooms.daemon.submission.submitter`).
    """

    PENDING = "pending"
    SUBMITTED = "submitted"
    REPLACED = "replaced"  # a newer revision of the event was accepted
    DELETED = "deleted"  # the event was retracted
    REJECTED = "rejected"  # the server refused it (never retried)
    FAILED = "failed"  # the operator must look
    SKIPPED = "skipped"  # gates, dry run, or superseded/withdrawn before it was sent


STATES = tuple(SubmissionState)
#: States whose queue may be on the server (the submitter still has work with them).
OPEN = (SubmissionState.PENDING, SubmissionState.SUBMITTED)
#: Transitions that are published as a ``submission`` status document.
PUBLISHED = (SubmissionState.SUBMITTED, SubmissionState.REPLACED, SubmissionState.DELETED, SubmissionState.REJECTED,
             SubmissionState.FAILED)


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
    body: Any
    remote_id: str | None
    http_status: int | None
    answer: str | None
    attempts: int
    created_at: str
    attempted_at: str | None
    submitted_at: str | None
    finished_at: str | None
    #: ``{"tried": [names sent at least once], "put": [names accepted], "gone": [names removed],
    #: "rejected": reason, "refused": [the name refused], "watch": [names sent without an answer, not
    #: listed when the revision was settled], "expired": [watched names whose window ended unseen],
    #: "told": [the troubles already notified: "submitted", "removed"]}``; SkyPortal also
    #: ``"ids": {plan name: request id}``
    progress: dict[str, Any] = field(default_factory=dict)

    def queue_names(self) -> list[str]:
        """The names of the requests of this revision (Kowalski: its queues; SkyPortal: its plans)."""
        names = [name_of(q) for q in set_of(self.body)] if isinstance(self.body, list) else []
        if not names and isinstance(self.body, dict) and ("targets" in self.body or "plan_name" in self.body):
            names = [name_of(self.body)]  # a row written before sets: one queue, or one SkyPortal plan
        return names or ([self.queue_name] if self.queue_name else [])

    def request_ids(self) -> str | None:
        """SkyPortal's request ids of the plans of this revision, comma-separated in order (None: none known)."""
        ids = self.progress.get("ids", {})
        return ",".join(str(ids[n]) for n in self.queue_names() if n in ids) or None

    def maybe_sent(self) -> set[str]:
        """Names that may be on the server: accepted, or sent at least once.

        A row written before ``tried`` was kept for Kowalski, once attempted:
        its accepted queues and the first one not accepted (a set is PUT in
        order and a pass stops at the first queue not accepted); for
        SkyPortal, all of them.
        """
        tried, put = self.progress.get("tried"), set(self.progress.get("put", ()))
        if tried is not None or not self.attempts:
            return put | set(tried or ())
        names = self.queue_names()
        if self.target == "kowalski":
            return put | set(next(([n] for n in names if n not in put), []))
        return put | set(names)

    def maybe_live(self) -> set[str]:
        """Names sent whose fate is unknown: neither accepted, nor refused, nor removed (they may still land)."""
        known = set(self.progress.get("put", ())) | set(self.progress.get("gone", ())) | \
            set(self.progress.get("refused", ()))
        return self.maybe_sent() - known

    def to_settle(self) -> list[str]:
        """The names a settlement of this revision must remove, in set order: accepted or maybe live, not gone.

        Never a name that was not sent (nothing to DELETE) nor one refused outright (Y3).
        """
        wanted = set(self.progress.get("put", ())) | self.maybe_live()
        gone = set(self.progress.get("gone", ()))
        return [n for n in self.queue_names() if n in wanted and n not in gone]


def submission_from_row(r: Any) -> Submission:
    """A ``submissions`` row (:class:`sqlite3.Row`) as a :class:`Submission` (its JSON columns parsed)."""
    progress = r["progress"] if "progress" in r.keys() else None
    return Submission(r["plan_id"], r["superevent_id"], r["target"], r["revision"], r["queue_name"], r["state"],
                      r["reason"], json.loads(r["body"]) if r["body"] else None, r["remote_id"], r["http_status"],
                      r["answer"], r["attempts"], r["created_at"], r["attempted_at"], r["submitted_at"],
                      r["finished_at"], json.loads(progress) if progress else {})


def submissions(store: Store, superevent_id: str | None = None) -> list[Submission]:
    """Every submission (of one event), oldest first: for operators and tests."""
    q, args = "SELECT * FROM submissions", ()
    if superevent_id is not None:
        q, args = q + " WHERE superevent_id=?", (superevent_id,)
    return [submission_from_row(r) for r in store.connection().execute(q + " ORDER BY created_at, rowid", args)]


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
        "queue_names": list(row_queues(sub.target, sub.state, sub.body, sub.queue_name)[0]),
        "state": sub.state,
        "http_status": sub.http_status,
        "answer": None if answer is None else answer[:2000],
        "reason": sub.reason,
        "attempts": int(sub.attempts),
        "created": now_iso_z(),
    }
