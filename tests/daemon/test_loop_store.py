"""The state file's ``executed`` table (schema 5) and ``mushrooms trigger SUPEREVENT --closed-until``."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import pytest
from astropy.time import Time

from mushrooms.cli import main
from mushrooms.daemon.state.executed import count_executed, executed_between, store_executed
from mushrooms.daemon.planning.replans import replan_jobs
from mushrooms.daemon.state.store import SCHEMA_VERSION, Store
from mushrooms.handlers.executed import read_depot, read_jsonl
from mushrooms.scheduler_core.executed import ExecutedExposure

from loop_helpers import SUPEREVENT, copy_state, planned_state

EXECUTED = Path(__file__).resolve().parents[1] / "data" / "executed"


def test_a_schema_4_state_file_gets_the_executed_table_and_keeps_its_rows(tmp_path):
    path = tmp_path / "v4.sqlite"
    Store(path).close()
    with sqlite3.connect(path) as c:
        c.execute("DROP TABLE executed")
        c.execute("INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at)"
                  " VALUES ('S1', 'abc', 0, '2026-01-01T00:00:00')")
        c.execute("INSERT INTO plans(plan_id, superevent_id, job_id, created_at, seq, document)"
                  " VALUES ('p1', 'S1', NULL, '2026-01-01T00:00:00', 1, '{}')")
        c.execute("PRAGMA user_version=4")
    c.close()
    s = Store(path)
    try:
        assert s.event_state("S1").plan_ids == ("p1",)
        assert store_executed(s, read_jsonl(EXECUTED / "executed.jsonl"), "file:test").added == 4
    finally:
        s.close()
    c = sqlite3.connect(path)
    try:
        assert c.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 6
        assert c.execute("SELECT COUNT(*) FROM executed").fetchone()[0] == 4
    finally:
        c.close()


def test_one_row_per_exposure_whatever_reported_it_and_the_larger_fraction_stays(tmp_path):
    s = Store(tmp_path / "s.sqlite")
    try:
        assert store_executed(s, read_jsonl(EXECUTED / "executed.jsonl"), "file:a").added == 4
        # the depot reports the same four exposures (JD starts: within E2's 1 s), none with more reduced
        again = store_executed(s, read_depot(EXECUTED / "ztf_recentproc_20250514.json"), "depot:b")
        assert (again.added, again.updated, again.unchanged) == (0, 0, 4)
        late = ExecutedExposure(601, "g", Time("2025-05-14T04:15:20.400", scale="utc"), 300.0, 1.0, "processed")
        assert store_executed(s, [late], "depot:b").updated == 1  # the pipeline reduced the rest of 601 g
        assert count_executed(s) == 4
        rows = {(e.field_id, e.filter): (e.processed_fraction, e.status) for e in executed_between(s)}
        assert rows == {(600, "g"): (1.0, "processed"), (600, "r"): (0.625, "processed"),
                        (601, "g"): (1.0, "processed"), (602, "r"): (0.0, "failed")}
    finally:
        s.close()


# ---------------------------------------------------------------- the operator's closure, from the command line
@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("planned"))


def _config(tmp_path: Path) -> Path:
    config = tmp_path / "config.toml"
    config.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\ntime_step_s = 600.0\nmin_gain = 0.0\n'
                      'min_coverage = 0.0\n[policy]\nallow_mock = true\n'
                      f'[daemon]\npid_file = "{tmp_path / "d.pid"}"\ntrigger_dir = "{tmp_path / "triggers"}"\n'
                      f'[loop]\nexecuted_source = "file:{tmp_path / "executed.jsonl"}"\n')
    return config


def test_trigger_closed_until_records_a_replan_job_from_the_reopening(planned, tmp_path, capsys):
    """No daemon runs: the command records the re-plan and runs it here; the 2023 plan's window has ended by
    the wall clock's reopening, so the job closes without a plan and says why (the plan stands)."""
    state = copy_state(planned, tmp_path)
    status = main(["trigger", SUPEREVENT, "--closed-until", "2200-01-01T00:00:00Z", "--config", str(_config(tmp_path)),
                   "--state", str(state), "--outbox", str(tmp_path / "out")])
    out = capsys.readouterr()
    assert status == 0, out.err
    assert "replan" in out.out and "ends before the re-plan's start" in out.out
    s = Store(state)
    try:
        jobs = replan_jobs(s, SUPEREVENT)
        assert [(j["status"], j["start"]) for j in jobs] == [("done", "2200-01-01T00:00:00.000Z")]
        assert [d["decision"] for d in s.decisions()] == ["plan", "replan"]
        assert "telescope closed until 2200-01-01T00:00:00.000Z (operator)" in s.decisions()[-1]["reason"]
        assert len(s.plans(SUPEREVENT)) == 1  # nothing left in that window: the plan stands
    finally:
        s.close()


@pytest.mark.parametrize("args, message", [
    (["S990101zz", "--closed-until", "2200-01-01T00:00:00Z"], "no current plan of 'S990101zz'"),
    ([SUPEREVENT, "--closed-until", "at dawn"], "--closed-until 'at dawn': not an ISO-8601 time"),
    ([SUPEREVENT, "--closed-until", "2200-01-01T00:00:00Z", "--force"], "does not combine with --force"),
])
def test_trigger_closed_until_refusals_are_one_line_and_status_2(planned, tmp_path, capsys, args, message):
    state = copy_state(planned, tmp_path)
    status = main(["trigger", *args, "--config", str(_config(tmp_path)), "--state", str(state),
                   "--outbox", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and message in err, err


def test_closed_until_takes_a_superevent_not_a_file(tmp_path, capsys):
    notice = tmp_path / "n.json"
    notice.write_text(json.dumps({"superevent_id": "S1"}))
    assert main(["trigger", str(notice), "--closed-until", "2200-01-01T00:00:00Z",
                 "--config", str(_config(tmp_path))]) == 2
    assert "--closed-until takes a superevent id" in capsys.readouterr().err
