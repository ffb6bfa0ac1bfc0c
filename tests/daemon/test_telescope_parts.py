"""The service plans every configured telescope for every revision (issue 53 item 4, "through the service").

The daemon's own wiring (``open_pipeline``: real SQLite, a directory outbox,
greedy at nside 64) with ``[scheduler] telescopes = ["ztf", "ls4", ...]`` on
MS181101ab: ZTF's part is the revision as today, every other telescope's part
is a folder of the outbox (``telescopes/<event>/<job>-<alert type>/<telescope>/``)
with its target list (``queue = "target_list"``) or its SkyPortal request
(``queue = "skyportal"``); an update supersedes every part, a retraction
withdraws every part; a telescope that cannot observe, or fails, costs only its
own part; hostile description fields never leave the outbox's folders; a state
file of main's code (6bf5c61) loads and plans with two telescopes.
"""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
from pathlib import Path

import pytest

from daemon_helpers import notice_bytes
from telescope_parts_setup import (SID, newer_map_update, open_parts_pipeline, part, part_folders, part_rows,
                                   parts_config)

DATA = Path(__file__).resolve().parent / "data"
SHIPPED = Path(__file__).resolve().parents[2] / "mushrooms" / "scheduler_core" / "data" / "telescopes"


def _run(tmp_path: Path, telescopes: list[str], notices: list[bytes], min_coverage: float = 0.0) -> list:
    cfg = parts_config(tmp_path, telescopes)
    cfg.write_text(cfg.read_text().replace("min_coverage = 0.0", f"min_coverage = {min_coverage!r}"))
    pipeline, close = open_parts_pipeline(cfg)
    try:
        return [pipeline.handle(raw, "test:parts") for raw in notices]
    finally:
        close()


def _ztf_plans(outbox: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(outbox.glob("mushrooms-*.json"))]


def test_two_telescopes_give_two_parts_per_revision(tmp_path):
    (out,) = _run(tmp_path, ["ztf", "ls4"], [notice_bytes(f"{SID}-preliminary.json")])
    assert out.decision == "plan"
    outbox = tmp_path / "outbox"
    (ztf,) = _ztf_plans(outbox)  # ZTF's part: the revision, as for a ZTF-only service
    assert ztf["plan_id"] == out.plan_id and "telescopes" not in ztf["config"]  # planned as ZTF alone
    folders = part_folders(outbox)
    assert list(folders) == [("00001-PRELIMINARY", "ls4")]
    ls4 = folders[("00001-PRELIMINARY", "ls4")]
    doc = part(ls4)
    assert doc["state"] == "exported" and doc["queue"] == "target_list" and doc["superevent_id"] == SID
    assert doc["files"] == ["plan.json", "targets.csv", "targets.json"]
    targets = json.loads((ls4 / "targets.json").read_text())
    plan = json.loads((ls4 / "plan.json").read_text())
    assert targets["telescope"] == "ls4" and targets["plan_id"] == plan["plan_id"] == doc["plan_id"]
    assert plan["config"]["telescopes"] == ["ls4"] and len(targets["targets"]) == len(plan["observations"]) > 0
    csv_rows = (ls4 / "targets.csv").read_text().splitlines()
    assert csv_rows[0].startswith("field_id,ra,dec,filter") and len(csv_rows) == 1 + len(targets["targets"])
    assert part_rows(tmp_path / "state.sqlite") == [(1, "ls4", "exported", doc["plan_id"])]


def test_an_update_supersedes_every_telescopes_part(tmp_path):
    first, second = _run(tmp_path, ["ztf", "ls4"], [notice_bytes(f"{SID}-preliminary.json"), newer_map_update()])
    assert first.decision == "plan" and second.decision == "rerun" and second.supersedes == first.plan_id
    folders = part_folders(tmp_path / "outbox")
    old, new = folders[("00001-PRELIMINARY", "ls4")], folders[("00002-UPDATE", "ls4")]
    assert part(old)["state"] == "superseded" and (old / "SUPERSEDED").is_file()
    assert part(new)["state"] == "exported" and not (new / "SUPERSEDED").exists()
    rows = part_rows(tmp_path / "state.sqlite")
    assert [(r[0], r[2]) for r in rows] == [(1, "superseded"), (2, "exported")]


def test_a_retraction_withdraws_every_telescopes_part(tmp_path):
    plan, gone = _run(tmp_path, ["ztf", "ls4", "decam"],
                      [notice_bytes(f"{SID}-preliminary.json"), notice_bytes(f"{SID}-retraction.json")])
    assert plan.decision == "plan" and gone.decision == "withdraw"
    outbox = tmp_path / "outbox"
    withdrawal = json.loads(next(outbox.glob("withdrawal-*.json")).read_text())
    assert plan.plan_id in json.dumps(withdrawal)  # ZTF's part withdrawn as today
    folders = part_folders(outbox)
    assert sorted(t for _, t in folders) == ["decam", "ls4"]
    for folder in folders.values():
        assert part(folder)["state"] == "withdrawn" and (folder / "WITHDRAWN").is_file()
    assert {r[2] for r in part_rows(tmp_path / "state.sqlite")} == {"withdrawn"}


