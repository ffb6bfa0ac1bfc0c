"""``[loop]``: what the telescope did comes back (``docs/design/executed.md`` section 4).

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
    max_source_bytes : int
        Largest file or answer read (bytes); a larger one fails the poll (L16).
    max_read_s : float
        Wall-clock budget (s) of one poll's reading: a SkyPortal still
        paginating past it (or past 100 pages) fails the poll (L16).
    failed_settle_s : float
        An exposure processed below ``min_processed_fraction`` is still being
        reduced, not failed, until this long (s) after its end (L17).
    program_ids : tuple of int
        Count only exposures of these ZTF programmes (the depot rows'
        ``programid``: 1 public, 2 partnership, 3 Caltech; empty, the
        default: every programme's, L18).  Only the depot names an
        exposure's programme, so ids with another source are refused.
    """

    executed_source: str = "none"
    min_processed_fraction: float = setting(0.5, 0, 1, why="of the 64 readout quadrants; 0.5 is the marshal's 32/64")
    poll_interval_s: float = setting(300.0, 1, 86400, "s", why="the depot's recentproc file grows as exposures are reduced")
    max_slip_s: float = setting(900.0, 0, 86400, "s", why="0: any delay re-plans; three exposures by default")
    timeout_s: float = setting(10.0, 0.1, 600, "s")
    max_source_bytes: int = setting(256 * 1024 * 1024, 1024, 16 * 1024 ** 3, "bytes",
                                    why="a night's depot file is a few MB")
    max_read_s: float = setting(120.0, 1, 3600, "s", why="a source paging forever must not hold the poll")
    failed_settle_s: float = setting(1800.0, 0, 86400, "s",
                                     why="the depot lists an exposure before its reduction ends")
    program_ids: tuple[int, ...] = setting((), 1, 99, why="each element: a ZTF programme id; empty: every programme")

    def __post_init__(self) -> None:
        require_finite(self, "loop")
        try:
            parse_executed_source(self.executed_source)
        except ValueError as exc:
            raise ValueError(f"[loop] {exc}") from None
        ids = self.program_ids
        if not isinstance(ids, (tuple, list)) or not all(isinstance(i, int) and not isinstance(i, bool)
                                                         and 1 <= i <= 99 for i in ids):
            raise ValueError(f"[loop] program_ids must be a list of ZTF programme ids in [1, 99], got {ids!r}")
        object.__setattr__(self, "program_ids", tuple(ids))
        if ids and self.source.kind != "depot":
            raise ValueError("[loop] program_ids needs a depot: executed_source; only the depot's rows name an "
                             "exposure's programme (programid)")

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
