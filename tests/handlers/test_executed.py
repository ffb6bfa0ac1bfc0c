"""The readers of executed observations: ZTF's depot, SkyPortal's answer, JSON lines, each to one record.

Fixtures: tests/data/executed/ (SOURCES.md says what each holds and whose
shape it copies).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
from astropy.time import Time

from mushrooms.handlers.executed import (
    ExecutedSource, depot_paths, parse_executed_source, read_depot, read_jsonl, read_skyportal, write_jsonl,
)
from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs, is_done

DATA = Path(__file__).resolve().parents[1] / "data" / "executed"
DEPOT = DATA / "ztf_recentproc_20250514.json"
SKYPORTAL = DATA / "skyportal_observation_answer.json"
JSONL = DATA / "executed.jsonl"
LOGGER = "mushrooms.handlers.executed"


def _by_key(exposures):
    return {(e.field_id, e.filter): e for e in exposures}


def _warnings(caplog):
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.levelno >= logging.WARNING]


# ------------------------------------------------------------------ depot
def test_depot_groups_quadrants_into_exposures(caplog):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    got = read_depot(DEPOT)
    assert [(e.field_id, e.filter) for e in got] == [(600, "g"), (601, "g"), (600, "r"), (602, "r")]  # start order
    by = _by_key(got)
    assert by[600, "g"].processed_fraction == 1.0  # 64 quadrants, one of them listed twice
    assert by[600, "r"].processed_fraction == pytest.approx(40 / 64)
    assert by[601, "g"].processed_fraction == pytest.approx(20 / 64)
    assert by[602, "r"].processed_fraction == 0.0 and by[602, "r"].status == "failed"
    assert all(e.status == "processed" for e in got if e.processed_fraction > 0)
    assert all(e.exposure_s == 300.0 for e in got)
    assert abs((by[600, "g"].start - Time("2025-05-14T04:10:00", scale="utc")).to_value("s")) < 0.05  # obsjd
    # the failed and the partial exposure are not done; the 40-of-64 one is
    assert [is_done(by[k]) for k in ((600, "g"), (600, "r"), (601, "g"), (602, "r"))] == [True, True, False, False]
    lines = _warnings(caplog)
    assert len(lines) == 1 and "row 257" in lines[0] and "filter_id 7" in lines[0] and DEPOT.name in lines[0]


def test_depot_threshold_moves_the_partial_exposures():
    got = read_depot(DEPOT)
    assert sum(is_done(e, 0.3) for e in got) == 3
    assert sum(is_done(e, 0.7) for e in got) == 1
    assert sum(is_done(e, 0.0) for e in got) == 3  # a failed exposure is never done
    pairs = done_pairs(got, min_processed_fraction=0.7)
    assert not pairs.both and pairs.one[600].filters == ("g",)


def test_depot_bytes_and_text_read_like_the_file():
    assert read_depot(DEPOT.read_bytes()) == read_depot(DEPOT.read_text())


def test_depot_columns_form_is_read_as_pandas_would():
    rows = json.loads(DEPOT.read_text())[:64]
    columns = {k: [r.get(k) for r in rows] for k in rows[0]}
    (one,) = read_depot(json.dumps(columns))
    assert (one.field_id, one.filter, one.processed_fraction) == (600, "g", 1.0)


def test_depot_exposure_with_rows_that_disagree_is_skipped_once(caplog):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    rows = [{"exposure_id": 5, "field_id": 600 + (i % 2), "filter_id": 1, "rcid": i, "obsjd": 2460809.7,
             "exposure_time": 30, "status": 0} for i in range(4)]
    assert read_depot(json.dumps(rows)) == ()
    lines = _warnings(caplog)
    assert len(lines) == 1 and "exposure_id 5" in lines[0]


@pytest.mark.parametrize("text, words", [
    ("{not json", "not JSON"),
    ('{"a": 1}', "not a list"),
    ('"rows"', "not a list"),
    ('{"a": [1], "b": [1, 2]}', "different lengths"),
])
def test_depot_that_is_not_a_list_of_rows_raises_one_line(text, words):
    with pytest.raises(InputError, match=words) as info:
        read_depot(text)
    assert "\n" not in str(info.value)


def test_unreadable_file_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_depot(tmp_path / "absent.json")
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputError, match="not UTF-8"):
        read_jsonl(tmp_path / "bin.json")


def test_depot_paths_are_skyportals_days():
    # an evening and the following morning at Palomar: Julian days start at noon UTC
    assert depot_paths(Time("2025-05-14T03:00:00"), Time("2025-05-14T13:00:00")) == [
        "20250513/ztf_recentproc_20250513.json", "20250514/ztf_recentproc_20250514.json"]
    with pytest.raises(ValueError):
        depot_paths(Time("2025-05-14T13:00:00"), Time("2025-05-14T03:00:00"))


# ------------------------------------------------------------------ SkyPortal
def test_skyportal_answer(caplog):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    got = read_skyportal(SKYPORTAL)
    assert [(e.field_id, e.filter) for e in got] == [(600, "g"), (601, "g"), (600, "r")]
    by = _by_key(got)
    assert by[600, "r"].processed_fraction == 0.625 and is_done(by[600, "r"])
    assert not is_done(by[601, "g"])
    # field.field_id (ZTF's field), not instrument_field_id (SkyPortal's database key)
    assert {e.field_id for e in got} == {600, 601}
    assert by[600, "g"].start.isot == "2025-05-14T04:10:00.001"  # naive obstime read as UTC
    lines = _warnings(caplog)
    assert len(lines) == 1 and "observation 4" in lines[0] and "sdssr" in lines[0]


def test_skyportal_data_block_alone_is_accepted():
    doc = json.loads(SKYPORTAL.read_text())
    assert read_skyportal(json.dumps(doc["data"])) == read_skyportal(SKYPORTAL)


@pytest.mark.parametrize("doc, words", [
    ({"status": "error", "message": "Missing start_date"}, "answered an error: Missing start_date"),
    ({"status": "success", "data": {"totalMatches": 0}}, "no data.observations"),
    ([1, 2], "no data.observations"),
])
def test_skyportal_answer_that_is_not_one_raises(doc, words):
    with pytest.raises(InputError, match=words):
        read_skyportal(json.dumps(doc))


def test_skyportal_zero_fraction_is_failed_and_missing_field_is_skipped(caplog):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    doc = json.loads(SKYPORTAL.read_text())
    obs = doc["data"]["observations"]
    obs[2]["processed_fraction"] = 0.0
    del obs[1]["field"]
    got = _by_key(read_skyportal(json.dumps(doc)))
    assert got[601, "g"].status == "failed"
    assert (600, "r") not in got
    assert [line for line in _warnings(caplog) if "observation 1" in line] == [
        "SkyPortal answer observation 1: no field.field_id; skipped"]


# ------------------------------------------------------------------ JSON lines
def test_jsonl_fixture(caplog):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    got = read_jsonl(JSONL)
    assert [(e.field_id, e.filter, e.status) for e in got] == [
        (600, "g", "processed"), (601, "g", "processed"), (600, "r", "processed"), (602, "r", "failed")]
    # the duplicate 0.3 s later with 0.9 collapsed into the exposure with 1.0
    assert _by_key(got)[600, "g"].processed_fraction == 1.0
    lines = _warnings(caplog)
    assert len(lines) == 1 and "line 6" in lines[0] and "filter 'z'" in lines[0]


def test_three_sources_agree_on_what_is_done():
    done = [sorted((e.field_id, e.filter) for e in r(p) if is_done(e))
            for r, p in ((read_depot, DEPOT), (read_skyportal, SKYPORTAL), (read_jsonl, JSONL))]
    assert done[0] == done[1] == done[2] == [(600, "g"), (600, "r")]


@pytest.mark.parametrize("line, words", [
    ('{"field_id": 1}', "missing key"),
    ('{"field_id": 1, "filter": "g", "start": "2025-05-14T04:10:00Z", "exposure_s": 30, '
     '"processed_fraction": 1, "status": "processed", "note": "x"}', "unknown key(s) note"),
    ('{"field_id": 1, "filter": "g", "start": 60809.2, "exposure_s": 30, '
     '"processed_fraction": 1, "status": "processed"}', "not an ISO-8601 string"),
    ('{"field_id": 1, "filter": "g", "start": "yesterday", "exposure_s": 30, '
     '"processed_fraction": 1, "status": "processed"}', "start 'yesterday'"),
    ('{"field_id": 1, "filter": "g", "start": "2025-05-14T04:10:00Z", "exposure_s": 30, '
     '"processed_fraction": 1.5, "status": "processed"}', "processed_fraction 1.5"),
    ('{"field_id": 1, "filter": "g", "start": "2025-05-14T04:10:00Z", "exposure_s": 30, '
     '"processed_fraction": 1, "status": "ok"}', "status 'ok'"),
    ('[1, 2]', "not a JSON object"),
    ('{"field_id": 1,', "not JSON"),
])
def test_each_malformed_line_is_one_log_line(caplog, line, words):
    caplog.set_level(logging.WARNING, logger=LOGGER)
    good = ('{"field_id": 2, "filter": "r", "start": "2025-05-14T04:20:00Z", "exposure_s": 30, '
            '"processed_fraction": 1, "status": "processed"}')
    got = read_jsonl(good + "\n" + line + "\n")
    assert [e.field_id for e in got] == [2]
    (message,) = _warnings(caplog)
    assert message.startswith("executed file line 2: ") and words in message and "\n" not in message


def test_a_json_document_is_not_json_lines():
    with pytest.raises(InputError, match="not JSON lines"):
        read_jsonl(json.dumps([{"field_id": 1}], indent=2))
    assert read_jsonl("") == () and read_jsonl("\n\n") == ()


def test_jsonl_round_trip(tmp_path):
    exposures = read_depot(DEPOT)
    path = write_jsonl(exposures, tmp_path / "out.jsonl")
    back = read_jsonl(path)
    assert len(back) == len(exposures)
    for a, b in zip(exposures, back):
        assert (a.field_id, a.filter, a.exposure_s, a.processed_fraction, a.status) == \
               (b.field_id, b.filter, b.exposure_s, b.processed_fraction, b.status)
        assert abs((a.start - b.start).to_value("s")) < 1e-3  # milliseconds written
    assert write_jsonl(back, tmp_path / "again.jsonl").read_text() == path.read_text()
    assert not list(tmp_path.glob(".*.tmp"))


def test_same_exposure_from_two_sources_collapses():
    both = read_jsonl("\n".join(json.dumps(r) for r in (
        {"field_id": 7, "filter": "i", "start": "2025-05-14T05:00:00.000Z", "exposure_s": 30.0,
         "processed_fraction": 0.25, "status": "processed"},
        {"field_id": 7, "filter": "i", "start": "2025-05-14T05:00:00.600Z", "exposure_s": 30.0,
         "processed_fraction": 0.75, "status": "processed"},
        {"field_id": 7, "filter": "i", "start": "2025-05-14T05:00:31.000Z", "exposure_s": 30.0,
         "processed_fraction": 1.0, "status": "processed"},
    )))
    assert [e.processed_fraction for e in both] == [0.75, 1.0]  # the next exposure 31 s later stays


# ------------------------------------------------------------------ the configured source
@pytest.mark.parametrize("spec, kind, location", [
    ("none", "none", None),
    (" none ", "none", None),
    ("file:/var/lib/mushrooms/executed.jsonl", "file", "/var/lib/mushrooms/executed.jsonl"),
    ("file:relative/x.jsonl", "file", "relative/x.jsonl"),
    ("depot:https://ztfweb.ipac.caltech.edu/ztf/depot", "depot", "https://ztfweb.ipac.caltech.edu/ztf/depot"),
    ("depot:/data/depot", "depot", "/data/depot"),
    ("skyportal:https://fritz.science", "skyportal", "https://fritz.science"),
])
def test_parse_executed_source(spec, kind, location):
    assert parse_executed_source(spec) == ExecutedSource(kind, location)


@pytest.mark.parametrize("spec, words", [
    ("", "unknown kind"),
    ("nothing", "unknown kind"),
    ("ftp:host/x", "unknown kind 'ftp'"),
    ("none:x", "unknown kind 'none'"),
    ("file:", "no location"),
    ("file:https://x.org/a.jsonl", "not a URL"),
    ("skyportal:fritz.science", "http(s) URL"),
    ("skyportal:https://", "http(s) URL"),
    ("depot:ftp://host/depot", "not ftp:"),
    ("depot:https://", "no host"),
])
def test_bad_source_specs_say_what_is_wrong(spec, words):
    with pytest.raises(ValueError, match=r".*") as info:
        parse_executed_source(spec)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_non_string_spec():
    with pytest.raises(ValueError, match="not a string"):
        parse_executed_source(None)  # type: ignore[arg-type]


def test_records_are_the_library_record():
    assert all(isinstance(e, ExecutedExposure) for e in read_jsonl(JSONL))
