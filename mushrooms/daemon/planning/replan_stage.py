"""A re-plan job's one stage: the rest of the event's window, given what was executed (``executed.md`` L7).

::

    replan job ─ sky map (the event's planned notice) ▸ executed since the event's first plan
               ─ scheduler_core.replan.plan_remaining(start = the job's start) ▸ next revision, final

The plan covers ``[start, end of the plan it supersedes]`` (at least one
``[scheduler] time_step_s``, never past that end: L15), so the re-plan fills the rest of
the queue's validity window and no more; with ``[scheduler] nights > 1`` a
re-plan starting inside one of the event's nights covers the rest of that
night, ``[start, e_n]`` (L10).  It is published as the event's
next revision (one more than any it stored, ``final: true``) through the
same store and outbox path as every plan, so the submitter puts it in ZTF's
queue when ``[submit]`` is on.  A re-plan with nothing left to observe
publishes nothing: the current plan stays.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import TYPE_CHECKING, Any, Callable

from ..state.executed import executed_between
from ..outcomes import Outcome
from .nights import night_bounds, plans_as_done
from .replans import close_without_plan, current_plan, next_revision

if TYPE_CHECKING:
    from ..state.store import Job

__all__ = ["run_replan", "REPLAN_SOLVER_NOTE"]

log = logging.getLogger("mushrooms.daemon.pipeline")

#: What a re-plan's plan id is salted with (with its job id: the same job re-run after a crash gives the same id).
REPLAN_SOLVER_NOTE = "replan"


def _since_unix(store: Any, superevent_id: str) -> float | None:
    """Unix time of the event's first job's horizon start: exposures before it are not this event's follow-up."""
    from ...scheduler_core.plan.document import parse_time

    first = store.first_start(superevent_id)
    return None if first is None else float(parse_time(first).unix)


def run_replan(planner: Any, job: "Job", stage: Callable[[str], None],
               should_stop: Callable[[], bool] | None) -> Outcome:
    """Plan what is left of a started re-plan job's event and publish it (or close the job when nothing is).

    Parameters
    ----------
    planner : JobPlanner
        Its store, ``[scheduler]`` and ``[loop]`` sections, sky map reader and publisher.
    job : Job
        Started (``running``), decision ``replan``; ``job.start`` is the re-plan's start.
    stage : callable
        ``stage(name)`` raises when the job was superseded or cancelled meanwhile.
    should_stop : callable or None
        Polled by the scheduler.

    Returns
    -------
    Outcome
        ``replan`` with the new revision, or with no plan when nothing is left.
    """
    from ...scheduler_core import make_plan_id
    from astropy.time import Time

    from ...scheduler_core.plan.document import parse_time
    store, sched = planner.store, planner.planning
    skymap, event = planner.read_skymap(job, stage)  # on the merger clock
    start = parse_time(job.start)
    old = current_plan(store, job.superevent_id)
    if old is None:
        return _nothing(planner, job, "the event has no current plan any more")
    end = parse_time(old["document"]["end"])
    night = night_bounds(store, sched, job.superevent_id, start)  # (L10) nights > 1: the night holding the start
    if night is not None:
        end = Time(night[1], format="unix", scale="utc")
    left_s = float((end - start).to_value("s"))
    if left_s <= 0:
        return _nothing(planner, job, f"the window of {job.supersedes} ends before the re-plan's start {job.start}")
    if left_s < sched.time_step_s:  # (L15) not one time step of the window left
        return _nothing(planner, job, f"the window of {job.supersedes} ends {left_s:.0f} s after the re-plan's "
                        f"start {job.start}, less than one time step")
    # (L7) the rest of the superseded plan's window (L10: of the night), with what was executed since the
    # event's first plan; (L11) with nights > 1 and no executed source, the earlier revisions taken as done
    # (L15) the horizon never passes the window's end: at least one time step, not an hour
    config = dataclasses.replace(sched, horizon_h=min(sched.horizon_h, left_s / 3600.0))
    if sched.nights > 1 and not planner.loop.enabled:
        asked = store.asked_at(job.job_id)  # (L14) a closure: nothing was observed from the closing on
        before = float(start.unix) if asked is None else min(float(start.unix), asked)
        executed = list(plans_as_done(store, job.superevent_id, before))
    else:
        executed = executed_between(store, _since_unix(store, job.superevent_id))
    if sched.revisit and night is not None:  # (N4) revisit: the earlier nights' fields may be observed again
        from ...scheduler_core.nights import counted_for_night

        executed = counted_for_night(executed, Time(night[0], format="unix", scale="utc"), True)
    stage("planning what is left")
    plan = planner.replanner(skymap, config, start, executed, event=event,
                             min_processed_fraction=planner.loop.min_processed_fraction,
                             should_stop=lambda: planner.was_cancelled(job, should_stop), supersedes=job.supersedes)
    stage("storing the re-plan")
    plan = plan.with_(plan_id=make_plan_id(plan.plan_id, REPLAN_SOLVER_NOTE, job.job_id), supersedes=job.supersedes)
    log.info("job superevent_id=%s job=%s replan start=%s horizon_h=%.2f executed=%d observations=%d coverage=%.4f",
             job.superevent_id, job.job_id, job.start, config.horizon_h, len(executed), len(plan.observations),
             float(plan.metrics.coverage))
    if not plan.observations:
        return _nothing(planner, job, "nothing left to observe")
    return planner.publish_final(job, skymap, event, plan, next_revision(store, job.superevent_id))


def _nothing(planner: Any, job: "Job", why: str) -> Outcome:
    """Close the job without a plan: the current plan stays."""
    if not close_without_plan(planner.store, job.job_id, why):
        return planner.drop(job, "re-plan finished")
    log.info("job superevent_id=%s job=%s decision=replan plan_id=- reason=%r", job.superevent_id, job.job_id, why)
    return Outcome("replan", job.ref, why, supersedes=job.supersedes, final=True)
