"""The path every notice takes, shared by the daemon and ``mushrooms replay``.

::

    raw bytes ─ accept ─► size cap ▸ parse ▸ policy ▸ decide ─► store (one transaction)
                                                               │
           run_job ◄─ Job (plan / rerun) ◄─────────────────────┘
              │  sky map ▸ scheduler_core.make_plan (checked) ▸ store plan + outbox
              ▼
          flush_outbox ─► sink.publish (plan document / withdrawal)

How the daemon uses it
----------------------
1. ``acc = pipeline.accept(raw, origin)``: returns once the decision is
   durable (commit the Kafka offset after it).  Bad input never raises: it is
   a recorded ``rejected`` decision.  Only a failure to write the state
   (``sqlite3.Error``, :class:`~.store.StoreError`) raises.
2. If ``acc.job`` is set, run ``pipeline.run_job(acc.job, should_stop)`` in a
   worker (``acc.cancelled_jobs`` lists older jobs of the same superevent
   that the store has just superseded or cancelled: stop them; their results
   are discarded anyway).  Equivalently, submit the newest job per superevent
   of ``pipeline.store.pending_jobs()``.
3. After a withdrawal (``acc.action == "withdraw"``) or a failed publish,
   call ``pipeline.flush_outbox()`` (it returns how many messages are still
   pending).
4. At start: ``flush_outbox()`` then ``run_job`` on ``store.pending_jobs()``
   (accepted but not finished; :meth:`NoticePipeline.resume` does both).

Plan ids are stable: a job's horizon start is fixed at accept time, so a job
re-run after a crash produces the same ``plan_id`` and the sink overwrites
the same message.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any, Callable

from ..config import Config
from ..handlers.alert import Alert, NoticeError, parse_notice
from ..handlers.decisions import Decision, decide
from ..handlers.policy import evaluate
from ..scheduler_core.errors import InputError, PlanCheckError
from .sinks import Sink, message_key
from .store import Job, NoticeRecord, Store

__all__ = ["NoticePipeline", "Accepted", "Outcome", "iso_z"]

log = logging.getLogger(__name__)

Planner = Callable[..., Any]
_FITS_MAGIC = (b"SIMPLE  =", b"\x1f\x8b")


def _aware(t: datetime | None) -> datetime:
    """``t`` as an aware UTC datetime (naive means UTC); now when None."""
    if t is None:
        return datetime.now(timezone.utc)
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def iso_z(t: datetime) -> str:
    """Timezone-aware datetime as ``YYYY-MM-DDTHH:MM:SS.mmmZ`` (UTC)."""
    return t.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


@dataclass(frozen=True)
class Outcome:
    """What finally happened to a notice (or to a job).

    Attributes
    ----------
    decision : str
        ``plan``, ``rerun``, ``duplicate``, ``withdraw``, ``ignore``,
        ``rejected`` (bad input: notice or sky map) or ``failed`` (our side:
        plan checker, internal error).
    superevent_id : str or None
    reason : str
    plan_id : str or None
        The new plan (``plan``/``rerun``) or the event's current plan (``duplicate``).
    coverage : float or None
        Probability covered by the new plan.
    latency_s : float or None
        Receipt of the notice to the plan stored and handed to the sink (s).
    alert_type : str or None
    supersedes : str or None
    plan_ids : tuple of str
        Plans withdrawn (``withdraw``).
    published : bool
        The outbound message (plan or withdrawal) was accepted by the sink.
    notice_id, job_id : int or None
        Store ids.
    """

    decision: str
    superevent_id: str | None
    reason: str
    plan_id: str | None = None
    coverage: float | None = None
    latency_s: float | None = None
    alert_type: str | None = None
    supersedes: str | None = None
    plan_ids: tuple[str, ...] = ()
    published: bool = False
    notice_id: int | None = None
    job_id: int | None = None

    @property
    def action(self) -> str:
        return self.decision


@dataclass(frozen=True)
class Accepted:
    """The durable result of :meth:`NoticePipeline.accept`.

    Attributes
    ----------
    action : str
        The decision (see :class:`Outcome`).
    superevent_id, alert_type : str or None
    reason : str
    notice_id : int
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
    superevent_id: str | None
    reason: str
    notice_id: int
    alert_type: str | None = None
    job: Job | None = None
    cancelled_jobs: tuple[int, ...] = ()
    plan_id: str | None = None
    plan_ids: tuple[str, ...] = ()
    withdrawal_id: str | None = None

    @property
    def decision(self) -> str:
        return self.action

    def outcome(self, published: bool = False) -> Outcome:
        """The final outcome of a decision that needs no planning."""
        return Outcome(self.action, self.superevent_id, self.reason, plan_id=self.plan_id,
                       alert_type=self.alert_type, plan_ids=self.plan_ids, published=published,
                       notice_id=self.notice_id, job_id=self.job.job_id if self.job else None)


