"""``[submit_parts]``: whether the other telescopes' SkyPortal parts are sent (issue 53 item 4).

Off by default.  One SkyPortal (``url``), an allocation per telescope
(``allocations = { winter = 7 }``); the token is never a setting:
:func:`~mushrooms.daemon.credentials.load_parts_token` reads it from the
systemd credential ``skyportal_token`` or ``$MUSHROOMS_SKYPORTAL_TOKEN``.
See ``docs/design/submission.md``, "Telescope parts to SkyPortal".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from ...scheduler_core.tables import dataclass_from_table
from .http_settings import check_base_url, check_seconds

__all__ = ["PartSubmitConfig"]


@dataclass(frozen=True)
class PartSubmitConfig:
    """``[submit_parts]`` settings.

    Attributes
    ----------
    enabled : bool
        Send every exported part whose telescope's description says ``queue =
        "skyportal"`` (default false: the request is only written in its folder).
    url : str
        SkyPortal's base URL (``http://`` or ``https://``), required when enabled.
    allocations : mapping of str to int
        SkyPortal's allocation id by telescope name; a part of a telescope
        without one is recorded ``failed`` (nothing sent).
    status : str
        The plan's ``status`` in SkyPortal (``complete``).
    timeout_s : float
        Wall-clock deadline (s) of one request in all (connect, send, whole answer).
    retry_initial_s, retry_max_s : float
        Back-off (s) while requests wait (5xx, timeouts, unreachable), doubling.
    alert_types : tuple of str
        Alert types whose parts are sent (``EARLYWARNING`` only when listed).
    dry_run : bool
        Log the request (token ``***``) and record ``skipped`` instead of sending.
    """

    enabled: bool = False
    url: str = ""
    allocations: Mapping[str, int] = field(default_factory=dict)
    status: str = "complete"
    timeout_s: float = 10.0
    retry_initial_s: float = 5.0
    retry_max_s: float = 300.0
    alert_types: tuple[str, ...] = ("PRELIMINARY", "INITIAL", "UPDATE")
    dry_run: bool = False

    def __post_init__(self) -> None:
        if self.enabled:
            check_base_url(self.url, "[submit_parts]", "when enabled",
                           "MUSHROOMS_SKYPORTAL_TOKEN or the systemd credential skyportal_token")
        check_seconds(self, "[submit_parts]", (("timeout_s", 0.1, 600.0), ("retry_initial_s", 0.01, 86400.0),
                                              ("retry_max_s", 0.01, 86400.0)))
        bad = {k: v for k, v in dict(self.allocations).items()
               if not isinstance(k, str) or isinstance(v, bool) or not isinstance(v, int) or not 0 < v < 2**63}
        if bad:
            raise ValueError(f"[submit_parts] allocations must map telescope names to positive integer ids, "
                             f"got {sorted(map(str, bad))[:5]}")
        if not self.status.strip() or len(self.status) > 100:
            raise ValueError("[submit_parts] status must be a non-empty string of at most 100 characters")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "PartSubmitConfig":
        """Build from a ``[submit_parts]`` table; unknown keys are an error."""
        table = dict(table) if isinstance(table, Mapping) else table
        allocations = table.pop("allocations", {}) if isinstance(table, dict) else {}
        if not isinstance(allocations, Mapping):
            from ...scheduler_core.tables import TableError, shown_value, toml_type

            raise TableError(f"[submit_parts] allocations = {shown_value(allocations)}: expected a table "
                             f"({{ winter = 7 }}), got {toml_type(allocations)}", section="submit_parts",
                             key="allocations", value=allocations, expected="a table")
        config = dataclass_from_table(cls, table, "submit_parts")
        return cls(**{**{f: getattr(config, f) for f in cls.__dataclass_fields__}, "allocations": dict(allocations)})
