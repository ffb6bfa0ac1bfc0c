"""The daemon on hostile orderings and crashes, fast cases on real parts (SQLite file, greedy/hybrid
at nside 64, real sky maps): creation order through the store, crash accounting
and the fallback's plan_final, plan ids after a withdrawal, raw-byte pruning."""

from __future__ import annotations

import dataclasses
import json
from datetime import datetime, timedelta, timezone
from pathlib import Path

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store

from attack_helpers import FAST, NOTICES, base_doc, received_at

LATER = received_at() + timedelta(hours=2)  # every notice below is received after it was created
GREEDY = dataclasses.replace(FAST, scheduler=dataclasses.replace(FAST.scheduler, min_coverage=0.0))
HYBRID = dataclasses.replace(GREEDY, scheduler=dataclasses.replace(GREEDY.scheduler, solver="hybrid"))
OTHER_MAP = json.loads((NOTICES / "live" / "MS230425k-preliminary.json").read_bytes())["event"]["skymap"]


def notice(sid: str = "MS181101ab", alert_type: str = "PRELIMINARY", created_shift_s: float = 0.0,
           other_map: bool = False) -> bytes:
    """The sample notice as ``alert_type``, created ``created_shift_s`` (s) after the sample's time."""
    doc = base_doc()
    doc["superevent_id"] = sid
    doc["alert_type"] = alert_type
    t = datetime(2018, 11, 1, 22, 34, 49, tzinfo=timezone.utc) + timedelta(seconds=created_shift_s)
    doc["time_created"] = t.strftime("%Y-%m-%dT%H:%M:%SZ")
    if alert_type == "RETRACTION":
        doc["event"] = None
    elif other_map:
        doc["event"]["skymap"] = OTHER_MAP
    return json.dumps(doc).encode()


def pipeline(path: Path, config=GREEDY, sink=None) -> NoticePipeline:
    return NoticePipeline.from_config(config, Store(path), sink if sink is not None else MemorySink())


def types(sink: MemorySink) -> list[str]:
    """Message types; a ``not_observable`` document is the plan's answer in its place (the sample map
    is behind the Sun on its date), so it counts as ``plan``."""
    return ["plan" if m.get("type") == "not_observable" else m.get("type") for m in sink.messages]


def plan_messages(sink: MemorySink) -> list[dict]:
    return [m for m in sink.messages if m.get("type") in ("plan", "not_observable")]


# ---------------------------------------------------------------- 1. creation order
def test_a_late_older_preliminary_after_a_retraction_is_not_planned(tmp_path: Path) -> None:
    p = pipeline(tmp_path / "s.sqlite")
    p.handle(notice(created_shift_s=0), "kafka:t:0:1", LATER)
    p.handle(notice(alert_type="RETRACTION", created_shift_s=600), "kafka:t:1:1", LATER)
    out = p.handle(notice(created_shift_s=300, other_map=True), "kafka:t:2:1", LATER)
    assert out.decision == "ignore" and "before the retraction" in out.reason
    assert types(p.sink) == ["plan", "withdrawal"]
    (row,) = [d for d in p.store.decisions() if d["origin"] == "kafka:t:2:1"]
    assert row["decision"] == "ignore" and "stale" in row["reason"]  # the decision and its reason are stored


def test_an_older_map_arriving_late_never_supersedes_the_newer_plan(tmp_path: Path) -> None:
    p = pipeline(tmp_path / "s.sqlite")
    newer = p.handle(notice(alert_type="UPDATE", created_shift_s=200), "kafka:t:0:1", LATER)
    older = p.handle(notice(alert_type="EARLYWARNING", created_shift_s=0, other_map=True), "kafka:t:1:1",
                     LATER)
    assert newer.decision == "plan" and older.decision == "ignore"
    assert [m["plan_id"] for m in plan_messages(p.sink)] == [newer.plan_id]
    assert p.store.event_state("MS181101ab").latest_created == "2018-11-01T22:38:09.000Z"


def test_a_state_file_of_schema_2_is_migrated(tmp_path: Path) -> None:
    import sqlite3

    path = tmp_path / "old.sqlite"
    Store(path).close()
    with sqlite3.connect(path) as c:  # make it look like a schema-2 file: no latest_created column
        c.executescript("ALTER TABLE events DROP COLUMN latest_created; PRAGMA user_version=2;")
    s = Store(path)
    cols = [r[1] for r in s.connection().execute("PRAGMA table_info(events)")]
    assert "latest_created" in cols


