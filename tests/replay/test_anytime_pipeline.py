"""Anytime plans through the daemon's pipeline: revision 1 at once, revision 2 only when better.

Real notices, real sky maps, the real greedy scheduler and plan checker,
real SQLite.  The "optimiser" is a test planner built from real schedules:
revision 1 is the greedy plan without the first half of the fields it chose
(a valid plan that covers less), the optimiser returns the whole greedy plan, so the gain
of revision 2 over revision 1 is known before the margin is chosen.  Stages
that must overlap with a newer notice block on events the test releases:
no sleeps, no timing.
"""

from __future__ import annotations

import dataclasses
import json
import threading
from datetime import timedelta

import pytest

from mushrooms.daemon.planning.jobs import Staged
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.scheduler_core.plan.schema import validate_document
from mushrooms.scheduler_core.planner import run_scheduler

from replay_helpers import FAST, created, mutated, raw

PRELIM = "live/MS230425k-preliminary.json"
RETRACT = "live/MS230425k-retraction.json"


def hybrid(min_gain: float):
    """The hybrid with the coverage objective: revision 2 is judged by coverage."""
    return dataclasses.replace(FAST, scheduler=dataclasses.replace(FAST.scheduler, solver="hybrid", objective="coverage"),
                               daemon=dataclasses.replace(FAST.daemon, supersede_min_gain=min_gain))


