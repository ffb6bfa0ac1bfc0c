"""Hostile input, fast cases: bombs, broken maps, bad UNIQ, future times,
unstorable text, hostile XML.  Real sky maps, real SQLite, real pipeline.

The heavy versions (a 1 GiB bomb with peak RSS, a 50-event burst, SIGKILL
at several points) are ``benchmarks/attacks/attack.py``.
"""

from __future__ import annotations

import dataclasses
import json

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.handlers.alert import NoticeError, parse_notice
from mushrooms.scheduler_core import read_skymap
from mushrooms.scheduler_core.errors import SkyMapError

from attack_helpers import (
    FAST, MOC_MAP, base_doc, broken_gzip, fits_bomb, grown_gzip, moc_with_uniq, notice_with, received_at,
    utf16_voevent_with_entity,
)


@pytest.fixture
def pipeline(tmp_path):
    store = Store(tmp_path / "state.sqlite")
    yield NoticePipeline.from_config(FAST, store, MemorySink())
    store.close()


def one_decision_per_notice(store: Store) -> None:
    rows = store.connection().execute(
        "SELECT n.notice_id, COUNT(d.decision_id) FROM notices n LEFT JOIN decisions d USING(notice_id)"
        " GROUP BY n.notice_id").fetchall()
    assert rows and all(count == 1 for _, count in rows), [tuple(r) for r in rows]


# ---------------------------------------------------------------- 1. decompression bomb
def test_a_gzip_bomb_is_refused_by_its_header_without_unpacking_it() -> None:
    bomb = fits_bomb(64 << 20)  # a primary header without NAXIS, then 64 MiB of zeros, ~64 KiB packed
    with pytest.raises(SkyMapError, match="NAXIS") as err:
        read_skymap(bomb, nside=64)
    assert "\n" not in str(err.value)


def test_a_gzip_grown_past_its_declared_table_is_refused() -> None:
    """A valid map, then 64 MiB of zeros: reading stops at the declared table, the rest is refused
    (the first block past it is unpacked, not the 64 MiB: timed in benchmarks/speed/skymap_memory.py)."""
    bomb = grown_gzip(64 << 20)
    with pytest.raises(SkyMapError, match="more bytes follow its declared table"):
        read_skymap(bomb, nside=64)


def test_a_bomb_in_a_notice_is_a_rejected_job(pipeline: NoticePipeline) -> None:
    acc = pipeline.accept(notice_with("MS181101ab", skymap=grown_gzip(32 << 20)), "attack:bomb", received_at())
    assert acc.job is not None
    out = pipeline.run_job(acc.job)
    assert out.decision == "rejected" and "more bytes follow its declared table" in out.reason


def _flat_gzip(order: int) -> bytes:
    """The sample multi-order map rasterised to a flat one-column NESTED map (ligo.skymap), gzipped."""
    import gzip
    import io

    import numpy as np
    from astropy.io import fits
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    prob = np.asarray(rasterize(read_sky_map(str(MOC_MAP), moc=True), order=order)["PROB"], float)
    hdu = fits.BinTableHDU.from_columns([fits.Column(name="PROB", format="D", array=prob)])
    hdu.header.update({"PIXTYPE": "HEALPIX", "ORDERING": "NESTED", "NSIDE": 1 << order, "INDXSCHM": "IMPLICIT"})
    buf = io.BytesIO()
    fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(buf)
    return gzip.compress(buf.getvalue())


def test_max_skymap_bytes_bounds_what_is_carried_not_what_it_unpacks_to(pipeline: NoticePipeline) -> None:
    """A flat NSIDE 512 map: 25 MB unpacked, a few hundred kB packed.  Under a 1 MiB max_skymap_bytes
    it is planned, by ``mushrooms trigger`` (accept_skymap) and in a notice; (before the streaming reader both
    refused it: "unpacks to more than 1 MiB"); a map over 1 MiB as carried is refused unread."""
    flat = _flat_gzip(9)
    assert len(flat) < 1 << 20
    config = dataclasses.replace(FAST, policy=dataclasses.replace(FAST.policy, max_skymap_bytes=1 << 20))
    p = NoticePipeline.from_config(config, pipeline.store, pipeline.sink)
    acc = p.accept_skymap(flat, "trigger:flat")
    assert acc.action == "plan" and p.run_job(acc.job).decision == "plan"
    acc = p.accept(notice_with("MS181101ab", skymap=flat), "attack:flat", received_at())
    assert p.run_job(acc.job).decision == "plan"
    too_big = flat + bytes((1 << 20) + 1 - len(flat))
    acc = p.accept_skymap(too_big, "trigger:big")
    assert acc.action == "rejected" and "max_skymap_bytes" in acc.reason


