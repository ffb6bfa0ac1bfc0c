"""The loop's sources bounded (``executed.md`` L16-L18): nothing blocks, nothing grows without limit, one line once.

Real files, FIFOs and symbolic links in a temporary directory; a SkyPortal on
loopback (pytest-httpserver) that paginates forever; the pure slip rule on a
hand-written plan document.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import threading
from pathlib import Path

import pytest
from astropy.time import Time
from werkzeug.wrappers import Response

from mushrooms.daemon.loop.fetch import ExecutedReader, FetchError
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.handlers.executed import read_depot
from mushrooms.handlers.executed_source import parse_executed_source
from mushrooms.handlers.slip import slip_of
from mushrooms.scheduler_core.executed import ExecutedExposure

from executed_servers import EXECUTED

NIGHT = (Time("2025-05-14T03:00:00", scale="utc"), Time("2025-05-14T06:00:00", scale="utc"))
GOOD = {"field_id": 600, "filter": "g", "start": "2025-05-14T04:10:00.000Z", "exposure_s": 300.0,
        "processed_fraction": 1.0, "status": "processed"}


def reader(spec: str, **kw) -> ExecutedReader:
    return ExecutedReader(parse_executed_source(spec), None, 5.0, **kw)


def warnings_of(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


class _Writer(threading.Thread):
    """Opens the FIFO for writing as soon as a reader has it open, then closes it (a reader then sees EOF)."""

    def __init__(self, fifo: Path) -> None:
        super().__init__(daemon=True)
        self.fifo, self.stop = fifo, threading.Event()

    def run(self) -> None:
        while not self.stop.wait(0.01):
            try:
                os.close(os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK))
                return
            except OSError as exc:
                if exc.errno != errno.ENXIO:  # ENXIO: no reader yet
                    return


def test_a_fifo_file_source_is_refused_not_read(tmp_path):
    fifo = tmp_path / "executed.jsonl"
    os.mkfifo(fifo)
    writer = _Writer(fifo)
    writer.start()
    try:
        with pytest.raises(Exception) as err:
            reader(f"file:{fifo}").read(*NIGHT)
        assert "FIFO" in str(err.value)
    finally:
        writer.stop.set()
        writer.join()


def test_a_file_larger_than_the_cap_fails_the_poll_with_one_line(tmp_path):
    big = tmp_path / "executed.jsonl"
    big.write_text((json.dumps(GOOD) + "\n") * 40)
    config = LoopConfig(executed_source=f"file:{big}", max_source_bytes=1024)
    with pytest.raises(Exception) as err:
        ExecutedReader(config.source, None, config.timeout_s, config.max_source_bytes).read(*NIGHT)
    assert "1024-byte limit" in str(err.value)


def test_bad_lines_are_logged_ten_then_counted_and_never_again(tmp_path, caplog):
    path = tmp_path / "executed.jsonl"
    path.write_text(json.dumps(GOOD) + "\n" + "".join(json.dumps(GOOD | {"filter": "q", "exposure_s": 30.0 + i})
                                                      + "\n" for i in range(50)))
    source = reader(f"file:{path}")
    caplog.set_level(logging.WARNING)
    assert len(source.read(*NIGHT)) == 1
    first = warnings_of(caplog)
    assert len(first) == 11 and "40 more malformed record(s) skipped" in first[-1], first
    caplog.clear()
    assert len(source.read(*NIGHT)) == 1  # the next poll reads the same lines: nothing logged again
    assert warnings_of(caplog) == []


def test_a_depot_night_that_is_a_fifo_or_a_link_loop_is_one_line_once(tmp_path, caplog):
    depot = tmp_path / "depot"
    (depot / "20250514").mkdir(parents=True)
    (depot / "20250513").mkdir()
    os.mkfifo(depot / "20250514" / "ztf_recentproc_20250514.json")
    loop = depot / "20250513" / "ztf_recentproc_20250513.json"
    os.symlink(loop, loop)
    source = reader(f"depot:{depot}")
    caplog.set_level(logging.WARNING)
    assert source.read(*NIGHT) == ()
    lines = warnings_of(caplog)
    assert len(lines) == 2 and any("FIFO" in m for m in lines) and any("symbolic links" in m for m in lines), lines
    caplog.clear()
    assert source.read(*NIGHT) == () and warnings_of(caplog) == []


def test_a_skyportal_paginating_forever_stops_at_the_page_cap(loopback):
    server = loopback
    one = json.loads((EXECUTED / "skyportal_observation_answer.json").read_text())["data"]["observations"][0]
    pages = []

    def forever(request):
        pages.append(int(request.args["pageNumber"]))
        return Response(json.dumps({"status": "success", "data": {"observations": [one], "totalMatches": 10 ** 9}}),
                        content_type="application/json")

    server.expect_request("/api/observation").respond_with_handler(forever)
    with pytest.raises(FetchError, match="still paginating after 100 pages"):
        reader(f"skyportal:{server.url_for('')}", max_read_s=3600.0).read(*NIGHT)
    assert pages == list(range(1, 101))


def _plan():
    return {"type": "plan", "start": "2025-05-14T04:00:00Z", "end": "2025-05-14T10:00:00Z",
            "observations": [{"field_id": 600, "filter": "g", "start": "2025-05-14T04:10:00Z"},
                             {"field_id": 600, "filter": "r", "start": "2025-05-14T04:45:00Z"}]}


def test_an_exposure_still_being_reduced_is_failed_only_after_the_settle_time():
    partial = ExecutedExposure(600, "g", Time("2025-05-14T04:10:00", scale="utc"), 300.0, 20 / 64, "processed")
    soon = Time("2025-05-14T04:25:00", scale="utc")  # 10 min after its end: the depot is still reducing it
    early = slip_of(_plan(), [partial], soon, 900.0, 0.5, settle_s=1800.0)
    assert not early.replan and "still being reduced" in early.reason and early.executed == 1
    late = slip_of(_plan(), [partial], Time("2025-05-14T04:46:00", scale="utc"), 900.0, 0.5, settle_s=1800.0)
    assert late.replan and "failed" in late.reason
    nothing = ExecutedExposure(600, "g", Time("2025-05-14T04:10:00", scale="utc"), 300.0, 0.0, "failed")
    assert slip_of(_plan(), [nothing], soon, 900.0, 0.5, settle_s=1800.0).replan  # a failure is one at once


def test_program_ids_keep_only_those_programmes_depot_rows():
    rows = json.loads((EXECUTED / "ztf_recentproc_20250514.json").read_text())
    for r in rows:
        r["programid"] = 2 if r["field_id"] == 600 else 1
    data = json.dumps(rows).encode()
    every = read_depot(data)
    mine = read_depot(data, program_ids=(2,))
    assert {e.field_id for e in every} > {e.field_id for e in mine} == {600}
    assert LoopConfig(executed_source="depot:/srv/depot", program_ids=[2, 3]).program_ids == (2, 3)
    with pytest.raises(ValueError, match="program_ids needs a depot"):
        LoopConfig(executed_source="file:/tmp/x.jsonl", program_ids=[2])
