"""What a plan becomes on the telescope's side, and what an answer means (the submitter's pure rules).

:func:`queue_name_base` (the name base of a plan's queues: the one rule,
:func:`mushrooms.scheduler_core.plan.exports.queue_name_base`), :func:`gate`
(whether a plan document is submitted), :func:`build_body` (the queue set
or the SkyPortal plan of a revision), :func:`same_content` and
:func:`send_queue` (one ``PUT``/``POST`` and its :class:`Verdict`).  Shared
by the daemon's :class:`~mushrooms.daemon.submission.submitter.Submitter` and ``mushrooms submit``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING, Any

from ...scheduler_core.plan.exports import queue_name_base
from .remote import Answer, KowalskiQueue, SkyPortalPlans, Unreachable

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from .settings import SubmitConfig

__all__ = ["Verdict", "queue_name_base", "gate", "build_body", "same_content", "send_queue", "set_of", "name_of", "unix",
           "total_coverage"]


def unix(iso: str) -> float:
    """An ISO-8601 instant of a plan document as Unix seconds."""
    return datetime.fromisoformat(iso.replace("Z", "+00:00")).timestamp()


def total_coverage(metrics: dict[str, Any]) -> float:
    """The probability covered once the plan is done: its own ``coverage`` plus ``coverage_executed``.

    A re-plan's ``metrics.coverage`` is what it *adds* (replan.md P8); what the
    executed pairs hold is ``metrics.coverage_executed`` (absent: 0).
    """
    return float(metrics.get("coverage") or 0.0) + float(metrics.get("coverage_executed") or 0.0)


def gate(document: dict[str, Any], sub: SubmitConfig, now: float | None = None) -> str | None:
    """Why a plan document is not submitted (None: it is).

    Gates of ``[submit]``: only plans (not ``not_observable`` answers) with
    observations, of an alert type in ``alert_types``, whose total coverage
    (:func:`total_coverage`: a re-plan counts the executed pairs too) is at
    least ``min_coverage``, with at most ``max_exposures`` exposures (0:
    any), whose validity window has not ended.
    """
    if document.get("type") != "plan":
        return f"a {document.get('type')} document, not a plan"
    if not document.get("observations"):
        return "no observations"
    alert_type = (document.get("event") or {}).get("alert_type")
    if alert_type not in sub.alert_types:
        return f"alert type {alert_type} not in [submit] alert_types"
    metrics = document.get("metrics") or {}
    coverage = total_coverage(metrics)
    if coverage < sub.min_coverage:
        return f"coverage {coverage:.4f} below [submit] min_coverage {sub.min_coverage:g}"
    n = int(metrics.get("n_exposures") or len(document["observations"]))
    if sub.max_exposures and n > sub.max_exposures:
        return f"{n} exposures, more than [submit] max_exposures {sub.max_exposures}"
    if unix(document["end"]) <= (time.time() if now is None else now):
        return f"validity window ended at {document['end']}"
    return None


def build_body(document: dict[str, Any], submit: SubmitConfig, export: ExportConfig, name: str) -> Any:
    """The request body of a plan for ``[submit] target`` under the name base ``name``.

    Kowalski: the ordered queue set of
    :func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queues`, named
    ``<name>_<k>`` (a list of queue bodies, PUT in order); SkyPortal:
    the ordered plans of :func:`~...exports.to_skyportal_plans` (``plan
    --skyportal``; one per filter pass, or one per revision with ``[export]
    skyportal_plans = "single"``, POSTed in order) named from ``name``
    without its ``ToO_`` (SkyPortal's ZTF API puts it back when it queues a
    plan, so the queues get the Kowalski target's names).

    Raises
    ------
    ValueError
        The plan cannot be expressed (no observations, a non-ZTF filter,
        SkyPortal without allocation id or event time).
    """
    from ...scheduler_core import Plan
    from ...scheduler_core.plan import exports

    plan = Plan.from_document(document)
    if submit.target == "kowalski":
        queues = exports.to_trigger_queues(plan, export, name_base=name)
        if not queues:
            raise ValueError("the plan gives no queue")
        return queues
    return exports.to_skyportal_plans(plan, export, name_base=name.removeprefix("ToO_"))


def set_of(body: Any) -> list[dict[str, Any]]:
    """The queues (or SkyPortal plans) of a stored body: a set (list), or one (rows written before sets)."""
    if isinstance(body, list):
        return [q for q in body if isinstance(q, dict)]
    return [body] if isinstance(body, dict) else []


def name_of(part: dict[str, Any]) -> str:
    """The name of one request of a set: a Kowalski queue's ``queue_name``, a SkyPortal plan's ``plan_name``."""
    return str(part.get("queue_name") or part.get("plan_name"))


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

    200 with a JSON answer: submitted (a 200 that is not JSON, or larger than
    the cap, is retried: a captive portal or a proxy said it, not the
    server; a repeat finds Kowalski's queue by its 409).  Kowalski's 409 (a
    queue of that name exists) counts as submitted when ``GET`` lists the
    queue with the same content (a repeat after a crash), else rejected.  A
    3xx: rejected with its target (redirects are never followed).  Other
    4xx: rejected (the server's text kept).  5xx, the deadline, no
    connection, a cut or non-HTTP answer: retry.
    """
    try:
        answer = client.put(body) if isinstance(client, KowalskiQueue) else client.post(body)
    except Unreachable as exc:
        return Verdict("retry", None, str(exc))
    if answer.ok:
        if answer.problem is not None:
            return Verdict("retry", answer, f"{answer.status}, but {answer.problem}")
        remote = None
        if isinstance(answer.data, dict) and isinstance(answer.data.get("data"), dict):
            remote = answer.data["data"].get("id")
        return Verdict("submitted", answer, None, None if remote is None else str(remote))
    if answer.redirected:
        return Verdict("rejected", answer, f"{answer.status}: {answer.problem}")
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
