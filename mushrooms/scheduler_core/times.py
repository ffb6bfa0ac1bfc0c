"""One parser for every time the package reads: command lines, config values, plan documents, notices.

Accepted (the same everywhere):

* ISO-8601 with ``T`` or a space, a trailing ``Z`` or a UTC offset
  (``2026-05-01T03:00:00Z``, ``2026-05-01T05:00:00+02:00``); no offset means UTC;
* a leap second (``2016-12-31T23:59:60Z``), through astropy;
* a Modified Julian Date (``61161.125``) where the caller allows it
  (command lines), never in a notice or a plan document.

Refused, with one line of the one form ``<what> <value>: <why>; give ...``:
an empty string, anything else, and times outside :data:`EARLIEST` to
:data:`LATEST` (astropy and ERFA compute the Sun and the Moon there, with
approximate Earth orientation; year 9999 once ended in an internal error).
"""

from __future__ import annotations

import functools
import math
import warnings
from datetime import datetime, timezone
from typing import Any

from astropy.time import Time

from .errors import InputError

__all__ = ["parse_time", "iso_utc", "EARLIEST", "LATEST", "TIME_FORMS"]

#: The span of accepted times (UTC), inclusive.
EARLIEST = "1800-01-01T00:00:00"
LATEST = "2200-01-01T00:00:00"

#: How the error message says what is accepted.
TIME_FORMS = "ISO-8601 UTC (2026-05-01T03:00:00Z, or with an offset: 2026-05-01T05:00:00+02:00)"


@functools.lru_cache(maxsize=1)
def _span() -> tuple[Time, Time]:
    return Time(EARLIEST, scale="utc"), Time(LATEST, scale="utc")


def parse_time(value: Any, what: str = "time", mjd: bool = False) -> Time:
    """Parse a time into an astropy :class:`~astropy.time.Time` (UTC).

    Parameters
    ----------
    value : str, float or astropy.time.Time
        The text (or an MJD number when ``mjd``); a ``Time`` is returned
        as it is, after the span check.
    what : str
        What the value is (``--start``, ``event.time``), for the message.
    mjd : bool
        Also accept a Modified Julian Date (a plain number).

    Returns
    -------
    astropy.time.Time
        In the UTC scale.

    Raises
    ------
    InputError
        ``<what> <value>: <why>; give ISO-8601 UTC (...)[ or an MJD (...)]``.
    """
    forms = TIME_FORMS + (" or an MJD (61161.125)" if mjd else "")

    def refuse(why: str) -> InputError:
        shown = repr(value) if isinstance(value, str) else str(value)
        return InputError(f"{what} {shown[:60]}: {why}; give {forms}")

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ERFA's "dubious year": the span check below speaks instead
        t = _parse(value, mjd, refuse)
        lo, hi = _span()
        if not (lo <= t <= hi):
            raise refuse(f"outside {EARLIEST[:10]} to {LATEST[:10]}")
    return t


def _parse(value: Any, mjd: bool, refuse: Any) -> Time:
    if isinstance(value, Time):
        t = value.utc
    elif isinstance(value, (int, float)) and not isinstance(value, bool) and mjd:
        t = _from_mjd(float(value), refuse)
    elif isinstance(value, str):
        text = value.strip()
        if not text:
            raise refuse("empty")
        t = _from_text(text, mjd, refuse)
    else:
        raise refuse(f"a {type(value).__name__}, not a time")
    return t


def _from_mjd(number: float, refuse: Any) -> Time:
    if not math.isfinite(number) or number <= 0:
        raise refuse("an MJD is a positive day number")
    return Time(number, format="mjd", scale="utc")


def _from_text(text: str, mjd: bool, refuse: Any) -> Time:
    try:
        number = float(text)
    except ValueError:
        number = None
    if number is not None:
        if not mjd:
            raise refuse("a number, not a date")
        return _from_mjd(number, refuse)
    iso = text[:-1] + "+00:00" if text[-1:] in "Zz" else text
    try:
        t = datetime.fromisoformat(iso)
    except ValueError:
        return _leap_second(text, refuse)
    if t.tzinfo is not None:
        t = t.astimezone(timezone.utc).replace(tzinfo=None)
    return Time(t, scale="utc")


def _leap_second(text: str, refuse: Any) -> Time:
    """``...23:59:60`` (UTC only), which :mod:`datetime` cannot hold; astropy can."""
    body = text[:-1] if text[-1:] in "Zz" else text
    if ":60" not in body or "+" in body[10:] or "-" in body[10:]:
        raise refuse("not an ISO-8601 time")
    try:
        return Time(body.replace(" ", "T"), format="isot", scale="utc")
    except ValueError:
        raise refuse("not an ISO-8601 time") from None


def iso_utc(t: Time) -> str:
    """ISO-8601 UTC string with millisecond precision and a trailing ``Z``."""
    return Time(t, scale="utc").isot[:23] + "Z"
