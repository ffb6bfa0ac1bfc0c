"""One answer to "the event's current map / plan / notice" (``current_event`` C1-C4), through the real pipeline.

The loop's scenario (``loop_helpers``: MS181101ab re-dated, planned by the
real :class:`NoticePipeline` on real SQLite), then a newer notice of the same
superevent carrying another sky map (the same FITS map with one more header
card: other bytes, another SHA-256), accepted but not yet planned.
"""

from __future__ import annotations

import base64
import io
import json
from datetime import timedelta

import pytest
from astropy.io import fits

from mushrooms.daemon.planning.replans import replan_jobs
from mushrooms.daemon.state.views import connect_readonly, recent_events

from loop_helpers import (NOTICE, RECEIVED, SENT, SUPEREVENT, after, copy_state, loop_config, open_pipeline,
                          planned_state, t, the_plan)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("planned"))


@pytest.fixture
def pipe(planned, tmp_path):
    p = open_pipeline(copy_state(planned, tmp_path), loop_config(tmp_path / "executed.jsonl"))
    yield p
    p.store.close()


def newer_map_notice() -> bytes:
    """An UPDATE of the event ten minutes after :data:`SENT`, its sky map changed by one header card."""
    doc = json.loads(NOTICE.read_bytes())
    with fits.open(io.BytesIO(base64.b64decode(doc["event"]["skymap"]))) as hdus:
        hdus[1].header["HISTORY"] = "refined localisation (test)"
        out = io.BytesIO()
        hdus.writeto(out)
    doc["event"]["skymap"] = base64.b64encode(out.getvalue()).decode()
    doc["alert_type"] = "UPDATE"
    doc["time_created"] = "2023-04-15T03:05:00Z"
    doc["event"]["time"] = SENT
    return json.dumps(doc).encode()


def accept_newer(p):
    acc = p.accept(newer_map_notice(), "test:update", RECEIVED + timedelta(minutes=10))
    assert acc.action == "update" or acc.job is not None, acc
    return acc


def test_a_closure_while_a_newer_map_is_open_re_plans_the_newer_map(pipe):
    p = pipe
    first = the_plan(p)
    newer = accept_newer(p)
    assert newer.job is not None
    reopening = after(first["observations"][3]["end"], 3600.0)
    closure = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=RECEIVED + timedelta(minutes=11))
    assert closure.action == "replan" and closure.job is not None
    assert closure.job.skymap_sha256 == newer.job.skymap_sha256  # the newer map is re-planned, not the old one
    assert closure.job.notice_id == newer.job.notice_id
    assert closure.job.supersedes == first["plan_id"]  # the queue on the telescope is what it replaces
    assert p.store.job_status(newer.job.job_id) == "superseded"
    out = p.run_job(closure.job)
    assert out.decision == "replan" and out.plan_id, out
    assert min(t(o["start"]).unix for o in the_plan(p)["observations"]) >= reopening.unix - 1e-3
    # the newer map delivered again is a duplicate now: the closure's re-plan planned it
    again = p.accept(newer_map_notice(), "test:update-again", RECEIVED + timedelta(minutes=20))
    assert again.action == "duplicate", again


def test_a_newer_notice_whose_job_failed_leaves_the_current_plan_re_plannable(pipe):
    p = pipe
    first = the_plan(p)
    newer = accept_newer(p)
    assert p.store.prune_raw(older_than_s=0.0, planned_older_than_s=30 * 86400.0) == 0  # open job: all kept
    p.store.fail_job(newer.job.job_id, "bad sky map (test)")
    p.store.prune_raw(older_than_s=0.0, planned_older_than_s=30 * 86400.0)
    # the failed notice's bytes may go; the current plan's notice keeps them
    plan_notice = p.store.job(p.store.plans(SUPEREVENT)[-1]["job_id"])
    assert p.store.notice_raw(plan_notice.notice_id) is not None
    reopening = after(first["observations"][3]["end"], 3600.0)
    closure = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=RECEIVED + timedelta(minutes=11))
    assert closure.job is not None and closure.job.notice_id == plan_notice.notice_id
    out = p.run_job(closure.job)
    assert out.decision == "replan" and out.plan_id, out
    assert [j["status"] for j in replan_jobs(p.store, SUPEREVENT)] == ["done"]


def test_the_current_plans_notice_keeps_its_bytes_while_a_newer_job_is_open(pipe):
    p = pipe
    plan_job = p.store.job(p.store.plans(SUPEREVENT)[-1]["job_id"])
    newer = accept_newer(p)
    p.store.prune_raw(older_than_s=0.0, planned_older_than_s=30 * 86400.0)
    assert p.store.notice_raw(plan_job.notice_id) is not None
    assert p.store.notice_raw(newer.job.notice_id) is not None
    # trigger SUPEREVENT plans the current map: the newer notice
    assert p.store.latest_planned_notice(SUPEREVENT)[0] == newer.job.notice_id


def test_status_shows_the_submission_columns_the_table_has(pipe):
    p = pipe
    plan_id = the_plan(p)["plan_id"]
    with p.store.transaction() as c:
        c.execute("INSERT INTO submissions(plan_id, superevent_id, target, revision, queue_name, state, reason,"
                  " attempts, created_at, attempted_at, submitted_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                  (plan_id, SUPEREVENT, "kowalski", 1, "ToO_q", "submitted", "accepted", 2, "2023-04-15T03:00:00Z",
                   "2023-04-15T03:00:01Z", "2023-04-15T03:00:02Z"))
    conn = connect_readonly(p.store.path)
    try:
        sub = recent_events(conn)[0]["plans"][-1]["submission"]
    finally:
        conn.close()
    assert sub == {"state": "submitted", "queue_name": "ToO_q", "reason": "accepted", "attempts": 2,
                   "attempted_at": "2023-04-15T03:00:01Z", "submitted_at": "2023-04-15T03:00:02Z",
                   "finished_at": None}


def test_no_module_reaches_into_the_stores_private_job_sets_or_outbox():
    """The store's job sets and outbox insert are its own: other modules call its public methods."""
    from pathlib import Path

    import mushrooms.daemon as daemon

    reach = [(f.name, n) for f in Path(daemon.__file__).parent.rglob("*.py") if f.name != "store.py"
             for n in ("store._started", "store._parked", "Store._insert_outbox", "store._insert_outbox")
             if n in f.read_text()]
    assert reach == []
