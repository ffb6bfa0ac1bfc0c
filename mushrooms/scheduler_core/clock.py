"""The merger clock: one merger time per plan, the notice's when there is one, else the map's.

The kilonova's age at each exposure (light curves from the merger, the
detection objective, ``metrics.expected_detections``) is counted from the
merger time.  Two sources give it: the notice (``event.time``, GCN Kafka's
``igwn.gwalert`` schema) and the sky map's header (``DATE-OBS`` /
``MJD-OBS``, :attr:`~.sky.skymap.SkyMap.event_time`).  The notice wins: it
is what the alert says about *this* event, while a map's header can be
stale (a live copy of an archived notice, a map re-used for a drill) and
would put the merger years before the horizon, where every light curve is
dark.  When both are known and differ by more than
:data:`CLOCK_TOLERANCE_S`, one warning names both.

:func:`on_merger_clock` returns the sky map with ``event_time`` set to the
chosen merger time (so every consumer of the map reads the same clock) and
the event with ``event_time`` and ``merger_time_source`` (``notice`` or
``skymap``) for the plan document.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

from astropy.time import Time

from .errors import InputError
from .plan.document import EventInfo, iso_utc
from .sky.skymap import SkyMap
from .times import parse_time

__all__ = ["CLOCK_TOLERANCE_S", "MergerClock", "merger_clock", "on_merger_clock"]

log = logging.getLogger(__name__)

#: Notice and sky-map merger times further apart than this (s) are logged, both values.  A few
#: seconds: the two come from the same search pipeline's trigger time (a map's DATE-OBS is
#: written to the millisecond), so anything above is another event's header or a stale copy.
CLOCK_TOLERANCE_S = 5.0


@dataclass(frozen=True)
class MergerClock:
    """The merger time a plan uses and where it came from.

    Attributes
    ----------
    time : astropy.time.Time or None
        Merger time (UTC); None when neither the notice nor the map has one.
    source : str or None
        ``notice`` or ``skymap`` (None with no time).
    disagreement_s : float or None
        Notice minus map (s) when both are known.
    """

    time: Time | None
    source: str | None
    disagreement_s: float | None = None


def merger_clock(notice_time: Time | str | None, skymap_time: Time | None,
                 tolerance_s: float = CLOCK_TOLERANCE_S, context: str = "") -> MergerClock:
    """Choose the merger time: the notice's when given, else the map's; warn once on a disagreement.

    Parameters
    ----------
    notice_time : astropy.time.Time or str or None
        The notice's ``event.time`` (ISO UTC string or Time).
    skymap_time : astropy.time.Time or None
        The map's header time (``SkyMap.event_time``).
    tolerance_s : float
        Largest disagreement (s) not logged.
    context : str
        Prefix of the warning (e.g. the superevent).

    Returns
    -------
    MergerClock
    """
    t_notice = None if notice_time is None else parse_time(notice_time, "event.time")
    t_map = None
    if skymap_time is not None:
        try:
            t_map = parse_time(skymap_time, "the sky map's DATE-OBS")
        except InputError as exc:  # a header time outside what the package computes with: no map clock
            log.warning("%s%s", f"{context}: " if context else "", exc)
    if t_notice is None:
        return MergerClock(t_map, None if t_map is None else "skymap")
    diff = None if t_map is None else float((t_notice - t_map).to_value("sec"))
    if diff is not None and abs(diff) > tolerance_s:
        log.warning("%smerger time: the notice says %s, the sky map's header %s (%+.1f s apart, more than %g s): "
                    "the kilonova clock is the notice's", f"{context}: " if context else "", iso_utc(t_notice),
                    iso_utc(t_map), diff, tolerance_s)
    return MergerClock(t_notice, "notice", diff)


def on_merger_clock(skymap: SkyMap, event: EventInfo | None,
                    tolerance_s: float = CLOCK_TOLERANCE_S) -> tuple[SkyMap, EventInfo]:
    """The sky map and the event on one merger clock.

    The event's ``event_time`` is taken as the notice's unless its
    ``merger_time_source`` already says ``skymap`` (an event filled in from
    an earlier map); calling this again on its own output changes nothing
    and logs nothing.

    Parameters
    ----------
    skymap : SkyMap
    event : EventInfo or None
        None: a bare sky map (the map's clock).
    tolerance_s : float
        See :func:`merger_clock`.

    Returns
    -------
    (SkyMap, EventInfo)
        The map with ``event_time`` = the merger time (the same object when
        unchanged), the event with ``event_time`` and ``merger_time_source``.
    """
    event = event or EventInfo(skymap_sha256=skymap.sha256)
    notice = event.event_time if event.merger_time_source != "skymap" else None
    clock = merger_clock(notice, skymap.event_time, tolerance_s, context=event.superevent_id or "")
    if clock.time is None:
        return skymap, dataclasses.replace(event, event_time=None, merger_time_source=None)
    if skymap.event_time is None or abs(float((clock.time - skymap.event_time).to_value("sec"))) > 1e-3:
        skymap = dataclasses.replace(skymap, event_time=clock.time)
    return skymap, dataclasses.replace(event, event_time=iso_utc(clock.time), merger_time_source=clock.source)
