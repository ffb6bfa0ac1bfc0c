"""LVK ``igwn.gwalert`` notices: parse JSON, Avro or (archived) VOEvent into an :class:`Alert`.

Every problem with a notice is a :class:`NoticeError` carrying one line that
says what is wrong: the caller records the notice as rejected and carries on.
The records themselves (:class:`Alert`, :class:`EventDetails`,
:class:`ExternalCoinc`) are :mod:`~mushrooms.handlers.alert_records`'s; they
are importable from here too.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import io
import json
import math
from datetime import datetime, timezone
from typing import Any, Mapping

import astropy.units as _u

from ..scheduler_core.errors import InputError
from ..scheduler_core.sky.sniff import sniff_fits
from .alert_records import ALERT_TYPES, Alert, EventDetails, ExternalCoinc, NoticeError
from .chirp_mass import parse_mchirp_source
from .text import storable

__all__ = [
    "Alert",
    "EventDetails",
    "ExternalCoinc",
    "NoticeError",
    "ALERT_TYPES",
    "parse_notice",
    "parse_time",
    "notice_time_created",
]

_ALIASES = {"EARLY_WARNING": "EARLYWARNING"}
_AVRO_MAGIC = b"Obj\x01"


_SECOND = _u.s


# ---------------------------------------------------------------- helpers


def parse_time(value: Any, what: str = "time") -> datetime:
    """ISO-8601 string to a timezone-aware UTC datetime (naive means UTC).

    The package's one parser (:func:`mushrooms.scheduler_core.times.parse_time`,
    no MJD in a notice); a leap second is read as the second before it.

    Raises
    ------
    NoticeError
        When ``value`` is not an ISO-8601 string.
    """
    from ..scheduler_core.times import parse_time as parse

    if not isinstance(value, str):
        raise NoticeError(f"{what} must be an ISO-8601 string, got {type(value).__name__}")
    try:
        t = parse(value, what)
    except InputError as exc:
        raise NoticeError(str(exc)) from None
    return (t if t.ymdhms.second < 60 else t - 1 * _SECOND).to_datetime(timezone.utc)


def _need(obj: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in obj:
        raise NoticeError(f"{where} lacks key {key!r}")
    return obj[key]


def _str(obj: Mapping[str, Any], key: str, where: str) -> str:
    v = _need(obj, key, where)
    if not isinstance(v, str):
        raise NoticeError(f"{where}.{key} must be a string, got {type(v).__name__}")
    return storable(v)


def _num(v: Any, name: str, optional: bool = False) -> float | None:
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise NoticeError(f"{name} must be a number, got {type(v).__name__}")
    x = float(v)
    if not math.isfinite(x):
        raise NoticeError(f"{name} must be finite, got {v!r}")
    return x


#: Longest key of a classification or properties object kept (characters; longer ones end with ``...``).
KEY_CHARS = 64


def _prob_map(v: Any, name: str) -> dict[str, float]:
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise NoticeError(f"{name} must be an object, got {type(v).__name__}")
    out: dict[str, float] = {}
    for k, x in v.items():
        if not isinstance(k, str):
            raise NoticeError(f"{name} keys must be strings")
        k = storable(k, KEY_CHARS)  # a key is a name (BNS, HasNS, has_SSM): a longer one is cut, not kept whole
        p = _num(x, f"{name}.{k}")
        assert p is not None
        if not 0.0 <= p <= 1.0 + 1e-9:
            raise NoticeError(f"{name}.{k} is not a probability: {x!r}")
        out[k] = p
    return out


def _fits_bytes(v: Any, name: str, raw: bool) -> bytes:
    """Sky map payload (base64 text in JSON, raw bytes in Avro) to FITS bytes."""
    if raw:
        if not isinstance(v, (bytes, bytearray)):
            raise NoticeError(f"{name} must be bytes, got {type(v).__name__}")
        data = bytes(v)
    else:
        if not isinstance(v, str):
            raise NoticeError(f"{name} must be a base64 string, got {type(v).__name__}")
        try:
            data = base64.b64decode(v, validate=True)
        except (binascii.Error, ValueError):
            raise NoticeError(f"{name} is not valid base64") from None
    if not data:
        raise NoticeError(f"{name} is empty")
    if sniff_fits(data) is None:
        raise NoticeError(f"{name} is not a FITS file (starts with {data[:8]!r})")
    return data


def _normalise_type(v: Any) -> str:
    if not isinstance(v, str):
        raise NoticeError(f"alert_type must be a string, got {type(v).__name__}")
    t = _ALIASES.get(v, v)
    if t not in ALERT_TYPES:
        raise NoticeError(f"unknown alert_type {v[:40]!r}")
    return t


def _superevent(v: Any) -> str:
    if not isinstance(v, str):
        raise NoticeError(f"superevent_id must be a string, got {type(v).__name__}")
    if not v or len(v) > 64 or not v.isascii() or not v.isalnum():
        raise NoticeError(f"superevent_id is not an id: {v[:40]!r}")
    return v


# ---------------------------------------------------------------- JSON / Avro


def _from_record(rec: Any, raw_bytes: bool, fmt: str) -> Alert:
    if not isinstance(rec, Mapping):
        raise NoticeError(f"notice must be an object, got {type(rec).__name__}")
    superevent_id = _superevent(_need(rec, "superevent_id", "notice"))
    alert_type = _normalise_type(_need(rec, "alert_type", "notice"))
    time_created = parse_time(_need(rec, "time_created", "notice"), "time_created")
    ev = rec.get("event")
    if alert_type == "RETRACTION":
        event = None
    else:
        if ev is None:
            raise NoticeError(f"{alert_type} notice has no event")
        event = _event(ev, raw_bytes)
    ext = rec.get("external_coinc")
    external = None if ext is None or alert_type == "RETRACTION" else _external(ext, raw_bytes)
    urls = rec.get("urls") or {}
    if not isinstance(urls, Mapping):
        raise NoticeError(f"urls must be an object, got {type(urls).__name__}")
    return Alert(
        superevent_id=superevent_id,
        alert_type=alert_type,
        time_created=time_created,
        event=event,
        external_coinc=external,
        urls={storable(k): storable(v) for k, v in urls.items()},
        format=fmt,
    )


def _event(ev: Any, raw_bytes: bool) -> EventDetails:
    if not isinstance(ev, Mapping):
        raise NoticeError(f"event must be an object, got {type(ev).__name__}")
    significant = _need(ev, "significant", "event")
    if not isinstance(significant, bool):
        raise NoticeError(f"event.significant must be true or false, got {type(significant).__name__}")
    instruments = ev.get("instruments", [])
    if not isinstance(instruments, (list, tuple)) or not all(isinstance(i, str) for i in instruments):
        raise NoticeError("event.instruments must be a list of strings")
    sky = _need(ev, "skymap", "event")
    skymap = b"" if sky is None else _fits_bytes(sky, "event.skymap", raw_bytes)  # null: schema 1.3.0, no map
    far = _num(_need(ev, "far", "event"), "event.far")
    assert far is not None
    if far < 0:
        raise NoticeError(f"event.far is negative: {far}")
    chirp, chirp_note = parse_mchirp_source(ev.get("mchirp_source"))
    return EventDetails(
        time=parse_time(_need(ev, "time", "event"), "event.time"),
        far=far,
        significant=significant,
        instruments=tuple(storable(i) for i in instruments),
        group=_str(ev, "group", "event"),
        pipeline=_str(ev, "pipeline", "event"),
        search=_str(ev, "search", "event"),
        classification=_prob_map(ev.get("classification"), "event.classification"),
        properties=_prob_map(ev.get("properties"), "event.properties"),
        skymap=skymap,
        skymap_sha256=hashlib.sha256(skymap).hexdigest(),
        duration=_num(ev.get("duration"), "event.duration", optional=True),
        central_frequency=_num(ev.get("central_frequency"), "event.central_frequency", optional=True),
        mchirp_source=chirp,
        mchirp_note=chirp_note,
    )


def _external(ext: Any, raw_bytes: bool) -> ExternalCoinc:
    if not isinstance(ext, Mapping):
        raise NoticeError(f"external_coinc must be an object, got {type(ext).__name__}")
    sky = ext.get("combined_skymap")
    data = b"" if sky is None else _fits_bytes(sky, "external_coinc.combined_skymap", raw_bytes)
    gid = ext.get("gcn_notice_id")  # schema 1.3.0: an integer or a string; informational, so a bad one is dropped
    if isinstance(gid, str):
        gid = storable(gid) if 0 < len(gid) <= 128 else None
    elif isinstance(gid, bool) or not isinstance(gid, int):
        gid = None
    return ExternalCoinc(
        observatory=_str(ext, "observatory", "external_coinc"),
        search=_str(ext, "search", "external_coinc"),
        ivorn=_str(ext, "ivorn", "external_coinc"),
        gcn_notice_id=gid,
        time_difference=_num(ext.get("time_difference"), "external_coinc.time_difference", True),
        time_coincidence_far=_num(ext.get("time_coincidence_far"), "external_coinc.time_coincidence_far", True),
        time_sky_position_coincidence_far=_num(
            ext.get("time_sky_position_coincidence_far"), "external_coinc.time_sky_position_coincidence_far", True),
        combined_skymap=data,
        combined_skymap_sha256=hashlib.sha256(data).hexdigest() if data else None,
    )


def _parse_json(data: bytes) -> Alert:
    try:
        rec = json.loads(data)
    except UnicodeDecodeError:
        raise NoticeError("notice is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise NoticeError(f"notice is not valid JSON ({exc.msg} at byte {exc.pos})") from None
    except RecursionError:
        raise NoticeError("notice JSON is nested too deeply") from None
    return _from_record(rec, raw_bytes=False, fmt="json")


def _parse_avro(data: bytes) -> Alert:
    import fastavro

    try:
        reader = fastavro.reader(io.BytesIO(data))
        records = []
        for rec in reader:
            records.append(rec)
            if len(records) > 1:
                break
    except Exception as exc:  # fastavro raises many types on corrupt input
        raise NoticeError(f"notice is not a readable Avro container ({type(exc).__name__}: {str(exc)[:80]})") from None
    if len(records) != 1:
        found = "more than one" if len(records) > 1 else "none"
        raise NoticeError(f"Avro notice must hold exactly one record, found {found}")
    return _from_record(records[0], raw_bytes=True, fmt="avro")


# ---------------------------------------------------------------- VOEvent (archived GCN Classic)

_VOE_TYPES = {
    "EARLY_WARNING": "EARLYWARNING", "EARLYWARNING": "EARLYWARNING", "PRELIMINARY": "PRELIMINARY",
    "INITIAL": "INITIAL", "UPDATE": "UPDATE", "RETRACTION": "RETRACTION",
}


def _parse_voevent(data: bytes) -> Alert:
    from xml.etree.ElementTree import ParseError

    import defusedxml
    from defusedxml.ElementTree import fromstring

    try:  # no DTD, no entities, no external references, whatever the encoding
        root = fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except defusedxml.DefusedXmlException as exc:
        raise NoticeError(f"VOEvent with a DOCTYPE, entity or external reference is refused "
                          f"({type(exc).__name__})") from None
    except ParseError as exc:
        raise NoticeError(f"notice is not well-formed XML ({exc})") from None
    if not root.tag.endswith("VOEvent"):
        raise NoticeError(f"XML root is {root.tag!r}, not a VOEvent")
    params: dict[str, str] = {}
    groups: dict[str, dict[str, str]] = {}
    what = next((c for c in root if c.tag.endswith("What")), None)
    if what is None:
        raise NoticeError("VOEvent has no What section")
    for el in what.iter():
        if el.tag.endswith("Param") and "name" in el.attrib:
            params.setdefault(el.attrib["name"], storable(el.attrib.get("value", "")))
    for g in what:
        if g.tag.endswith("Group"):
            key = g.attrib.get("type") or g.attrib.get("name") or ""
            groups[key] = {p.attrib["name"]: p.attrib.get("value", "")
                           for p in g if p.tag.endswith("Param") and "name" in p.attrib}
    superevent_id = _superevent(params.get("GraceID", ""))
    alert_type = _VOE_TYPES.get(params.get("AlertType", "").upper())
    if alert_type is None:
        raise NoticeError(f"unknown VOEvent AlertType {params.get('AlertType', '')[:40]!r}")
    who = next((c for c in root if c.tag.endswith("Who")), None)
    date = None if who is None else next((c.text for c in who if c.tag.endswith("Date")), None)
    time_created = parse_time(date, "Who/Date")
    if alert_type == "RETRACTION":
        return Alert(superevent_id, alert_type, time_created, None, None, {}, "voevent")
    iso = None
    for el in root.iter():
        if el.tag.endswith("ISOTime"):
            iso = el.text
            break
    url = groups.get("GW_SKYMAP", {}).get("skymap_fits") or params.get("skymap_fits")
    if not url:
        raise NoticeError("VOEvent has no skymap_fits URL")

    def prob(group: str) -> dict[str, float]:
        vals = groups.get(group, {})
        out = {}
        for k, v in vals.items():
            try:
                out[k] = float(v)
            except ValueError:
                raise NoticeError(f"VOEvent {group}.{k} is not a number: {v[:20]!r}") from None
        return out

    try:
        far = float(params.get("FAR", "nan"))
    except ValueError:
        raise NoticeError("VOEvent FAR is not a number") from None
    if not math.isfinite(far):
        raise NoticeError("VOEvent has no FAR")
    sig = params.get("Significant")
    event = EventDetails(
        time=parse_time(iso, "WhereWhen ISOTime"),
        far=far,
        significant=(sig == "1") if sig is not None else True,
        instruments=tuple(i for i in params.get("Instruments", "").split(",") if i),
        group=params.get("Group", ""),
        pipeline=params.get("Pipeline", ""),
        search=params.get("Search", ""),
        classification=prob("Classification"),
        properties=prob("Properties"),
        skymap=b"",
        skymap_sha256=hashlib.sha256(url.encode()).hexdigest(),
        skymap_url=url,
    )
    return Alert(superevent_id, alert_type, time_created, event, None, {}, "voevent")


# ---------------------------------------------------------------- entry points


def parse_notice(data: bytes, max_bytes: int | None = None) -> Alert:
    """Parse one notice: JSON (GCN Kafka), Avro container (SCiMMA) or VOEvent XML.

    Parameters
    ----------
    data : bytes
        The message value or file content.
    max_bytes : int, optional
        Refuse anything larger (bytes) before decoding it.

    Returns
    -------
    Alert

    Raises
    ------
    NoticeError
        One line saying what is wrong.  Nothing else escapes for any input.
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise NoticeError(f"notice must be bytes, got {type(data).__name__}")
    data = bytes(data)
    if max_bytes is not None and len(data) > max_bytes:
        raise NoticeError(f"notice of {len(data)} bytes exceeds the {max_bytes}-byte limit")
    if not data.strip():
        raise NoticeError("notice is empty")
    try:
        if data.startswith(_AVRO_MAGIC):
            return _parse_avro(data)
        head = data.lstrip()[:64]
        if head.startswith(b"<"):
            return _parse_voevent(data)
        if head.startswith((b"{", b"[")) or head[:3] == b"\xef\xbb\xbf":
            return _parse_json(data[3:] if data[:3] == b"\xef\xbb\xbf" else data)
        raise NoticeError(f"notice is neither JSON, Avro nor VOEvent (starts with {data[:8]!r})")
    except NoticeError:
        raise
    except (MemoryError, RecursionError) as exc:
        raise NoticeError(f"notice could not be parsed ({type(exc).__name__})") from None
    except Exception as exc:  # a parser bug must still be a one-line rejection
        raise NoticeError(f"notice could not be parsed ({type(exc).__name__}: {str(exc)[:80]})") from None


def notice_time_created(data: bytes, max_bytes: int | None = None) -> datetime | None:
    """The notice's ``time_created``, or None when it cannot be parsed (for sorting replays)."""
    try:
        return parse_notice(data, max_bytes).time_created
    except NoticeError:
        return None
