"""The daemon's path end to end on real notices: parse -> policy -> decide -> plan -> check -> store -> sink."""

from __future__ import annotations

import base64
import dataclasses
import json
import logging
from datetime import timedelta

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import DirectorySink, MemorySink
from mushrooms.daemon.state.store import Store

from replay_helpers import FAST, created, mutated, raw


@pytest.fixture
def store(tmp_path):
    s = Store(tmp_path / "state.sqlite")
    yield s
    s.close()


def pipe(store, sink=None, config=FAST, planner=None):
    return NoticePipeline.from_config(config, store, sink if sink is not None else MemorySink(), planner=planner)


def handle(p, rel, data=None, minutes=0.5):
    return p.handle(data if data is not None else raw(rel), f"test:{rel}", created(rel) + timedelta(minutes=minutes))


def test_plan_then_duplicate_then_withdraw(store, tmp_path):
    sink = DirectorySink(tmp_path / "out")
    p = pipe(store, sink)
    first = handle(p, "json/MS181101ab-preliminary.json")
    assert first.decision == "plan" and first.published
    assert first.plan_id.startswith("mushrooms-") and 0.0 <= first.coverage <= 1.0 and first.latency_s > 0
    doc = json.loads((tmp_path / "out" / f"{first.plan_id}.json").read_text())
    assert doc["type"] == "plan" and doc["supersedes"] is None
    assert doc["event"]["superevent_id"] == "MS181101ab" and doc["event"]["alert_type"] == "PRELIMINARY"
    assert doc["event"]["skymap_sha256"].startswith("db875e1b8cc8")
    assert doc["metrics"]["latency_s"] == first.latency_s
    dup = handle(p, "json/MS181101ab-initial.json")
    assert dup.decision == "duplicate" and dup.plan_id == first.plan_id
    gone = handle(p, "json/MS181101ab-retraction.json")
    assert gone.decision == "withdraw" and gone.plan_ids == (first.plan_id,) and gone.published
    files = sorted(f.name for f in (tmp_path / "out").iterdir())
    assert len(files) == 2
    w = json.loads((tmp_path / "out" / [f for f in files if f.startswith("withdrawal-")][0]).read_text())
    assert w["type"] == "withdrawal" and w["superevent_id"] == "MS181101ab"
    assert w["plan_ids"] == [first.plan_id] and "RETRACTION" in w["reason"] and w["created"].endswith("Z")
    assert [d["decision"] for d in store.decisions()] == ["plan", "duplicate", "withdraw"]
    assert store.plans()[0]["withdrawn"] == 1


def test_changed_sky_map_reruns_and_supersedes(store, tmp_path):
    sink = MemorySink()
    p = pipe(store, sink)
    first = handle(p, "json/MS181101ab-preliminary.json")
    other_map = json.loads(raw("live/MS230425k-preliminary.json"))["event"]["skymap"]
    second = handle(p, "json/MS181101ab-update.json", mutated("json/MS181101ab-update.json", skymap=other_map))
    assert second.decision == "rerun" and second.supersedes == first.plan_id != second.plan_id
    assert [m["supersedes"] for m in sink.messages] == [None, first.plan_id]
    assert store.event_state("MS181101ab").plan_ids == (first.plan_id, second.plan_id)
    # the superseding plan is the new map's plan: what a fresh service plans for that notice
    fresh = Store(tmp_path / "fresh.sqlite")
    fresh_sink = MemorySink()
    pipe(fresh, fresh_sink).handle(mutated("json/MS181101ab-update.json", skymap=other_map), "x",
                                   created("json/MS181101ab-update.json") + timedelta(minutes=0.5))
    fresh.close()
    old, new = sink.messages
    assert observations(new) == observations(fresh_sink.messages[0]) != observations(old)


