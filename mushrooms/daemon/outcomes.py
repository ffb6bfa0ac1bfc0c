"""What the pipeline answers: :class:`Accepted` (a decision is durable) and :class:`Outcome` (what finally happened).

Both carry the same identity of the event, notice and job they are about in
one :class:`~mushrooms.daemon.state.records.EventRef` (``ref``), read through the properties
``superevent_id``, ``alert_type``, ``notice_id`` and ``job_id``; a stored
:class:`~mushrooms.daemon.state.store.Job` gives its own with :attr:`~mushrooms.daemon.state.store.Job.ref`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .state.records import EventRef

__all__ = ["EventRef", "Outcome", "Accepted", "log_fields"]


class _Refers:
    """The :class:`EventRef` fields of ``self.ref`` as attributes."""

    ref: EventRef

    def __post_init__(self) -> None:
        if not isinstance(self.ref, EventRef):  # ``Outcome("failed", None, reason)``: no event (or its id only)
            object.__setattr__(self, "ref", EventRef(self.ref))

    @property
    def superevent_id(self) -> str | None:
        return self.ref.superevent_id

    @property
    def alert_type(self) -> str | None:
        return self.ref.alert_type

    @property
    def notice_id(self) -> int | None:
        return self.ref.notice_id

    @property
    def job_id(self) -> int | None:
        return self.ref.job_id


@dataclass(frozen=True)
class Outcome(_Refers):
    """What finally happened to a notice (or to a job).

    Attributes
    ----------
    decision : str
        ``plan``, ``rerun``, ``duplicate``, ``withdraw``, ``ignore``,
        ``rejected`` (bad input: notice or sky map) or ``failed`` (our side:
        plan checker, internal error).  Also ``action``.
    ref : EventRef
        ``superevent_id``, ``alert_type``, ``notice_id``, ``job_id`` (properties).
    reason : str
    plan_id : str or None
        The new plan (``plan``/``rerun``) or the event's current plan (``duplicate``).
    coverage : float or None
        Probability covered by the new plan.
    latency_s : float or None
        Receipt of the notice to the plan stored and handed to the sink (s).
    supersedes : str or None
    plan_ids : tuple of str
        Plans withdrawn (``withdraw``).
    published : bool
        The outbound message (plan or withdrawal) was accepted by the sink.
    revision : int or None
        Which revision of the job's plan ``plan_id`` is (1: the fast plan).
    final : bool
        No further revision of this job will follow.
    """

    decision: str
    ref: EventRef
    reason: str
    plan_id: str | None = None
    coverage: float | None = None
    latency_s: float | None = None
    supersedes: str | None = None
    plan_ids: tuple[str, ...] = ()
    published: bool = False
    revision: int | None = None
    final: bool = False

    @property
    def action(self) -> str:
        return self.decision


@dataclass(frozen=True)
class Accepted(_Refers):
    """The durable result of :meth:`~mushrooms.daemon.intake.pipeline.NoticePipeline.accept` (and the manual entry points).

    Attributes
    ----------
    action : str
        The decision (see :class:`Outcome`).  Also ``decision``.
    ref : EventRef
        ``superevent_id``, ``alert_type``, ``notice_id``, ``job_id`` (properties).
    reason : str
    job : Job or None
        Planning work to run (``plan``/``rerun``).
    cancelled_jobs : tuple of int
        Older jobs of the same superevent the store superseded or cancelled.
    plan_id : str or None
        The event's current plan (``duplicate``).
    plan_ids : tuple of str
        Plans being withdrawn (``withdraw``).
    withdrawal_id : str or None
        Key of the queued withdrawal message.
    """

    action: str
    ref: EventRef
    reason: str
    job: Any = None  # a store Job (not imported: the store imports this module)
    cancelled_jobs: tuple[int, ...] = ()
    plan_id: str | None = None
    plan_ids: tuple[str, ...] = ()
    withdrawal_id: str | None = None

    @property
    def decision(self) -> str:
        return self.action

    def outcome(self, published: bool = False) -> Outcome:
        """The final outcome of a decision that needs no planning."""
        return Outcome(self.action, self.ref, self.reason, plan_id=self.plan_id, plan_ids=self.plan_ids,
                       published=published)


def log_fields(decision: Any) -> str:
    """A decision as ``key=value`` fields of a log line (``decision=plan superevent_id=... reason='...'``).

    ``decision`` is an :class:`Accepted`, a handlers ``Decision``, a result
    dict, or None (a message quarantined before a decision).
    """
    if decision is None:
        return "decision=quarantined"
    fields = []
    for name in ("superevent_id", "alert_type", "action", "kind", "reason", "plan_id"):
        value = getattr(decision, name, None)
        if value is None and isinstance(decision, dict):
            value = decision.get(name)
        if value is not None:
            value = getattr(value, "value", value)
            text = str(value)
            fields.append(f"{'decision' if name in ('action', 'kind') else name}="
                          + (repr(text) if " " in text or not text else text))
    return " ".join(fields) or f"decision={decision!r}"
