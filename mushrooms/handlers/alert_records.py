"""What a parsed LVK notice is: :class:`Alert`, its :class:`EventDetails` and :class:`ExternalCoinc`.

Small frozen records; the parsers that build them are :mod:`~mushrooms.handlers.alert`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Mapping

from ..scheduler_core.errors import InputError
from .chirp_mass import ChirpMass

__all__ = ["Alert", "EventDetails", "ExternalCoinc", "NoticeError", "ALERT_TYPES"]

ALERT_TYPES = ("EARLYWARNING", "PRELIMINARY", "INITIAL", "UPDATE", "RETRACTION")


class NoticeError(InputError):
    """A notice that cannot be understood; the message says why in one line."""


@dataclass(frozen=True)
class EventDetails:
    """The ``event`` object of a notice (absent for a RETRACTION).

    Attributes
    ----------
    time : datetime
        Merger (event) time, timezone-aware UTC.
    far : float
        False-alarm rate (Hz).
    significant : bool
        LVK's significance flag.
    instruments : tuple of str
        Detectors, e.g. ``("H1", "L1", "V1")``.
    group, pipeline, search : str
        ``CBC``/``Burst``; e.g. ``gstlal``; e.g. ``AllSky``, ``MDC``.
    classification : dict of str to float
        Source-class probabilities (``BNS``, ``NSBH``, ``BBH``, ``Terrestrial``); empty for Burst.
    properties : dict of str to float
        ``HasNS``, ``HasRemnant``, ``HasMassGap``, ...; may be empty.
    skymap : bytes
        The decoded multi-order FITS sky map (b"" for a VOEvent, see ``skymap_url``, and for a
        notice whose ``event.skymap`` is null, which schema 1.3.0 allows).
    skymap_sha256 : str
        Hex SHA-256 of ``skymap`` (of the URL text for a VOEvent).
    duration, central_frequency : float or None
        Burst-only properties (s, Hz).
    skymap_url : str or None
        Sky map URL (VOEvent notices only; not downloaded).
    mchirp_source : ChirpMass or None
        Source-frame chirp-mass bins (schema 1.3.0's optional ``event.mchirp_source``).
    mchirp_note : str
        Why a malformed ``mchirp_source`` was left out ("" when absent or used).
    """

    time: datetime
    far: float
    significant: bool
    instruments: tuple[str, ...]
    group: str
    pipeline: str
    search: str
    classification: Mapping[str, float]
    properties: Mapping[str, float]
    skymap: bytes = field(repr=False)
    skymap_sha256: str
    duration: float | None = None
    central_frequency: float | None = None
    skymap_url: str | None = None
    mchirp_source: ChirpMass | None = None
    mchirp_note: str = ""

    @property
    def has_skymap(self) -> bool:
        """The notice carries a sky map (bytes, or a VOEvent's URL)."""
        return bool(self.skymap) or self.skymap_url is not None


@dataclass(frozen=True)
class ExternalCoinc:
    """The ``external_coinc`` object: a coincident external (e.g. GRB) trigger.

    Attributes
    ----------
    observatory, search, ivorn : str
        Where the external trigger came from.
    gcn_notice_id : int, str or None
        GCN notice id of the external trigger (schema 1.3.0: an integer or a string).
    time_difference : float or None
        External minus GW time (s).
    time_coincidence_far, time_sky_position_coincidence_far : float or None
        Joint FARs (Hz).
    combined_skymap : bytes
        Decoded combined sky map FITS (may be b"").
    combined_skymap_sha256 : str or None
        Its SHA-256 (None when empty).
    """

    observatory: str
    search: str
    ivorn: str
    gcn_notice_id: int | str | None
    time_difference: float | None
    time_coincidence_far: float | None
    time_sky_position_coincidence_far: float | None
    combined_skymap: bytes = field(repr=False, default=b"")
    combined_skymap_sha256: str | None = None


@dataclass(frozen=True)
class Alert:
    """One parsed LVK alert notice.

    Attributes
    ----------
    superevent_id : str
        GraceDB superevent, e.g. ``S230518h``; ``MS...`` mock, ``TS...`` test.
    alert_type : str
        One of :data:`ALERT_TYPES` (``EARLY_WARNING`` is normalised to ``EARLYWARNING``).
    time_created : datetime
        When LVK created the notice (timezone-aware UTC).
    event : EventDetails or None
        None for a RETRACTION.
    external_coinc : ExternalCoinc or None
        Coincident external trigger, if any.
    urls : dict of str to str
        Links (``gracedb``).
    format : str
        ``json``, ``avro`` or ``voevent``.
    """

    superevent_id: str
    alert_type: str
    time_created: datetime
    event: EventDetails | None
    external_coinc: ExternalCoinc | None = None
    urls: Mapping[str, str] = field(default_factory=dict)
    format: str = "json"

    @property
    def skymap(self) -> bytes | None:
        """The decoded sky map bytes, or None (retraction)."""
        return None if self.event is None else self.event.skymap

    @property
    def skymap_sha256(self) -> str | None:
        """SHA-256 (hex) of the sky map, or None (retraction)."""
        return None if self.event is None else self.event.skymap_sha256

    @property
    def is_retraction(self) -> bool:
        return self.alert_type == "RETRACTION"

    def summary(self) -> str:
        """One line for logs."""
        if self.event is None:
            return f"{self.superevent_id} {self.alert_type} {self.time_created.isoformat()}"
        ev = self.event
        cls = ",".join(f"{k}={v:.3g}" for k, v in sorted(ev.classification.items()))
        return (f"{self.superevent_id} {self.alert_type} {ev.group}/{ev.pipeline}/{ev.search} "
                f"FAR={ev.far:.3g}Hz significant={ev.significant} [{cls}] map={ev.skymap_sha256[:12]}")
