"""The loop: read what the telescope did, keep it, re-plan what slipped (``docs/design/executed.md`` section 4).

::

    every [loop] poll_interval_s (the service's timer thread, never the consume loop):
      live events' current plans ─ span [earliest plan start, now]
        ▸ ExecutedReader.read (file / depot / SkyPortal)      (L1)
        ▸ store_executed: one row per exposure (E2)           (L2)
        ▸ per event: slip_of(current plan, executed, now)     (L3-L5)
        ▸ replan_event ─► a ``replan`` job for the JobRunner  (L7, guards L8)
      [scheduler] nights > 1: an event's later night begun ─► its night re-plan first (L9, L10)

A poll that cannot read its source (unreachable, refused, not the source's
shape) logs one line and changes nothing; the next poll tries again.  A
malformed record inside a readable source is the reader's one warning
line, and the rest of the source is stored.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .fetch import ExecutedReader, FetchError
from ..state.executed import Stored, executed_between, store_executed
from ..planning.nights import due_nights, record_night_replans
from ..submission.remote import Unreachable
from ..planning.replans import current_plan, live_events

if TYPE_CHECKING:
    from astropy.time import Time

    from ..loop_settings import LoopConfig

__all__ = ["ExecutedLoop", "Poll"]

log = logging.getLogger("mushrooms.daemon.loop")


@dataclass(frozen=True)
class Poll:
    """What one poll did.

    Attributes
    ----------
    read : int
        Exposures the source reported (duplicates collapsed).
    stored : Stored or None
        Added, updated, unchanged (None when nothing was read).
    replans : list of Accepted
        The re-plan jobs recorded (each ``replan`` with its job), and the
        events the guards passed over (``ignore``).
    error : str or None
        Why the source could not be read (one line).
    """

    read: int = 0
    stored: Stored | None = None
    replans: list[Any] = field(default_factory=list)
    error: str | None = None

    @property
    def jobs(self) -> list[Any]:
        """The recorded re-plan decisions that carry a job."""
        return [a for a in self.replans if getattr(a, "job", None) is not None]


class ExecutedLoop:
    """Poll the executed source and re-plan slipped plans.

    Parameters
    ----------
    config : LoopConfig
        ``[loop]`` (a source other than ``none``).
    pipeline : NoticePipeline
        Its store, and :meth:`~mushrooms.daemon.intake.pipeline.NoticePipeline.replan_event`.
    token : str or None
        A URL source's token (:func:`~.credentials.load_executed_token`).
    reader : ExecutedReader, optional
        Default: one for ``config.source``.
    """

    def __init__(self, config: "LoopConfig", pipeline: Any, token: str | None = None,
                 reader: ExecutedReader | None = None) -> None:
        self.config = config
        self.pipeline = pipeline
        self.reader = reader if reader is not None else ExecutedReader(
            config.source, token, config.timeout_s, config.max_source_bytes, config.max_read_s, config.program_ids)

    def poll(self, now: "Time | None" = None) -> Poll:
        """Read, store, compare, re-plan (once); ``now`` default the wall clock (tests pass the night's time)."""
        from astropy.time import Time

        from ...scheduler_core.errors import InputError
        from ...handlers.slip import slip_of

        now = Time.now() if now is None else now
        store = self.pipeline.store
        # (L1) the events with a current plan whose window has not ended; the span: their earliest start to now
        plans = {sid: p for sid in live_events(store) if (p := current_plan(store, sid)) is not None
                 and p["document"].get("type", "plan") == "plan"
                 and Time(str(p["document"]["end"]).rstrip("Z"), scale="utc") > now}
        # (L9) [scheduler] nights > 1: the events whose later night has begun are read for too
        due = due_nights(store, self.pipeline.planning, now)
        if not plans and not due:
            log.debug("event=executed_poll_skipped reason='no event has a current plan in its window'")
            return Poll()
        begin = min([Time(str(p["document"]["start"]).rstrip("Z"), scale="utc") for p in plans.values()]
                    + [Time(s, format="unix", scale="utc") for _, _, s, _ in due])
        if due:
            first = store.first_start(*(sid for sid, *_ in due))
            if first is not None:
                begin = min(begin, Time(first.rstrip("Z"), scale="utc"))
        source = self.reader.describe()
        try:
            exposures = self.reader.read(min(begin, now), now)
        except (InputError, Unreachable, FetchError, OSError) as exc:
            log.warning("event=executed_poll_failed source=%s error=%r (nothing stored; the next poll tries again)",
                        source, f"{type(exc).__name__}: {exc}")
            return Poll(error=f"{type(exc).__name__}: {exc}")
        stored = store_executed(store, exposures, source)
        log.info("event=executed_read source=%s exposures=%d added=%d updated=%d unchanged=%d events=%d", source,
                 len(exposures), stored.added, stored.updated, stored.unchanged, len(plans))
        # (L10) a later night's re-plan first: it replaces the slip check of that event in this poll
        replans: list[Any] = record_night_replans(self.pipeline, now) if due else []
        nighted = {a.ref.superevent_id for a in replans}
        for sid, plan in plans.items():
            if sid in nighted:
                continue
            doc = plan["document"]
            start = Time(str(doc["start"]).rstrip("Z"), scale="utc")
            executed = executed_between(store, float(start.unix) - 1.0, float(now.unix))
            slip = slip_of(doc, executed, now, self.config.max_slip_s, self.config.min_processed_fraction,
                           self.config.failed_settle_s)
            log.info("event=slip_check superevent_id=%s plan_id=%s replan=%s executed=%d planned=%d slip_s=%s "
                     "reason=%r", sid, plan["plan_id"], str(slip.replan).lower(), slip.executed, slip.planned,
                     "-" if slip.slip_s is None else f"{slip.slip_s:.0f}", slip.reason)
            if slip.replan:
                replans.append(self.pipeline.replan_event(sid, now.utc.to_datetime(timezone_utc()), slip.reason,
                                                          f"loop:{source}"))
        return Poll(len(exposures), stored, replans)


def timezone_utc() -> Any:
    """UTC as a ``datetime`` time zone (astropy's ``to_datetime`` takes one)."""
    from datetime import timezone

    return timezone.utc
