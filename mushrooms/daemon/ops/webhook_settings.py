"""``[notify]``: whether and how the observer on call is told when something happens.

Off by default (``target = "off"``).  The webhook's URL is a secret and never a
setting: :func:`~mushrooms.daemon.credentials.load_notify_url` reads it from
the systemd credential ``notify_url`` or ``$MUSHROOMS_NOTIFY_URL``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from ...scheduler_core.tables import dataclass_from_table

__all__ = ["NotifyConfig", "NOTIFY_TARGETS"]

#: How messages are posted: not at all, Slack's incoming-webhook JSON, or a generic JSON object.
NOTIFY_TARGETS = ("off", "slack", "json")


@dataclass(frozen=True)
class NotifyConfig:
    """``[notify]`` settings.

    Attributes
    ----------
    target : str
        ``off`` (default), ``slack`` (``{"text": ...}``, Slack's incoming
        webhooks and the chat tools that accept their format) or ``json``
        (``{"event": ..., "text": ..., ...}``, a generic JSON webhook).
    timeout_s : float
        Hard deadline (s) of one POST, connect to answer (the socket is closed
        at it, however slowly the answer trickles); a webhook that does not
        answer in time is given up on (the message is dropped, logged without the URL).
    max_pending : int
        Messages waiting to be posted at most; beyond, the oldest is dropped
        (a hanging webhook never holds planning or submission up).
    """

    target: str = "off"
    timeout_s: float = 5.0
    max_pending: int = 100

    def __post_init__(self) -> None:
        if self.target not in NOTIFY_TARGETS:
            raise ValueError(f"[notify] target must be one of {', '.join(NOTIFY_TARGETS)}, got {self.target!r}")
        if not (math.isfinite(float(self.timeout_s)) and 0.1 <= float(self.timeout_s) <= 120.0):
            raise ValueError(f"[notify] timeout_s must be a finite number in [0.1, 120] s, got {self.timeout_s!r}")
        if not 1 <= int(self.max_pending) <= 100_000:
            raise ValueError(f"[notify] max_pending must be in [1, 100000], got {self.max_pending!r}")

    @property
    def enabled(self) -> bool:
        """Messages are posted."""
        return self.target != "off"

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "NotifyConfig":
        """Build from a ``[notify]`` table; unknown keys are an error."""
        return dataclass_from_table(cls, table, "notify")