# ---------------------------------------------------------------- 3. crash accounting
def test_waiting_for_an_optimisation_slot_is_not_a_counted_start(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    p = pipeline(path, HYBRID)
    acc = p.accept(notice(), "kafka:t:0:1", LATER)
    staged = p.run_job(acc.job, staged=True)
    assert staged.outcome.revision == 1 and not staged.outcome.final
    # the process is killed while the job waits behind other optimisations
    after = Store(path).job(acc.job.job_id)
    assert after.status == "running" and after.attempts == 0


def test_the_fallback_after_repeated_crashes_publishes_plan_final(tmp_path: Path) -> None:
    path, sink = tmp_path / "s.sqlite", MemorySink()
    p = pipeline(path, HYBRID, sink)
    acc = p.accept(notice(), "kafka:t:0:1", LATER)
    for _ in range(3):  # three processes each die inside the optimiser
        p = pipeline(path, HYBRID, sink)
        staged = p.run_job(p.store.job(acc.job.job_id), staged=True)
        assert p.store.resume_job(acc.job.job_id)  # the optimisation begins ... and the process dies
    assert Store(path).job(acc.job.job_id).attempts == 3
    p = pipeline(path, HYBRID, sink)
    out = p.run_job(p.store.job(acc.job.job_id), staged=True)
    assert out.final and out.revision == 1, out
    plans = plan_messages(sink)
    finals = [m for m in sink.messages if m["type"] == "plan_final"]
    assert {m["plan_id"] for m in plans} == {staged.outcome.plan_id} and plans[0]["final"] is False
    assert [m["plan_id"] for m in finals] == [staged.outcome.plan_id]
    assert p.store.job_status(acc.job.job_id) == "done"


def test_giving_up_on_a_job_with_a_published_revision_still_closes_it_with_plan_final(tmp_path: Path) -> None:
    path, sink = tmp_path / "s.sqlite", MemorySink()
    p = pipeline(path, HYBRID, sink)
    acc = p.accept(notice(), "kafka:t:0:1", LATER)
    staged = p.run_job(acc.job, staged=True)
    p.store.resume_job(acc.job.job_id)
    while p.store.start_job(acc.job.job_id) is not None:  # every later start dies, the fallback's too
        pass
    assert p.store.job_status(acc.job.job_id) == "done"
    p.flush_outbox()
    assert [m["plan_id"] for m in sink.messages if m["type"] == "plan_final"] == [staged.outcome.plan_id]


# ---------------------------------------------------------------- 4. plan ids after a withdrawal
def test_a_replan_after_a_withdrawal_gets_a_new_plan_id(tmp_path: Path) -> None:
    p = pipeline(tmp_path / "s.sqlite")
    first = p.handle(notice(created_shift_s=0), "kafka:t:0:1", LATER)
    p.handle(notice(alert_type="RETRACTION", created_shift_s=100), "kafka:t:0:2", LATER)
    again = p.handle(notice(alert_type="INITIAL", created_shift_s=200), "kafka:t:0:3", LATER)
    assert again.decision == "plan" and again.plan_id != first.plan_id
    (withdrawal,) = [m for m in p.sink.messages if m["type"] == "withdrawal"]
    assert again.plan_id not in withdrawal["plan_ids"]
    live = [pl for pl in p.store.plans("MS181101ab") if not pl["withdrawn"]]
    assert [pl["plan_id"] for pl in live] == [again.plan_id]
    assert [pl["plan_id"] for pl in p.store.plans("MS181101ab") if pl["withdrawn"]] == [first.plan_id]


def test_ordinary_plan_ids_do_not_change(tmp_path: Path) -> None:
    """The same notice planned in two fresh states gives one id, that of the plan without any salt."""
    a = pipeline(tmp_path / "a.sqlite").handle(notice(), "kafka:t:0:1", LATER)
    b = pipeline(tmp_path / "b.sqlite").handle(notice(), "kafka:t:0:1", LATER)
    assert a.plan_id == b.plan_id and a.plan_id.startswith("mushrooms-")
    assert Store(tmp_path / "a.sqlite").plan_epoch(1) == 0


# ---------------------------------------------------------------- 7. a read-only state directory
def test_a_read_only_state_directory_is_one_line_and_exit_2(tmp_path: Path) -> None:
    """It was exit 70 on the pid file, which ``Restart=on-failure`` restarts every 5 s."""
    import os
    import shutil
    import subprocess
    import sys

    if shutil.which("unshare") is None:
        import pytest

        pytest.skip("unshare(1) is needed to mount the state directory read-only")
    state = tmp_path / "state"
    state.mkdir()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(__file__).resolve().parents[2]),
                                                       os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run(["unshare", "-rm", "sh", "-c",
                        'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" && shift && exec "$@"', "sh",
                        str(state), sys.executable, "-m", "mushrooms.cli", "run", "--state",
                        str(state / "s.sqlite"), "--bootstrap", "127.0.0.1:9", "--outbox", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    if "mount" in r.stderr and r.returncode != 2:
        import pytest

        pytest.skip(f"no mount namespace here: {r.stderr.strip()[:200]}")
    assert r.returncode == 2, (r.returncode, r.stderr)
    (line,) = [ln for ln in r.stderr.splitlines() if "error" in ln]
    assert "cannot write the pid file" in line and "Read-only file system" in line
    assert "Traceback" not in r.stderr + r.stdout
    unit = (Path(__file__).resolve().parents[2] / "systemd" / "mushrooms.service").read_text()
    prevent = next(ln for ln in unit.splitlines() if ln.startswith("RestartPreventExitStatus="))
    assert "2" in prevent.split("=", 1)[1].split()


# ---------------------------------------------------------------- 7. raw bytes of planned notices are pruned
def test_raw_bytes_of_planned_notices_are_pruned_once_not_needed(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    p = pipeline(path)
    a1 = p.handle(notice("MS181101ab", created_shift_s=0), "kafka:t:0:1", LATER)
    a2 = p.handle(notice("MS181101ab", "UPDATE", created_shift_s=60, other_map=True), "kafka:t:0:2", LATER)
    b = p.handle(notice("MS181102ab"), "kafka:t:0:3", LATER)
    pending = p.accept(notice("MS181103ab"), "kafka:t:0:4", LATER)  # its job has not run
    assert a2.decision == "rerun"
    pages_before = p.store.connection().execute("PRAGMA page_count").fetchone()[0]
    # superseded notice: pruned at once; each event's newest kept for the retention; an open job's never
    assert p.store.prune_raw(older_than_s=0, planned_older_than_s=3600) == 1
    assert p.store.notice_raw(a1.notice_id) is None
    assert p.store.notice_raw(a2.notice_id) is not None and p.store.notice_raw(b.notice_id) is not None
    assert p.store.notice_raw(pending.notice_id) is not None
    assert p.rerun_superevent("MS181101ab", "trigger:x").action == "rerun"  # still re-plannable
    for j in p.store.pending_jobs():
        p.run_job(j)
    # after the retention even the newest go; the rows, hashes and decisions stay
    assert p.store.prune_raw(older_than_s=0, planned_older_than_s=0) == 4
    assert p.store.notice_raw(a2.notice_id) is None and p.store.notice_raw(pending.notice_id) is None
    assert len(p.store.decisions()) == 5
    # the file gives the pages back (incremental auto-vacuum): fewer pages than with four notices' bytes
    conn = p.store.connection()
    assert conn.execute("PRAGMA auto_vacuum").fetchone()[0] == 2  # incremental
    assert conn.execute("PRAGMA freelist_count").fetchone()[0] == 0
    assert conn.execute("PRAGMA page_count").fetchone()[0] < pages_before


def test_the_service_prunes_planned_raw_bytes_with_the_configured_retention() -> None:
    from mushrooms.tool.config import load_config

    cfg = load_config(None)
    assert cfg.daemon.planned_raw_retention_s == 604800.0
    from types import SimpleNamespace

    from mushrooms.daemon.timers import Timers

    asked = []
    store = SimpleNamespace(prune_raw=lambda rejected_s, planned_s: asked.append((rejected_s, planned_s)) or 0)
    Timers(SimpleNamespace(config=cfg, pipeline=SimpleNamespace(store=store))).prune_raw()
    assert asked == [(cfg.daemon.rejected_raw_retention_s, 604800.0)]


def test_a_retraction_before_any_notice_of_its_event_keeps_older_notices_unplanned(tmp_path: Path) -> None:
    """The retraction arrives first (another partition), a PRELIMINARY created 300 s before it later:
    nothing is planned or sent; a notice created after the retraction plans the event again."""
    p = pipeline(tmp_path / "s.sqlite")
    ret = p.handle(notice(alert_type="RETRACTION", created_shift_s=300), "kafka:t:0:1", LATER)
    assert ret.decision == "ignore" and "never planned" in ret.reason
    late = p.handle(notice(created_shift_s=0), "kafka:t:1:1", LATER)
    assert late.decision == "ignore" and "before the retraction" in late.reason
    assert types(p.sink) == []
    again = p.handle(notice(alert_type="INITIAL", created_shift_s=600), "kafka:t:2:1", LATER)
    assert again.decision == "plan"
    (row,) = [d for d in p.store.decisions() if d["origin"] == "kafka:t:2:1"]
    assert "after a retraction" in row["reason"]
    assert types(p.sink) == ["plan"]