class HalfThenWhole:
    """Greedy cut to half of its fields for the fast plan; the whole greedy plan as the 'optimiser'."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.hold: threading.Event | None = None  # when set: the optimiser waits for it or for a stop
        self.entered = threading.Event()

    def __call__(self, problem, solver, should_stop=None):
        self.calls.append(solver)
        whole = run_scheduler(problem, "greedy", None)
        if solver == "greedy":
            fields = list(dict.fromkeys(o.field_id for o in whole.observations))  # in the order greedy chose them
            keep = set(fields[len(fields) // 2:])  # drop the first (richest) half
            return dataclasses.replace(whole, observations=tuple(o for o in whole.observations if o.field_id in keep))
        self.entered.set()
        if self.hold is not None:
            while not self.hold.wait(0.01):
                if should_stop is not None and should_stop():
                    return dataclasses.replace(whole, observations=(), status="interrupted")
        return dataclasses.replace(whole, solver="test-optimiser")


def accept(p, rel, data=None, minutes=0.5):
    return p.accept(data if data is not None else raw(rel), f"test:{rel}", created(rel) + timedelta(minutes=minutes))


def accept_newer_map(p):
    """MS230425k's INITIAL notice carrying another BAYESTAR map (MS181101ab's): a rerun."""
    other = json.loads(raw("json/MS181101ab-preliminary.json"))["event"]["skymap"]
    rel = "live/MS230425k-initial.json"
    return accept(p, rel, mutated(rel, skymap=other))


def observations(doc):
    return [(o["field_id"], o["filter"], o["start"]) for o in doc["observations"]]


@pytest.fixture(scope="module")
def gain(tmp_path_factory):
    """Coverage of the whole greedy plan minus that of its half (the same inputs as the tests)."""
    s = Store(tmp_path_factory.mktemp("gain") / "state.sqlite")
    sink = MemorySink()
    out = NoticePipeline.from_config(hybrid(0.0), s, sink, planner=HalfThenWhole()).run_job(accept(
        NoticePipeline.from_config(hybrid(0.0), s, sink), PRELIM).job)
    first, second = [m for m in sink.messages if m["type"] == "plan"]
    s.close()
    assert out.revision == 2
    g = second["metrics"]["coverage"] - first["metrics"]["coverage"]
    # the map is mostly unobservable in this horizon, so coverages are small; the gain is still
    # two orders of magnitude above the 1e-6 rounding of reported coverages
    assert g > 1e-4, "the half plan must cover clearly less for the margin tests to mean anything"
    return g


@pytest.mark.parametrize("above", [False, True])
def test_revision_2_supersedes_only_when_better_by_the_margin(store, gain, above):
    sink = MemorySink()
    margin = gain * (0.5 if above else 1.5)  # the gain is above / below the margin
    p = NoticePipeline.from_config(hybrid(margin), store, sink, planner=HalfThenWhole())
    out = p.run_job(accept(p, PRELIM).job)
    plans = [m for m in sink.messages if m["type"] == "plan"]
    assert plans[0]["revision"] == 1 and plans[0]["final"] is False and plans[0]["metrics"]["solver"] == "greedy"
    if above:
        assert [m["type"] for m in sink.messages] == ["plan", "plan"]
        assert plans[1]["revision"] == 2 and plans[1]["final"] is True
        assert plans[1]["supersedes"] == plans[0]["plan_id"] and out.plan_id == plans[1]["plan_id"]
        assert plans[1]["metrics"]["coverage"] == pytest.approx(plans[0]["metrics"]["coverage"] + gain, abs=1e-6)
        assert len(plans[1]["observations"]) > len(plans[0]["observations"])
        assert store.job_status(out.job_id) == "done" and out.revision == 2 and out.final
    else:
        assert [m["type"] for m in sink.messages] == ["plan", "plan_final"]
        final = sink.messages[1]
        assert final["plan_id"] == plans[0]["plan_id"] and final["final"] is True and "supersede_min_gain" in final["reason"]
        assert out.plan_id == plans[0]["plan_id"] and out.revision == 1 and out.final
        assert [r["final"] for r in store.job_plans(out.job_id)] == [1]


def test_greedy_solver_publishes_one_final_revision(store):
    sink = MemorySink()
    p = NoticePipeline.from_config(FAST, store, sink)
    out = p.run_job(accept(p, PRELIM).job)
    assert [(m["type"], m["revision"], m["final"]) for m in sink.messages] == [("plan", 1, True)]
    assert out.final and out.revision == 1


def test_retraction_after_revision_2_withdraws_both_revisions(store, gain):
    sink = MemorySink()
    p = NoticePipeline.from_config(hybrid(0.0), store, sink, planner=HalfThenWhole())
    out = p.run_job(accept(p, PRELIM).job)
    assert out.revision == 2
    rev_ids = [m["plan_id"] for m in sink.messages if m["type"] == "plan"]
    gone = accept(p, RETRACT)
    assert gone.action == "withdraw" and list(gone.plan_ids) == rev_ids
    p.flush_outbox()
    (withdrawal,) = [m for m in sink.messages if m["type"] == "withdrawal"]
    assert withdrawal["plan_ids"] == rev_ids
    assert all(r["withdrawn"] for r in store.plans("MS181101ab"))


def test_cancellation_during_preparation_stores_nothing_and_frees_the_worker(store):
    """A newer sky map arrives while the job prepares its problem: the job ends before the scheduler."""
    sink = MemorySink()
    stop = threading.Event()
    in_prep, go_on = threading.Event(), threading.Event()
    planner = HalfThenWhole()

    class SlowCache:  # the real preparation, held inside until the test lets it go
        def prepare(self, skymap, config, start):
            from mushrooms.scheduler_core.prepare import prepare_problem

            in_prep.set()
            assert go_on.wait(30)
            return prepare_problem(skymap, config, start)

    p = NoticePipeline.from_config(FAST, store, sink, planner=planner, sky_cache=SlowCache())
    old = accept(p, PRELIM)
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault("out", p.run_job(old.job, stop.is_set)))
    worker.start()
    try:
        assert in_prep.wait(30)
        newer = accept_newer_map(p)
        assert newer.action == "rerun" and newer.cancelled_jobs == (old.job.job_id,)
        stop.set()  # what the JobRunner does for a superseded job
    finally:
        go_on.set()
        worker.join(30)
    assert not worker.is_alive()
    out = result["out"]
    assert out.decision == "ignore" and "stopped before the fast scheduler" in out.reason and "superseded" in out.reason
    assert planner.calls == [] and sink.messages == [] and store.pending_outbox() == []
    assert store.job_status(old.job.job_id) == "superseded"
    p2 = NoticePipeline.from_config(FAST, store, sink)  # the freed worker takes the newer map at once
    assert p2.run_job(newer.job).decision == "rerun"
    assert [m["event"]["skymap_sha256"] for m in sink.messages] == [newer.job.skymap_sha256]


def test_newer_map_during_the_optimisation_cancels_it_and_its_first_plan_supersedes(store):
    sink = MemorySink()
    planner = HalfThenWhole()
    planner.hold = threading.Event()  # the optimiser runs until it is stopped
    stop = threading.Event()
    p = NoticePipeline.from_config(hybrid(0.0), store, sink, planner=planner)
    old = accept(p, PRELIM)
    staged = p.run_job(old.job, stop.is_set, staged=True)
    assert isinstance(staged, Staged) and staged.outcome.revision == 1 and not staged.outcome.final
    rev1 = staged.outcome.plan_id
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault("out", staged.run(stop.is_set)))
    worker.start()
    try:
        assert planner.entered.wait(30)
        newer = accept_newer_map(p)
    finally:
        stop.set()
        worker.join(30)
    assert not worker.is_alive()
    assert result["out"].decision == "ignore" and "superseded" in result["out"].reason
    assert [m["plan_id"] for m in sink.messages] == [rev1]  # no revision 2, no plan_final of the old map
    new_first = NoticePipeline.from_config(hybrid(0.0), store, sink, planner=HalfThenWhole()).run_job(newer.job, staged=True)
    assert new_first.outcome.supersedes == rev1
    doc = sink.messages[-1]
    assert doc["revision"] == 1 and doc["supersedes"] == rev1 and doc["event"]["skymap_sha256"] == newer.job.skymap_sha256


def test_restart_after_revision_1_republishes_nothing_and_finishes_with_the_same_plans(store, tmp_path):
    """A crash between the revisions: the rerun job finds revision 1 stored and goes on to revision 2."""
    sink = MemorySink()
    p = NoticePipeline.from_config(hybrid(0.0), store, sink, planner=HalfThenWhole())
    acc = accept(p, PRELIM)
    staged = p.run_job(acc.job, staged=True)  # revision 1 stored; then the process "dies"
    assert isinstance(staged, Staged)
    rev1 = sink.messages[0]
    (job,) = store.pending_jobs()
    assert job.status == "running"
    again = Store(tmp_path / "state.sqlite")  # the restarted process
    sink2 = MemorySink()
    out = NoticePipeline.from_config(hybrid(0.0), again, sink2, planner=HalfThenWhole()).run_job(job)
    assert out.revision == 2 and out.supersedes == rev1["plan_id"]
    rows = again.pending_outbox()
    assert rows == []
    kinds = [(m["type"], m["plan_id"]) for m in sink2.messages]
    assert kinds == [("plan", out.plan_id)]  # revision 1 was already published, not queued again
    revs = again.job_plans(job.job_id)
    assert [r["plan_id"] for r in revs] == [rev1["plan_id"], out.plan_id]
    assert observations(revs[0]["document"]) == observations(rev1)  # the same plan, not only the same id
    again.close()


# ---------------------------------------------------------------- objective = detection

#: detection_max_coverage_loss of the runs whose revision 2 must expect more detections than revision 1.
LOOSE_FLOOR = 0.1


def detecting(min_gain: float, loss: float = 0.02):
    """The hybrid config with the detection objective (a small budget: the maps are small at nside 64)."""
    cfg = hybrid(min_gain)
    return dataclasses.replace(cfg, scheduler=dataclasses.replace(
        cfg.scheduler, objective="detection", time_limit_s=8.0, detection_time_limit_s=6.0,
        detection_max_coverage_loss=loss, deterministic=True))


@pytest.fixture(scope="module")
def detection_run(tmp_path_factory):
    """Revision 1 (half the greedy plan) and revision 2 (the detection stage started from the whole greedy plan).

    A 10 % coverage floor: the stage's best plan on this small map executes 0.000544 of the probability where
    the whole greedy plan executes 0.000577, below a 2 % floor as executed (X10)."""
    s = Store(tmp_path_factory.mktemp("detection") / "state.sqlite")
    sink = MemorySink()
    planner = HalfThenWhole()
    p = NoticePipeline.from_config(detecting(0.0, LOOSE_FLOOR), s, sink, planner=planner)
    out = p.run_job(accept(p, PRELIM).job)
    s.close()
    assert planner.calls == ["greedy", "hybrid"] and out.revision == 2, [m.get("reason") for m in sink.messages]
    first, second = [m for m in sink.messages if m["type"] == "plan"]
    assert second["metrics"]["solver"] in ("test-optimiser", "detection(test-optimiser)")
    return first, second


@pytest.mark.parametrize("above", [False, True])
def test_detection_objective_supersedes_by_expected_detections_within_the_floor(store, detection_run, above):
    """objective = detection: revision 2 must expect supersede_min_gain more detections, within the floor."""
    first, second = detection_run
    m1, m2 = first["metrics"], second["metrics"]
    d_gain = m2["expected_detections"] - m1["expected_detections"]
    assert d_gain > 1e-4, "revision 2 must expect clearly more detections for the margin tests to mean anything"
    c_gain = m2["coverage"] - m1["coverage"]
    assert m2["coverage"] >= (1 - LOOSE_FLOOR) * m1["coverage"]
    assert second["supersedes"] == first["plan_id"]
    margin = d_gain * (0.5 if above else 1.5)
    sink = MemorySink()
    p = NoticePipeline.from_config(detecting(margin, LOOSE_FLOOR), store, sink, planner=HalfThenWhole())
    out = p.run_job(accept(p, PRELIM).job)
    kinds = [m["type"] for m in sink.messages]
    if above:
        assert kinds == ["plan", "plan"] and out.revision == 2
        assert sink.messages[1]["metrics"]["expected_detections"] >= m1["expected_detections"] + margin - 1e-6
    else:  # below the margin in detections: a tie, decided by the coverage rule
        m2_now = sink.messages[1].get("metrics") or {}
        if kinds == ["plan", "plan"]:
            assert m2_now["coverage"] >= m1["coverage"] + margin - 1e-6
            assert abs(m2_now["expected_detections"] - m1["expected_detections"]) < margin + 1e-6
        else:
            assert kinds == ["plan", "plan_final"] and out.revision == 1, (d_gain, c_gain)
            assert c_gain < margin + 1e-6
            assert "detections" in sink.messages[1]["reason"] and "coverage floor" in sink.messages[1]["reason"]


def test_a_plan_with_more_detections_and_a_little_less_coverage_is_better_only_for_the_detection_objective(
        detection_run):
    """The supersede rule (is_better) on the pipeline's real plans, one side's coverage moved across the floor."""
    from mushrooms.scheduler_core.anytime import is_better
    from mushrooms.scheduler_core.plan.document import Plan

    first, second = (Plan.from_document(d) for d in detection_run)
    d_gain = second.metrics.expected_detections - first.metrics.expected_detections

    def covering(plan, coverage):
        return plan.with_(metrics=dataclasses.replace(plan.metrics, coverage=coverage))

    c1 = first.metrics.coverage
    a_little_less = covering(second, c1 * (1 - 0.01))  # within a 2 % floor
    too_little = covering(second, c1 * (1 - 0.03))
    assert is_better(a_little_less, first, d_gain / 2, "detection", 0.02)
    assert not is_better(a_little_less, first, d_gain / 2, "coverage", 0.02)
    assert not is_better(too_little, first, d_gain / 2, "detection", 0.02)
    assert not is_better(a_little_less, first, d_gain * 2, "detection", 0.02)
    # fewer detections never replace, however much more the plan covers
    assert not is_better(covering(first, c1 + 0.1), second, 0.0, "detection", 0.02)
    assert is_better(covering(first, c1 + 0.1), second, 0.0, "coverage", 0.02)
    # the same detections and more coverage: the coverage rule decides, by its margin
    assert is_better(covering(second, second.metrics.coverage + 0.01), second, 0.005, "detection", 0.02)
    assert not is_better(covering(second, second.metrics.coverage + 0.004), second, 0.005, "detection", 0.02)
    assert is_better(covering(second, second.metrics.coverage + 0.01), second, 0.005, "coverage", 0.02)


# ---------------------------------------------------------------- one clock, ties to coverage

def with_map(data: bytes, edit) -> bytes:
    """The notice with its embedded sky map rewritten by ``edit(hdul)`` (a FITS edit of the real map)."""
    import base64
    import io

    from astropy.io import fits

    d = json.loads(data)
    with fits.open(io.BytesIO(base64.b64decode(d["event"]["skymap"]))) as hdul:
        hdul[1].data  # load the table before it is edited
        edit(hdul)
        out = io.BytesIO()
        hdul.writeto(out)
    d["event"]["skymap"] = base64.b64encode(out.getvalue()).decode()
    return json.dumps(d).encode()


def dated(iso: str):
    """A FITS edit: the map's header says the merger was at ``iso``."""
    def edit(hdul) -> None:
        from astropy.time import Time

        hdul[1].header["DATE-OBS"] = iso
        if "MJD-OBS" in hdul[1].header:
            hdul[1].header["MJD-OBS"] = Time(iso, scale="utc").mjd
    return edit


