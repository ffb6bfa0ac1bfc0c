"""One decision rule for bare sky maps, one migration mechanism for state files."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import SCHEMA_VERSION, Store
from mushrooms.handlers.policy import PolicyConfig
from mushrooms.scheduler_core import PlanningConfig

DATA = Path(__file__).resolve().parents[1] / "data"
SKYMAP = DATA / "skymaps" / "S200129m_cWB_RING.fits.gz"  # 214 kB as carried


def _pipeline(tmp_path: Path, policy: PolicyConfig) -> NoticePipeline:
    planning = PlanningConfig(solver="greedy", nside=64, time_step_s=600.0)
    return NoticePipeline(policy, planning, Store(tmp_path / "s.sqlite"), MemorySink())


def test_a_bare_sky_map_is_capped_by_max_skymap_bytes_not_by_the_notice_cap(tmp_path: Path) -> None:
    """The one intended behaviour change of the one decision rule: a bare map is bounded by [policy] max_skymap_bytes.

    (The pipeline of f999d02 already compared with max_skymap_bytes; this keeps it so with the rule in intake.)
    """
    data = SKYMAP.read_bytes()
    policy = PolicyConfig(allow_mock=True, max_notice_bytes=1024, max_skymap_bytes=len(data) + 4096)
    assert len(data) > policy.max_notice_bytes * 4
    p = _pipeline(tmp_path, policy)
    try:
        acc = p.accept_skymap(data, "trigger:map")
        assert acc.action == "plan" and acc.job is not None, acc
        assert acc.superevent_id.startswith("skymap-") and acc.alert_type == "SKYMAP"
        assert acc.job_id == acc.job.job_id and acc.notice_id is not None
        # decided by handlers.decisions.decide: the same map again is a duplicate while its job is open
        again = p.accept_skymap(data, "trigger:map-again")
        assert again.action == "duplicate" and again.job is None
        too_big = data + bytes(policy.max_skymap_bytes + 1 - len(data))
        refused = p.accept_skymap(too_big, "trigger:big")
        assert refused.action == "rejected" and "max_skymap_bytes" in refused.reason
        assert [d["decision"] for d in p.store.decisions()] == ["plan", "duplicate", "rejected"]
    finally:
        p.store.close()


def test_a_bare_sky_map_whose_planning_failed_can_be_triggered_again(tmp_path: Path) -> None:
    """Degrade, never drop (decide's rule, now also the bare map's): no plan went out, none is coming."""
    data = SKYMAP.read_bytes()
    p = _pipeline(tmp_path, PolicyConfig(allow_mock=True))
    try:
        acc = p.accept_skymap(data, "trigger:map")
        p.store.start_job(acc.job.job_id)
        p.store.fail_job(acc.job.job_id, "internal error: test")
        assert p.accept_skymap(data, "trigger:again").action == "plan"
    finally:
        p.store.close()


# ---------------------------------------------------------------- state files of every schema version
#: What each older schema version lacked, as statements that take it out of a current file.
OLDER = {
    0: ("ALTER TABLE events DROP COLUMN localization", "ALTER TABLE events DROP COLUMN latest_created",
        "DROP TABLE submissions", "DROP TABLE incidents", "ALTER TABLE plans DROP COLUMN revision",
        "ALTER TABLE plans DROP COLUMN final", "DROP TABLE executed"),
    1: ("ALTER TABLE events DROP COLUMN localization", "ALTER TABLE events DROP COLUMN latest_created",
        "DROP TABLE submissions", "DROP TABLE incidents", "ALTER TABLE plans DROP COLUMN revision",
        "ALTER TABLE plans DROP COLUMN final", "DROP TABLE executed"),
    2: ("ALTER TABLE events DROP COLUMN latest_created", "DROP TABLE submissions", "DROP TABLE incidents",
        "DROP TABLE executed"),
    3: ("ALTER TABLE events DROP COLUMN latest_created", "DROP TABLE incidents", "DROP TABLE executed"),
    4: ("DROP TABLE incidents", "DROP TABLE executed"),
}


def _columns(conn: sqlite3.Connection, table: str) -> set[str]:
    return {r[1] for r in conn.execute(f"PRAGMA table_info({table})")}


@pytest.mark.parametrize("version", sorted(OLDER))
def test_a_state_file_of_each_older_schema_version_opens_with_its_rows(tmp_path: Path, version: int) -> None:
    path = tmp_path / f"v{version}.sqlite"
    Store(path).close()
    with sqlite3.connect(path) as c:
        want = {t: _columns(c, t) for t in ("events", "plans", "submissions", "incidents", "executed")}
        for sql in OLDER[version]:
            c.execute(sql)
        c.execute("INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at)"
                  " VALUES ('S1', 'abc', 0, '2026-01-01T00:00:00')")
        c.execute("INSERT INTO plans(plan_id, superevent_id, job_id, created_at, seq, document)"
                  " VALUES ('p1', 'S1', NULL, '2026-01-01T00:00:00', 1, '{}')")
        c.execute(f"PRAGMA user_version={version}")
    c.close()
    s = Store(path)
    try:
        st = s.event_state("S1")
        assert (st.skymap_sha256, st.retracted, st.plan_ids, st.localization) == ("abc", False, ("p1",), None)
        assert [(r["revision"], r["final"]) for r in s.plans("S1")] == [(1, 1)]
        s.record_incident("test", {"x": 1})  # the table exists
    finally:
        s.close()
    c = sqlite3.connect(path)
    try:
        assert c.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        assert {t: _columns(c, t) for t in want} == want
    finally:
        c.close()
    Store(path).close()  # and it opens again as a current file
