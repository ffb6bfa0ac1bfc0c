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

import logging
import time
from typing import Any

from ...handlers.text import storable

__all__ = ["WarmPlanRecord", "KIND"]

log = logging.getLogger("mushrooms.daemon")

#: The incident kind of the warm-up plan's outcome.
KIND = "warm_up_plan"
#: Characters of the plan's error kept.
ERROR_CHARS = 300


class WarmPlanRecord:
    """Writes the warm-up plan's outcome to the store: the first one given, then each change.

    Parameters
    ----------
    store : Store
        The state store (:meth:`~mushrooms.daemon.state.store.Store.record_incident`).
    """

    def __init__(self, store: Any) -> None:
        self.store = store
        self._written: bool | None = None  # failed, as last written (None: nothing written by this process)

    def update(self, failure: str | None) -> None:
        """Record the plan's outcome (``failure``: its error, None when it succeeded) when it changed."""
        failed = failure is not None
        if self._written is failed:
            return
        detail = {"failed": failed, "error": storable(failure, ERROR_CHARS) if failed else None,
                  "since": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        try:
            self.store.record_incident(KIND, detail)
        except Exception as exc:  # a full disk must not stop the timer; said, written at the next change or start
            log.error("event=incident_not_stored kind=%s error=%r", KIND, f"{type(exc).__name__}: {exc}")
            return
        self._written = failed
