"""The path every notice takes, shared by the daemon and ``mushrooms replay``.

::

    raw bytes ─ accept ─► size cap ▸ parse ▸ policy ▸ decide ─► store (one transaction)
                                                               │
           run_job ◄─ Job (plan / rerun) ◄─────────────────────┘
              │  sky map ▸ prepare (warm cache) ▸ greedy ▸ checker ▸ store revision 1 + outbox
              │  configured solver ▸ checker ▸ revision 2 if better by supersede_min_gain, else plan_final
              ▼
          flush_outbox ─► sink.publish (plan document / plan_final / withdrawal)

Anytime plans
-------------
Every job publishes its fast (greedy) plan at once as revision 1
(``revision: 1``, ``final: false`` unless the configured solver is greedy),
then runs ``config.scheduler.solver`` (and the detection stage when the
objective is ``detection``, :func:`~mushrooms.scheduler_core.planner.optimise`)
with the job's ``should_stop``.  Its
plan goes out as revision 2 (``supersedes`` = revision 1, ``final: true``)
only when it covers at least ``[daemon] supersede_min_gain`` more (with
``[scheduler] objective = "detection"``: when it expects at least that much
more detections within the coverage floor, or, the expected detections
tying within that margin, covers that much more,
:func:`~mushrooms.scheduler_core.anytime.is_better`);
otherwise a small ``plan_final`` message (key ``<plan_id>-final``) says that
revision 1 stands.  A newer sky map supersedes the job in the store at
accept time; its stop flag then ends the job at the next stage boundary or
scheduler poll, and the new job's revision 1 supersedes whatever the event
last published.  A retraction withdraws every revision.

How the daemon uses it
----------------------
1. ``acc = pipeline.accept(raw, origin)``: returns once the decision is
   durable (commit the Kafka offset after it).  Bad input never raises: it is
   a recorded ``rejected`` decision.  Only a failure to write the state
   (``sqlite3.Error``, :class:`~.store.StoreError`) raises.
2. If ``acc.job`` is set, run ``pipeline.run_job(acc.job, should_stop,
   staged=True)`` in a worker: it returns after revision 1 with a
   :class:`~.jobs.Staged` whose ``run`` is the optimisation (the
   :class:`~.jobs.JobRunner` queues it behind newer first plans).
   ``acc.cancelled_jobs`` lists older jobs of the same superevent that the
   store has just superseded or cancelled: stop them.
3. With ``on_outbox`` (the daemon's :class:`~.jobs.OutboxDrain`) planning
   threads never publish: they queue and kick the drain.  Without it
   (replay, ``mushrooms trigger`` with no daemon) ``run_job`` publishes
   inline and optimises inline.
4. At start: ``flush_outbox()`` then ``run_job`` on ``store.pending_jobs()``
   (accepted but not finished; :meth:`NoticePipeline.resume` does both).

Plan ids are stable: a job's horizon start is fixed at accept time, and a
plan id hashes the map, start, configuration, solver and superevent, so a
job re-run after a crash produces the same ids; a revision the job already
stored is not queued again (:meth:`~.store.Store.store_revision`).
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
from ..handlers.instants import iso_z
from ..handlers.localization import check_skymap_header, choose_localization, coincidence_summary, skymap_for_sha
from ..handlers.policy import evaluate
from ..scheduler_core.errors import InputError, PlanCheckError
from ..scheduler_core.sky.sniff import is_fits
from .sinks import Sink, message_key
from .store import Job, NoticeRecord, Store

__all__ = ["NoticePipeline", "Accepted", "Outcome", "iso_z"]


class _Cancelled(Exception):
    """The job was superseded or retracted; the message names the stage it stopped before."""


@dataclass
class _Work:
    """A job between its first plan and its optimisation (kept in memory only)."""

    job: Job
    skymap: Any
    problem: Any
    event: Any
    first: Any
    prepare_s: float
    outcome: "Outcome | None" = None

log = logging.getLogger(__name__)

Planner = Callable[..., Any]


def _aware(t: datetime | None) -> datetime:
    """``t`` as an aware UTC datetime (naive means UTC); now when None."""
    if t is None:
        return datetime.now(timezone.utc)
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def _age_s(iso: str | None) -> str:
    """Seconds since an ISO-8601 UTC time (``-`` when unknown), for log lines."""
    if not iso:
        return "-"
    try:
        return f"{(datetime.now(timezone.utc) - datetime.fromisoformat(iso)).total_seconds():.3f}"
    except ValueError:
        return "-"


def _after_withdrawals(plan: Any, epoch: int) -> Any:
    """``plan`` with an id of its own when its event was withdrawn ``epoch`` times before its notice.

    A re-plan after a withdrawal (PRELIMINARY, RETRACTION, then an INITIAL
    with the same map) would otherwise hash to the id the withdrawal listed,
    and consumers that de-duplicate by id would drop the live plan.  Epoch 0
    (every event never withdrawn, every replay of one) keeps the plain
    :func:`~mushrooms.scheduler_core.plan.document.make_plan_id` id.
    """
    if not epoch:
        return plan
    from ..scheduler_core import make_plan_id

    return plan.with_(plan_id=make_plan_id(plan.plan_id, "after-withdrawal", epoch))


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
    revision : int or None
        Which revision of the job's plan ``plan_id`` is (1: the fast plan).
    final : bool
        No further revision of this job will follow.
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
    revision: int | None = None
    final: bool = False

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
        ``run_scheduler``-compatible function ``(problem, solver,
        should_stop) -> ScheduleResult`` (default
        :func:`mushrooms.scheduler_core.planner.run_scheduler`).
    sky_cache : SkyCache, optional
        The daemon's warm grid, footprints and per-night visibility
        (:mod:`.warm`); without it every job computes its own.
    on_outbox : callable, optional
        Called (instead of publishing in the planning thread) whenever a
        message was queued in the outbox: the daemon's outbox drain.
    """

    def __init__(self, config: Config, store: Store, sink: Sink, planner: Planner | None = None,
                 sky_cache: Any = None, on_outbox: Callable[[], None] | None = None):
        self.config = config
        self.store = store
        self.sink = sink
        if planner is None:
            from ..scheduler_core.planner import run_scheduler as planner
        self._scheduler = planner
        self._cache = sky_cache
        self._on_outbox = on_outbox
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

        localization = None
        if verdict.keep and not alert.is_retraction:
            localization = choose_localization(
                alert, policy.use_combined_skymap,
                # headers only (bounded, milliseconds): the full decode is the job's, off the consume loop
                check=lambda data: check_skymap_header(data, max_bytes=policy.max_skymap_bytes))
            if localization is not None and localization.note and localization.kind == "gw" \
                    and alert.external_coinc is not None:
                log.warning("notice origin=%s superevent_id=%s: %s", origin, alert.superevent_id, localization.note)

        nid, decision, job, cancelled, key = self.store.record_decision(
            record,
            lambda ledger: decide(alert, verdict, ledger, localization),
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
    def run_job(self, job: Job, should_stop: Callable[[], bool] | None = None,
                staged: bool = False) -> "Outcome | Staged":
        """Plan one accepted job: publish a first plan at once, then optimise.

        The fast scheduler's plan is checked, stored and queued as revision
        1; then ``config.scheduler.solver`` optimises within what
        ``should_stop`` allows, and its plan is published as revision 2
        (superseding revision 1) only when it covers more by
        ``[daemon] supersede_min_gain``; otherwise a ``plan_final`` message
        says that revision 1 stands.  A job whose solver is the fast one is
        done after revision 1 (``final: true``).

        Parameters
        ----------
        job : Job
            From :meth:`accept` or :meth:`Store.pending_jobs`.
        should_stop : callable, optional
            Polled at every stage and by the schedulers.  When it is True
            and the store says the job was superseded or cancelled, the job
            ends at the next stage (nothing stored); otherwise (the job's
            deadline) the fast plan is still completed and the optimiser
            returns its best plan so far.
        staged : bool
            Return a :class:`~.jobs.Staged` after revision 1 (the
            optimisation is then run by whoever calls its ``run``: the
            daemon queues it behind newer events' first plans) instead of
            optimising here.

        Returns
        -------
        Outcome or Staged
            ``plan``/``rerun`` with plan_id, coverage, latency, revision;
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
            if state.startswith("done") and self.store.pending_outbox(limit=1):
                self._hand_over(-1)  # the give-up closed it on its stored revision: plan_final is queued
            log.info("job superevent_id=%s job=%s decision=%s reason=%r", job.superevent_id, job.job_id, decision,
                     reason)
            return Outcome(decision, reason=reason, **base)
        try:
            work = self._first_plan(started, should_stop)
        except _Cancelled as exc:
            return self._dropped(started, f"stopped before {exc}", base)
        except (NoticeError, InputError) as exc:  # SkyMapError is an InputError
            return self._job_failed(started, "rejected", str(exc), base)
        except PlanCheckError as exc:
            return self._job_failed(started, "failed", str(exc), base)
        except Exception as exc:
            log.exception("job superevent_id=%s job=%s decision=failed internal error", job.superevent_id, job.job_id)
            return self._job_failed(started, "failed", f"internal error: {type(exc).__name__}: {exc}", base)
        if isinstance(work, Outcome):
            return work
        if staged:
            from .jobs import Staged

            # waiting for an optimisation slot is not a start: a kill meanwhile is not this job's crash
            self.store.park_job(job.job_id)

            def optimise(stop: Callable[[], bool] | None) -> Outcome:
                if not self.store.resume_job(job.job_id):
                    return self._dropped(started, "optimisation not started", base)
                return self._optimise(work, stop)

            return Staged(work.outcome, optimise)
        return self._optimise(work, should_stop)

    def _cancelled(self, job: Job, should_stop: Callable[[], bool] | None) -> bool:
        """Stop requested and the store no longer has the job running (superseded, retracted)."""
        return bool(should_stop is not None and should_stop()) and self.store.job_status(job.job_id) != "running"

    def _first_plan(self, job: Job, should_stop: Callable[[], bool] | None) -> "_Work | Outcome":
        from ..scheduler_core import not_observable, read_skymap
        from ..scheduler_core.anytime import FIRST_SOLVER, checked_plan
        from ..scheduler_core.clock import on_merger_clock
        from ..scheduler_core.plan.document import parse_time

        def stage(name: str) -> None:
            if self._cancelled(job, should_stop):
                raise _Cancelled(name)

        t0 = time.perf_counter()
        took: dict[str, float] = {}

        def lap(name: str) -> None:
            took[name] = time.perf_counter() - t0 - sum(took.values())

        skymap_bytes, event = self._skymap_bytes(job)
        sched = self.config.scheduler
        stage("reading the sky map")
        try:
            skymap = read_skymap(skymap_bytes, nside=sched.nside, max_bytes=self.config.policy.max_skymap_bytes)
        except InputError as exc:
            gw = self._gw_fallback(job, event)
            if gw is None:
                raise
            log.warning("job superevent_id=%s job=%s: combined sky map unusable (%s); planning on the GW map",
                        job.superevent_id, job.job_id, exc)
            try:  # the decision (taken on the headers) said "combined map": keep why the job did otherwise
                self.store.record_incident("combined_map_unusable", {
                    "superevent_id": job.superevent_id, "job_id": job.job_id, "notice_id": job.notice_id,
                    "reason": f"combined sky map unusable ({exc}); planned on the GW map"})
            except Exception as store_exc:
                log.error("event=incident_not_stored kind=combined_map_unusable error=%r", str(store_exc))
            skymap_bytes, event = gw
            skymap = read_skymap(skymap_bytes, nside=sched.nside, max_bytes=self.config.policy.max_skymap_bytes)
        skymap, event = on_merger_clock(skymap, event)  # the kilonova's clock: the notice's merger time
        lap("read")
        stage("preparing the problem")
        start = parse_time(job.start)
        problem = self._cache.prepare(skymap, sched, start) if self._cache is not None else \
            self._prepare(skymap, sched, start)
        lap("prepare")
        t_prep = time.perf_counter() - t0
        stage("the fast scheduler")
        result = self._scheduler(problem, FIRST_SOLVER, lambda: self._cancelled(job, should_stop))
        lap("greedy")
        stage("checking the fast plan")
        supersedes = job.supersedes
        plan = checked_plan(problem, result, skymap, FIRST_SOLVER, event=event, supersedes=supersedes,
                            runtime_s=time.perf_counter() - t0)
        lap("check")
        plan = _after_withdrawals(plan, self.store.plan_epoch(job.job_id))
        if plan.supersedes == plan.plan_id:
            plan = plan.with_(supersedes=None)
        # too little coverage: the answer published is the not_observable document, in the plan's place
        answer = not_observable(plan, skymap, sched)
        if answer is not None:
            log.warning("job superevent_id=%s job=%s %s", job.superevent_id, job.job_id, answer.summary)
            plan = answer
        log.info("job superevent_id=%s job=%s first_plan_stages %s", job.superevent_id, job.job_id,
                 " ".join(f"{k}_s={v:.3f}" for k, v in took.items()))
        stage("storing the fast plan")
        final = sched.solver == FIRST_SOLVER or job.fallback
        if job.fallback:  # the optimiser died too often on this job: the fast scheduler's plan still goes out
            log.warning("job superevent_id=%s job=%s fallback=greedy reason='%d starts died'", job.superevent_id,
                        job.job_id, job.attempts - 1)
        if (dataclasses.is_dataclass(skymap) and getattr(skymap, "distmu", None) is not None
                and sched.objective != "detection"):
            # the coverage optimisation needs the probability only: a burst of queued jobs must not
            # hold three distance layers (3 x 6 MB at nside 256) each; the detection objective needs them
            skymap = dataclasses.replace(skymap, distmu=None, distsigma=None, distnorm=None)
        work = _Work(job, skymap, problem, event, plan, t_prep)
        if job.fallback and any(r["plan_id"] == plan.plan_id and not r["final"]
                                for r in self.store.job_plans(job.job_id)):
            # revision 1 went out (final: false) before the optimiser died: it stands, and plan_final says so
            return self._close_with_first(work, f"the optimiser died in {job.attempts - 1} starts; "
                                                f"the fast plan stands")
        outcome = self._publish_revision(work, plan, 1, final)
        if outcome.decision == "ignore" or final:
            return outcome
        work.outcome = outcome
        return work

    def _optimise(self, work: "_Work", should_stop: Callable[[], bool] | None) -> Outcome:
        """Run the configured solver; publish revision 2 if better by the margin, else ``plan_final``."""
        from ..scheduler_core import not_observable
        from ..scheduler_core.anytime import checked_plan, is_better
        from ..scheduler_core.planner import optimise

        job, first = work.job, work.first
        base = dict(superevent_id=job.superevent_id, alert_type=job.alert_type, job_id=job.job_id,
                    notice_id=job.notice_id)
        solver = self.config.scheduler.solver
        if self.store.job_status(job.job_id) != "running" or self._cancelled(job, should_stop):
            return self._dropped(job, "optimisation not started", base)
        t0 = time.perf_counter()
        why = ""
        try:
            result = optimise(work.problem, work.skymap, solver, should_stop, scheduler=self._scheduler)
            if self._cancelled(job, should_stop):
                return self._dropped(job, f"optimisation ({solver}) stopped", base)
            better = checked_plan(work.problem, result, work.skymap, solver, event=work.event,
                                  supersedes=first.plan_id, runtime_s=time.perf_counter() - t0)
            better = _after_withdrawals(better, self.store.plan_epoch(job.job_id))
        except PlanCheckError as exc:  # revision 1 stands; the optimiser's plan is never published
            log.error("job superevent_id=%s job=%s optimised plan refused by the checker: %s", job.superevent_id,
                      job.job_id, exc)
            better, why = None, f"the {solver} plan failed the checker"
        except Exception as exc:
            log.exception("job superevent_id=%s job=%s optimisation failed", job.superevent_id, job.job_id)
            better, why = None, f"the {solver} optimisation failed: {type(exc).__name__}: {exc}"
        gain = self.config.daemon.supersede_min_gain
        sched = self.config.scheduler
        if better is not None and not_observable(better, work.skymap, sched) is not None:
            better, why = None, (f"{solver} covered {better.metrics.coverage:.4f}: still below min_coverage "
                                 f"{sched.min_coverage:g}")
        if better is not None and better.plan_id != first.plan_id and is_better(
                better, first, gain, sched.objective, sched.detection_max_coverage_loss):
            return self._publish_revision(work, better, 2, True)
        if better is not None:
            why = (f"{solver} covered {better.metrics.coverage:.4f} against {first.metrics.coverage:.4f}: "
                   f"less than supersede_min_gain {gain:g} more")
            e_new, e_old = better.metrics.expected_detections, first.metrics.expected_detections
            if sched.objective == "detection" and e_new is not None and e_old is not None:
                why = (f"{solver} expects {e_new:.4f} detections against {e_old:.4f} (coverage "
                       f"{better.metrics.coverage:.4f} against {first.metrics.coverage:.4f}): not "
                       f"supersede_min_gain {gain:g} more within the coverage floor "
                       f"(detection_max_coverage_loss {sched.detection_max_coverage_loss:g}), nor a tie "
                       f"on detections with that much more coverage")
        return self._close_with_first(work, why)

    def _publish_revision(self, work: "_Work", plan: Any, revision: int, final: bool) -> Outcome:
        """Store one revision (and queue it), then have it published."""
        from ..scheduler_core.anytime import revision_document

        job = work.job
        base = dict(superevent_id=job.superevent_id, alert_type=job.alert_type, job_id=job.job_id,
                    notice_id=job.notice_id)
        latency = round(time.time() - job.received_wall, 3)
        plan = plan.with_(metrics=dataclasses.replace(plan.metrics, latency_s=latency))
        doc = revision_document(plan, revision, final)
        coverage = float(plan.metrics.coverage)
        outbox_id = self.store.store_revision(job.job_id, plan.plan_id, doc, coverage, latency, final, revision)
        if outbox_id is None:
            return self._dropped(job, f"plan {plan.plan_id} (revision {revision}) dropped", base, plan.plan_id)
        published = self._hand_over(outbox_id)
        log.info("job superevent_id=%s job=%s decision=%s plan_id=%s revision=%d final=%s coverage=%.4f "
                 "latency_s=%.3f supersedes=%s published=%s solver=%s", job.superevent_id, job.job_id,
                 job.decision, plan.plan_id, revision, str(final).lower(), coverage, latency,
                 plan.supersedes or "-", published, plan.metrics.solver)
        summary = getattr(plan, "summary", None) or f"{plan.metrics.n_fields} fields, {plan.metrics.n_exposures} exposures"
        return Outcome(job.decision, reason=summary,
                       plan_id=plan.plan_id, coverage=coverage, latency_s=latency, supersedes=plan.supersedes,
                       published=published, revision=revision, final=final, **base)

    def _close_with_first(self, work: "_Work", why: str) -> Outcome:
        job, first = work.job, work.first
        base = dict(superevent_id=job.superevent_id, alert_type=job.alert_type, job_id=job.job_id,
                    notice_id=job.notice_id)
        outbox_id = self.store.close_job(job.job_id, first.plan_id, why)
        if outbox_id is None:
            return self._dropped(job, "optimisation finished", base, first.plan_id)
        published = self._hand_over(outbox_id)
        log.info("job superevent_id=%s job=%s decision=%s plan_id=%s revision=1 final=true reason=%r published=%s",
                 job.superevent_id, job.job_id, job.decision, first.plan_id, why, published)
        return Outcome(job.decision, reason=why, plan_id=first.plan_id, coverage=float(first.metrics.coverage),
                       latency_s=work.outcome.latency_s if work.outcome else None, supersedes=first.supersedes,
                       published=published, revision=1, final=True, **base)

    def _dropped(self, job: Job, what: str, base: dict[str, Any], plan_id: str | None = None) -> Outcome:
        reason = f"{what}: job {self.store.describe_job(job.job_id)}"
        log.info("job superevent_id=%s job=%s decision=ignore reason=%r", job.superevent_id, job.job_id, reason)
        return Outcome("ignore", reason=reason, plan_id=plan_id, **base)

    def _hand_over(self, outbox_id: int) -> bool:
        """Have the outbox published: by the daemon's drain (``on_outbox``), else here."""
        if self._on_outbox is not None:
            self._on_outbox()
            return False
        self.flush_outbox()
        return self._published(outbox_id)

    def _skymap_bytes(self, job: Job) -> tuple[bytes, Any]:
        from ..scheduler_core import EventInfo

        raw = self.store.notice_raw(job.notice_id)
        if raw is None:
            raise RuntimeError(f"notice {job.notice_id} of job {job.job_id} has no stored bytes")
        if is_fits(raw):  # a bare sky map handed in by ``mushrooms trigger``
            return raw, EventInfo(skymap_sha256=job.skymap_sha256)
        alert = parse_notice(raw)
        assert alert.event is not None
        found = skymap_for_sha(alert, job.skymap_sha256)
        if found is None:  # a job recorded before joint maps were told apart: the GW map
            found = ("gw", alert.event.skymap)
        kind, skymap_bytes = found
        return skymap_bytes, EventInfo(superevent_id=alert.superevent_id, alert_type=alert.alert_type,
                                       time_created=iso_z(alert.time_created),
                                       skymap_sha256=hashlib.sha256(skymap_bytes).hexdigest(), localization=kind,
                                       external_coinc=coincidence_summary(alert.external_coinc),
                                       event_time=iso_z(alert.event.time))  # the merger clock (issue 24)

    def _gw_fallback(self, job: Job, event: Any) -> tuple[bytes, Any] | None:
        """The notice's GW map (and event) when the job's map was its joint map; else None."""
        if getattr(event, "localization", None) != "combined":
            return None
        raw = self.store.notice_raw(job.notice_id)
        alert = parse_notice(raw) if raw else None
        if alert is None or alert.event is None or not alert.event.skymap:
            return None
        data = alert.event.skymap
        return data, dataclasses.replace(event, localization="gw", skymap_sha256=hashlib.sha256(data).hexdigest())

    @staticmethod
    def _prepare(skymap: Any, config: Any, start: Any) -> Any:
        from ..scheduler_core.prepare import prepare_problem

        return prepare_problem(skymap, config, start)

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
                log.info("publish key=%s kind=%s superevent_id=%s ok queued_s=%s", message_key(msg.message), msg.kind,
                         msg.message.get("superevent_id") or (msg.message.get("event") or {}).get("superevent_id"),
                         _age_s(msg.created_at))
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

        return self._record_rerun(record, alert, "manual rerun requested", origin, now, wall, logging.INFO)

    def _record_rerun(self, record: NoticeRecord, alert: Alert, reason: str, origin: str, now: datetime,
                      wall: float, level: int) -> Accepted:
        """Store an operator's ``rerun`` of a notice: no policy, supersedes the event's latest plan."""
        sid = alert.superevent_id
        loc = choose_localization(alert, self.config.policy.use_combined_skymap)
        sha, kind = (loc.sha256, loc.kind) if loc is not None else (alert.skymap_sha256, "gw")

        def dec(ledger: Any) -> Decision:
            st = ledger.event_state(sid)
            latest = st.latest_plan_id if st is not None else None
            return Decision("rerun", sid, f"{reason} ({kind} map)", alert.alert_type, sha,
                            supersedes=latest, localization=kind, time_created=iso_z(alert.time_created))

        nid, decision, job, cancelled, _ = self.store.record_decision(
            record, dec, lambda d: self._plan_start(alert, now), received_wall=wall)
        log.log(level, "trigger origin=%s superevent_id=%s decision=%s reason=%r%s", origin, sid, decision.action,
                decision.reason, f" job={job.job_id}" if job else "")
        return Accepted(decision.action, sid, decision.reason, nid, alert.alert_type, job, tuple(cancelled))

    def force_plan(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a notice past the policy and the duplicate check (``mushrooms trigger --force``).

        The notice is stored like any other; the decision is ``rerun`` (it
        supersedes the event's latest plan, if any) with the reason
        ``forced by operator``.  A notice without a sky map is rejected.
        """
        wall = time.time()
        now = _aware(received_at)
        raw = bytes(raw)
        sha = hashlib.sha256(raw).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(raw), received_at=iso_z(now))
        try:
            alert = parse_notice(raw, max_bytes=self.config.policy.max_notice_bytes)
        except NoticeError as exc:
            nid = self.store.record_rejected(record, str(exc))
            return Accepted("rejected", None, str(exc), nid)
        sid = alert.superevent_id
        if alert.event is None or not alert.event.skymap:
            reason = "forced, but the notice has no sky map to plan"
            nid = self.store.record_rejected(dataclasses.replace(record, superevent_id=sid), reason)
            return Accepted("rejected", sid, reason, nid, alert.alert_type)
        record = dataclasses.replace(record, superevent_id=sid, alert_type=alert.alert_type,
                                     time_created=iso_z(alert.time_created), raw=raw)
        return self._record_rerun(record, alert, "forced by operator", origin, now, wall, logging.WARNING)

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
        limit = self.config.policy.max_skymap_bytes
        if len(data) > limit or not is_fits(data):
            reason = f"sky map of {len(data)} bytes, more than [policy] max_skymap_bytes = {limit} (gzip it)" \
                if is_fits(data) else "not a FITS sky map"
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