# ---------------------------------------------------------------- 8. broken gzip, bad UNIQ
def test_a_truncated_gzip_map_is_a_one_line_sky_map_error() -> None:
    with pytest.raises(SkyMapError, match="gzip"):
        read_skymap(broken_gzip(), nside=64)


def test_a_truncated_gzip_map_in_a_notice_is_rejected_not_failed(pipeline: NoticePipeline) -> None:
    acc = pipeline.accept(notice_with("MS181101ab", skymap=broken_gzip()), "attack:gz", received_at())
    out = pipeline.run_job(acc.job)
    assert out.decision == "rejected", out


@pytest.mark.parametrize("change", ["zero", "order30", "duplicate", "overlap"])
def test_a_multi_order_map_with_invalid_uniq_is_refused(change: str) -> None:
    read_skymap(MOC_MAP, nside=64)  # the untouched map reads
    with pytest.raises(SkyMapError, match="UNIQ"):
        read_skymap(moc_with_uniq(change), nside=64)


# ---------------------------------------------------------------- 3. times in the future
@pytest.mark.parametrize("field,value", [
    ("event.time", "2200-01-01T00:00:00Z"),
    ("event.time", "9999-12-31T23:00:00Z"),
    ("time_created", "2200-01-01T00:00:00Z"),
])
def test_an_event_or_notice_dated_in_the_future_is_rejected(pipeline: NoticePipeline, field: str,
                                                            value: str) -> None:
    doc = base_doc()
    if field == "time_created":
        doc["time_created"] = value
    else:
        doc["event"]["time"] = value
    acc = pipeline.accept(json.dumps(doc).encode(), "attack:future", received_at())
    assert acc.action == "rejected" and acc.job is None
    # year 9999 is refused by the package's one time parser (span 1800-2200) before the policy's clock check
    assert "future" in acc.reason or "outside 1800-01-01 to 2200-01-01" in acc.reason
    one_decision_per_notice(pipeline.store)


def test_a_few_seconds_of_clock_skew_is_tolerated(pipeline: NoticePipeline) -> None:
    doc = base_doc()
    doc["time_created"] = "2018-11-01T22:35:20Z"  # 20 s after our clock
    acc = pipeline.accept(json.dumps(doc).encode(), "attack:skew", received_at())
    assert acc.action == "plan"


# ---------------------------------------------------------------- 4. text that SQLite refuses
@pytest.mark.parametrize("where", ["group", "pipeline", "search", "instrument", "url", "class_key"])
def test_a_lone_surrogate_still_gets_exactly_one_decision_row(pipeline: NoticePipeline, where: str) -> None:
    doc = base_doc()
    bad = "CBC\ud800x"
    if where in ("group", "pipeline", "search"):
        doc["event"][where] = bad
    elif where == "instrument":
        doc["event"]["instruments"] = ["H1", bad]
    elif where == "url":
        doc["urls"] = {"gracedb": bad}
    else:
        doc["event"]["classification"] = {bad: 0.5}
    raw = json.dumps(doc).encode()  # json escapes it as \ud800: valid JSON, invalid Unicode
    acc = pipeline.accept(raw, "attack:surrogate", received_at())
    assert acc.action in ("ignore", "plan", "rejected")
    one_decision_per_notice(pipeline.store)
    (row,) = pipeline.store.decisions()
    row["reason"].encode("utf-8")  # storable and printable


# ---------------------------------------------------------------- 8. hostile XML
def test_a_voevent_with_an_entity_declaration_is_refused_in_any_encoding() -> None:
    with pytest.raises(NoticeError, match="(?i)DTD|entit"):
        parse_notice(utf16_voevent_with_entity())


def test_billion_laughs_is_refused_quickly() -> None:
    lol = ('<?xml version="1.0"?><!DOCTYPE l [<!ENTITY a "lol">'
           + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(8))
           + ']><voe:VOEvent xmlns:voe="x"><What><Param name="GraceID" value="&i;"/></What></voe:VOEvent>')
    with pytest.raises(NoticeError):
        parse_notice(lol.encode("utf-16-le"))
