"""Whether the warm-up plan fails, kept in the state file so that ``mushrooms status`` can tell it.

The warm-up's throw-away plan (:func:`~mushrooms.daemon.planning.warm.warm_plan`)
runs the first stage of every job on the bundled map; while it fails the
service is not ready (``/readyz``), but with the metrics listener off by
default only the log's ERROR line said so.  As for the brokers
(:mod:`.broker_record`), the daemon writes the plan's outcome as an incident,
of kind ``warm_up_plan`` (detail: ``failed``, ``error``, ``since``): once at
each start, then on each change (a failure, a recovery at a re-warm or a
reload).  ``status`` reads the newest row
(:func:`~mushrooms.daemon.state.views.warm_up_plan`) and needs attention while
it says ``failed``.
"""

from __future__ import annotations

from ...handlers.text import storable
from .incident_record import ERROR_CHARS, IncidentRecord, iso_utc

__all__ = ["WarmPlanRecord", "KIND"]

#: The incident kind of the warm-up plan's outcome.
KIND = "warm_up_plan"


class WarmPlanRecord(IncidentRecord):
    """Writes the warm-up plan's outcome to the store (``WarmPlanRecord(store)``): the first one given, then each
    change."""

    kind = KIND

    def update(self, failure: str | None) -> None:
        """Record the plan's outcome (``failure``: its error, None when it succeeded) when it changed."""
        failed = failure is not None
        self.write("plan", failed, {"failed": failed, "error": storable(failure, ERROR_CHARS) if failed else None,
                                    "since": iso_utc()})