def test_a_plan_the_checker_refuses_is_never_published(store, monkeypatch):
    """A scheduler bug (overlapping exposures) is caught by the checker: job failed, outbox empty."""
    import mushrooms.scheduler_core.planner as planner

    real = planner.run_scheduler

    def overlapping(problem, solver, should_stop=None):
        result = real(problem, solver, should_stop)
        o = list(result.observations)
        o[1] = dataclasses.replace(o[1], start=o[0].start + 10.0)
        return dataclasses.replace(result, observations=tuple(o))

    monkeypatch.setattr(planner, "run_scheduler", overlapping)
    sink = MemorySink()
    out = handle(pipe(store, sink), "json/MS181101ab-preliminary.json")
    assert out.decision == "failed" and out.reason.startswith("plan failed the checker: overlap:")
    assert sink.messages == [] and store.pending_outbox() == [] and store.plans() == []
    assert [d["decision"] for d in store.decisions()][-1:] == ["plan"]  # accepted, then the job failed
    assert store.describe_job(out.job_id).startswith("failed")


def test_retraction_then_later_initial_is_planned_again(store):
    """MS230425k: PRELIMINARY, RETRACTION, then an INITIAL 77 minutes later."""
    sink = MemorySink()
    p = pipe(store, sink)
    outs = [handle(p, f"live/MS230425k-{k}.json") for k in ("preliminary", "retraction", "initial")]
    assert [o.decision for o in outs] == ["plan", "withdraw", "plan"]
    assert outs[2].supersedes is None and outs[2].plan_id != outs[0].plan_id
    assert [m["type"] for m in sink.messages] == ["plan", "withdrawal", "plan"]
    assert store.event_state("MS230425k").plan_ids == (outs[2].plan_id,)


def test_burst_and_bbh_events_are_ignored_with_the_reason_logged(store, caplog):
    p = pipe(store)
    with caplog.at_level(logging.INFO, logger="mushrooms.daemon.pipeline"):
        burst = handle(p, "live/S230528ay-preliminary.json")
        bbh = handle(p, "json/MS181101ab-preliminary.json", mutated(
            "json/MS181101ab-preliminary.json",
            classification={"BNS": 0.0, "NSBH": 0.0, "BBH": 0.99, "Terrestrial": 0.01},
            properties={"HasNS": 0.0, "HasRemnant": 0.0}))
    assert burst.decision == "ignore" and "group Burst" in burst.reason
    assert bbh.decision == "ignore" and "most likely BBH" in bbh.reason
    lines = [r.getMessage() for r in caplog.records if "decision=ignore" in r.getMessage()]
    assert len(lines) == 2
    assert "superevent_id=S230528ay" in lines[0] and "group Burst not in CBC" in lines[0]
    assert "superevent_id=MS181101ab" in lines[1] and "BBH" in lines[1]
    assert store.plans() == []


def test_mock_events_are_ignored_by_default(store):
    import dataclasses

    cfg = dataclasses.replace(FAST, policy=dataclasses.replace(FAST.policy, allow_mock=False))
    out = handle(pipe(store, config=cfg), "json/MS181101ab-preliminary.json")
    assert out.decision == "ignore" and "mock" in out.reason


def test_avro_notice_is_planned(store):
    out = handle(pipe(store), "avro/MS181101ab-earlywarning.avro")
    assert out.decision == "plan" and out.alert_type == "EARLYWARNING"


def test_voevent_with_url_sky_map_is_rejected_cleanly(store):
    out = handle(pipe(store), "voevent/MS181101ab-2-Preliminary.xml")
    assert out.decision == "rejected" and "URL" in out.reason


NOT_FITS = base64.b64encode(b"SIMPLE  =" + b"\x00garbage" * 500).decode()


@pytest.mark.parametrize("case", ["truncated", "base64", "not_fits_magic", "fits_header_garbage", "missing_key",
                                  "wrong_type", "unknown_type", "huge"])
