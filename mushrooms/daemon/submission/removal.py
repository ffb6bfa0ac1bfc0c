"""Taking a revision's queues back: DELETE what may be live, and watch for what may still land.

A revision is settled (replaced by a newer one, withdrawn by a retraction,
or taken back after a refusal) by removing every queue of its set that was
accepted, and every queue it *sent* whose fate is unknown
(:meth:`~mushrooms.daemon.submission.rows.Submission.maybe_live`: a PUT whose
answer was lost to the deadline, a cut, a 5xx or a kill).  A queue that was
never sent is not asked for (issue 52, LOW).

Kowalski may apply a PUT after the client gave up on it (a slow mountain
link: ``kowalski/api/handlers/ztf.py`` forwards the PUT to the mountain and
answers only when the mountain does).  So a maybe-live queue that the DELETE
does not find (400) and the list (``GET``) does not show is *watched*: every
pass reads the list and DELETEs it when it appears, until its validity window
ends (after which ZTF neither switches to it nor keeps it).  Until then the row
keeps its open state: it never says ``replaced``/``deleted`` while one of its
queues can still appear (issue 52, finding 1).  What is watched is in the
row's ``progress`` (``watch``), so a restart goes on watching: (Y2) of ``docs/design/submission.md``.

:class:`Removal` is a part of :class:`~mushrooms.daemon.submission.submitter.Submitter`.
"""

from __future__ import annotations

import logging
import time
from datetime import datetime, timezone
from typing import TYPE_CHECKING

from .remote import Answer, SkyPortalPlans, Unreachable
from .rows import OPEN, Submission
from .rows import SubmissionState as State
from .rules import name_of, set_of, window_end

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from ..state.store import Store
    from .remote import KowalskiQueue

__all__ = ["Removal", "DONE", "RETRY", "WATCH"]

log = logging.getLogger("mushrooms.daemon.submit")

#: Outcomes of a removal: all gone (or failed for good); try again after a back-off; watching for a late queue.
DONE, RETRY, WATCH = "done", "retry", "watch"


