"""On real maps with the real HiGHS: the kilonova clock is the notice's, and a tie in expected detections
is decided by coverage in the detection stage.  Only APIs older than the merger clock are used, so the file
runs against the code of before (where these tests fail)."""

from __future__ import annotations

import dataclasses

import pytest
from astropy.time import TimeDelta

from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.plan.document import EventInfo
from mushrooms.scheduler_core.planner import make_plan, run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers.detection.stage import detection_stage
from mushrooms.scheduler_core.sky.skymap import read_skymap

MAP = "MS220722v_bayestar.multiorder.fits"


def test_make_plan_counts_the_kilonova_from_the_notice_not_from_a_stale_header(data_dir) -> None:
    """A map whose DATE-OBS is years old: with the notice's merger time the plan expects detections again."""
    cfg = PlanningConfig(nside=64, solver="greedy", time_step_s=600.0)
    sm = read_skymap(data_dir / "skymaps" / MAP, nside=64)
    fresh = make_plan(sm, cfg)  # the map's own (true) clock
    stale = dataclasses.replace(sm, event_time=sm.event_time - TimeDelta(4 * 365.25 * 86400, format="sec"))
    assert make_plan(stale, cfg, start=sm.event_time).metrics.expected_detections == 0.0  # the old behaviour
    told = make_plan(stale, cfg, start=sm.event_time, event=EventInfo(event_time=sm.event_time.isot + "Z"))
    assert told.event.event_time == fresh.event.event_time
    assert told.to_document()["event"].get("merger_time_source") == "notice"
    assert fresh.metrics.expected_detections > 0.01
    assert told.metrics.expected_detections == pytest.approx(fresh.metrics.expected_detections, abs=1e-9)
    assert fresh.to_document()["event"].get("merger_time_source") == "skymap"


# ---------------------------------------------------------------- the detection stage

def test_detection_stage_on_a_source_beyond_reach_keeps_the_coverage_plan_without_solving(data_dir) -> None:
    """Expected detections ~0 on every plan (the source 100 x farther): the detection ceiling (X7) is below
    min_gain, no plan can be preferred for its detections, and the stage keeps the coverage plan it was given
    (more coverage on a tie, R3, is the coverage stage's to find: the stage does not run as a coverage solver)."""
    cfg = PlanningConfig(nside=64, time_limit_s=6.0, detection_time_limit_s=5.0, deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / MAP, nside=64)
    far = dataclasses.replace(sm, distmu=sm.distmu * 100, distsigma=sm.distsigma * 100, distnorm=None,
                              distmean=None if sm.distmean is None else sm.distmean * 100)
    problem = prepare_problem(far, cfg, far.event_time)
    whole = run_scheduler(problem, "greedy")
    fields = list(dict.fromkeys(o.field_id for o in whole.observations))
    keep = set(fields[len(fields) // 2:])  # a valid coverage plan that leaves the richest half out
    weak = dataclasses.replace(whole, observations=tuple(o for o in whole.observations if o.field_id in keep))
    det = detection_stage(problem, far, weak, time_limit_s=10.0)
    d = det.detection
    assert d.expected_detections_coverage < 1e-4 and det.expected_detections < 1e-4
    assert d.choice == "coverage (at the detection ceiling)" and d.grids == ()  # no grid solved
    assert det.observations == weak.observations
    # the same source at its own distance: the stage runs its grids
    near = detection_stage(problem, sm, weak, time_limit_s=10.0)
    assert near.detection.choice in ("coverage", "detection") and near.detection.grids