def test_bad_input_is_one_rejected_outcome_and_one_log_line(store, caplog, case):
    rel = "json/MS181101ab-preliminary.json"
    d = json.loads(raw(rel))
    if case == "truncated":
        data = raw(rel)[:100_000]
    elif case == "base64":
        d["event"]["skymap"] = "%%%%"
        data = json.dumps(d).encode()
    elif case == "not_fits_magic":
        d["event"]["skymap"] = base64.b64encode(b"GIF89a" + bytes(100)).decode()
        data = json.dumps(d).encode()
    elif case == "fits_header_garbage":  # passes the parser's magic check, fails in read_skymap
        d["event"]["skymap"] = NOT_FITS
        data = json.dumps(d).encode()
    elif case == "missing_key":
        del d["event"]["group"]
        data = json.dumps(d).encode()
    elif case == "wrong_type":
        d["event"]["instruments"] = "H1,L1"
        data = json.dumps(d).encode()
    elif case == "unknown_type":
        d["alert_type"] = "SUPERUPDATE"
        data = json.dumps(d).encode()
    else:
        data = b'{"superevent_id": "S1", "pad": "' + b"A" * (50 * 1024 * 1024) + b'"}'
    p = pipe(store)
    with caplog.at_level(logging.INFO, logger="mushrooms.daemon.pipeline"):
        out = handle(p, rel, data)
    assert out.decision == "rejected", out
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "decision=rejected" in warnings[0].getMessage()
    assert "\n" not in warnings[0].getMessage()
    recorded = [x["decision"] for x in store.decisions()]
    if case == "fits_header_garbage":  # accepted for planning, then the job was rejected
        assert recorded == ["plan"] and store.decisions()[0]["job_status"] == "failed"
    else:
        assert recorded == ["rejected"]
    if case == "huge":
        row = store.connection().execute("SELECT size, raw FROM notices").fetchone()
        assert row[0] > 50 * 1024 * 1024 and row[1] is None  # the payload itself is not stored
    # the pipeline carries on with the next, good notice (a retraction: no planning, same path)
    nxt = handle(p, "live/MS230425k-retraction.json")
    assert nxt.decision == "ignore" and "never planned" in nxt.reason


def observations(doc):
    """What a plan asks the telescope to do: (field, filter, start) of every exposure."""
    return [(o["field_id"], o["filter"], o["start"]) for o in doc["observations"]]


def test_crash_after_accept_resumes_with_the_same_plan(tmp_path):
    rel = "json/MS181101ab-preliminary.json"
    s1 = Store(tmp_path / "a.sqlite")
    acc = pipe(s1).accept(raw(rel), "kafka:igwn.gwalert:0:7", created(rel))
    assert acc.action == "plan" and acc.job is not None
    s1.close()  # the process dies before planning
    s2 = Store(tmp_path / "a.sqlite")
    sink = MemorySink()
    [resumed] = pipe(s2, sink).resume()
    assert resumed.decision == "plan" and resumed.published
    assert pipe(s2, sink).resume() == []  # nothing left
    s2.close()
    fresh = Store(tmp_path / "b.sqlite")  # the same notice elsewhere gives the same plan
    fresh_sink = MemorySink()
    assert pipe(fresh, fresh_sink).handle(raw(rel), "x", created(rel)).plan_id == resumed.plan_id
    fresh.close()
    [after_crash], [uninterrupted] = sink.messages, fresh_sink.messages
    assert observations(after_crash) and observations(after_crash) == observations(uninterrupted)


def test_sink_failure_keeps_the_message_in_the_outbox(store):
    sink = MemorySink()
    sink.fail = 1
    p = pipe(store, sink)
    out = handle(p, "json/MS181101ab-preliminary.json")
    assert out.decision == "plan" and not out.published and sink.messages == []
    assert p.flush_outbox() == 0
    assert [m["plan_id"] for m in sink.messages] == [out.plan_id]
    assert p.flush_outbox() == 0 and len(sink.messages) == 1


