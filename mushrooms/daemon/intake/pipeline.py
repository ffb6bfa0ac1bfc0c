"""The path every notice takes, shared by the daemon and ``mushrooms replay``.

::

    raw bytes ─ accept ─► size cap ▸ parse ▸ policy ▸ decide ─► store (one transaction)   (.intake)
                                                               │
           run_job ◄─ Job (plan / rerun) ◄─────────────────────┘
              │  sky map ▸ prepare (warm cache) ▸ anytime.first_plan ▸ store revision 1 + outbox  (.planning)
              │  anytime.optimised_plan ▸ revision 2 if better by supersede_min_gain, else plan_final
              ▼
          flush_outbox ─► sink.publish (plan document / plan_final / withdrawal)               (here)

:class:`NoticePipeline` joins three parts: :class:`~mushrooms.daemon.intake.accept.Intake`
(parse, decide, store), :class:`~mushrooms.daemon.planning.revisions.JobPlanner` (the anytime flow of
:mod:`mushrooms.scheduler_core.anytime`, the one ``mushrooms plan
--deadline`` runs) and the outbox flush.  Every outbound document is built
by :mod:`mushrooms.scheduler_core.plan.messages`; the results are
:mod:`~mushrooms.daemon.outcomes`.  It takes the configuration's sections, not the whole
configuration.

Anytime plans
-------------
Every job publishes its fast (greedy) plan at once as revision 1
(``revision: 1``, ``final: false`` unless the configured solver is greedy),
then runs ``[scheduler] solver`` (and the detection stage when the
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
   (``sqlite3.Error``, :class:`~mushrooms.daemon.state.store.StoreError`) raises.
2. If ``acc.job`` is set, run ``pipeline.run_job(acc.job, should_stop,
   staged=True)`` in a worker: it returns after revision 1 with a
   :class:`~mushrooms.daemon.planning.jobs.Staged` whose ``run`` is the optimisation (the
   :class:`~mushrooms.daemon.planning.jobs.JobRunner` queues it behind newer first plans).
   ``acc.cancelled_jobs`` lists older jobs of the same superevent that the
   store has just superseded or cancelled: stop them.
3. With ``on_outbox`` (the daemon's :class:`~mushrooms.daemon.planning.jobs.OutboxDrain`) planning
   threads never publish: they queue and kick the drain.  Without it
   (replay, ``mushrooms trigger`` with no daemon) ``run_job`` publishes
   inline and optimises inline.
4. At start: ``flush_outbox()`` then ``run_job`` on ``store.pending_jobs()``
   (accepted but not finished; :meth:`NoticePipeline.resume` does both).

Plan ids are stable: a job's horizon start is fixed at accept time, and a
plan id hashes the map, start, configuration, solver and superevent, so a
job re-run after a crash produces the same ids; a revision the job already
stored is not queued again (:meth:`~mushrooms.daemon.state.store.Store.store_revision`).
"""

from __future__ import annotations

import logging
import threading
from datetime import datetime, timezone
from typing import Any, Callable

from ...handlers.instants import iso_z
from ...handlers.policy import PolicyConfig
from .accept import Intake
from ..outcomes import Accepted, EventRef, Outcome
from ..settings import DaemonConfig
from ..sinks import Sink, message_key
from ..state.store import Job, Store

__all__ = ["NoticePipeline", "Accepted", "Outcome", "EventRef", "iso_z"]

log = logging.getLogger("mushrooms.daemon.pipeline")

Planner = Callable[..., Any]


def _age_s(iso: str | None) -> str:
    """Seconds since an ISO-8601 UTC time (``-`` when unknown), for log lines."""
    if not iso:
        return "-"
    try:
        return f"{(datetime.now(timezone.utc) - datetime.fromisoformat(iso)).total_seconds():.3f}"
    except ValueError:
        return "-"


