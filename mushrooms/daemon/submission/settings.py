"""``[submit]``: whether and where plans are submitted to ZTF's ToO queue.

Off by default (``target = "none"``).  The bearer token is never a setting:
:func:`~mushrooms.daemon.credentials.load_submit_token` reads it from the
systemd credential ``submit_token`` or ``$MUSHROOMS_SUBMIT_TOKEN``.
See ``docs/design/submission.md`` for the neighbours' contracts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from ...scheduler_core.tables import dataclass_from_table
from .http_settings import check_base_url, check_seconds

__all__ = ["SubmitConfig", "SUBMIT_TARGETS"]

#: Where plans can be submitted.
SUBMIT_TARGETS = ("none", "kowalski", "skyportal")


@dataclass(frozen=True)
class SubmitConfig:
    """``[submit]`` settings.

    Attributes
    ----------
    target : str
        ``none`` (default: nothing is submitted), ``kowalski`` (``PUT
        {url}/api/triggers/ztf``: the queue goes to ZTF) or ``skyportal``
        (``POST {url}/api/observation_plan/manual``).
    url : str
        Base URL of the target (``http://`` or ``https://``); required unless
        ``target = "none"``.
    timeout_s : float
        Wall-clock deadline (s) of one HTTP request, in all (connect, send,
        the whole answer), after which it counts as failed and is retried.
    max_pending_s : float
        A submission pending longer than this (s) needs attention:
        ``/readyz`` not ready (check ``submission``), ``mushrooms status``
        exit 1 (the gauge ``mushrooms_submission_oldest_pending_age_seconds``
        has the alert rule of docs/operations.md).
    retry_initial_s, retry_max_s : float
        Back-off (s) after a failed (5xx, timeout, unreachable) request,
        doubling from the first to the second.  A refusal (4xx) is never retried.
    min_coverage : float
        Least probability a plan must cover to be submitted (0: every plan).
    max_exposures : int
        Most exposures a submitted plan may have (0: no limit).
    alert_types : tuple of str
        Alert types whose plans are submitted; ``EARLYWARNING`` only when listed.
    dry_run : bool
        Log the request that would be sent (token redacted) instead of sending it.
    """

    target: str = "none"
    url: str = ""
    timeout_s: float = 10.0
    max_pending_s: float = 600.0
    retry_initial_s: float = 5.0
    retry_max_s: float = 300.0
    min_coverage: float = 0.0
    max_exposures: int = 0
    alert_types: tuple[str, ...] = ("PRELIMINARY", "INITIAL", "UPDATE")
    dry_run: bool = False

    def __post_init__(self) -> None:
        if self.target not in SUBMIT_TARGETS:
            raise ValueError(f"[submit] target must be one of {', '.join(SUBMIT_TARGETS)}, got {self.target!r}")
        if self.target != "none":
            check_base_url(self.url, "[submit]", f"for target {self.target!r}",
                           "MUSHROOMS_SUBMIT_TOKEN or the systemd credential submit_token")
        check_seconds(self, "[submit]", (("timeout_s", 0.1, 600.0), ("retry_initial_s", 0.01, 86400.0),
                                         ("retry_max_s", 0.01, 86400.0), ("max_pending_s", 1.0, 86400.0)))
        if not (math.isfinite(float(self.min_coverage)) and 0.0 <= self.min_coverage <= 1.0):
            raise ValueError(f"[submit] min_coverage must be in [0, 1], got {self.min_coverage!r}")
        if not 0 <= int(self.max_exposures) <= 100_000:
            raise ValueError(f"[submit] max_exposures must be in [0, 100000] (0: no limit), got {self.max_exposures!r}")
        bad = [t for t in self.alert_types if not isinstance(t, str) or not t.strip()]
        if bad:
            raise ValueError(f"[submit] alert_types must be non-empty strings, got {bad!r}")

    @property
    def enabled(self) -> bool:
        """A target is configured."""
        return self.target != "none"

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "SubmitConfig":
        """Build from a ``[submit]`` table; unknown keys are an error."""
        return dataclass_from_table(cls, table, "submit")
