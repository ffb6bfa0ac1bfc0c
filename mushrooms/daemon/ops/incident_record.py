"""A state the daemon keeps in the state file for ``mushrooms status``: written as an incident when it changes.

``status`` runs without the metrics listener (off by default), so what an
operator must see of a running daemon (its brokers: :mod:`.broker_record`;
its warm-up plan: :mod:`.warm_record`) is written to the ``incidents`` table:
one row per change of a state, and one at each start once the state is known.
"""

from __future__ import annotations

import logging
import time
from typing import Any

__all__ = ["IncidentRecord", "iso_utc", "ERROR_CHARS"]

log = logging.getLogger("mushrooms.daemon")
#: Characters of an error kept in a record.
ERROR_CHARS = 300


def iso_utc(unix: float | None = None) -> str:
    """``YYYY-MM-DDTHH:MM:SSZ`` of a Unix time (default now)."""
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(unix))


class IncidentRecord:
    """Writes each keyed state to the store (an incident of :attr:`kind`) when it changed since this process wrote it.

    Parameters
    ----------
    store : Store
        The state store (:meth:`~mushrooms.daemon.state.store.Store.record_incident`).
    """

    #: The incident kind (a subclass's: ``broker``, ``warm_up_plan``).
    kind = "incident"

    def __init__(self, store: Any) -> None:
        self.store = store
        self._written: dict[str, bool] = {}

    def write(self, key: str, state: bool, detail: dict[str, Any]) -> None:
        """Write ``detail`` when ``key``'s ``state`` differs from what was last written (or nothing was)."""
        if self._written.get(key) is state:
            return
        try:
            self.store.record_incident(self.kind, detail)
        except Exception as exc:  # a full disk must not stop the timer; said, tried again at the next call
            log.error("event=incident_not_stored kind=%s error=%r", self.kind, f"{type(exc).__name__}: {exc}")
            return
        self._written[key] = state