def _iso(unix: float) -> str:
    return datetime.fromtimestamp(unix, timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


class Removal:
    """DELETEs of a revision's queues (Kowalski) or plans (SkyPortal), for the :class:`Submitter`."""

    store: Store
    export: ExportConfig
    client: KowalskiQueue | SkyPortalPlans | None

    # provided by the Submitter
    def _note(self, sub: Submission, key: str, value: str, answer: Answer | None = None, absent: bool = False,
              remote_id: str | None = None, reason: str | None = None) -> Submission:
        raise NotImplementedError

    def _retry(self, sub: Submission, status: int | None, error: str) -> None:
        raise NotImplementedError

    def _finish(self, sub: Submission, state: str, answer: Answer | None = None, reason: str | None = None,
                remote_id: str | None = None) -> Submission | None:
        raise NotImplementedError

    def _plan_end(self, plan_id: str) -> float | None:
        raise NotImplementedError

    def _current(self, plan_id: str) -> Submission:
        raise NotImplementedError

    # ------------------------------------------------------------ a revision
    def _remove(self, sub: Submission, end_state: str, reason: str | None = None) -> str:
        """Settle an older (or retracted) revision: :data:`DONE` once its queues are gone and the row is ``end_state``.

        :data:`WATCH` while a queue it sent without an answer may still land
        (the row stays open); :data:`RETRY` after a failed request.
        """
        assert self.client is not None
        outcome = self._remove_all(sub, end_state, reason)
        if outcome != DONE:
            return outcome
        current = self._current(sub.plan_id)
        if current.state in OPEN:
            self._finish(current, end_state, reason=reason or _settled_reason(current))
        return DONE

    def _remove_all(self, sub: Submission, end_state: str, reason: str | None) -> str:
        """Remove every queue of the set that may be live (:meth:`Submission.to_settle`); the outcome."""
        assert self.client is not None
        if isinstance(self.client, SkyPortalPlans):
            return self._remove_plans(sub)
        return self._remove_queues(sub)

    # ------------------------------------------------------------ Kowalski
    def _remove_queues(self, sub: Submission) -> str:
        """DELETE each accepted or maybe-live queue; a maybe-live one not listed is watched (module docstring)."""
        listed: set[str] | None = None
        watched = set(sub.progress.get("watch", ()))
        for name in sub.to_settle():
            if name in watched:
                continue  # looked for in the list below
            try:
                answer = self.client.delete(name, self.export.user)  # type: ignore[union-attr]
            except Unreachable as exc:
                self._retry(sub, None, str(exc))
                return RETRY
            if answer.ok and answer.problem is None:
                sub = self._note(sub, "gone", name, answer)
                continue
            if answer.ok:  # a 200 that is not Kowalski's JSON: not known to be removed
                self._retry(sub, answer.status, f"DELETE {name}: {answer.status}, but {answer.problem}")
                return RETRY
            if answer.redirected:
                self._finish(sub, State.FAILED, answer, reason=f"DELETE {name}: {answer.status}: {answer.problem}")
                return DONE
            if not answer.refused:
                self._retry(sub, answer.status, answer.message())
                return RETRY
            listed = self._listed(sub, f"DELETE {name} refused ({answer.status})")
            if listed is None:
                return RETRY
            accepted = name in sub.progress.get("put", ())
            if name in listed and accepted:
                self._finish(sub, State.FAILED, answer, reason=f"DELETE {name} refused: {answer.message()}")
                return DONE
            if name in listed:  # it landed between the DELETE and the list: DELETE it again
                self._retry(sub, answer.status, f"DELETE {name} refused, and it is listed now")
                return RETRY
            if accepted:
                sub = self._note(sub, "gone", name, answer, absent=True)
            else:
                sub = self._watch(sub, name, answer)
        return self._look_for_late(sub, listed)

    def _watch(self, sub: Submission, name: str, answer: Answer) -> Submission:
        until = self._queue_end(sub, name)
        log.warning("event=submission_watch superevent_id=%s plan_id=%s queue_name=%s until=%s reason=%r",
                    sub.superevent_id, sub.plan_id, name, _iso(until) if until is not None else "-",
                    "sent without an answer and not listed: it may still land; the list is read until its "
                    "window ends")
        return self._note(sub, "watch", name, answer, reason=f"watching for {name} (sent without an answer, "
                          f"may still land) until {_iso(until) if until is not None else 'its window ends'}")

    def _look_for_late(self, sub: Submission, listed: set[str] | None) -> str:
        """The watched queues: gone once their window ended unseen; DELETEd when the list shows them."""
        now = time.time()
        for name in [n for n in sub.to_settle() if n in sub.progress.get("watch", ())]:
            end = self._queue_end(sub, name)
            if end is None or end <= now:
                sub = self._note(sub, "expired", name)
                sub = self._note(sub, "gone", name)
        left = [n for n in sub.to_settle() if n in sub.progress.get("watch", ())]
        if not left:
            return DONE
        if listed is None:
            listed = self._listed(sub, "reading the list for a queue that may still land")
            if listed is None:
                return RETRY
        for name in [n for n in left if n in listed]:
            log.warning("event=submission_late_queue superevent_id=%s plan_id=%s queue_name=%s reason=%r",
                        sub.superevent_id, sub.plan_id, name, "a PUT without an answer landed late: deleting it")
            try:
                answer = self.client.delete(name, self.export.user)  # type: ignore[union-attr]
            except Unreachable as exc:
                self._retry(sub, None, str(exc))
                return RETRY
            if not (answer.ok and answer.problem is None):
                self._retry(sub, answer.status, f"DELETE {name} (landed late): {answer.message()}")
                return RETRY
            sub = self._note(sub, "gone", name, answer)
        return WATCH if sub.to_settle() else DONE

    def _listed(self, sub: Submission, why: str) -> set[str] | None:
        """The names Kowalski lists now (None after a failed read: retried)."""
        try:
            return {str(q.get("queue_name")) for q in self.client.queues()}  # type: ignore[union-attr]
        except (Unreachable, RuntimeError) as exc:
            self._retry(sub, None, f"{why}, and the queue list could not be read: {exc}")
            return None

    def _queue_end(self, sub: Submission, name: str) -> float | None:
        """When queue ``name`` of the set stops mattering: its window's end (else the plan's)."""
        part = next((q for q in set_of(sub.body) if name_of(q) == name), None)
        end = window_end(part) if part is not None else None
        return end if end is not None else self._plan_end(sub.plan_id)

    # ------------------------------------------------------------ SkyPortal
    def _remove_plans(self, sub: Submission) -> str:
        """SkyPortal: DELETE each plan by request id (refused or id unknown: gone if no longer listed by name) (T3)."""
        assert isinstance(self.client, SkyPortalPlans)
        names, sent = sub.queue_names(), sub.maybe_sent()
        ids = dict(sub.progress.get("ids") or ({names[0]: sub.remote_id} if sub.remote_id and len(names) == 1 else {}))
        by_hand = []
        for name in names:
            if name in sub.progress.get("gone", ()) or name not in sent:
                continue  # removed already, or never sent
            try:
                answer = self.client.delete(ids[name]) if name in ids else None
                if answer is not None and answer.ok and answer.problem is None:
                    sub = self._note(sub, "gone", name, answer)
                    continue
                if answer is not None and answer.redirected:
                    self._finish(sub, State.FAILED, answer, reason=f"DELETE {name}: {answer.status}: {answer.problem}")
                    return DONE
                if answer is not None and not answer.refused:  # 5xx, or a 200 that is not SkyPortal's JSON
                    self._retry(sub, answer.status, answer.problem if answer.ok else answer.message())
                    return RETRY
                listed = self.client.exists(name)
            except (Unreachable, RuntimeError) as exc:
                self._retry(sub, None, str(exc))
                return RETRY
            if not listed:
                sub = self._note(sub, "gone", name, answer, absent=True)
            elif answer is not None:
                self._finish(sub, State.FAILED, answer, reason=f"DELETE {name} refused: {answer.message()}")
                return DONE
            else:
                by_hand.append(name)
        if by_hand:
            self._finish(sub, State.FAILED, reason="SkyPortal request id unknown (interrupted POST): remove plan(s) "
                         f"{', '.join(by_hand)} by hand")
        return DONE


def _settled_reason(sub: Submission) -> str | None:
    """Why a settled row's queues are gone, when it is not the plain DELETE."""
    expired = sub.progress.get("expired")
    if expired:
        return (f"{', '.join(expired)} sent without an answer, never listed before its window ended "
                "(no longer executable)")
    if sub.progress.get("absent"):
        return "not on the server (already removed)"
    return None
