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
import re
import time
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING, Any

from ...scheduler_core.plan.exports import queue_name_base
from .remote import Answer, KowalskiQueue, SkyPortalPlans, Unreachable

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from .settings import SubmitConfig

__all__ = ["Verdict", "queue_name_base", "gate", "build_body", "same_content", "listed_as_ours", "send_queue", "set_of",
           "name_of", "unix", "window_end", "total_coverage", "kowalski_timed_out"]

#: The Unix time of MJD 0 is -40587 days (1858-11-17 is 40587 days before 1970-01-01).
_MJD_UNIX_DAYS = 40587.0


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


def window_end(queue: dict[str, Any]) -> float | None:
    """The end of a queue's ``validity_window_mjd`` as Unix seconds (None: the queue has none that parses).

    After it the queue cannot be executed: ZTF's scheduler switches only to a queue whose window
    holds now and deletes the expired ones (ztf_sim ``Scheduler.check_for_timed_queue_and_switch``,
    ``remove_empty_and_expired_queues``).
    """
    try:
        end = float(queue["validity_window_mjd"][1])
    except (KeyError, IndexError, TypeError, ValueError):
        return None
    return (end - _MJD_UNIX_DAYS) * 86400.0 if end == end else None


def _targets_key(targets: Any) -> list[tuple[int, int, float]]:
    if isinstance(targets, str):
        targets = json.loads(targets)
    return sorted((int(t["field_id"]), int(t["filter_id"]), round(float(t["exposure_time"]), 3)) for t in targets)


def _same_window(body: dict[str, Any], listed: dict[str, Any]) -> bool:
    mine, theirs = body["validity_window_mjd"], listed.get("validity_window_mjd")
    return (theirs is not None and len(theirs) == 2
            and all(abs(float(a) - float(b)) <= 1e-6 for a, b in zip(mine, theirs)))


def same_content(body: dict[str, Any], listed: dict[str, Any]) -> bool:
    """Whether a queue listed by ``GET /api/triggers/ztf`` is ``body``: same validity window, fields, filters, exposures."""
    try:
        return _same_window(body, listed) and \
            _targets_key(body["targets"]) == _targets_key(listed.get("queue", listed.get("targets", [])))
    except (KeyError, TypeError, ValueError):
        return False


def listed_as_ours(body: dict[str, Any], listed: dict[str, Any]) -> tuple[bool, int]:
    """Whether a listed queue is ``body`` as the telescope left it, and how many of its targets are still listed.

    The mountain's list shows a list queue's targets *not yet observed*: an
    observed target leaves it (ztf_sim ``ListQueueManager._remove_requests``,
    ``return_queue``).  So our queue is listed with our validity window (to
    1e-6 d) and a sub-multiset of our (field, filter, exposure) targets.
    """
    try:
        if not _same_window(body, listed):
            return False, 0
        left = list(_targets_key(listed.get("queue", listed.get("targets", []))))
        mine = _targets_key(body["targets"])
    except (KeyError, TypeError, ValueError):
        return False, 0
    pool = list(mine)
    for t in left:
        if t not in pool:
            return False, len(left)
        pool.remove(t)
    return True, len(left)


#: Kowalski's ``error_middleware`` text for a timeout of its own request to the mountain (Y0): ``TimeoutError: ``
#: (aiohttp's total timeout), or a subclass's name (``ServerTimeoutError: ...``, ``SocketTimeoutError: ...``).
_KOWALSKI_TIMEOUT = re.compile(r"\w*Timeout\w*: ")


def kowalski_timed_out(answer: Answer) -> bool:
    """Whether a 400 is Kowalski's own timeout towards the mountain, not a refusal: the request may still be applied.

    Kowalski forwards a PUT or DELETE to the mountain with a 10 s timeout
    (``kowalski/api/handlers/ztf.py``); when it runs out, ``error_middleware``
    answers 400 ``"<ExceptionName>: <text>"`` while the mountain may apply
    the request later (docs/design/submission.md Y0).  Such an answer is a
    request without an answer (retried; a PUT's queue is maybe live, Y2).
    """
    return answer.status == 400 and _KOWALSKI_TIMEOUT.match(answer.message()) is not None


@dataclass(frozen=True)
class Verdict:
    """What one PUT/POST of a queue came to: ``submitted``, ``rejected`` or ``retry`` (5xx, timeout, unreachable)."""

    state: str
    answer: Answer | None
    reason: str | None = None
    remote_id: str | None = None


def send_queue(client: KowalskiQueue | SkyPortalPlans, body: dict[str, Any], name: str,
               sent_before: bool = False) -> Verdict:
    """Send one queue (Kowalski ``PUT``) or plan (SkyPortal ``POST``) and classify the answer.

    200 with a JSON answer: submitted (a 200 that is not JSON, or larger than
    the cap, is retried: a captive portal or a proxy said it, not the
    server; a repeat finds Kowalski's queue by its 409).  Kowalski's 409 (a
    queue of that name exists): see :func:`_conflict`.  A 3xx: rejected with
    its target (redirects are never followed).  Kowalski's own timeout to
    the mountain (a 400 ``TimeoutError: ``, :func:`kowalski_timed_out`): retry,
    the queue maybe live.  Other 4xx: rejected (the server's text kept).  5xx, the deadline, no connection, a cut or
    non-HTTP answer: retry.

    Parameters
    ----------
    sent_before : bool
        This queue was sent before by the same revision (a PUT whose answer
        was lost: a kill -9, the deadline): a 409 may be our own queue.
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
        return _conflict(client, body, name, answer, sent_before)
    if isinstance(client, KowalskiQueue) and kowalski_timed_out(answer):  # Y0: not a refusal; maybe live (Y2)
        return Verdict("retry", answer, f"{answer.status} {answer.message()[:200].strip()} (Kowalski's own timeout to the "
                       "mountain: the queue may still be applied; retried)")
    if answer.refused:
        return Verdict("rejected", answer)
    return Verdict("retry", answer, answer.message())


def _conflict(client: KowalskiQueue, body: dict[str, Any], name: str, answer: Answer, sent_before: bool) -> Verdict:
    """Kowalski's 409 (the mountain already holds a queue of that name) against what ``GET`` lists.

    Queue names are unique per revision, so the queue is ours when it is
    listed with our window and a sub-multiset of our targets (the telescope
    took the others: :func:`listed_as_ours`), or when this revision sent it
    before and it is no longer listed (emptied or expired since the 409).
    A listed queue with another window or other targets is someone else's:
    rejected: (Y1) of ``docs/design/submission.md``.
    """
    try:
        listed = [q for q in client.queues() if q.get("queue_name") == name]
    except (Unreachable, RuntimeError) as exc:
        return Verdict("retry", answer, f"409, and the queue list could not be read: {exc}")
    if listed:
        ours, left = listed_as_ours(body, listed[0])
        if ours:
            n = len(body.get("targets") or ())
            return Verdict("submitted", answer, "409: already queued with the same content (accepted)" if left == n
                           else f"409: our queue, {n - left} of its {n} targets already observed (accepted)")
        return Verdict("rejected", answer, "409: a queue of that name exists with other content")
    if sent_before:
        return Verdict("submitted", answer, "409 on a queue this revision sent before, no longer listed "
                       "(observed or expired since; accepted)")
    return Verdict("rejected", answer, "409, but the queue list does not show it")