def test_retraction_while_planning_drops_the_plan(store):
    sink = MemorySink()
    p = pipe(store, sink)
    acc = p.accept(raw("live/MS230425k-preliminary.json"), "k:1", created("live/MS230425k-preliminary.json"))
    gone = p.accept(raw("live/MS230425k-retraction.json"), "k:2", created("live/MS230425k-retraction.json"))
    assert gone.action == "withdraw" and gone.cancelled_jobs == (acc.job.job_id,)
    out = p.run_job(acc.job)
    assert out.decision == "ignore" and "cancelled" in out.reason
    p.flush_outbox()
    assert [m["type"] for m in sink.messages] == ["withdrawal"]


def test_newer_map_while_planning_supersedes_the_old_job(store):
    sink = MemorySink()

    calls = []

    def planner(problem, solver, should_stop=None):
        from mushrooms.scheduler_core.planner import run_scheduler

        calls.append(solver)
        if len(calls) == 1:  # a newer sky map arrives while the first job is running
            other = json.loads(raw("live/MS230425k-preliminary.json"))["event"]["skymap"]
            rel = "json/MS181101ab-update.json"
            p.accept(mutated(rel, skymap=other), "k:2", created(rel))
        return run_scheduler(problem, solver, should_stop)

    p = pipe(store, sink, planner=planner)
    rel = "json/MS181101ab-preliminary.json"
    first = p.accept(raw(rel), "k:1", created(rel))
    out = p.run_job(first.job)
    assert out.decision == "ignore" and "superseded" in out.reason
    [job] = store.pending_jobs()
    second = p.run_job(job)
    assert second.decision == "rerun" and second.supersedes is None  # nothing was published before
    assert [m["plan_id"] for m in sink.messages] == [second.plan_id]


def test_internal_planner_error_is_failed_and_the_same_map_is_retried(store):
    def broken(problem, solver, should_stop=None):
        raise ZeroDivisionError("bug")

    p = pipe(store, planner=broken)
    out = handle(p, "json/MS181101ab-preliminary.json")
    assert out.decision == "failed" and "ZeroDivisionError" in out.reason
    again = handle(pipe(store), "json/MS181101ab-initial.json")  # same map, a fixed planner
    assert again.decision == "plan"


def test_plan_start_policy(store):
    import dataclasses

    rel = "json/MS181101ab-preliminary.json"
    for mode, expected in (("event", "2018-11-01T22:22:46.654Z"), ("created", "2018-11-01T22:34:49.000Z"),
                           ("received", "2018-11-01T22:40:49.000Z")):
        cfg = dataclasses.replace(FAST, policy=dataclasses.replace(FAST.policy, plan_start=mode))
        s = Store(store.path.with_name(f"{mode}.sqlite"))
        acc = pipe(s, config=cfg).accept(raw(rel), "x", created(rel) + timedelta(minutes=6))
        assert acc.job.start == expected, mode
        s.close()


def test_manual_rerun_of_a_superevent(store):
    sink = MemorySink()
    p = pipe(store, sink)
    first = handle(p, "live/MS230425k-preliminary.json")
    acc = p.rerun_superevent("MS230425k", "trigger:x", created("live/MS230425k-preliminary.json")
                             + timedelta(hours=1))
    assert acc.action == "rerun" and acc.job is not None
    out = p.run_job(acc.job)
    assert out.decision == "rerun" and out.supersedes == first.plan_id and out.plan_id != first.plan_id
    unknown = p.rerun_superevent("S999999zz", "trigger:y")
    assert unknown.action == "rejected" and "no stored notice" in unknown.reason


def test_bare_sky_map_trigger(store, data_dir):
    sink = MemorySink()
    p = pipe(store, sink)
    fits = (data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits").read_bytes()
    acc = p.accept_skymap(fits, "trigger:map")
    assert acc.action == "plan"
    out = p.run_job(acc.job)
    assert out.decision == "plan" and sink.messages[0]["event"]["superevent_id"] is None
    assert p.accept_skymap(fits, "trigger:map").action == "duplicate"
    assert p.accept_skymap(b"GIF89a....", "trigger:gif").action == "rejected"