class NoticePipeline:
    """handlers -> scheduler_core -> plan checker -> store -> sink.

    Parameters
    ----------
    config : Config
        Whole configuration (``[policy]`` and ``[scheduler]`` are used).
    store : Store
        Durable state.
    sink : Sink
        Outbound messages.
    planner : callable, optional
        ``make_plan``-compatible function (default
        :func:`mushrooms.scheduler_core.make_plan`).
    """

    def __init__(self, config: Config, store: Store, sink: Sink, planner: Planner | None = None):
        self.config = config
        self.store = store
        self.sink = sink
        self._planner = planner
        self._flush_lock = getattr(store, "publish_lock", None) or threading.Lock()

    # ------------------------------------------------------------ accept
    def accept(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Parse, filter and decide one notice; record it durably.

        Parameters
        ----------
        raw : bytes
            The notice (message value or file content).
        origin : str
            Where it came from (``kafka:topic:partition:offset``, a file name).
        received_at : datetime, optional
            The clock of the policy (age cuts) and of ``plan_start = received``;
            default now.  Replays pass the notice's ``time_created``.

        Returns
        -------
        Accepted
            Never raises for bad input (``action == "rejected"``).

        Raises
        ------
        sqlite3.Error, StoreError
            Only when the decision cannot be stored.
        """
        wall = time.time()
        now = _aware(received_at)
        if isinstance(raw, str):
            raw = raw.encode("utf-8", "surrogatepass")
        raw = bytes(raw) if not isinstance(raw, bytes) else raw
        policy = self.config.policy
        sha = hashlib.sha256(raw).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(raw), received_at=iso_z(now))
        try:
            alert = parse_notice(raw, max_bytes=policy.max_notice_bytes)
        except NoticeError as exc:
            keep = raw if len(raw) <= policy.max_notice_bytes else None
            nid = self.store.record_rejected(dataclasses.replace(record, raw=keep), str(exc))
            log.warning("notice origin=%s superevent_id=- decision=rejected reason=%r bytes=%d sha256=%s",
                        origin, str(exc), len(raw), sha[:12])
            return Accepted("rejected", None, str(exc), nid)
        record = dataclasses.replace(record, superevent_id=alert.superevent_id, alert_type=alert.alert_type,
                                     time_created=iso_z(alert.time_created), raw=raw)
        try:
            verdict = evaluate(alert, policy, now)
        except Exception as exc:  # a policy bug must not block the stream: record and go on
            log.exception("notice origin=%s superevent_id=%s: policy evaluation failed", origin, alert.superevent_id)
            reason = f"policy evaluation failed: {type(exc).__name__}: {exc}"
            nid = self.store.record_rejected(dataclasses.replace(record, raw=None), reason)
            return Accepted("rejected", alert.superevent_id, reason, nid, alert.alert_type)

        def withdrawal(d: Decision, notice_id: int) -> dict[str, Any]:
            h = hashlib.sha256(f"{d.superevent_id}|{sha}|{'|'.join(d.plan_ids)}".encode()).hexdigest()[:12]
            return {
                "type": "withdrawal",
                "withdrawal_id": f"withdrawal-{d.superevent_id}-{h}",
                "superevent_id": d.superevent_id,
                "plan_ids": list(d.plan_ids),
                "reason": f"{alert.alert_type} notice of {iso_z(alert.time_created)}: {d.reason}",
                "created": iso_z(datetime.now(timezone.utc)),
            }

        nid, decision, job, cancelled, key = self.store.record_decision(
            record,
            lambda ledger: decide(alert, verdict, ledger),
            lambda d: self._plan_start(alert, now),
            received_wall=wall,
            withdrawal=withdrawal,
        )
        acc = Accepted(
            decision.action, alert.superevent_id, decision.reason, nid, alert.alert_type, job,
            tuple(cancelled),
            plan_id=decision.plan_ids[-1] if decision.action == "duplicate" and decision.plan_ids else None,
            plan_ids=decision.plan_ids if decision.action == "withdraw" else (),
            withdrawal_id=key,
        )
        level = logging.WARNING if decision.action == "rejected" else logging.INFO
        log.log(level, "notice origin=%s superevent_id=%s alert_type=%s decision=%s reason=%r%s%s",
                origin, alert.superevent_id, alert.alert_type, decision.action, decision.reason,
                f" job={job.job_id} start={job.start}" if job else "",
                f" cancelled_jobs={','.join(map(str, cancelled))}" if cancelled else "")
        return acc

    def _plan_start(self, alert: Alert, now: datetime) -> str | None:
        ev = alert.event
        if ev is None or not ev.skymap:
            return None
        mode = self.config.policy.plan_start
        if mode == "event":
            return iso_z(ev.time)
        if mode == "created":
            return iso_z(alert.time_created)
        return iso_z(max(now, ev.time))

    # ------------------------------------------------------------ jobs
    def run_job(self, job: Job, should_stop: Callable[[], bool] | None = None) -> Outcome:
        """Plan one accepted job, store the plan and publish it.

        Parameters
        ----------
        job : Job
            From :meth:`accept` or :meth:`Store.pending_jobs`.
        should_stop : callable, optional
            Polled by the scheduler; True makes it return its best plan so far.

        Returns
        -------
        Outcome
            ``plan``/``rerun`` with plan_id, coverage and latency;
            ``ignore`` when the job was superseded or withdrawn meanwhile;
            ``rejected`` for an unusable sky map; ``failed`` for a plan the
            checker refused or an internal error (logged with a traceback).
        """
        base = dict(superevent_id=job.superevent_id, alert_type=job.alert_type, job_id=job.job_id,
                    notice_id=job.notice_id)
        started = self.store.start_job(job.job_id)
        if started is None:
            state = self.store.describe_job(job.job_id)
            reason = f"job {job.job_id} not run: {state}"
            decision = "failed" if state.startswith("failed") else "ignore"
            log.info("job superevent_id=%s job=%s decision=%s reason=%r", job.superevent_id, job.job_id, decision,
                     reason)
            return Outcome(decision, reason=reason, **base)
        try:
            plan = self._plan(started, should_stop)
        except (NoticeError, InputError) as exc:  # SkyMapError is an InputError
            return self._job_failed(started, "rejected", str(exc), base)
        except PlanCheckError as exc:
            return self._job_failed(started, "failed", str(exc), base)
        except Exception as exc:
            log.exception("job superevent_id=%s job=%s decision=failed internal error", job.superevent_id, job.job_id)
            return self._job_failed(started, "failed", f"internal error: {type(exc).__name__}: {exc}", base)
        latency = round(time.time() - started.received_wall, 3)
        plan = plan.with_(metrics=dataclasses.replace(plan.metrics, latency_s=latency))
        doc = plan.to_document()
        coverage = float(plan.metrics.coverage)
        outbox_id = self.store.finish_job(started.job_id, plan.plan_id, doc, coverage, latency)
        if outbox_id is None:
            reason = f"plan {plan.plan_id} dropped: job {self.store.describe_job(started.job_id)} while planning"
            log.info("job superevent_id=%s job=%s decision=ignore reason=%r", job.superevent_id, job.job_id, reason)
            return Outcome("ignore", reason=reason, plan_id=plan.plan_id, **base)
        self.flush_outbox()
        published = self._published(outbox_id)
        log.info("job superevent_id=%s job=%s decision=%s plan_id=%s coverage=%.4f latency_s=%.3f supersedes=%s "
                 "published=%s solver=%s", job.superevent_id, job.job_id, started.decision, plan.plan_id,
                 coverage, latency, plan.supersedes or "-", published, plan.metrics.solver)
        return Outcome(started.decision, reason=f"{plan.metrics.n_fields} fields, {plan.metrics.n_exposures} exposures",
                       plan_id=plan.plan_id, coverage=coverage, latency_s=latency, supersedes=plan.supersedes,
                       published=published, **base)

    def _plan(self, job: Job, should_stop: Callable[[], bool] | None) -> Any:
        from ..scheduler_core import EventInfo, make_plan, read_skymap
        from ..scheduler_core.plan import parse_time

        raw = self.store.notice_raw(job.notice_id)
        if raw is None:
            raise RuntimeError(f"notice {job.notice_id} of job {job.job_id} has no stored bytes")
        if raw.startswith(_FITS_MAGIC):  # a bare sky map handed in by ``mushrooms trigger``
            skymap_bytes = raw
            event = EventInfo(skymap_sha256=job.skymap_sha256)
        else:
            alert = parse_notice(raw)
            assert alert.event is not None
            skymap_bytes = alert.event.skymap
            event = EventInfo(superevent_id=alert.superevent_id, alert_type=alert.alert_type,
                              time_created=iso_z(alert.time_created), skymap_sha256=alert.event.skymap_sha256)
        sched = self.config.scheduler
        skymap = read_skymap(skymap_bytes, nside=sched.nside, max_bytes=self.config.policy.max_skymap_bytes)
        planner = self._planner or make_plan
        if job.fallback:  # the optimiser died too often on this job: the fast scheduler's plan still goes out
            log.warning("job superevent_id=%s job=%s fallback=greedy reason='%d starts died'", job.superevent_id,
                        job.job_id, job.attempts - 1)
        plan = planner(skymap, config=sched, start=parse_time(job.start), event=event,
                       supersedes=job.supersedes, should_stop=should_stop,
                       **({"solver": "greedy"} if job.fallback else {}))
        if plan.supersedes == plan.plan_id:
            plan = plan.with_(supersedes=None)
        return plan

    def _job_failed(self, job: Job, decision: str, reason: str, base: dict[str, Any]) -> Outcome:
        try:
            self.store.fail_job(job.job_id, reason, retry_same_map=(decision == "failed"))
        except Exception:
            log.exception("job superevent_id=%s job=%s: could not record the failure", job.superevent_id, job.job_id)
        log.warning("job superevent_id=%s job=%s decision=%s reason=%r", job.superevent_id, job.job_id,
                    decision, reason)
        return Outcome(decision, reason=reason, **base)

    def _published(self, outbox_id: int) -> bool:
        return all(m.outbox_id != outbox_id for m in self.store.pending_outbox())

    # ------------------------------------------------------------ outbox
    def flush_outbox(self) -> int:
        """Publish pending outbox messages in order; stop at the first failure.

        Returns
        -------
        int
            Messages still pending (0 when all went out).
        """
        with self._flush_lock:
            pending = self.store.pending_outbox()
            for i, msg in enumerate(pending):
                try:
                    self.sink.publish(msg.message)
                except Exception as exc:
                    self.store.mark_publish_failed(msg.outbox_id, f"{type(exc).__name__}: {exc}")
                    log.warning("publish key=%s kind=%s failed (attempt %d): %s: %s; %d message(s) pending",
                                msg.key, msg.kind, msg.attempts + 1, type(exc).__name__, exc, len(pending) - i)
                    return len(pending) - i
                self.store.mark_published(msg.outbox_id)
                log.info("publish key=%s kind=%s superevent_id=%s ok", message_key(msg.message), msg.kind,
                         msg.message.get("superevent_id") or (msg.message.get("event") or {}).get("superevent_id"))
            return 0

    # ------------------------------------------------------------ helpers
    def handle(self, raw: bytes, origin: str, received_at: datetime | None = None,
               should_stop: Callable[[], bool] | None = None) -> Outcome:
        """accept + run_job + flush_outbox, synchronously (``mushrooms replay``)."""
        acc = self.accept(raw, origin, received_at)
        if acc.job is not None:
            return self.run_job(acc.job, should_stop)
        left = self.flush_outbox()
        return acc.outcome(published=acc.withdrawal_id is not None and left == 0)

    def resume(self, should_stop: Callable[[], bool] | None = None) -> list[Outcome]:
        """After a restart: publish the outbox, then run every unfinished job."""
        self.flush_outbox()
        return [self.run_job(job, should_stop) for job in self.store.pending_jobs()]

    def rerun_superevent(self, superevent_id: str, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a superevent again from its newest stored notice (``mushrooms trigger SUPEREVENT_ID``).

        An operator's explicit request: no policy and no duplicate check; the
        new plan supersedes the event's latest plan.  The horizon starts as
        ``plan_start`` says, with now as the receipt time.
        """
        wall = time.time()
        now = _aware(received_at)
        sid = superevent_id.strip()
        found = self.store.latest_planned_notice(sid)
        record = NoticeRecord(origin=origin, sha256=hashlib.sha256(sid.encode()).hexdigest(), size=len(sid),
                              received_at=iso_z(now), superevent_id=sid or None)
        if found is None:
            reason = f"no stored notice of {sid!r} to plan from"
            nid = self.store.record_rejected(record, reason)
            log.warning("trigger origin=%s superevent_id=%s decision=rejected reason=%r", origin, sid or "-", reason)
            return Accepted("rejected", sid or None, reason, nid)
        _, raw = found
        alert = parse_notice(raw)
        record = dataclasses.replace(record, sha256=hashlib.sha256(raw).hexdigest(), size=len(raw),
                                     alert_type=alert.alert_type, time_created=iso_z(alert.time_created), raw=raw)

        def dec(ledger: Any) -> Decision:
            st = ledger.event_state(sid)
            latest = st.latest_plan_id if st is not None else None
            return Decision("rerun", sid, "manual rerun requested", alert.alert_type, alert.skymap_sha256,
                            supersedes=latest)

        nid, decision, job, cancelled, _ = self.store.record_decision(
            record, dec, lambda d: self._plan_start(alert, now), received_wall=wall)
        log.info("trigger origin=%s superevent_id=%s decision=%s reason=%r%s", origin, sid, decision.action,
                 decision.reason, f" job={job.job_id}" if job else "")
        return Accepted(decision.action, sid, decision.reason, nid, alert.alert_type, job, tuple(cancelled))

    def accept_skymap(self, data: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a bare sky map (``mushrooms trigger SKYMAP.fits``); no policy applies.

        The map is planned from the receipt time (``plan_start = event`` uses
        the notice's time only, which a bare map does not have).  The same map
        again is a ``duplicate``.
        """
        wall = time.time()
        now = _aware(received_at)
        data = bytes(data)
        sha = hashlib.sha256(data).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(data), received_at=iso_z(now))
        if len(data) > self.config.policy.max_notice_bytes * 4 or not data.startswith(_FITS_MAGIC):
            reason = "sky map too large" if data.startswith(_FITS_MAGIC) else "not a FITS sky map"
            nid = self.store.record_rejected(record, reason)
            log.warning("skymap origin=%s decision=rejected reason=%r", origin, reason)
            return Accepted("rejected", None, reason, nid)
        sid = f"skymap-{sha[:12]}"
        record = dataclasses.replace(record, superevent_id=sid, alert_type="SKYMAP", raw=data)

        def dec(ledger: Any) -> Decision:
            st = ledger.event_state(sid)
            if st is not None and st.skymap_sha256 == sha and not st.retracted:
                return Decision("duplicate", sid, "same sky map already planned", "SKYMAP", sha,
                                plan_ids=st.plan_ids)
            return Decision("plan", sid, "manual trigger", "SKYMAP", sha)

        nid, decision, job, cancelled, _ = self.store.record_decision(
            record, dec, lambda d: iso_z(now), received_wall=wall)
        log.info("skymap origin=%s superevent_id=%s decision=%s reason=%r", origin, sid, decision.action,
                 decision.reason)
        return Accepted(decision.action, sid, decision.reason, nid, "SKYMAP", job, tuple(cancelled),
                        plan_id=decision.plan_ids[-1] if decision.plan_ids else None)