class NoticePipeline:
    """handlers -> scheduler_core -> plan checker -> store -> sink.

    Parameters
    ----------
    policy : PolicyConfig
        ``[policy]``: cuts, size caps, ``plan_start``, ``use_combined_skymap``.
    planning : PlanningConfig
        ``[scheduler]``: the planning problem and the configured solver.
    store : Store
        Durable state.
    sink : Sink
        Outbound messages.
    daemon : DaemonConfig, optional
        ``[daemon]``: ``supersede_min_gain`` (default the built-in section).
    planner : callable, optional
        ``run_scheduler``-compatible function ``(problem, solver,
        should_stop) -> ScheduleResult`` (default
        :func:`mushrooms.scheduler_core.planner.run_scheduler`).
    sky_cache : SkyCache, optional
        The daemon's warm grid, footprints and per-night visibility
        (:mod:`~mushrooms.daemon.planning.warm`); without it every job computes its own.
    on_outbox : callable, optional
        Called (instead of publishing in the planning thread) whenever a
        message was queued in the outbox: the daemon's outbox drain.
    loop : LoopConfig, optional
        ``[loop]``: the done rule of re-plan jobs (default the built-in section).
    replanner : callable, optional
        What plans the rest of a re-plan job (default
        :func:`mushrooms.scheduler_core.replan.plan_remaining`).
    parts : TelescopeParts, optional
        The other configured telescopes' parts of every job
        (:mod:`~mushrooms.daemon.planning.parts`); None (default): ZTF alone.

    See Also
    --------
    from_config : the same from a whole configuration.
    """

    def __init__(self, policy: PolicyConfig, planning: Any, store: Store, sink: Sink, *,
                 daemon: DaemonConfig | None = None, planner: Planner | None = None,
                 sky_cache: Any = None, on_outbox: Callable[[], None] | None = None, loop: Any = None,
                 replanner: Callable[..., Any] | None = None, parts: Any = None):
        from ..loop_settings import LoopConfig
        from ..planning.revisions import JobPlanner

        self.policy = policy
        self.planning = planning
        self.daemon = daemon if daemon is not None else DaemonConfig()
        self.loop = loop if loop is not None else LoopConfig()
        self.store = store
        self.sink = sink
        if planner is None:
            from ...scheduler_core.planner import run_scheduler as planner
        self._on_outbox = on_outbox
        self._flush_lock = getattr(store, "publish_lock", None) or threading.Lock()
        self.intake = Intake(policy, store)
        self.planner = JobPlanner(policy, planning, self.daemon.supersede_min_gain, store, planner, sky_cache,
                                  self._hand_over, self.loop, replanner, parts)
        self.parts = parts  # [scheduler] telescopes after ztf (:mod:`~mushrooms.daemon.planning.parts`), else None

    @classmethod
    def from_config(cls, config: Any, store: Store, sink: Sink, **kw: Any) -> "NoticePipeline":
        """A pipeline on ``config.policy``, ``config.scheduler``, ``config.daemon`` and ``config.loop`` (a whole Config)."""
        kw.setdefault("loop", getattr(config, "loop", None))
        return cls(config.policy, config.scheduler, store, sink, daemon=config.daemon, **kw)

    # ------------------------------------------------------------ intake
    def accept(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Parse, filter and decide one notice; record it durably (:meth:`~mushrooms.daemon.intake.accept.Intake.accept`).

        Returns
        -------
        Accepted
            Never raises for bad input (``action == "rejected"``).

        Raises
        ------
        sqlite3.Error, StoreError
            Only when the decision cannot be stored.
        """
        return self.intake.accept(raw, origin, received_at)

    def accept_skymap(self, data: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a bare sky map (``mushrooms trigger SKYMAP.fits``; :meth:`~mushrooms.daemon.intake.accept.Intake.accept_skymap`)."""
        return self.intake.accept_skymap(data, origin, received_at)

    def rerun_superevent(self, superevent_id: str, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a superevent again from its newest stored notice (:meth:`~mushrooms.daemon.intake.accept.Intake.rerun_superevent`)."""
        return self.intake.rerun_superevent(superevent_id, origin, received_at)

    def force_plan(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a notice past the policy and the duplicate check (:meth:`~mushrooms.daemon.intake.accept.Intake.force_plan`)."""
        return self.intake.force_plan(raw, origin, received_at)

    def replan_closure(self, superevent_id: str, closed_until: str, origin: str,
                       now: datetime | None = None) -> Accepted:
        """The telescope is closed until ``closed_until``: re-plan the event from the reopening (L6).

        ``mushrooms trigger SUPEREVENT --closed-until TIME``.  The re-plan starts
        at ``max(closed_until, now)`` (``now`` default the wall clock) with what
        was executed counted as done; an open job of the event is superseded.

        Returns
        -------
        Accepted
            ``replan`` with its job, or ``rejected`` (no current plan, a bad time).
        """
        from ...handlers.instants import parse_instant
        from .accept import aware
        from ..planning.replans import record_replan

        sid = superevent_id.strip()
        until = parse_instant(closed_until)
        if until is None:
            why = f"--closed-until {closed_until!r}: not an ISO-8601 UTC time (2026-05-01T03:00:00Z)"
            log.warning("replan superevent_id=%s origin=%s decision=rejected reason=%r", sid or "-", origin, why)
            return Accepted("rejected", EventRef(sid or None), why)
        start = max(aware(until), aware(now))  # (L6)
        return record_replan(self.store, sid, iso_z(start), f"telescope closed until {iso_z(aware(until))} "
                             f"(operator); re-planned from {iso_z(start)}", origin, operator=True,
                             asked_at=iso_z(aware(now)))

    def replan_event(self, superevent_id: str, start: datetime, reason: str, origin: str) -> Accepted:
        """Record the loop's re-plan of an event from ``start`` (the slip rule said so; guards L8)."""
        from .accept import aware
        from ..planning.replans import record_replan

        return record_replan(self.store, superevent_id, iso_z(aware(start)), reason, origin)

    # ------------------------------------------------------------ jobs
    def run_job(self, job: Job, should_stop: Callable[[], bool] | None = None,
                staged: bool = False) -> Any:
        """Plan one accepted job: publish a first plan at once, then optimise.

        The fast scheduler's plan is checked, stored and queued as revision
        1; then ``[scheduler] solver`` optimises within what
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
            Return a :class:`~mushrooms.daemon.planning.jobs.Staged` after revision 1 (the
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
        return self.planner.run_job(job, should_stop, staged)

    def _hand_over(self, outbox_id: int) -> bool | None:
        """Have the outbox published: by the daemon's drain (``on_outbox``: None, not yet known), else here."""
        if self._on_outbox is not None:
            self._on_outbox()
            return None
        self.flush_outbox()
        return self._published(outbox_id)

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
            if self.parts is not None:  # a retraction's withdrawal went out: the other telescopes' parts too
                self.parts.sync(self.store)
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
