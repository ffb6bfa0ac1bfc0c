"""A live copy of an archived notice: the same alert, as if it were sent now.

The service ignores a notice created long ago (``[policy] max_notice_age_s``,
``max_event_age_s``), and plans the kilonova from the merger time.  A live
copy moves every clock of the notice by one shift: ``time_created`` becomes
now, the merger (``event.time``) keeps its original lead on the creation
(at most :data:`MAX_LEAD_S`), and the sky maps' ``DATE-OBS`` / ``MJD-OBS``
follow the merger.  Nothing else changes.
"""

from __future__ import annotations

import base64
import binascii
import datetime as dt
import io
import json
from typing import Any

from ..scheduler_core.errors import InputError

__all__ = ["live_copy", "retime_skymap", "MAX_LEAD_S"]

#: Longest kept gap (s) between the merger and the notice's creation (an archived update may be days late).
MAX_LEAD_S = 600.0


def _iso(t: dt.datetime) -> str:
    return t.astimezone(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def _parse(text: Any) -> dt.datetime | None:
    if not isinstance(text, str):
        return None
    try:
        t = dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    return t if t.tzinfo else t.replace(tzinfo=dt.timezone.utc)


def retime_skymap(b64: str, merger: dt.datetime) -> str:
    """The base64 FITS sky map with ``DATE-OBS`` and ``MJD-OBS`` moved to ``merger`` (UTC).

    Raises
    ------
    InputError
        The payload is not base64 FITS.
    """
    from astropy.io import fits
    from astropy.time import Time

    t = Time(merger.astimezone(dt.timezone.utc).replace(tzinfo=None), scale="utc")
    try:
        raw = base64.b64decode(b64, validate=False)
        with fits.open(io.BytesIO(raw)) as hdus:
            for hdu in hdus:
                if "DATE-OBS" in hdu.header:
                    hdu.header["DATE-OBS"] = t.isot
                if "MJD-OBS" in hdu.header:
                    hdu.header["MJD-OBS"] = t.mjd
            out = io.BytesIO()
            hdus.writeto(out)
    except (binascii.Error, OSError, ValueError, TypeError) as exc:
        raise InputError(f"the notice's sky map is not base64 FITS ({exc})") from None
    return base64.b64encode(out.getvalue()).decode()


def live_copy(raw: bytes, now: dt.datetime | None = None, superevent_id: str | None = None) -> tuple[bytes, dict]:
    """A JSON notice sent again at ``now``: created now, the merger its original lead before.

    Parameters
    ----------
    raw : bytes
        An IGWN GCN Kafka notice in JSON (``docs/design/CONTRACTS.md``).
    now : datetime, optional
        The new creation time (default: now, UTC).
    superevent_id : str, optional
        A new superevent id (default: the notice's own).

    Returns
    -------
    notice : bytes
        The live copy (JSON).
    times : dict
        ``created`` and ``merger`` of the copy (ISO UTC), ``shift_s`` (how far
        its clocks moved, s).

    Raises
    ------
    InputError
        Not a JSON notice with ``superevent_id``, ``time_created`` and an ``event`` block.
    """
    try:
        doc = json.loads(raw)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not a JSON notice ({exc}); a rehearsal takes an IGWN GCN Kafka notice in JSON") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("superevent_id"), str):
        raise InputError("not an IGWN notice: no superevent_id")
    now = (now or dt.datetime.now(dt.timezone.utc)).astimezone(dt.timezone.utc)
    created = _parse(doc.get("time_created"))
    if created is None:
        raise InputError("the notice has no readable time_created")
    event = doc.get("event")
    merger = _parse(event.get("time")) if isinstance(event, dict) else None
    lead = 0.0 if merger is None else min(max((created - merger).total_seconds(), 0.0), MAX_LEAD_S)
    new_merger = now - dt.timedelta(seconds=lead)
    doc["time_created"] = _iso(now)
    if superevent_id:
        doc["superevent_id"] = superevent_id
    if isinstance(event, dict):
        event = dict(event)
        if merger is not None:
            event["time"] = _iso(new_merger)
        if isinstance(event.get("skymap"), str) and event["skymap"]:
            event["skymap"] = retime_skymap(event["skymap"], new_merger)
        doc["event"] = event
    ext = doc.get("external_coinc")
    if isinstance(ext, dict) and isinstance(ext.get("combined_skymap"), str) and ext["combined_skymap"]:
        doc["external_coinc"] = dict(ext, combined_skymap=retime_skymap(ext["combined_skymap"], new_merger))
    times = {"created": doc["time_created"], "merger": _iso(new_merger),
             "shift_s": (now - created).total_seconds()}
    return json.dumps(doc).encode(), times
