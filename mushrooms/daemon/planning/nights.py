"""The following nights in the daemon: each later night re-planned at its evening twilight (``executed.md`` L9-L11).

::

    [scheduler] nights = N > 1, every poll (the loop's timer, or the nights' own timer without a source):
      live event ─ nights of its first job's start (night_windows, N1)
        ▸ night n >= 2 under way (s_n <= now < e_n), no ``night:n`` notice of the event yet
        ▸ record_replan(start = now, origin = "night:n", night=True) ─► a ``replan`` job     (L9, L10)
      the job (daemon/planning/replan_stage.py) plans [start, e_n] on the executed record, or, without
      a source, on the earlier revisions' exposures taken as done                              (L11)

The ``notices`` row the re-plan records (origin ``night:n``) is the state
file's memory that night ``n`` of the event was re-planned: a restart, or the
next poll, finds it and records nothing.  ``nights = 1`` (the default): none
of this runs.
"""

from __future__ import annotations

import dataclasses
import logging
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from .replans import current_plan, live_events

if TYPE_CHECKING:
    from astropy.time import Time

    from ...scheduler_core import PlanningConfig
    from ...scheduler_core.executed import ExecutedExposure
    from ..state.store import Store

__all__ = ["event_nights", "night_of", "due_nights", "night_origin", "night_replanned", "record_night_replans",
           "night_one", "plans_as_done", "night_bounds"]

log = logging.getLogger("mushrooms.daemon.loop")


@lru_cache(maxsize=256)
def _windows(start_iso: str, sun_alt_max_deg: float, nights: int) -> tuple[tuple[float, float], ...]:
    """Unix times of ``night_windows`` from ``start_iso`` (cached: every poll asks again for the same event)."""
    from ...scheduler_core import PlanningConfig
    from ...scheduler_core.plan.document import parse_time
    from ...scheduler_core.sky.twilight import night_windows

    config = PlanningConfig(sun_alt_max_deg=sun_alt_max_deg)
    return tuple((float(a.unix), float(b.unix)) for a, b in night_windows(parse_time(start_iso), config, nights))


def event_nights(store: "Store", planning: "PlanningConfig", superevent_id: str) -> tuple[tuple[float, float], ...]:
    """The event's nights (N1) as unix ``(s_n, e_n)``: ``planning.nights`` of them from its first job's start.

    Empty when the event has no job, or when ``nights = 1``.
    """
    if planning.nights <= 1:
        return ()
    first = store.first_start(superevent_id)
    if first is None:
        return ()
    return _windows(first, float(planning.sun_alt_max_deg), int(planning.nights))


def night_of(nights: tuple[tuple[float, float], ...], when_unix: float) -> int | None:
    """The night (1-based) whose window ``[s_n, e_n)`` holds ``when_unix``; None between nights."""
    for n, (s, e) in enumerate(nights, 1):
        if s <= when_unix < e:
            return n
    return None


def night_origin(n: int) -> str:
    """The origin a night's re-plan is recorded under (its ``notices`` row): ``night:n``."""
    return f"night:{n}"


def night_replanned(store: "Store", superevent_id: str, n: int) -> bool:
    """Whether night ``n`` of the event was re-planned already (its ``night:n`` notice is in the state file)."""
    return store.connection().execute("SELECT 1 FROM notices WHERE superevent_id=? AND origin=? LIMIT 1",
                                 (superevent_id, night_origin(n))).fetchone() is not None


def due_nights(store: "Store", planning: "PlanningConfig", now: "Time") -> list[tuple[str, int, float, float]]:
    """(L9) The events whose night ``n >= 2`` is under way at ``now`` and not re-planned yet: ``(sid, n, s_n, e_n)``."""
    if planning.nights <= 1:
        return []
    from ...scheduler_core.plan.document import parse_time

    out = []
    for sid in live_events(store):
        first = store.first_start(sid)
        # an event whose nights are all over (they lie within nights + 2 days of its start) costs no twilight
        if first is None or float(now.unix) - float(parse_time(first).unix) > (planning.nights + 2) * 86400.0:
            continue
        nights = event_nights(store, planning, sid)
        n = night_of(nights, float(now.unix))
        if n is None or n < 2 or night_replanned(store, sid, n):
            continue
        plan = current_plan(store, sid)
        if plan is not None and float(parse_time(plan["document"]["start"]).unix) >= nights[n - 1][0]:
            continue  # (L13) the current plan was planned from inside night n (a closure into it, a slip in it)
        out.append((sid, n, *nights[n - 1]))
    return out


