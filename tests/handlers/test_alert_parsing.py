"""Parsing real igwn.gwalert notices (JSON, Avro, VOEvent) and refusing bad ones."""

from __future__ import annotations

import base64
import hashlib
import json
from datetime import datetime, timezone

import pytest

from mushrooms.handlers.alert import ALERT_TYPES, NoticeError, parse_notice
from mushrooms.scheduler_core.errors import InputError

from notice_helpers import NOTICES, dumps, notice_bytes, notice_dict

FITS_SHA = "db875e1b8cc81426"  # the User Guide's BAYESTAR map (shared SOURCES.md)


def test_preliminary_json_fields():
    a = parse_notice(notice_bytes("json/MS181101ab-preliminary.json"))
    assert a.superevent_id == "MS181101ab"
    assert a.alert_type == "PRELIMINARY"
    assert a.format == "json"
    assert a.time_created == datetime(2018, 11, 1, 22, 34, 49, tzinfo=timezone.utc)
    ev = a.event
    assert ev.time == datetime(2018, 11, 1, 22, 22, 46, 654000, tzinfo=timezone.utc)
    assert ev.far == pytest.approx(9.11069936486e-14)
    assert ev.significant is True
    assert ev.instruments == ("H1", "L1", "V1")
    assert (ev.group, ev.pipeline, ev.search) == ("CBC", "gstlal", "MDC")
    assert ev.classification["BNS"] == pytest.approx(0.95)
    assert ev.properties["HasNS"] == pytest.approx(0.95)
    assert ev.skymap.startswith(b"SIMPLE  =")
    assert len(ev.skymap) == 777600
    assert ev.skymap_sha256 == hashlib.sha256(ev.skymap).hexdigest()
    assert ev.skymap_sha256.startswith(FITS_SHA)
    assert a.skymap_sha256 == ev.skymap_sha256
    assert a.external_coinc is None
    assert "gracedb" in a.urls


def test_every_json_notice_parses_with_the_same_sky_map():
    types = []
    for p in sorted((NOTICES / "json").glob("*.json")):
        a = parse_notice(p.read_bytes())
        types.append(a.alert_type)
        if a.alert_type != "RETRACTION":
            assert a.skymap_sha256.startswith(FITS_SHA)
    assert sorted(set(types)) == sorted(ALERT_TYPES)


def test_retraction_has_no_event():
    a = parse_notice(notice_bytes("json/MS181101ab-retraction.json"))
    assert a.alert_type == "RETRACTION"
    assert a.event is None and a.skymap is None and a.skymap_sha256 is None
    assert a.is_retraction


def test_external_coinc_is_decoded():
    a = parse_notice(notice_bytes("json/MS181101ab-ext-update.json"))
    ext = a.external_coinc
    assert ext.observatory == "Fermi" and ext.search == "GRB"
    assert ext.time_difference == pytest.approx(2.02)
    assert ext.combined_skymap.startswith(b"SIMPLE")
    assert ext.combined_skymap_sha256 == hashlib.sha256(ext.combined_skymap).hexdigest()


def test_real_burst_candidate():
    a = parse_notice(notice_bytes("live/S230528ay-preliminary.json"))
    assert a.superevent_id == "S230528ay"
    ev = a.event
    assert (ev.group, ev.pipeline, ev.search, ev.significant) == ("Burst", "oLIB", "AllSky", False)
    assert ev.classification == {} and ev.properties == {}
    assert ev.duration == pytest.approx(0.0013956958745169087)
    assert ev.central_frequency == pytest.approx(487.32952931440246)


def test_avro_twin_matches_json():
    j = parse_notice(notice_bytes("json/MS181101ab-earlywarning.json"))
    a = parse_notice(notice_bytes("avro/MS181101ab-earlywarning.avro"))
    assert a.format == "avro"
    for name in ("superevent_id", "alert_type", "time_created"):
        assert getattr(a, name) == getattr(j, name)
    assert a.event.skymap_sha256 == j.event.skymap_sha256
    assert dict(a.event.classification) == pytest.approx(dict(j.event.classification))
    r = parse_notice(notice_bytes("avro/MS181101ab-retraction.avro"))
    assert r.alert_type == "RETRACTION" and r.event is None


def test_old_early_warning_spelling_is_normalised():
    d = notice_dict("json/MS181101ab-earlywarning.json")
    d["alert_type"] = "EARLY_WARNING"
    assert parse_notice(dumps(d)).alert_type == "EARLYWARNING"


