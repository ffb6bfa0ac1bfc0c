"""A poisoned executed record (a field id no ZTF field has, past SQLite's 64-bit integers) through the real loop.

The loop's scenario (``loop_helpers``): the plan's first exposures executed,
one more record with ``field_id = 2**63``.  The record is skipped with one
line; the rest is stored, and slips and later nights are still re-planned.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import subprocess
import sys
from pathlib import Path

import pytest
from astropy.time import Time, TimeDelta

from mushrooms.daemon.state.executed import count_executed
from mushrooms.daemon.loop.poll import ExecutedLoop
from mushrooms.scheduler_core.sky.twilight import night_windows

from loop_helpers import (PLANNING, SENT, after, copy_state, executed_like, loop_config, open_pipeline, planned_state,
                          poller, the_plan, write_executed)

POISON = {"field_id": 2 ** 63, "filter": "g", "start": "2023-04-15T03:10:00.000Z", "exposure_s": 300.0,
          "processed_fraction": 1.0, "status": "processed"}
TWO = dataclasses.replace(PLANNING, nights=2)


def poisoned(path: Path, exposures) -> Path:
    write_executed(path, exposures)
    with path.open("a") as f:
        f.write(json.dumps(POISON) + "\n")
    return path


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("planned"))


@pytest.fixture(scope="module")
def planned_two(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("two"), TWO)


def test_a_field_id_past_64_bits_is_one_line_and_the_slip_is_still_re_planned(planned, tmp_path, caplog):
    executed = tmp_path / "executed.jsonl"
    p = open_pipeline(copy_state(planned, tmp_path), loop_config(executed, max_slip_s=900.0))
    try:
        obs = the_plan(p)["observations"]
        poisoned(executed, executed_like(obs[:10]))
        caplog.set_level(logging.WARNING)
        now = after(obs[10]["start"], 900.0 + 120.0)
        poll = poller(p).poll(now)
        assert poll.error is None and poll.stored.added == 10 and count_executed(p.store) == 10
        warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert len(warnings) == 1 and "not a ZTF field" in warnings[0], warnings
        assert [a.action for a in poll.replans] == ["replan"]
        out = p.run_job(poll.replans[0].job)
        assert out.decision == "replan" and out.revision == 2
        assert poller(p).poll(now).error is None  # and the next poll too
    finally:
        p.store.close()


def test_a_poisoned_record_does_not_stop_the_night_re_plan(planned_two, tmp_path):
    executed = tmp_path / "executed.jsonl"
    p = open_pipeline(copy_state(planned_two, tmp_path), loop_config(executed), TWO)
    try:
        obs = the_plan(p)["observations"]
        poisoned(executed, executed_like(obs[:10]))
        nights = night_windows(Time(SENT.rstrip("Z"), scale="utc"), TWO, 2)
        poll = ExecutedLoop(p.loop, p).poll(nights[1][0] + TimeDelta(120.0, format="sec"))
        assert poll.error is None and poll.stored.added == 10
        assert len(poll.jobs) == 1 and p.run_job(poll.jobs[0].job).decision == "replan"
    finally:
        p.store.close()


def test_plan_executed_skips_the_poisoned_record(tmp_path):
    data = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    good = {"field_id": 600, "filter": "g", "start": "2022-07-23T02:10:00.000Z", "exposure_s": 300.0,
            "processed_fraction": 1.0, "status": "processed"}
    executed = tmp_path / "executed.jsonl"
    executed.write_text(json.dumps(good) + "\n" + json.dumps(POISON | {"start": good["start"]}) + "\n")
    r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "plan", str(data), "--solver", "greedy", "--executed",
                        str(executed), "--start", "2022-07-23T03:00:00Z", "-o", str(tmp_path / "plan.json")],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "not a ZTF field" in r.stderr and r.stderr.count("line 2") == 1
