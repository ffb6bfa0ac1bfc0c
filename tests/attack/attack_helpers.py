"""Shared bits of the attack suite: real notices and sky maps turned hostile.

Every helper builds a message a hostile or broken sender could put on the
topic; the tests (fast) and ``benchmarks/attacks/attack.py`` (heavy) feed them to
the real pipeline, store and daemon.
"""

from __future__ import annotations

import base64
import gzip
import io
import json
import zlib
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from mushrooms.tool.config import Config
from mushrooms.handlers.policy import PolicyConfig
from mushrooms.scheduler_core import PlanningConfig

TESTS = Path(__file__).resolve().parents[1]
REPO = TESTS.parent
NOTICES = TESTS / "data" / "notices"
BASE_NOTICE = NOTICES / "json" / "MS181101ab-preliminary.json"
VOEVENT = NOTICES / "voevent" / "MS181101ab-2-Preliminary.xml"
MOC_MAP = TESTS / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"

#: greedy at a coarse resolution: a plan in one to two seconds; no age cuts (archived notices)
FAST = Config(scheduler=PlanningConfig(solver="greedy", nside=64, time_step_s=600.0),
              policy=PolicyConfig(allow_mock=True, max_notice_age_s=0, max_event_age_s=0))


def base_doc() -> dict[str, Any]:
    """The sample PRELIMINARY notice as a dict (a fresh copy)."""
    return json.loads(BASE_NOTICE.read_bytes())


def received_at() -> datetime:
    """The receipt clock of the sample notice (its own time_created)."""
    return datetime(2018, 11, 1, 22, 35, tzinfo=timezone.utc)


def notice_with(superevent_id: str | None = None, skymap: bytes | None = None, **event: Any) -> bytes:
    """The sample notice with a new id, sky map bytes or event fields."""
    doc = base_doc()
    if superevent_id is not None:
        doc["superevent_id"] = superevent_id
    if skymap is not None:
        doc["event"]["skymap"] = base64.b64encode(skymap).decode()
    doc["event"].update(event)
    return json.dumps(doc).encode()


def fits_bomb(unpacked_bytes: int, chunk: int = 1 << 24) -> bytes:
    """gzip of a FITS primary header followed by zeros: tiny packed, huge unpacked."""
    header = (b"SIMPLE  =                    T" + b" " * 50 + b"END" + b" " * 77).ljust(2880, b" ")
    z = zlib.compressobj(9, zlib.DEFLATED, 31)
    parts = [z.compress(header)]
    zeros = bytes(chunk)
    left = unpacked_bytes - len(header)
    while left > 0:
        parts.append(z.compress(zeros[:min(chunk, left)]))
        left -= chunk
    parts.append(z.flush())
    return b"".join(parts)


def grown_gzip(extra_bytes: int, chunk: int = 1 << 24) -> bytes:
    """gzip of a real sky map followed by ``extra_bytes`` zeros: a valid table, then a bomb past it."""
    z = zlib.compressobj(9, zlib.DEFLATED, 31)
    parts = [z.compress(MOC_MAP.read_bytes())]
    zeros = bytes(chunk)
    while extra_bytes > 0:
        parts.append(z.compress(zeros[:min(chunk, extra_bytes)]))
        extra_bytes -= chunk
    parts.append(z.flush())
    return b"".join(parts)


