"""``[loop]``: what the telescope did comes back (issue 28; ``docs/design/executed.md`` section 4).

Off by default (``executed_source = "none"``): the daemon then plans once per
sky map, as before.  With a source the daemon polls it every
``poll_interval_s``, stores what it read (the state file's ``executed``
table) and re-plans an event whose published plan slipped by more than
``max_slip_s`` or whose exposures failed.  A token for a URL source is never
a setting: :func:`~mushrooms.daemon.credentials.load_executed_token` reads it
from the systemd credential ``executed_token`` or ``$MUSHROOMS_EXECUTED_TOKEN``.

A light leaf (standard library only): reading the configuration imports no
numpy nor astropy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from ..handlers.executed_source import ExecutedSource, parse_executed_source
from ..scheduler_core.ranges import require_finite, setting
from ..scheduler_core.tables import dataclass_from_table

__all__ = ["LoopConfig"]


@dataclass(frozen=True)
class LoopConfig:
    """``[loop]`` settings.

    Attributes
    ----------
    executed_source : str
        ``"none"`` (default: no loop), ``"file:PATH"`` (a JSON-lines file of
        executed exposures), ``"depot:URL_OR_DIR"`` (ZTF's depot
        ``<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json``, over HTTP or in a
        directory) or ``"skyportal:URL"`` (SkyPortal's ``GET /api/observation``).
    min_processed_fraction : float
        An exposure counts as done when at least this fraction of its 64
        readout quadrants was processed (E1; default 0.5, growth-too-marshal's
        32 of 64).
    poll_interval_s : float
        How often (s) the source is read.
    max_slip_s : float
        A published plan whose first exposure not yet executed was planned more
        than this (s) ago has slipped: the event is re-planned from now (L4).  Keep it above the
        source's reporting delay (exposures reach the depot and SkyPortal once
        reduced), or a plan reported late looks slipped.
    timeout_s : float
        One HTTP request (s) of a URL source before the poll counts as failed
        (the next poll tries again).
    """

    executed_source: str = "none"
    min_processed_fraction: float = setting(0.5, 0, 1, why="of the 64 readout quadrants; 0.5 is the marshal's 32/64")
    poll_interval_s: float = setting(300.0, 1, 86400, "s", why="the depot's recentproc file grows as exposures are reduced")
    max_slip_s: float = setting(900.0, 0, 86400, "s", why="0: any delay re-plans; three exposures by default")
    timeout_s: float = setting(10.0, 0.1, 600, "s")

    def __post_init__(self) -> None:
        require_finite(self, "loop")
        try:
            parse_executed_source(self.executed_source)
        except ValueError as exc:
            raise ValueError(f"[loop] {exc}") from None

    @property
    def source(self) -> ExecutedSource:
        """The parsed ``executed_source``."""
        return parse_executed_source(self.executed_source)

    @property
    def enabled(self) -> bool:
        """A source is configured."""
        return self.source.kind != "none"

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "LoopConfig":
        """Build from a ``[loop]`` table; unknown keys are an error."""
        return dataclass_from_table(cls, table, "loop")