def _polar(tmp_path: Path) -> Path:
    """LS4 limited to the south celestial pole (dec < -85): it cannot observe MS181101ab."""
    text = (SHIPPED / "ls4.toml").read_text().replace('name = "ls4"', 'name = "ls4polar"')
    text = text.replace("dec_max_deg = 30.0", "dec_max_deg = -85.0")
    path = tmp_path / "ls4polar.toml"
    path.write_text(text)
    return path


def test_a_telescope_that_cannot_observe_gets_no_export_and_the_other_goes_on(tmp_path):
    polar = _polar(tmp_path)
    (out,) = _run(tmp_path, ["ztf", str(polar), "ls4"], [notice_bytes(f"{SID}-preliminary.json")], 0.001)
    assert out.decision == "plan"
    folders = part_folders(tmp_path / "outbox")
    blind, ls4 = folders[("00001-PRELIMINARY", "ls4polar")], folders[("00001-PRELIMINARY", "ls4")]
    assert part(blind)["state"] == "not_observable" and part(blind)["files"] == [] and part(blind)["detail"]
    assert sorted(p.name for p in blind.iterdir()) == ["part.json"]  # no export
    assert part(ls4)["state"] == "exported" and (ls4 / "targets.csv").is_file()


def test_one_telescopes_failure_does_not_lose_the_others_parts(tmp_path, monkeypatch):
    from mushrooms.scheduler_core import joint_parts

    real = joint_parts._part

    def failing(skymap, problem, *args, **kw):
        if problem.telescope == "ls4":
            raise RuntimeError("ls4 planner broke (test)")
        return real(skymap, problem, *args, **kw)

    monkeypatch.setattr(joint_parts, "_part", failing)
    (out,) = _run(tmp_path, ["ztf", "ls4", "decam"], [notice_bytes(f"{SID}-preliminary.json")])
    assert out.decision == "plan" and _ztf_plans(tmp_path / "outbox")  # ZTF's part published
    folders = part_folders(tmp_path / "outbox")
    assert part(folders[("00001-PRELIMINARY", "ls4")])["state"] == "failed"
    assert "ls4 planner broke" in part(folders[("00001-PRELIMINARY", "ls4")])["detail"]
    assert part(folders[("00001-PRELIMINARY", "decam")])["state"] == "exported"


def test_hostile_description_fields_stay_inside_the_outbox(tmp_path):
    huge = "../../" * 3000 + "\u202e\x00evil/" + "x" * 100_000
    text = (SHIPPED / "winter.toml").read_text().replace('name = "winter"', 'name = "w"')
    text = text.replace('skyportal_instrument = "WINTER"', f"skyportal_instrument = {json.dumps(huge)}")
    text = text.replace('title = "Wide-field', f"title = {json.dumps(huge)[:-1]} Wide-field")
    (tmp_path / "w.toml").write_text(text)
    (out,) = _run(tmp_path, ["ztf", str(tmp_path / "w.toml")], [notice_bytes(f"{SID}-preliminary.json")])
    assert out.decision == "plan"
    outbox = (tmp_path / "outbox").resolve()
    every = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert all(p.resolve().is_relative_to(tmp_path.resolve()) for p in every)
    assert all(len(p.name) <= 64 for p in outbox.rglob("*"))
    (folder,) = part_folders(outbox).values()
    doc = part(folder)
    assert doc["telescope"] == "w" and len(doc["title"]) <= 200 and len(json.dumps(doc)) < 5_000
    if doc["state"] == "exported":
        request = json.loads((folder / "skyportal_request.json").read_text())
        assert request["sent"] is False and len(request["instrument"]) <= 100


def test_a_state_file_of_mains_code_loads_and_plans_two_telescopes(tmp_path):
    """``state_main_6bf5c61.sqlite``: main (6bf5c61) planned MS181101ab's PRELIMINARY with ZTF alone."""
    shutil.copy(DATA / "state_main_6bf5c61.sqlite", tmp_path / "state.sqlite")
    (out,) = _run(tmp_path, ["ztf", "ls4"], [newer_map_update()])
    assert out.decision == "rerun" and out.supersedes  # the stored plan of main's code is superseded
    conn = sqlite3.connect(tmp_path / "state.sqlite")
    try:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 6  # main's code still reads it
    finally:
        conn.close()
    assert [(r[1], r[2]) for r in part_rows(tmp_path / "state.sqlite")] == [("ls4", "exported")]