def record_night_replans(pipeline: Any, now: "Time") -> list[Any]:
    """(L9, L10) Record the re-plan of every event whose later night has begun (once per event and night).

    Parameters
    ----------
    pipeline : NoticePipeline
        Its store and ``[scheduler]`` (``nights``, ``sun_alt_max_deg``).
    now : astropy.time.Time
        The poll's time; the re-plan starts then (inside night ``n``).

    Returns
    -------
    list of Accepted
        One per due event: ``replan`` with its job, or ``ignore`` (a job of
        the event is open: the next poll tries again, the night is not marked).
    """
    from astropy.time import Time

    from ...handlers.instants import iso_z
    from ...scheduler_core.plan.document import iso_utc as iso
    from .replans import record_replan

    out = []
    for sid, n, s, e in due_nights(pipeline.store, pipeline.planning, now):
        reason = (f"night {n} of {pipeline.planning.nights} began at {iso(Time(s, format='unix'))}: re-planned "
                  f"to {iso(Time(e, format='unix'))} from the executed record")
        start = iso_z(now.utc.to_datetime(_utc()))
        out.append(record_replan(pipeline.store, sid, start, reason, night_origin(n), night=True))
    return out


def night_bounds(store: "Store", planning: "PlanningConfig", superevent_id: str,
                 start: "Time") -> tuple[float, float] | None:
    """With ``nights > 1``, the unix ``(s_n, e_n)`` of the event's night holding ``start``; else None."""
    nights = event_nights(store, planning, superevent_id)
    n = night_of(nights, float(start.unix))
    return None if n is None else nights[n - 1]


def night_one(planning: "PlanningConfig", start: "Time") -> "PlanningConfig":
    """(L9) The alert's job with ``nights > 1``: its horizon ends at night 1's morning twilight ``e_1``.

    ``horizon_h = min(horizon_h, (e_1 - start) / 3600)``, at least one grid
    step; ``nights = 1`` returns ``planning`` itself.
    """
    if planning.nights <= 1:
        return planning
    from ...scheduler_core.plan.document import iso_utc as iso

    (_, e1), = _windows(iso(start), float(planning.sun_alt_max_deg), 1)
    hours = max(planning.time_step_s / 3600.0, (e1 - float(start.unix)) / 3600.0)
    return dataclasses.replace(planning, horizon_h=min(planning.horizon_h, hours))


def plans_as_done(store: "Store", superevent_id: str, before_unix: float) -> tuple["ExecutedExposure", ...]:
    """(L11) Without an executed source: the event's revisions' exposures before ``before_unix``, taken as done.

    Revision ``i`` was the queue from its start until the next revision's
    start (it superseded ``i``), or until the next revision was asked for
    when that was earlier (L14: an operator's closure closed the dome then):
    its observations starting in that span (and before ``before_unix``)
    count as executed, fully reduced at their planned times (``as_planned``, N2).  Withdrawn plans and answers that are not
    plans count for nothing.
    """
    from ...scheduler_core.executed import ExecutedExposure
    from ...scheduler_core.plan.document import parse_time

    rows = [r for r in store.plans(superevent_id)
            if not r["withdrawn"] and r["document"].get("type", "plan") == "plan"]
    docs = [r["document"] for r in rows]
    # (L14) a revision is the queue until the next one starts, or until the next one was asked for when that
    # was earlier (an operator's closure: nothing was observed from the closing to the reopening)
    asked = [store.asked_at(r["job_id"]) if r["job_id"] is not None else None for r in rows]
    starts = [float(parse_time(d["start"]).unix) for d in docs]
    ends = [min(s, a) if a is not None else s for s, a in zip(starts, asked)][1:] + [before_unix]
    done = []
    for d, until in zip(docs, ends):
        until = min(until, before_unix)
        for o in d.get("observations", []):
            t = parse_time(o["start"])
            if float(t.unix) < until:
                done.append(ExecutedExposure(int(o["field_id"]), str(o["filter"]), t, float(o["exposure_s"]), 1.0,
                                             "processed"))
    return tuple(done)


def _utc() -> Any:
    from datetime import timezone

    return timezone.utc
