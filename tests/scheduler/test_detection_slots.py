"""The detection objective on the slot model (scheduler_core.schedulers.detection_slots), with real HiGHS."""

from __future__ import annotations

import numpy as np
import pytest

from mushrooms.scheduler_core.sky.cells import Cells
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.schedulers.detection_slots import (
    build_detection_model,
    detection_stage,
    detection_start_vector,
    pair_levels,
)
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.sky.skymap import read_skymap
from mushrooms.scheduler_core.schedulers.slots import SlotGrid, SlotInstance, build_slot_model
from mushrooms.scheduler_core.schedulers.solvers import solve_milp


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


def test_detection_stage_never_returns_fewer_expected_detections_than_its_coverage_plan(data_dir) -> None:
    cfg = PlanningConfig(nside=64, time_limit_s=5.0, detection_time_limit_s=10.0)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(problem, "greedy")
    det = detection_stage(problem, sm, cov)
    d = det.details
    assert d["expected_detections"] >= d["expected_detections_coverage"] > 0
    assert d["detection_choice"] in ("coverage", "detection")
    if d["detection_choice"] == "coverage":
        assert det.observations == cov.observations
    ran = [g for g in d["detection_grids"] if "expected_detections" in g]
    assert ran and max(g["expected_detections"] for g in ran) <= d["expected_detections"] + 1e-12