def test_the_service_takes_ztf_and_another_telescope_and_refuses_ztf_second():
    from mushrooms.daemon.wiring import service_telescopes_problem
    from mushrooms.scheduler_core import PlanningConfig
    from mushrooms.tool.config import Config

    ok = Config(scheduler=PlanningConfig.from_mapping({"telescopes": ["ztf", "ls4"]}))
    assert service_telescopes_problem(ok) == ""
    bad = Config(scheduler=PlanningConfig.from_mapping({"telescopes": ["ls4", "ztf"]}))
    assert "plans ZTF first" in service_telescopes_problem(bad)


@pytest.mark.parametrize("telescopes", [["ztf"]])
def test_ztf_alone_writes_no_part(tmp_path, telescopes):
    (out,) = _run(tmp_path, telescopes, [notice_bytes(f"{SID}-preliminary.json")])
    assert out.decision == "plan" and not (tmp_path / "outbox" / "telescopes").exists()
    assert part_rows(tmp_path / "state.sqlite") == []


@pytest.mark.slow
def test_a_kill_between_two_parts_loses_none_and_duplicates_none(tmp_path):
    import os
    import subprocess
    import sys

    from mushrooms.daemon.state.store import Store

    repo = Path(__file__).resolve().parents[2]
    cfg = parts_config(tmp_path, ["ztf", "ls4", "decam"])
    env = {**os.environ, "PYTHONPATH": f"{repo}{os.pathsep}{repo / 'tests' / 'daemon'}"}
    run = subprocess.run([sys.executable, str(Path(__file__).with_name("telescope_parts_kill.py")), str(cfg)],
                         cwd=repo, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == -9, run.stderr[-2000:]
    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    (ls4_row,) = part_rows(state)  # ls4's part recorded, decam's not yet, ZTF's revision not yet
    assert ls4_row[1:3] == ("ls4", "exported") and not _ztf_plans(outbox)
    ls4 = part_folders(outbox)[("00001-PRELIMINARY", "ls4")]
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in ls4.iterdir()}
    pipeline, close = open_parts_pipeline(cfg)  # the restart: the killed job is run again
    try:
        (out,) = pipeline.resume()
    finally:
        close()
    assert out.decision == "plan"
    assert [(r[1], r[2]) for r in part_rows(state)] == [("decam", "exported"), ("ls4", "exported")]
    assert part_rows(state)[1] == ls4_row  # not planned again
    assert {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in ls4.iterdir()} == before  # not rewritten
    assert [d["plan_id"] for d in _ztf_plans(outbox)] == [out.plan_id]  # ZTF's revision once
    assert sorted(t for _, t in part_folders(outbox)) == ["decam", "ls4"]
    store = Store(state)
    try:
        assert store.job_status(1) == "done"
    finally:
        store.close()


def test_the_summary_page_and_webhook_name_every_telescopes_part(tmp_path, httpserver, monkeypatch):
    import time

    httpserver.expect_request("/hook", method="POST").respond_with_data("ok")
    monkeypatch.setenv("MUSHROOMS_NOTIFY_URL", httpserver.url_for("/hook"))
    cfg = parts_config(tmp_path, ["ztf", "ls4"])
    cfg.write_text(cfg.read_text() + '\n[notify]\ntarget = "json"\n')
    pipeline, close = open_parts_pipeline(cfg)
    try:
        plan = pipeline.handle(notice_bytes(f"{SID}-preliminary.json"), "test:parts")
        pipeline.handle(notice_bytes(f"{SID}-retraction.json"), "test:parts")
    finally:
        close()
    outbox = tmp_path / "outbox"
    text = (outbox / f"{plan.plan_id}.txt").read_text()
    assert "Telescopes ztf (ztf_too): this plan" in text  # drawn again after the retraction: withdrawn by then
    assert "ls4 (target_list): exported" in text or "ls4 (target_list): withdrawn" in text
    assert '<pre class="telescopes">' in (outbox / f"{plan.plan_id}.html").read_text()
    end = time.monotonic() + 30
    while len(httpserver.log) < 2 and time.monotonic() < end:
        time.sleep(0.1)
    bodies = [json.loads(req.get_data()) for req, _ in httpserver.log]
    said = json.dumps(bodies, ensure_ascii=False)
    # each telescope's covered area on its own grid (tests/test_covered_area_telescopes.py)
    assert re.search(r"ZTF at Palomar: this plan \(fields cover [\d,]+ deg²\); other telescopes: ls4 target_list "
                     r"exported at La Silla \(fields cover [\d,]+ deg²\)", said)
    assert any(b.get("telescope_parts") == ["ls4 target_list exported"] for b in bodies)
    assert "Every telescope's part withdrawn too (ls4)" in said
