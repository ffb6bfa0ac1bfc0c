"""A record of the wrong type is refused before its start time is parsed (issue 52 follow-up, "mend" 4).

``from_record`` parsed ``start`` with astropy (a few hundred microseconds)
before the cheap checks of ``field_id``, ``filter``, ``exposure_s``,
``processed_fraction`` and ``status``, so a file of records of the wrong type
cost a time parse per line.  Here a 100 000-line file of such records is read
by ``mushrooms plan --executed``'s reader (:func:`read_jsonl`, from an open
file) and by the service's ``file:`` source
(:class:`~mushrooms.daemon.loop.fetch.ExecutedReader`): every line is refused
(one warning each for the first ten, then a count), astropy's ``Time`` is
never built, and the reader's peak Python allocation stays far below the
file's size.  Good records still give exactly what they gave before the
change (the values below were printed by the code on main, af0ff7d).
"""

from __future__ import annotations

import json
import logging
import tracemalloc
from pathlib import Path

import pytest
from astropy.time import Time

from mushrooms.handlers.executed import read_jsonl
from mushrooms.scheduler_core.executed import from_record, to_record

LINES = 100_000
START = "2025-05-14T04:10:00.000Z"
GOOD = {"field_id": 600, "filter": "g", "start": START, "exposure_s": 300.0, "processed_fraction": 1.0,
        "status": "processed"}
#: One bad value each, of the wrong type or out of range; the start is always a valid ISO-8601 string.
WRONG = [{"field_id": "six hundred"}, {"field_id": True}, {"field_id": 1.5}, {"field_id": 10**7},
         {"filter": 1}, {"filter": "z"}, {"exposure_s": "300"}, {"exposure_s": None}, {"exposure_s": -1.0},
         {"processed_fraction": "all"}, {"processed_fraction": [1]}, {"processed_fraction": 2.0},
         {"status": 0}, {"status": "done"}]


@pytest.fixture(scope="module")
def wrong_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("executed") / "wrong.jsonl"
    lines = [json.dumps(dict(GOOD, **bad)).encode() + b"\n" for bad in WRONG]
    with path.open("wb") as fh:
        for k in range(LINES):
            fh.write(lines[k % len(lines)])
    return path


@pytest.fixture
def time_built(monkeypatch) -> list[int]:
    """How many astropy ``Time`` objects are built (a guard stops the read after 100: one per line is the bug)."""
    built = [0]
    init = Time.__init__

    def counting(self, *args, **kwargs):
        built[0] += 1
        if built[0] > 100:
            raise AssertionError(f"astropy Time built {built[0]} times while reading records of the wrong type")
        return init(self, *args, **kwargs)

    monkeypatch.setattr(Time, "__init__", counting)
    return built


def _refused_line_by_line(caplog, lines: int) -> None:
    said = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(said) == 11, said[:3]
    assert all(f"line {k + 1}: " in said[k] and said[k].endswith("; skipped") for k in range(10)), said[:10]
    assert f"{lines - 10} more malformed record(s) skipped ({lines} in all" in said[10], said[10]


def test_a_file_of_wrong_type_records_is_refused_without_a_time_parse_per_line(wrong_file, time_built, caplog):
    caplog.set_level(logging.WARNING, logger="mushrooms.handlers.executed")
    tracemalloc.start()
    try:
        with wrong_file.open("rb") as fh:  # streamed, as the service reads it
            got = read_jsonl(fh)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert got == ()
    assert time_built[0] == 0
    _refused_line_by_line(caplog, LINES)
    assert peak < 4 << 20 < wrong_file.stat().st_size / 2, (peak, wrong_file.stat().st_size)  # a line, not the file


def test_the_services_file_source_refuses_them_the_same_way(wrong_file, time_built, caplog):
    from mushrooms.daemon.loop.fetch import ExecutedReader
    from mushrooms.handlers.executed_source import parse_executed_source

    caplog.set_level(logging.WARNING, logger="mushrooms.handlers.executed")
    reader = ExecutedReader(parse_executed_source(f"file:{wrong_file}"), None, 5.0)
    span = Time(["2025-05-14T03:00:00", "2025-05-14T06:00:00"], scale="utc")
    start, end = span[0], span[1]
    built = time_built[0]  # the span above
    assert reader.read(start, end) == ()
    assert time_built[0] == built
    assert any(f"({LINES} in all" in r.getMessage() for r in caplog.records)


#: Good records and what ``from_record`` made of them on main (af0ff7d): ``to_record`` of it, and its start's
#: two Julian-date parts and scale.
GOOD_RECORDS = [
    {"field_id": 1, "filter": "g", "start": "2025-05-14T04:10:00Z", "exposure_s": 30, "processed_fraction": 1,
     "status": "processed"},
    {"field_id": 999999, "filter": "r", "start": "2025-05-14T04:10:00.1234Z", "exposure_s": 300.5,
     "processed_fraction": 0.5, "status": "processed"},
    {"field_id": 600, "filter": "i", "start": "2025-05-14T04:10:00", "exposure_s": 86400, "processed_fraction": 0,
     "status": "failed"},
    {"field_id": 245, "filter": "g", "start": "2026-03-20 06:00:00.999", "exposure_s": 0.001,
     "processed_fraction": 0.015625, "status": "aborted"},
    {"field_id": 700, "filter": "r", "start": "2025-05-14T23:59:59.9996Z", "exposure_s": 45.0,
     "processed_fraction": 1.0, "status": "processed"},
]
ON_MAIN = [
    [{"field_id": 1, "filter": "g", "start": "2025-05-14T04:10:00.000Z",
     "exposure_s": 30.0, "processed_fraction": 1.0, "status": "processed"},
     2460810.0, -0.3263888888888889, "utc"],
    [{"field_id": 999999, "filter": "r", "start": "2025-05-14T04:10:00.123Z",
     "exposure_s": 300.5, "processed_fraction": 0.5, "status": "processed"},
     2460810.0, -0.32638746064814816, "utc"],
    [{"field_id": 600, "filter": "i", "start": "2025-05-14T04:10:00.000Z",
     "exposure_s": 86400.0, "processed_fraction": 0.0, "status": "failed"},
     2460810.0, -0.3263888888888889, "utc"],
    [{"field_id": 245, "filter": "g", "start": "2026-03-20T06:00:00.999Z",
     "exposure_s": 0.001, "processed_fraction": 0.015625, "status": "aborted"},
     2461120.0, -0.2499884375, "utc"],
    [{"field_id": 700, "filter": "r", "start": "2025-05-15T00:00:00.000Z",
     "exposure_s": 45.0, "processed_fraction": 1.0, "status": "processed"},
     2460810.0, 0.4999999953703703, "utc"],
]


@pytest.mark.parametrize("record, before", list(zip(GOOD_RECORDS, ON_MAIN)))
def test_good_records_parse_as_they_did_before(record, before):
    got = from_record(record)
    assert [to_record(got), got.start.jd1, got.start.jd2, got.start.scale] == before
    assert read_jsonl(json.dumps(record) + "\n") == (got,)
