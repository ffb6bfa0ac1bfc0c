"""The detection objective on the slot model (scheduler_core.schedulers.detection.stage), with real HiGHS."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mushrooms.scheduler_core.sky.cells import Cells
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.schedulers.detection.model import build_detection_model, detection_start_vector, pair_levels
from mushrooms.scheduler_core.schedulers.detection.stage import detection_stage
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.source.detection import expected_detections
from mushrooms.scheduler_core.source.kilonova import load_kilonova
from mushrooms.scheduler_core.planner import build_plan, optimise, run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.sky.skymap import read_skymap
from mushrooms.scheduler_core.schedulers.detection.ceiling import detection_ceiling
from mushrooms.scheduler_core.schedulers.slots.model import SlotGrid, SlotInstance, build_slot_model
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp


def two_slot_instance() -> SlotInstance:
    """One field holding one cell, eligible in an early and a late slot; it can be observed once (S2)."""
    grid = SlotGrid(1, "start", np.array([0.0, 7200.0]), np.array([1, 1]), np.array([0, 1]), np.array([0, 0]),
                    np.array([0.0, 7200.0]), np.array([1800.0, 9000.0]))
    cells = Cells(np.array([1.0]), np.array([0, 1]), np.array([0]), 1)
    return SlotInstance(np.array([0]), grid, cells, np.array([0, 0]), np.array([0, 1]), np.array([0, 0]),
                        np.array([0, 0]))


def test_detection_objective_picks_the_later_deeper_slot_when_the_early_one_is_too_shallow() -> None:
    inst = two_slot_instance()
    # the cell's sources lie uniformly between 100 and 200 Mpc; the early slot reaches 80 Mpc, the late 220
    reach = np.array([80.0, 220.0])
    levels = np.array([80.0, 150.0, 220.0])
    plev = pair_levels(reach, levels)
    assert plev.tolist() == [1, 3]

    def cdf(r: np.ndarray) -> np.ndarray:
        return np.clip((np.asarray(r) - 100.0) / 100.0, 0.0, 1.0)

    W = np.diff(np.concatenate([[0.0], cdf(levels)]))[None, :]
    # coverage alone cannot tell the slots apart
    cov = build_slot_model(inst)
    x_early, x_late = np.zeros(cov.milp.n_vars), np.zeros(cov.milp.n_vars)
    for x, k in ((x_early, 0), (x_late, 1)):
        x[k] = 1.0
        x[cov.off_z] = 1.0
        x[cov.off_y] = 1.0
    assert cov.milp.c @ x_early == cov.milp.c @ x_late
    dm = build_detection_model(inst, W, plev, coverage_weight=0.05)
    start = detection_start_vector(dm, np.array([0]))  # warm start: the early slot
    # threads=0: HiGHS keeps one global thread pool per process, and an earlier solve in the same
    # process (any other test) has fixed its size; asking for another count makes run() fail
    res = solve_milp(dm.model.milp, "highs", 10.0, 0.0, 0, start=start)
    assert res.status == "optimal"
    assert res.x[:2].round().tolist() == [0.0, 1.0]
    assert res.objective == pytest.approx(1.0 + 0.05)  # every source in reach, plus the coverage tie-break
    assert dm.model.milp.c @ start == pytest.approx(0.05)  # the early slot detects nothing
    # the solution vector respects every row
    ax = dm.model.milp.A @ res.x
    assert np.all(ax >= dm.model.milp.row_lo - 1e-9) and np.all(ax <= dm.model.milp.row_hi + 1e-9)


def one_slot_two_fields() -> SlotInstance:
    """Two fields (one cell each: 0.7 and 0.3 of the probability) competing for a single slot."""
    grid = SlotGrid(1, "start", np.array([0.0]), np.array([1]), np.array([0]), np.array([0]),
                    np.array([0.0]), np.array([1800.0]))
    cells = Cells(np.array([0.7, 0.3]), np.array([0, 1, 2]), np.array([0, 1]), 2)
    return SlotInstance(np.array([0, 1]), grid, cells, np.array([0, 1]), np.array([0, 0]), np.array([0, 1]),
                        np.array([0, 1]))


@pytest.mark.parametrize("floor", [None, 0.7 * 0.98])
def test_the_coverage_floor_keeps_the_rich_field_the_detection_objective_alone_would_give_up(floor) -> None:
    """(X6): the rich field's sources are out of reach, the poor field's in reach; the floor decides."""
    inst = one_slot_two_fields()
    levels = np.array([80.0, 220.0])
    plev = pair_levels(np.array([80.0, 220.0]), levels)  # field 0 reaches the first level only
    # cell 0's sources lie beyond 80 Mpc (nothing in reach of field 0), cell 1's within 80-220 Mpc
    W = np.array([[0.0, 0.0], [0.0, 0.3]])
    dm = build_detection_model(inst, W, plev, coverage_weight=0.05, coverage_floor=floor)
    res = solve_milp(dm.model.milp, "highs", 10.0, 0.0, 0)
    assert res.status == "optimal"
    base = dm.base
    covered = float(inst.cells.weight @ res.x[base.off_y:base.off_y + 2])
    if floor is None:  # detections first: the poor field, 0.3 detections and 0.3 coverage
        assert res.x[:2].round().tolist() == [0.0, 1.0] and covered == pytest.approx(0.3)
    else:  # the floor 0.686 forbids giving up the rich field
        assert res.x[:2].round().tolist() == [1.0, 0.0] and covered >= floor - 1e-9
    ax = dm.model.milp.A @ res.x
    assert np.all(ax >= dm.model.milp.row_lo - 1e-9) and np.all(ax <= dm.model.milp.row_hi + 1e-9)


@pytest.mark.parametrize("loss", [0.0, 0.02])
def test_detection_stage_never_returns_fewer_expected_detections_than_its_coverage_plan(data_dir, loss) -> None:
    cfg = PlanningConfig(nside=64, time_limit_s=5.0, detection_time_limit_s=4.0, detection_max_coverage_loss=loss,
                         deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(problem, "greedy")
    det = detection_stage(problem, sm, cov, time_limit_s=10.0)
    d = det.detection
    assert det.expected_detections >= d.expected_detections_coverage > 0
    assert d.choice in ("coverage", "detection")
    if d.choice == "coverage":
        assert det.observations == cov.observations
    ran = [g for g in d.grids if "expected_detections" in g]
    # no grid's plan above the floor expects more, beyond the choice rule's margin (R2-R3: closer than min_gain
    # is a tie on detections, settled by coverage)
    assert ran and max(g["expected_detections"] for g in ran if g["above_floor"]) <= det.expected_detections + cfg.min_gain
    # the floor (X6) holds for the plan as published: after the real timing and the least-gain rule
    c0 = published_coverage(problem, cov)
    assert d.coverage_floor == pytest.approx((1 - loss) * c0)
    assert published_coverage(problem, det) >= (1 - loss) * c0 - 1e-9
    # the plan reuses the stage's score of its exposures: the same as scoring the plan afresh
    plan = build_plan(problem, det, sm, "greedy")
    fresh = expected_detections(plan, sm, problem.footprints, load_kilonova(cfg.detection_lightcurve))
    assert plan.metrics.expected_detections == pytest.approx(fresh, abs=2e-6)


def test_a_detection_plan_never_covers_less_than_greedy_however_much_coverage_it_may_give_up(data_dir) -> None:
    """(X6) C_f = max((1 - ε) C₀, C_g): with ε = 0.5 the floor is greedy's coverage, found in the portfolio."""
    cfg = PlanningConfig(nside=64, objective="detection", time_limit_s=6.0, detection_time_limit_s=2.5,
                         detection_max_coverage_loss=0.5, deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    det = optimise(problem, sm, "hybrid")
    c_greedy = {e.name: e.coverage for e in det.portfolio}["greedy"]
    c0 = max(e.coverage for e in det.portfolio)
    assert 0 < 0.5 * c0 < c_greedy <= c0
    assert det.detection.coverage_floor == pytest.approx(c_greedy)
    assert published_coverage(problem, det) >= c_greedy - 1e-9
    # every grid plan the stage could have chosen respects it
    ran = [g for g in det.detection.grids if "coverage" in g]
    assert all(g["above_floor"] == (g["coverage"] >= c_greedy - 1e-9) for g in ran)
    # without a greedy plan to compare with, the floor is (1 - ε) C₀
    alone = detection_stage(problem, sm, run_scheduler(problem, "greedy"), time_limit_s=1.0)
    assert alone.detection.coverage_floor == pytest.approx(0.5 * published_coverage(problem, run_scheduler(problem, "greedy")))


def test_the_detection_objective_shares_one_budget_between_its_two_stages(data_dir) -> None:
    """objective = detection: the scheduler gets time_limit_s minus the detection share, the stage the rest."""
    cfg = PlanningConfig(nside=64, objective="detection", time_limit_s=6.0, detection_time_limit_s=2.5,
                         deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    given = []

    def scheduler(p, solver, should_stop=None):
        given.append(p.config.time_limit_s)
        return run_scheduler(p, solver, should_stop)

    det = optimise(problem, sm, "slots", scheduler=scheduler)
    assert given == [pytest.approx(3.5)]
    assert 0 < det.detection.budget_s <= 2.5
    assert det.detection.choice in ("coverage", "detection")
    # the coverage objective leaves the scheduler the whole budget and runs no detection stage
    cov_problem = prepare_problem(sm, dataclasses.replace(cfg, objective="coverage"), sm.event_time)
    given.clear()
    assert optimise(cov_problem, sm, "greedy", scheduler=scheduler).detection is None
    assert given == [6.0]


def test_no_plan_has_more_expected_detections_than_the_ceiling_and_a_far_source_skips_the_stage(data_dir) -> None:
    cfg = PlanningConfig(nside=64, time_limit_s=5.0, detection_time_limit_s=4.0, deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    kilonova = load_kilonova(cfg.detection_lightcurve)
    ceiling = detection_ceiling(problem, sm, kilonova)
    cov = run_scheduler(problem, "greedy")
    det = detection_stage(problem, sm, cov, time_limit_s=4.0)
    # (X7) above what the coverage plan and the detection stage's best plan reach, below all the probability
    assert det.expected_detections <= ceiling <= 1.0
    assert det.detection.choice in ("coverage", "detection") and ceiling > det.expected_detections + cfg.min_gain
    # the same map a hundred times farther: no plan can detect it, the stage keeps the coverage plan at once
    far = dataclasses.replace(sm, distmu=sm.distmu * 100.0, distsigma=sm.distsigma * 100.0)
    assert detection_ceiling(problem, far, kilonova) < cfg.min_gain
    kept = detection_stage(problem, far, cov, time_limit_s=4.0)
    assert kept.detection.choice == "coverage (at the detection ceiling)" and kept.detection.grids == ()
    assert kept.observations == cov.observations and kept.expected_detections < cfg.min_gain


def test_the_stage_solves_at_most_max_grids_grids_and_says_which_it_did_not_try(data_dir, monkeypatch) -> None:
    from mushrooms.scheduler_core.schedulers.detection import stage as detection_slots

    cfg = PlanningConfig(nside=64, time_limit_s=5.0, detection_time_limit_s=4.0, deterministic=True)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(problem, "greedy")
    monkeypatch.setattr(detection_slots, "MAX_GRIDS", None)
    every = detection_stage(problem, sm, cov, time_limit_s=30.0).detection.grids
    assert len(every) > 2  # the portfolio has more grids than the cap below
    monkeypatch.setattr(detection_slots, "MAX_GRIDS", 2)
    capped = detection_stage(problem, sm, cov, time_limit_s=30.0).detection.grids
    assert [g["grid"] for g in capped[:2]] == [g["grid"] for g in every[:2]]  # the coverage plan's own grid first
    assert capped[2] == {"grid": every[2]["grid"], "status": "not tried"} and len(capped) == 3
