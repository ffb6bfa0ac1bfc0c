"""Instants as the service writes and compares them: ISO-8601 UTC, milliseconds, a trailing ``Z``.

The state file, the outbound messages and the decisions' creation order all
use this one form (``2026-12-02T16:31:09.000Z``); reading accepts any
ISO-8601 text Python's :meth:`datetime.fromisoformat` takes (``Z`` or an
offset; a naive time means UTC).  Astropy times of the scheduler have their
own twin, :func:`mushrooms.scheduler_core.plan.document.iso_utc`.

The standard library only.  ``mushrooms status`` keeps a reader of its own
(:func:`mushrooms.daemon.state.views.parse_iso`): importing this module loads
the ``handlers`` package and with it the notice parsers (about 1 s), which the
status command must not pay.
"""

from __future__ import annotations

from datetime import datetime, timezone

__all__ = ["iso_z", "now_iso_z", "parse_instant"]


def iso_z(t: datetime) -> str:
    """An aware datetime as ``YYYY-MM-DDTHH:MM:SS.mmmZ`` (UTC)."""
    return t.astimezone(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def now_iso_z() -> str:
    """The current time as :func:`iso_z` writes it."""
    return iso_z(datetime.now(timezone.utc))


def parse_instant(value: str | datetime | None) -> datetime | None:
    """An ISO-8601 time (or a datetime) as an aware datetime; None when absent or unreadable.

    A naive time is taken as UTC.
    """
    if value is None or value == "":
        return None
    try:
        t = value if isinstance(value, datetime) else datetime.fromisoformat(str(value))
    except ValueError:
        return None
    return t if t.tzinfo is not None else t.replace(tzinfo=timezone.utc)
