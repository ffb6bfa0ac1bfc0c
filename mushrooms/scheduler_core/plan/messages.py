"""Every outbound document the daemon publishes, built in one place.

Pure functions (no clock, no store, no I/O): the caller passes the
``created`` instant, as ISO-8601 UTC (``YYYY-MM-DDTHH:MM:SS.mmmZ``).  Each
result validates against the package's JSON Schema
(:func:`~.schema.validate_document`); ``docs/design/CONTRACTS.md`` and
``docs/design/plan-format.md`` describe the fields.

=================  ===========================================  ======================
type               what it says                                  key (:func:`~mushrooms.daemon.sinks.message_key`)
=================  ===========================================  ======================
``plan``           a revision of a job's plan (1, 2)             ``plan_id``
``not_observable`` a revision that has nothing worth observing   ``plan_id``
``plan_final``     revision 1 of ``plan_id`` stands              ``<plan_id>-final``
``withdrawal``     the event was retracted: drop these plans     ``withdrawal_id``
=================  ===========================================  ======================

Incidents are not published; :func:`combined_map_incident` is the detail the
store keeps of the one the planning path records.
"""

from __future__ import annotations

import hashlib
from typing import Any, Sequence

__all__ = ["revision_document", "plan_final_message", "withdrawal_message", "combined_map_incident"]


def revision_document(plan: Any, revision: int, final: bool) -> dict[str, Any]:
    """The plan (or not_observable) document with ``revision`` (1, 2, ...) and ``final`` added.

    Parameters
    ----------
    plan : Plan or NotObservable
        Anything with ``to_document()``.
    revision : int
        1: the fast plan; 2: the optimised replacement.
    final : bool
        No further revision of this job will follow.
    """
    doc = plan.to_document()
    doc["revision"] = int(revision)
    doc["final"] = bool(final)
    return doc


def plan_final_message(plan_id: str, superevent_id: str | None, reason: str, created: str) -> dict[str, Any]:
    """The ``plan_final`` message: revision 1 of ``plan_id`` stands, nothing follows.

    Parameters
    ----------
    plan_id : str
    superevent_id : str or None
    reason : str
        Why no revision 2 (e.g. the optimised plan was not better by the margin).
    created : str
        ISO-8601 UTC instant of the message.
    """
    return {
        "type": "plan_final",
        "plan_id": plan_id,
        "revision": 1,
        "final": True,
        "superevent_id": superevent_id,
        "reason": reason,
        "created": created,
    }


def withdrawal_message(superevent_id: str, plan_ids: Sequence[str], notice_sha256: str, alert_type: str,
                       notice_created: str, why: str, created: str) -> dict[str, Any]:
    """The ``withdrawal`` of every plan of a retracted event.

    Parameters
    ----------
    superevent_id : str
    plan_ids : sequence of str
        The plans withdrawn, oldest first.
    notice_sha256 : str
        SHA-256 of the retraction notice: with the event and the plan ids it
        makes the stable ``withdrawal_id`` (the same notice again gives the same key).
    alert_type, notice_created : str
        The retraction's type and ``time_created`` (ISO-8601 UTC), for the reason.
    why : str
        The decision's reason.
    created : str
        ISO-8601 UTC instant of the message.
    """
    ids = list(plan_ids)
    h = hashlib.sha256(f"{superevent_id}|{notice_sha256}|{'|'.join(ids)}".encode()).hexdigest()[:12]
    return {
        "type": "withdrawal",
        "withdrawal_id": f"withdrawal-{superevent_id}-{h}",
        "superevent_id": superevent_id,
        "plan_ids": ids,
        "reason": f"{alert_type} notice of {notice_created}: {why}",
        "created": created,
    }


def combined_map_incident(superevent_id: str, job_id: int, notice_id: int, error: str) -> dict[str, Any]:
    """Detail of the ``combined_map_unusable`` incident: the job planned on the GW map instead.

    Parameters
    ----------
    superevent_id : str
    job_id, notice_id : int
    error : str
        Why the joint map did not decode.
    """
    return {"superevent_id": superevent_id, "job_id": job_id, "notice_id": notice_id,
            "reason": f"combined sky map unusable ({error}); planned on the GW map"}
