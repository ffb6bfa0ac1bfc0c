"""Planning: one accepted job through :mod:`mushrooms.scheduler_core.anytime`, revision by revision.

::

    job ─ sky map ▸ prepare (warm cache) ▸ anytime.first_plan ▸ store revision 1 + outbox
        ─ anytime.optimised_plan ▸ anytime.supersession (supersede_min_gain) ? revision 2 : plan_final

The flow is :mod:`~mushrooms.scheduler_core.anytime`'s (the one
``mushrooms plan --deadline`` runs); what is the daemon's own here is the
store (revisions, job states), the stop checks between stages, and the
documents (:mod:`mushrooms.scheduler_core.plan.messages`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from dataclasses import dataclass
from typing import Any, Callable

from ...handlers.alert import NoticeError, parse_notice
from ...handlers.instants import iso_z
from ...handlers.localization import coincidence_summary, skymap_for_sha
from ...handlers.policy import PolicyConfig
from ...scheduler_core.errors import InputError, PlanCheckError
from ...scheduler_core.plan.messages import combined_map_incident, revision_document
from ...scheduler_core.sky.sniff import is_fits
from .nights import night_one
from ..outcomes import Outcome
from ..state.records import JobState
from ..state.store import Job, Store

__all__ = ["JobPlanner"]

log = logging.getLogger("mushrooms.daemon.pipeline")

StopCheck = Callable[[], bool]


class _Cancelled(Exception):
    """The job was superseded or retracted; the message names the stage it stopped before."""


class _UnreadableNotice(Exception):
    """The job's notice or its sky map cannot be read: the notice's fault (``rejected``); the message says why."""


def _config_problem(exc: Exception, planning: Any, superevent_id: str | None) -> str:
    """Why a job whose notice and sky map were read failed on bad input: the configuration's fault, in words.

    After the map is read, what feeds the plan is the configuration and the
    files it names (a ``detection_lightcurve`` edited or removed after the
    service loaded it, a filter sequence a scheduler does not plan).  The job
    is recorded ``failed`` (not ``rejected``): the event forgets the map's
    hash, so the same notice, or ``mushrooms trigger``, plans it again once
    the configuration is fixed.
    """
    from ...scheduler_core.source.lightcurves import LightCurveError

    key = (f"[scheduler] detection_lightcurve = {str(planning.detection_lightcurve)!r}: "
           if isinstance(exc, LightCurveError) else "")
    again = f"mushrooms trigger {superevent_id}" if superevent_id else "mushrooms trigger"
    return (f"configuration: {key}{exc} (not the notice's fault: fix the configuration or the file it names, "
            f"reload the service (SIGHUP), then re-plan with {again})")


@dataclass
class _Work:
    """A job between its first plan and its optimisation (kept in memory only)."""

    job: Job
    skymap: Any
    problem: Any
    event: Any
    first: Any
    outcome: Outcome | None = None


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
    from ...scheduler_core import make_plan_id

    return plan.with_(plan_id=make_plan_id(plan.plan_id, "after-withdrawal", epoch))


class JobPlanner:
    """Run accepted jobs: revision 1 at once, then the optimisation (revision 2 or ``plan_final``).

    Parameters
    ----------
    policy : PolicyConfig
        ``max_skymap_bytes`` bounds the sky map read.
    planning : PlanningConfig
        ``[scheduler]``: the problem, ``solver``, ``objective``, ``min_coverage``.
    supersede_min_gain : float
        ``[daemon] supersede_min_gain``: what revision 2 must gain.
    store : Store
    scheduler : callable
        ``run_scheduler``-compatible ``(problem, solver, should_stop) -> ScheduleResult``.
    sky_cache : SkyCache or None
        The daemon's warm grids (:mod:`~mushrooms.daemon.planning.warm`).
    hand_over : callable
        ``hand_over(outbox_id) -> published``: have a queued message published.
    loop : LoopConfig, optional
        ``[loop]``: the done rule of a re-plan job (``min_processed_fraction``).
    replanner : callable, optional
        ``plan_remaining``-compatible ``(skymap, config, start, executed, *, event,
        min_processed_fraction, should_stop) -> Plan`` for re-plan jobs (default
        :func:`mushrooms.scheduler_core.replan.plan_remaining`).
    """

    def __init__(self, policy: PolicyConfig, planning: Any, supersede_min_gain: float, store: Store,
                 scheduler: Callable[..., Any], sky_cache: Any, hand_over: Callable[[int], bool],
                 loop: Any = None, replanner: Callable[..., Any] | None = None, parts: Any = None):
        from ..loop_settings import LoopConfig

        self.parts = parts  # the other telescopes' parts (:mod:`.parts`); None: ZTF alone
        self.loop = loop if loop is not None else LoopConfig()
        self._replanner = replanner
        self.policy = policy
        self.planning = planning
        self.gain = supersede_min_gain
        self.store = store
        self.scheduler = scheduler
        self.cache = sky_cache
        self.hand_over = hand_over

    @property
    def replanner(self) -> Callable[..., Any]:
        """What plans the rest of a re-plan job (``plan_remaining`` unless one was given)."""
        if self._replanner is None:
            from ...scheduler_core.replan import plan_remaining

            self._replanner = plan_remaining
        return self._replanner

    # ------------------------------------------------------------ the job
    def run_job(self, job: Job, should_stop: StopCheck | None = None, staged: bool = False) -> Any:
        """See :meth:`~mushrooms.daemon.intake.pipeline.NoticePipeline.run_job`."""
        started = self.store.start_job(job.job_id)
        if started is None:
            state = self.store.describe_job(job.job_id)
            reason = f"job {job.job_id} not run: {state}"
            decision = "failed" if state.startswith("failed") else "ignore"
            if state.startswith("done") and self.store.pending_outbox(limit=1):
                self.hand_over(-1)  # the give-up closed it on its stored revision: plan_final is queued
            log.info("job superevent_id=%s job=%s decision=%s reason=%r", job.superevent_id, job.job_id, decision,
                     reason)
            return Outcome(decision, job.ref, reason)
        try:
            if started.decision == "replan":  # the loop's re-plan: one stage (.replanning)
                from .replan_stage import run_replan

                def stage(name: str) -> None:
                    if self.was_cancelled(started, should_stop):
                        raise _Cancelled(name)

                return run_replan(self, started, stage, should_stop)
            work = self._first_stage(started, should_stop)
        except _Cancelled as exc:
            return self.drop(started, f"stopped before {exc}")
        except _UnreadableNotice as exc:  # the notice or its map (SkyMapError, NoticeError): the notice's fault
            return self._job_failed(started, "rejected", str(exc))
        except InputError as exc:  # read fine, then bad input: the configuration's (or a file it names)
            return self._job_failed(started, "failed", _config_problem(exc, self.planning, job.superevent_id))
        except PlanCheckError as exc:
            return self._job_failed(started, "failed", str(exc))
        except Exception as exc:
            log.exception("job superevent_id=%s job=%s decision=failed internal error", job.superevent_id, job.job_id)
            return self._job_failed(started, "failed", f"internal error: {type(exc).__name__}: {exc}")
        if isinstance(work, Outcome):
            return work
        if staged:
            from .jobs import Staged

            # waiting for an optimisation slot is not a start: a kill meanwhile is not this job's crash
            self.store.park_job(job.job_id)

            def optimise(stop: StopCheck | None) -> Outcome:
                if not self.store.resume_job(job.job_id):
                    return self.drop(started, "optimisation not started")
                return self._second_stage(work, stop)

            return Staged(work.outcome, optimise)
        return self._second_stage(work, should_stop)

    def was_cancelled(self, job: Job, should_stop: StopCheck | None) -> bool:
        """Stop requested and the store no longer has the job running (superseded, retracted)."""
        return bool(should_stop is not None and should_stop()) and self.store.job_status(job.job_id) != JobState.RUNNING

    def _first_stage(self, job: Job, should_stop: StopCheck | None) -> "_Work | Outcome":
        from ...scheduler_core import not_observable
        from ...scheduler_core.anytime import FIRST_SOLVER, first_plan
        from ...scheduler_core.plan.document import parse_time

        def stage(name: str) -> None:
            if self.was_cancelled(job, should_stop):
                raise _Cancelled(name)

        t0 = time.perf_counter()
        took: dict[str, float] = {}

        def lap(name: str) -> None:
            took[name] = time.perf_counter() - t0 - sum(took.values())

        sched = self.planning
        skymap, event = self.read_skymap(job, stage)  # on the kilonova's clock: the notice's merger time
        lap("read")
        stage("preparing the problem")
        start = parse_time(job.start)
        sched = night_one(sched, start)  # (L9) nights > 1: the alert's plan is night 1's, to its morning twilight
        if self.cache is not None:
            problem = self.cache.prepare(skymap, sched, start)
        else:
            from ...scheduler_core.prepare import prepare_problem

            problem = prepare_problem(skymap, sched, start)
        lap("prepare")
        stage("the fast scheduler")
        plan = first_plan(problem, skymap, event=event, supersedes=job.supersedes,
                          should_stop=lambda: self.was_cancelled(job, should_stop), scheduler=self._checked_stage(
                              "checking the fast plan", stage, lap), started=t0)
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
        work = _Work(job, skymap, problem, event, plan)
        if self.parts is not None:  # every other telescope's part, before ZTF's revision 1 (a restart redoes the rest)
            stage("the other telescopes' parts")
            self._export_parts(work, plan, should_stop, final)
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

    def _checked_stage(self, name: str, stage: Callable[[str], None],
                       lap: Callable[[str], None]) -> Callable[..., Any]:
        """The scheduler, timed as ``greedy``, with the stop check ``name`` before the plan check."""
        def run(problem: Any, solver: str, stop: StopCheck | None) -> Any:
            result = self.scheduler(problem, solver, stop)
            lap("greedy")
            stage(name)
            return result

        return run

    def read_skymap(self, job: Job, stage: Callable[[str], None]) -> tuple[Any, Any]:
        """The job's sky map, decoded (the notice's GW map when its joint map does not decode), and its event,
        both on the merger clock (:func:`~mushrooms.scheduler_core.clock.on_merger_clock`).

        Raises
        ------
        _UnreadableNotice
            The notice, its map or its times cannot be read (what blames the
            notice: every other bad input of a job is the configuration's).
        """
        from ...scheduler_core.clock import on_merger_clock

        try:
            return on_merger_clock(*self._read_skymap(job, stage))  # the kilonova's clock: the notice's merger time
        except (NoticeError, InputError) as exc:  # SkyMapError is an InputError
            raise _UnreadableNotice(str(exc)) from exc

    def _read_skymap(self, job: Job, stage: Callable[[str], None]) -> tuple[Any, Any]:
        from ...scheduler_core import read_skymap

        skymap_bytes, event = self._skymap_bytes(job)
        stage("reading the sky map")
        nside, limit = self.planning.nside, self.policy.max_skymap_bytes
        try:
            return read_skymap(skymap_bytes, nside=nside, max_bytes=limit), event
        except InputError as exc:
            gw = self._gw_fallback(job, event)
            if gw is None:
                raise
            log.warning("job superevent_id=%s job=%s: combined sky map unusable (%s); planning on the GW map",
                        job.superevent_id, job.job_id, exc)
            try:  # the decision (taken on the headers) said "combined map": keep why the job did otherwise
                self.store.record_incident("combined_map_unusable", combined_map_incident(
                    job.superevent_id, job.job_id, job.notice_id, str(exc)))
            except Exception as store_exc:
                log.error("event=incident_not_stored kind=combined_map_unusable error=%r", str(store_exc))
            skymap_bytes, event = gw
            return read_skymap(skymap_bytes, nside=nside, max_bytes=limit), event

    def _second_stage(self, work: _Work, should_stop: StopCheck | None) -> Outcome:
        """Run the configured solver; revision 2 or ``plan_final``, as ``anytime.supersession`` decides."""
        from ...scheduler_core.anytime import optimised_plan, supersession

        job, first, sched = work.job, work.first, self.planning
        solver = sched.solver
        if self.store.job_status(job.job_id) != JobState.RUNNING or self.was_cancelled(job, should_stop):
            return self.drop(job, "optimisation not started")
        why = ""
        try:
            better = optimised_plan(work.problem, work.skymap, solver, first, event=work.event,
                                    should_stop=should_stop, scheduler=self.scheduler,
                                    interrupted=lambda: self.was_cancelled(job, should_stop))
            if better is None:
                return self.drop(job, f"optimisation ({solver}) stopped")
            better = _after_withdrawals(better, self.store.plan_epoch(job.job_id))
        except PlanCheckError as exc:  # revision 1 stands; the optimiser's plan is never published
            log.error("job superevent_id=%s job=%s optimised plan refused by the checker: %s", job.superevent_id,
                      job.job_id, exc)
            better, why = None, f"the {solver} plan failed the checker"
        except Exception as exc:
            log.exception("job superevent_id=%s job=%s optimisation failed", job.superevent_id, job.job_id)
            better, why = None, f"the {solver} optimisation failed: {type(exc).__name__}: {exc}"
        decided = supersession(first, better, work.skymap, sched, self.gain)
        if decided.revision == 2:
            # the other telescopes' parts around revision 2, before it closes the job (a restart redoes the rest)
            self._export_parts(work, decided.plan, should_stop)
            return self._publish_revision(work, decided.plan, 2, True)
        self._export_parts(work, first, should_stop)  # revision 1 stands: its parts (nothing to do unless a killed
        # attempt planned parts around a revision 2 it never published)
        if decided.reason == "below_min_coverage":
            why = f"{solver} covered {better.metrics.coverage:.4f}: still below min_coverage {sched.min_coverage:g}"
        elif decided.reason == "not_better":
            from .final_words import first_plan_stands

            why = first_plan_stands(solver, better, first, self.gain, sched.objective,
                                    sched.detection_max_coverage_loss)
        return self._close_with_first(work, why)

    def _export_parts(self, work: _Work, plan: Any, should_stop: StopCheck | None, final: bool = True) -> None:
        """The other telescopes' parts planned around ZTF's revision ``plan`` (none for ZTF alone).

        ``final``: ``plan`` is the job's last revision.  Their failure never
        costs ZTF's revision: logged, and the job goes on.
        """
        if self.parts is None or work.problem is None:
            return
        from ...scheduler_core.plan.document import parse_time

        job = work.job
        try:
            self.parts.export_job(self.store, job, work.skymap, work.event, parse_time(job.start),
                                  (plan, work.problem), lambda: self.was_cancelled(job, should_stop), final)
        except Exception:
            log.exception("job superevent_id=%s job=%s: the other telescopes' parts failed", job.superevent_id,
                          job.job_id)

    # ------------------------------------------------------------ store + outbox
    def publish_final(self, job: Job, skymap: Any, event: Any, plan: Any, revision: int) -> Outcome:
        """Store ``plan`` as the job's final revision ``revision`` (a re-plan's one stage) and have it published."""
        return self._publish_revision(_Work(job, skymap, None, event, plan), plan, revision, True)

    def _publish_revision(self, work: _Work, plan: Any, revision: int, final: bool) -> Outcome:
        """Store one revision (and queue it), then have it published."""
        job = work.job
        latency = round(time.time() - job.received_wall, 3)
        plan = plan.with_(metrics=dataclasses.replace(plan.metrics, latency_s=latency))
        doc = revision_document(plan, revision, final)
        coverage = float(plan.metrics.coverage)
        outbox_id = self.store.store_revision(job.job_id, plan.plan_id, doc, coverage, latency, final, revision)
        if outbox_id is None:
            return self.drop(job, f"plan {plan.plan_id} (revision {revision}) dropped", plan.plan_id)
        published = self.hand_over(outbox_id)
        log.info("job superevent_id=%s job=%s decision=%s plan_id=%s revision=%d final=%s coverage=%.4f "
                 "latency_s=%.3f supersedes=%s published=%s solver=%s", job.superevent_id, job.job_id,
                 job.decision, plan.plan_id, revision, str(final).lower(), coverage, latency,
                 plan.supersedes or "-", _published_word(published), plan.metrics.solver)
        summary = getattr(plan, "summary", None) or f"{plan.metrics.n_fields} fields, {plan.metrics.n_exposures} exposures"
        return Outcome(job.decision, job.ref, summary, plan_id=plan.plan_id, coverage=coverage, latency_s=latency,
                       supersedes=plan.supersedes, published=bool(published), revision=revision, final=final)

    def _close_with_first(self, work: _Work, why: str) -> Outcome:
        job, first = work.job, work.first
        outbox_id = self.store.close_job(job.job_id, first.plan_id, why)
        if outbox_id is None:
            return self.drop(job, "optimisation finished", first.plan_id)
        published = self.hand_over(outbox_id)
        log.info("job superevent_id=%s job=%s decision=%s plan_id=%s revision=1 final=true reason=%r published=%s",
                 job.superevent_id, job.job_id, job.decision, first.plan_id, why, _published_word(published))
        return Outcome(job.decision, job.ref, why, plan_id=first.plan_id, coverage=float(first.metrics.coverage),
                       latency_s=work.outcome.latency_s if work.outcome else None, supersedes=first.supersedes,
                       published=bool(published), revision=1, final=True)

    def drop(self, job: Job, what: str, plan_id: str | None = None) -> Outcome:
        reason = f"{what}: job {self.store.describe_job(job.job_id)}"
        log.info("job superevent_id=%s job=%s decision=ignore reason=%r", job.superevent_id, job.job_id, reason)
        return Outcome("ignore", job.ref, reason, plan_id=plan_id)

    def _job_failed(self, job: Job, decision: str, reason: str) -> Outcome:
        try:
            self.store.fail_job(job.job_id, reason, retry_same_map=(decision == "failed"))
        except Exception:
            log.exception("job superevent_id=%s job=%s: could not record the failure", job.superevent_id, job.job_id)
        log.warning("job superevent_id=%s job=%s decision=%s reason=%r", job.superevent_id, job.job_id,
                    decision, reason)
        return Outcome(decision, job.ref, reason)

    # ------------------------------------------------------------ the sky map
    def _skymap_bytes(self, job: Job) -> tuple[bytes, Any]:
        from ...scheduler_core import EventInfo

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
                                       event_time=iso_z(alert.event.time),  # the merger clock
                                       classification=dict(alert.event.classification) or None,
                                       far_hz=float(alert.event.far))

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


def _published_word(published: bool | None) -> str:
    """``true``, ``false``, or ``queued`` (handed to the daemon's outbox drain, which publishes it and logs that)."""
    return "queued" if published is None else str(bool(published)).lower()