def broken_gzip() -> bytes:
    """A real sky map, gzipped, cut short (a truncated download)."""
    packed = gzip.compress(MOC_MAP.read_bytes())
    return packed[: len(packed) // 2]


def moc_with_uniq(change: str) -> bytes:
    """The sample multi-order map with its UNIQ column made invalid.

    ``change``: ``zero`` (an index below 4), ``order30`` (beyond HEALPix
    order 29), ``duplicate`` (one pixel twice) or ``overlap`` (a pixel and
    its parent both present).
    """
    from astropy.table import Table

    t = Table.read(MOC_MAP, format="fits")
    uniq = np.array(t["UNIQ"], dtype=np.int64)
    if change == "zero":
        uniq[0] = 0
    elif change == "order30":
        uniq[0] = 4 * 4**30 + 5
    elif change == "duplicate":
        uniq[1] = uniq[0]
    elif change == "overlap":
        uniq[1] = uniq[0] // 4 if uniq[0] // 4 >= 4 else uniq[0] * 4
    else:
        raise ValueError(change)
    t["UNIQ"] = uniq
    buf = io.BytesIO()
    t.write(buf, format="fits")
    return buf.getvalue()


def utf16_voevent_with_entity() -> bytes:
    """The sample VOEvent in UTF-16 (no BOM) with an internal entity in a value."""
    text = VOEVENT.read_text()
    body = text.split("?>", 1)[1]
    doc = ('<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE x [<!ENTITY g "CBC">]>'
           + body.replace('name="Group" ucd="meta.code" value="CBC"', 'name="Group" ucd="meta.code" value="&g;"'))
    return doc.encode("utf-16-le")


def hostile_corpus() -> list[tuple[str, bytes]]:
    """Malformed, hostile and odd messages (name, bytes): every one must get exactly one decision row."""
    doc = base_doc()
    ok = json.dumps(doc).encode()
    out: list[tuple[str, bytes]] = [
        ("empty", b""), ("spaces", b"   \n"), ("nul bytes", b"\0" * 100), ("binary", bytes(range(256)) * 4),
        ("not utf-8", b'{"a": "\xff\xfe"}'), ("json list", b"[1,2,3]"), ("json number", b"42"),
        ("truncated json", ok[: len(ok) // 2]), ("deep json", b"[" * 100_000 + b"]" * 100_000),
        ("huge number", b'{"superevent_id": "S1", "x": ' + b"9" * 5000 + b"}"),
        ("bom json", b"\xef\xbb\xbf" + ok), ("avro magic junk", b"Obj\x01" + bytes(500)),
        ("xml junk", b"<not xml"), ("xml root", b"<?xml version='1.0'?><x/>"),
        ("xml entity", b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaa">]><x>&a;</x>'),
        ("xml external", b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]><x>&e;</x>'),
        ("utf-16 voevent entity", utf16_voevent_with_entity()),
        ("voevent", VOEVENT.read_bytes()),
        ("oversize", b"{" + b" " * (8 * 1024 * 1024 + 10) + b"}"),
    ]

    def variant(name: str, change) -> None:
        d = base_doc()
        change(d)
        out.append((name, json.dumps(d).encode()))

    variant("no event", lambda d: d.pop("event"))
    variant("event null", lambda d: d.update(event=None))
    variant("bad id", lambda d: d.update(superevent_id="../../etc"))
    variant("id surrogate", lambda d: d.update(superevent_id="S1\ud800"))
    variant("group surrogate", lambda d: d["event"].update(group="CBC\ud800"))
    variant("search newline", lambda d: d["event"].update(search="MDC\nevent=forged"))
    variant("bad alert type", lambda d: d.update(alert_type="PWNED"))
    variant("time 2200", lambda d: d["event"].update(time="2200-01-01T00:00:00Z"))
    variant("time 9999", lambda d: d["event"].update(time="9999-12-31T23:59:59Z"))
    variant("created 9999", lambda d: d.update(time_created="9999-12-31T23:59:59Z"))
    variant("time overflow", lambda d: d["event"].update(time="9999-12-31T23:59:59-05:00"))
    variant("time garbage", lambda d: d["event"].update(time="yesterday"))
    variant("far nan", lambda d: d["event"].update(far="NaN"))
    variant("far negative", lambda d: d["event"].update(far=-1))
    variant("p > 1", lambda d: d["event"]["classification"].update(BNS=7))
    variant("skymap not base64", lambda d: d["event"].update(skymap="!!!"))
    variant("skymap not fits", lambda d: d["event"].update(skymap=base64.b64encode(b"hello").decode()))
    variant("skymap broken gzip", lambda d: d["event"].update(skymap=base64.b64encode(broken_gzip()).decode()))
    variant("skymap bad uniq", lambda d: d["event"].update(skymap=base64.b64encode(moc_with_uniq("duplicate")).decode()))
    variant("retraction", lambda d: d.update(alert_type="RETRACTION", event=None))
    return out


def amplifying_map(order: int = 6) -> bytes:
    """gzip of a flat float32 NSIDE 1024 NESTED map (50 MB unpacked, ~100 kB packed): the sample
    map rasterised at ``order`` and upgraded to order 10 as ``healpy.ud_grade`` does (children share
    their parent's probability), the kind of map of the amplifying notices (a small notice, a huge map)."""
    from astropy.io import fits
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    prob = np.asarray(rasterize(read_sky_map(str(MOC_MAP), moc=True), order=order)["PROB"], float)
    k = 4 ** (10 - order)
    flat = (np.repeat(prob, k) / k).astype(np.float32)
    hdu = fits.BinTableHDU.from_columns([fits.Column(name="PROB", format="E", array=flat)])
    hdu.header.update({"PIXTYPE": "HEALPIX", "ORDERING": "NESTED", "NSIDE": 1024, "INDXSCHM": "IMPLICIT"})
    buf = io.BytesIO()
    fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(buf)
    return gzip.compress(buf.getvalue(), 9)


def joint_notice(superevent_id: str, gw_map: bytes, combined_map: bytes) -> bytes:
    """The sample notice with a GRB coincidence (MS181101ab-ext-update) carrying these two maps."""
    doc = json.loads((NOTICES / "json" / "MS181101ab-ext-update.json").read_bytes())
    doc["superevent_id"] = superevent_id
    doc["alert_type"] = "PRELIMINARY"
    doc["event"]["skymap"] = base64.b64encode(gw_map).decode()
    doc["external_coinc"]["combined_skymap"] = base64.b64encode(combined_map).decode()
    return json.dumps(doc).encode()
