"""Which localisation of an alert to plan on: the GW sky map or the joint one.

When an LVK alert has a coincident external trigger (a Fermi-GBM or Swift
GRB, an IceCube neutrino), the notice's ``external_coinc`` carries a
``combined_skymap``: the GW localisation multiplied by the external one,
often far smaller than the GW map alone.  :func:`choose_localization` picks
the map to plan on (the joint one when the policy allows it and it decodes as
a valid sky map, else the GW map, with the reason) and
:func:`coincidence_summary` is what travels into the plan's event block.

Pure functions of the parsed alert; the sky-map check is handed in (the
service uses :func:`check_skymap`, which reads the map with the scheduler's
own reader), so tests can run them on any bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from .alert import Alert, ExternalCoinc

__all__ = ["Localization", "choose_localization", "check_skymap", "check_skymap_header", "coincidence_summary",
           "skymap_for_sha", "GW", "COMBINED"]

#: The GW-only localisation (``event.skymap``).
GW = "gw"
#: The joint GW x external localisation (``external_coinc.combined_skymap``).
COMBINED = "combined"

#: HEALPix resolution at which :func:`check_skymap` reads a map (cheap; the
#: check is about decoding and normalisation, not about detail).
_CHECK_NSIDE = 64


@dataclass(frozen=True)
class Localization:
    """The sky map chosen for planning.

    Attributes
    ----------
    kind : str
        :data:`GW` or :data:`COMBINED`.
    skymap : bytes
        The FITS bytes to plan on.
    sha256 : str
        Their SHA-256 (hex): the key of the planning decision.
    note : str
        Why this map (e.g. the joint map's decoding error on a fallback);
        empty when nothing needs saying.
    joint_preferred : bool
        The policy plans on joint maps: an event already planned on one
        keeps it rather than fall back to this GW-only map.
    """

    kind: str
    skymap: bytes
    sha256: str
    note: str = ""
    joint_preferred: bool = True


def check_skymap(data: bytes, max_bytes: int | None = None) -> None:
    """Raise when ``data`` is not a usable sky map (the scheduler's own reader).

    Parameters
    ----------
    data : bytes
        FITS bytes, possibly gzipped.
    max_bytes : int, optional
        Largest map (bytes as carried, packed for a gzip) accepted
        (``[policy] max_skymap_bytes``); default no bound.  The unpacked
        size is bounded by the reader from the map's own header.

    Raises
    ------
    mushrooms.scheduler_core.SkyMapError
        Not FITS, no probability column, not normalised, ...
    """
    from ..scheduler_core import read_skymap

    read_skymap(data, nside=_CHECK_NSIDE, **({} if max_bytes is None else {"max_bytes": max_bytes}))


def check_skymap_header(data: bytes, max_bytes: int | None = None) -> None:
    """Raise when ``data`` is plainly not a usable sky map, from its FITS headers only.

    The cheap check the consume loop runs on a joint map: the
    sky-map reader's own header parser
    (:func:`~mushrooms.scheduler_core.sky.fitstable.open_table`, plain or
    gzip) reads the headers up to the first binary table and no row
    (milliseconds, bounded memory, whatever the map); the table must have a
    probability column and fit ``max_bytes``.  The full decode happens in the
    planning job, which falls back to the GW map when the joint map still
    turns out unusable.

    Raises
    ------
    ValueError
        Not FITS, broken gzip, no (well-formed) binary table, no PROB /
        PROBDENSITY column, or a table larger than ``max_bytes``
        (:class:`~mushrooms.scheduler_core.errors.SkyMapError` is a ValueError).
    """
    import io

    from ..scheduler_core.sky.fitstable import open_table

    table = open_table(io.BytesIO(data), "combined sky map", size=None, hashed=False)
    if not set(table.names) & {"PROB", "PROBDENSITY"}:
        raise ValueError("no PROB or PROBDENSITY column")
    declared = table.rows * table.row_dtype.itemsize
    if max_bytes is not None and declared > max_bytes:
        raise ValueError(f"table of {declared} bytes exceeds the {max_bytes}-byte sky map limit")


def choose_localization(alert: Alert, use_combined: bool,
                        check: Callable[[bytes], None] = check_skymap) -> Localization | None:
    """The localisation to plan an alert on.

    Parameters
    ----------
    alert : Alert
        A parsed notice.
    use_combined : bool
        The policy's ``use_combined_skymap``.
    check : callable
        ``check(bytes)`` raises when the joint map is unusable.

    Returns
    -------
    Localization or None
        None when the alert has no sky map (a retraction).  The joint map
        when allowed, present and usable; otherwise the GW map, with the
        reason in ``note`` when a joint map was there but not used.
    """
    ev = alert.event
    if ev is None or not ev.skymap:
        return None
    gw = Localization(GW, ev.skymap, ev.skymap_sha256, joint_preferred=use_combined)
    ext = alert.external_coinc
    if ext is None or not ext.combined_skymap or not ext.combined_skymap_sha256:
        return gw
    if not use_combined:
        return Localization(GW, gw.skymap, gw.sha256, "combined sky map present; policy use_combined_skymap=false",
                            joint_preferred=False)
    try:
        check(ext.combined_skymap)
    except Exception as exc:  # any decoding failure means: fall back, never crash
        return Localization(GW, gw.skymap, gw.sha256,
                            f"combined sky map unusable ({type(exc).__name__}: {exc}); planning on the GW map")
    return Localization(COMBINED, ext.combined_skymap, ext.combined_skymap_sha256,
                        f"joint GW x {ext.observatory} {ext.search} localisation")


def skymap_for_sha(alert: Alert, sha256: str) -> tuple[str, bytes] | None:
    """The (kind, bytes) of the alert's map whose SHA-256 is ``sha256``, or None."""
    ev = alert.event
    if ev is None:
        return None
    ext = alert.external_coinc
    if ext is not None and ext.combined_skymap and ext.combined_skymap_sha256 == sha256:
        return COMBINED, ext.combined_skymap
    if ev.skymap and ev.skymap_sha256 == sha256:
        return GW, ev.skymap
    return None


def coincidence_summary(ext: ExternalCoinc | None) -> dict[str, Any] | None:
    """The external coincidence as it goes into a plan's event block (no map bytes)."""
    if ext is None:
        return None
    return {
        "observatory": ext.observatory,
        "search": ext.search,
        "ivorn": ext.ivorn,
        "gcn_notice_id": ext.gcn_notice_id,
        "time_difference_s": ext.time_difference,
        "time_coincidence_far_hz": ext.time_coincidence_far,
        "time_sky_position_coincidence_far_hz": ext.time_sky_position_coincidence_far,
        "combined_skymap_sha256": ext.combined_skymap_sha256,
    }
