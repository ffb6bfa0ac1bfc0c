"""Whether the brokers answer, kept in the state file so that ``mushrooms status`` can tell it.

The broker-down alert of docs/operations.md needs the metrics listener,
which is off by default; wrong GCN credentials then showed only as
``event=broker_unreachable`` in the log.  At each heartbeat the daemon
compares each client's :class:`~mushrooms.daemon.kafka.broker_log.BrokerHealth`
(``consumer``: the GCN input; ``sink``: an outbound Kafka sink) with what it
last wrote, and writes a change as an incident of kind ``broker`` (detail:
``client``, ``up``, ``since``, ``error``).  So the state file holds one row
per change of state (and one at each start, once the state is known), and
``status`` reads the newest row of each client
(:func:`~mushrooms.daemon.state.views.broker_reachability`).
"""

from __future__ import annotations

from typing import Any, Mapping

from ...handlers.text import storable
from .incident_record import ERROR_CHARS, IncidentRecord, iso_utc

__all__ = ["BrokerRecord", "KIND"]

#: The incident kind of a broker's change of state.
KIND = "broker"


class BrokerRecord(IncidentRecord):
    """Writes each client's broker state to the store (``BrokerRecord(store)``) when it changes."""

    kind = KIND

    def update(self, healths: Mapping[str, Any]) -> None:
        """Write the clients whose state (up or down; unknown is skipped) changed since the last write.

        Parameters
        ----------
        healths : mapping
            Client name -> its ``BrokerHealth`` (or None: no such client).
        """
        for client, health in healths.items():
            up = getattr(health, "up", None)
            if up is None:
                continue
            error = None if up else storable(health.last_error or "-", ERROR_CHARS)
            self.write(client, bool(up), {"client": client, "up": bool(up), "error": error,
                                          "since": iso_utc(health.since)})