def hundred_times_farther(hdul) -> None:
    for col in ("DISTMU", "DISTSIGMA"):
        hdul[1].data[col] *= 100.0
    for key in ("DISTMEAN", "DISTSTD"):
        if key in hdul[1].header:
            hdul[1].header[key] *= 100.0


#: MS181101ab (35 deg2 at 40 Mpc, RA 194 deg, dec -18) sent again live on a night it is observable from
#: Palomar: the notice's event.time and time_created are now, its map is the archived one (DATE-OBS 2018)
LIVE_COPY = "json/MS181101ab-preliminary.json"
LIVE_TIME = "2025-04-05T04:00:00.000Z"


def live_copy() -> bytes:
    d = json.loads(raw(LIVE_COPY))
    d["event"]["time"] = LIVE_TIME
    d["time_created"] = "2025-04-05T04:05:00Z"
    return json.dumps(d).encode()


def test_a_live_notice_with_a_stale_dated_map_counts_the_kilonova_from_the_notice(tmp_path, caplog):
    """The notice's event.time is the kilonova clock; revision 2 then supersedes by expected detections."""
    import logging

    from mushrooms.handlers.alert import parse_notice

    stale, fresh = live_copy(), with_map(live_copy(), dated(LIVE_TIME.rstrip("Z")))
    when = parse_notice(stale).time_created + timedelta(minutes=0.5)
    runs = {}
    for name, data, margin in (("fresh", fresh, 0.0), ("stale", stale, None)):
        if margin is None:  # half of what revision 2 gained on the fresh map, in expected detections
            f1, f2 = runs["fresh"]
            margin = 0.5 * (f2["metrics"]["expected_detections"] - f1["metrics"]["expected_detections"])
            assert margin > 1e-3, "revision 2 must expect clearly more detections for the test to mean anything"
            caplog.clear()
            caplog.set_level(logging.WARNING, logger="mushrooms.scheduler_core.clock")
        sink = MemorySink()
        store = Store(tmp_path / f"{name}.sqlite")
        p = NoticePipeline.from_config(detecting(margin), store, sink, planner=HalfThenWhole())
        out = p.run_job(p.accept(data, f"test:{name}", when).job)
        store.close()
        # on the stale map's own clock (its 2018 header): 0 expected detections, revision 1 final
        assert [m["type"] for m in sink.messages] == ["plan", "plan"] and out.revision == 2, \
            [m.get("reason") for m in sink.messages]
        runs[name] = [m for m in sink.messages if m["type"] == "plan"]
    for doc in runs["stale"]:
        assert doc["event"]["event_time"] == LIVE_TIME and doc["event"]["merger_time_source"] == "notice"
        validate_document(doc)
    # revision 1 (deterministic) expects the same detections as from the map dated right
    e_stale, e_fresh = (runs[k][0]["metrics"]["expected_detections"] for k in ("stale", "fresh"))
    assert e_stale == pytest.approx(e_fresh, abs=1e-9)
    # and revision 2's published score is its exposures' score against the map dated right: the notice's clock
    import base64

    from mushrooms.scheduler_core.plan.document import Plan
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.scheduler_core.source.detection import expected_detections
    from mushrooms.scheduler_core.source.kilonova import load_kilonova

    cfg = detecting(0.0).scheduler
    right = read_skymap(base64.b64decode(json.loads(fresh)["event"]["skymap"]), nside=cfg.nside)
    second = Plan.from_document(runs["stale"][1])
    e2 = expected_detections(second, right, field_footprints(load_ztf_fields(), cfg.nside),
                             load_kilonova(cfg.detection_lightcurve))
    assert second.metrics.expected_detections == pytest.approx(e2, abs=2e-6) and e2 > 0.01
    assert e2 >= e_stale + margin - 1e-6
    warned = [r.getMessage() for r in caplog.records if r.name == "mushrooms.scheduler_core.clock"]
    assert len(warned) == 1 and LIVE_TIME[:19] in warned[0] and "2018-11-01T22:22:46" in warned[0]


def test_a_distant_event_publishes_the_plan_with_more_coverage(store, gain):
    """Expected detections ~0 on both revisions (the source 100 x farther): coverage decides the supersede."""
    sink = MemorySink()
    p = NoticePipeline.from_config(detecting(gain * 0.5), store, sink, planner=HalfThenWhole())
    out = p.run_job(accept(p, PRELIM, with_map(raw(PRELIM), hundred_times_farther)).job)
    plans = [m for m in sink.messages if m["type"] == "plan"]
    assert all(doc["metrics"]["expected_detections"] < 1e-4 for doc in plans)
    # on the map's clock: "hybrid expects 0.0000 detections against 0.0000 (coverage ...)" and revision 1 stayed final
    assert [m["type"] for m in sink.messages] == ["plan", "plan"] and out.revision == 2, \
        [m.get("reason") for m in sink.messages]
    first, final = plans
    assert final["final"] is True and final["supersedes"] == first["plan_id"]
    assert final["metrics"]["coverage"] >= first["metrics"]["coverage"] + gain - 1e-6