def test_voevent_gives_the_skymap_url():
    a = parse_notice(notice_bytes("voevent/MS181101ab-2-Preliminary.xml"))
    assert (a.superevent_id, a.alert_type, a.format) == ("MS181101ab", "PRELIMINARY", "voevent")
    assert a.event.skymap == b""
    assert a.event.skymap_url.startswith("https://") and "multiorder.fits" in a.event.skymap_url
    assert a.event.classification["BNS"] == pytest.approx(0.95)
    r = parse_notice(notice_bytes("voevent/MS181101ab-5-Retraction.xml"))
    assert r.alert_type == "RETRACTION" and r.event is None


# ------------------------------------------------------------------ bad input

def _mutated(**changes):
    d = notice_dict("json/MS181101ab-preliminary.json")
    for path, value in changes.items():
        obj = d
        keys = path.split("__")
        for k in keys[:-1]:
            obj = obj[k]
        if value is KeyError:
            del obj[keys[-1]]
        else:
            obj[keys[-1]] = value
    return dumps(d)


NOT_FITS = base64.b64encode(b"<html>not a sky map</html>" * 10).decode()

BAD = {
    "truncated JSON": (notice_bytes("json/MS181101ab-preliminary.json")[:5000], "not valid JSON"),
    "invalid base64": (_mutated(event__skymap="@@@not base64@@@"), "not valid base64"),
    "sky map not FITS": (_mutated(event__skymap=NOT_FITS), "not a FITS file"),
    "missing superevent_id": (_mutated(superevent_id=KeyError), "lacks key 'superevent_id'"),
    "missing event.far": (_mutated(event__far=KeyError), "lacks key 'far'"),
    "missing event": (_mutated(event=None), "has no event"),
    "far is a string": (_mutated(event__far="tiny"), "event.far must be a number"),
    "significant is 1": (_mutated(event__significant=1), "event.significant must be true or false"),
    "classification is a list": (_mutated(event__classification=[0.9]), "must be an object"),
    "probability > 1": (_mutated(event__classification={"BNS": 7.0}), "not a probability"),
    "time_created not a time": (_mutated(time_created="yesterday"), "not an ISO-8601 time"),
    "unknown alert_type": (_mutated(alert_type="FINAL"), "unknown alert_type"),
    "alert_type is a number": (_mutated(alert_type=3), "alert_type must be a string"),
    "superevent id with a path": (_mutated(superevent_id="../../etc"), "not an id"),
    "notice is a list": (b"[1, 2, 3]", "must be an object"),
    "empty": (b"   ", "empty"),
    "binary junk": (bytes(range(256)), "neither JSON"),
    "not UTF-8": (b'{"a": "\xff\xfe"}', "not UTF-8"),
    "truncated Avro": (notice_bytes("avro/MS181101ab-earlywarning.avro")[:3000], "Avro"),
    "XML entity bomb": (b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "aaaa">]><x>&a;</x>', "DOCTYPE"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_notice_is_one_clear_notice_error(name):
    data, expected = BAD[name]
    with pytest.raises(NoticeError) as info:
        parse_notice(data)
    msg = str(info.value)
    assert expected in msg
    assert "\n" not in msg and len(msg) < 300
    assert isinstance(info.value, InputError)


def test_oversized_payload_is_refused_before_decoding():
    big = b"{" + b" " * (50 * 1024 * 1024) + b"}"  # would be valid-ish JSON if decoded
    with pytest.raises(NoticeError, match="exceeds the 8388608-byte limit"):
        parse_notice(big, max_bytes=8_388_608)


def test_size_limit_holds_at_the_limit_and_refuses_one_byte_over():
    notice = (NOTICES / "json" / "MS181101ab-preliminary.json").read_bytes()
    limit = len(notice) + 100
    at_limit = notice + b" " * (limit - len(notice))  # trailing blanks keep the JSON valid
    assert len(at_limit) == limit
    assert parse_notice(at_limit, max_bytes=limit).superevent_id == "MS181101ab"
    with pytest.raises(NoticeError, match=f"notice of {limit + 1} bytes exceeds the {limit}-byte limit"):
        parse_notice(at_limit + b" ", max_bytes=limit)


def test_deeply_nested_json_is_rejected():
    with pytest.raises(NoticeError):
        parse_notice(b"[" * 100000 + b"]" * 100000)


def test_non_bytes_input_is_rejected():
    with pytest.raises(NoticeError, match="must be bytes"):
        parse_notice(json.loads(notice_bytes("json/MS181101ab-retraction.json")))  # type: ignore[arg-type]
