"""Exposure as a decision: the menu grid, its span constraint (X7), and what the menu chooses.

Real HiGHS, the real test map (MS220722v BAYESTAR, distance layers), the
checker, the exports and the Kowalski / SkyPortal contract servers.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from mushrooms.scheduler_core.config import RECORDED_WHEN_CLEARED, RECORDED_WHEN_SET, PlanningConfig
from mushrooms.scheduler_core.plan.checker import check_plan
from mushrooms.scheduler_core.plan.document import make_plan_id, iso_utc
from mushrooms.scheduler_core.plan.exports import ExportConfig, to_skyportal, to_trigger_queue
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers.slots.exposure_menu import (dominated_pairs, map_start_menu, menu_instance,
                                                               menu_portfolio, menu_positions, menu_spans)
from mushrooms.scheduler_core.schedulers.slots.model import SlotGrid, SlotInstance, build_slot_model
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp
from mushrooms.scheduler_core.sky.cells import Cells
from mushrooms.scheduler_core.sky.skymap import SkyMap, read_skymap

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "daemon"))
from contract_servers import KowalskiContract, SkyPortalContract, loopback_server  # noqa: E402

MENU = (30.0, 60.0, 120.0, 300.0, 600.0)
TOKEN = "s3cr3t-token-0123456789abcdef"


def _map(data_dir: Path) -> SkyMap:
    return read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)


def scaled(sm: SkyMap, k: float) -> SkyMap:
    """The same map with every distance times k (DISTNORM / k², so each pixel's posterior is the scaled one)."""
    return dataclasses.replace(sm, distmu=sm.distmu * k, distsigma=sm.distsigma * k, distnorm=sm.distnorm / k ** 2,
                               distmean=sm.distmean * k, sha256=f"{sm.sha256}-x{k:g}")


def test_a_longer_exposure_holds_its_span_of_positions_in_both_passes() -> None:
    """(X7): field A's 60 s visit holds positions 0-1, so B (30 s at 1) and C (30 s at 0) cannot join it."""
    grid = SlotGrid(2, "start", np.array([0.0]), np.array([2]), np.array([0, 0]), np.array([0, 1]),
                    np.array([0.0, 40.0]), np.array([1800.0, 1840.0]))

    def solve(w_a: float) -> list[int]:
        cells = Cells(np.array([w_a, 0.3, 0.2]), np.array([0, 1, 2, 3]), np.array([0, 1, 2]), 3)
        inst = SlotInstance(np.array([0, 1, 2]), grid, cells, np.array([0, 1, 2]), np.array([0, 1, 0]),
                            np.zeros(3, np.int64), np.zeros(3, np.int64), np.array([60.0, 30.0, 30.0]),
                            np.array([2, 1, 1]))
        res = solve_milp(build_slot_model(inst).milp, "highs", 10.0, 0.0, 0)
        assert res.status == "optimal"
        return np.flatnonzero(res.x[:3] > 0.5).tolist()

    assert solve(0.6) == [0]       # the long visit alone (0.6) beats the two short ones (0.5)
    assert solve(0.4) == [1, 2]    # and loses to them when it is worth less


def test_the_menu_grid_spans_and_aligned_starts(data_dir) -> None:
    sm = _map(data_dir)
    cfg = PlanningConfig(nside=64, exposure_menu_s=MENU)
    # s0 = 30 + 10 s; 60 s holds 2 positions, 120 s 4, 300 s 8, 600 s 16; a menu block of n = 6 holds 6 x 300 s
    assert menu_spans(cfg).tolist() == [1, 2, 4, 8, 16]
    assert menu_positions(6, cfg) == 48
    problem = prepare_problem(sm, cfg, sm.event_time)
    rows = np.arange(min(40, problem.field_ids.size))
    from mushrooms.scheduler_core.schedulers.blocks.schedule import shortlist_footprints
    from mushrooms.scheduler_core.sky.cells import merge_cells

    grid = menu_portfolio(problem, rows)[0]
    inst = menu_instance(problem, rows, grid, merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob))
    q = grid.slot_position[inst.pair_slot]
    size = grid.block_size[grid.slot_block[inst.pair_slot]]
    assert set(np.unique(inst.pair_exposure)) <= set(MENU) and inst.n_pairs > 0
    assert np.all(q % inst.pair_span == 0) and np.all(q + inst.pair_span <= size)
    # both exposures of every pair lie in windows of the field, at the pair's own length
    w = problem.windows
    for t, win in ((grid.t1, inst.pair_window1), (grid.t2, inst.pair_window2)):
        start = t[inst.pair_slot]
        assert np.all(w.start[win] <= start + 1e-9) and np.all(start + inst.pair_exposure <= w.end[win] + 1e-9)
    # a longer exposure reaching no farther than a shorter one at the same start is not offered
    level = np.full(inst.n_pairs, 2)  # every exposure reaches the same level
    dom = dominated_pairs(inst, level)
    assert not dom[inst.pair_exposure == 30.0].any() and dom[inst.pair_exposure > 30.0].all()
    # the mapped start keeps each field's exposure and holds no position twice
    start = {int(f): float(grid.t1[inst.pair_slot[inst.pair_field == f]].min()) for f in np.unique(inst.pair_field)}
    pairs = map_start_menu(inst, start, {f: 300.0 for f in start})
    assert pairs.size and np.all(inst.pair_exposure[pairs] == 300.0)
    held = np.concatenate([np.arange(s, s + n) for s, n in zip(inst.pair_slot[pairs], inst.pair_span[pairs])])
    assert held.size == np.unique(held).size


def test_menu_off_gives_the_plans_and_plan_ids_of_before(data_dir) -> None:
    """No menu: the plan records no exposure_menu_s and its id is the pre-menu hash of the same configuration."""
    sm = _map(data_dir)
    cfg = PlanningConfig(nside=64, solver="greedy", objective="detection")
    problem = prepare_problem(sm, cfg, sm.event_time)
    plan = build_plan(problem, run_scheduler(problem, "greedy"), sm, "greedy")
    before = dataclasses.asdict(cfg)
    for key in RECORDED_WHEN_SET:  # recorded only when set
        if not before[key]:
            del before[key]
    for key in RECORDED_WHEN_CLEARED:  # recorded only when cleared
        if before[key]:
            del before[key]
    if tuple(before["telescopes"]) == ("ztf",):  # recorded only when not ZTF alone (issue 53)
        del before["telescopes"]
    assert "exposure_menu_s" not in plan.config
    assert plan.plan_id == make_plan_id(sm.sha256, iso_utc(problem.start), before, "greedy", plan.event.superevent_id)
    assert {o.exposure_s for o in plan.observations} == {cfg.exposure_s}
    # a menu is part of the configuration: another plan id
    menu = prepare_problem(sm, dataclasses.replace(cfg, exposure_menu_s=MENU), sm.event_time)
    assert build_plan(menu, run_scheduler(menu, "greedy"), sm, "greedy").plan_id != plan.plan_id


def test_the_menu_needs_the_detection_objective_and_a_sorted_menu() -> None:
    with pytest.raises(ValueError, match="exposure_menu_s needs objective"):
        PlanningConfig(objective="coverage", exposure_menu_s=MENU)
    with pytest.raises(ValueError, match="increasing without repeats"):
        PlanningConfig(exposure_menu_s=(300.0, 30.0))
    with pytest.raises(ValueError, match=r"\[1, 3600\]"):
        PlanningConfig(exposure_menu_s=(0.5, 30.0))


@pytest.fixture
def server():
    s = loopback_server()
    yield s
    s.clear()
    s.stop()


def menu_grid_plan(sm: SkyMap, time_limit_s: float = 60.0):
    """The first menu grid of the detection stage solved on its own (no fixed grid to compete), timed for real."""
    from mushrooms.scheduler_core.schedulers.blocks.schedule import shortlist_footprints
    from mushrooms.scheduler_core.schedulers.detection.model import (build_detection_model, distance_levels,
                                                                     level_weights, pair_levels, pair_reach)
    from mushrooms.scheduler_core.schedulers.slots.schedule import slot_rows, time_slot_plan
    from mushrooms.scheduler_core.sky.cells import merge_cells
    from mushrooms.scheduler_core.source.kilonova import load_kilonova
    from mushrooms.scheduler_core.problem import ScheduleResult

    cfg = PlanningConfig(nside=64, exposure_menu_s=MENU, deterministic=True)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(problem, "greedy")
    rows = slot_rows(problem, np.unique([o.field_id for o in cov.observations]))
    fp = shortlist_footprints(problem.footprints, rows)
    cells = merge_cells(fp, problem.prob)
    inst = menu_instance(problem, rows, menu_portfolio(problem, rows)[0], cells)
    reach = pair_reach(problem, inst, load_kilonova(cfg.detection_lightcurve), sm.event_time)
    levels = distance_levels(sm, np.unique(fp.indices), float(reach.max()), cfg.detection_levels)
    plev = pair_levels(reach, levels)
    keep = ~dominated_pairs(inst, plev)
    inst, plev = inst.subset(keep), plev[keep]
    dm = build_detection_model(inst, level_weights(sm, fp, cells, levels), plev, 0.0, cfg.detection_coverage_weight)
    res = solve_milp(dm.model.milp, "highs", time_limit_s, cfg.mip_gap, 0, clock=problem.clock)  # work, not wall s
    assert res.has_solution
    obs, _, _ = time_slot_plan(problem, dm.model, res.x)
    return problem, ScheduleResult(tuple(obs), "detection", res.status)


def test_a_mixed_exposure_plan_is_valid_and_its_exports_are_accepted(data_dir, server) -> None:
    sm = _map(data_dir)
    problem, det = menu_grid_plan(sm)
    exposures = {o.field_id: o.exposure_s for o in det.observations}
    assert len(set(exposures.values())) >= 2, exposures
    # both visits of a field have the same exposure
    assert all(o.exposure_s == exposures[o.field_id] for o in det.observations)
    plan = build_plan(problem, det, sm, "greedy")
    report = check_plan(plan, sm, problem.config)
    assert report.ok, report.problems
    # the queue: one target per exposure, each with its own exposure time, accepted by Kowalski's contract
    queue = to_trigger_queue(plan, ExportConfig())
    assert [t["exposure_time"] for t in queue["targets"]] == [o.exposure_s for o in plan.observations]
    from mushrooms.daemon.submission.remote import make_client

    kowalski = KowalskiContract(server, TOKEN)
    answer = make_client("kowalski", kowalski.url, TOKEN, 5.0).put(queue)
    assert answer.ok, answer.message
    # SkyPortal: per planned observation, and the payload's one number is the exposure of most fields
    sp = to_skyportal(plan, ExportConfig(skyportal_allocation_id=7))
    planned = sp["observation_plans"][0]["planned_observations"]
    assert [p["exposure_time"] for p in planned] == [int(round(o.exposure_s)) for o in plan.observations]
    values, counts = np.unique(list(exposures.values()), return_counts=True)
    assert sp["payload"]["exposure_time"] == int(values[counts == counts.max()].max())
    skyportal = SkyPortalContract(server, TOKEN)
    answer = make_client("skyportal", skyportal.url, TOKEN, 5.0).post(sp)
    assert answer.ok, answer.message


def _probability_weighted_exposure(problem, observations) -> float:
    per = {o.field_id: o.exposure_s for o in observations}
    w = {f: problem.footprints.coverage({f}, problem.prob) for f in per}
    return sum(w[f] * e for f, e in per.items()) / sum(w.values())


def test_the_menu_gives_a_more_distant_map_longer_exposures(data_dir) -> None:
    """The same map at 0.35x and 2.5x its distances (44 and 315 Mpc): the far one's probable fields go deeper.

    On the menu grid alone (solved to the MIP gap, not against the fixed
    grid within a few seconds, on the work budget), so the choice is the
    model's, not the clock's; the full stage on the shared maps is in
    ``benchmarks/quality/exposure_menu.py``.
    """
    sm = _map(data_dir)
    near_problem, near = menu_grid_plan(scaled(sm, 0.35))
    far_problem, far = menu_grid_plan(scaled(sm, 2.5))
    e_near = _probability_weighted_exposure(near_problem, near.observations)
    e_far = _probability_weighted_exposure(far_problem, far.observations)
    assert e_far > e_near + 60.0, (e_near, e_far)


def test_make_plan_with_a_menu_plans_checks_and_bounds_the_coverage_for_the_shortest_exposure(data_dir) -> None:
    """The whole planner with a menu: the coverage stage plans exposure_s, the bound is the shortest exposure's."""
    from mushrooms.scheduler_core.planner import make_plan

    sm = _map(data_dir)
    cfg = PlanningConfig(nside=64, time_limit_s=6.0, detection_time_limit_s=3.0, exposure_menu_s=MENU,
                         deterministic=True)
    plan = make_plan(sm, cfg, solver="slots")
    assert plan.config["exposure_menu_s"] == list(MENU)
    assert {o.exposure_s for o in plan.observations} <= set(MENU)
    fixed = make_plan(sm, dataclasses.replace(cfg, exposure_menu_s=()), solver="slots")
    # a plan of 30 s exposures could cover more than one of 300 s: the menu's certified bound is not the fixed one's
    assert plan.metrics.upper_bound >= fixed.metrics.upper_bound
    assert plan.metrics.upper_bound >= plan.metrics.coverage - 1e-9


def _greedy_case(sm: SkyMap):
    """A menu grid of the real map, its levels and weights, the seed (every field at 300 s) and the greedy start."""
    from mushrooms.scheduler_core.schedulers.blocks.schedule import shortlist_footprints
    from mushrooms.scheduler_core.schedulers.detection.model import (distance_levels, level_weights, pair_levels,
                                                                     pair_reach)
    from mushrooms.scheduler_core.schedulers.slots.exposure_menu import _menu_value, menu_start_pairs
    from mushrooms.scheduler_core.sky.cells import merge_cells
    from mushrooms.scheduler_core.source.kilonova import load_kilonova

    cfg = PlanningConfig(nside=64, exposure_menu_s=MENU, objective="detection")
    problem = prepare_problem(sm, cfg, sm.event_time)
    rows = np.argsort(-np.array([problem.footprints.coverage({int(f)}, problem.prob)
                                 for f in problem.field_ids]))[:40]
    fp = shortlist_footprints(problem.footprints, rows)
    cells = merge_cells(fp, problem.prob)
    grid = menu_portfolio(problem, rows)[0]
    inst = menu_instance(problem, rows, grid, cells)
    reach = pair_reach(problem, inst, load_kilonova(cfg.detection_lightcurve), sm.event_time)
    levels = distance_levels(sm, np.unique(fp.indices), float(reach.max()), cfg.detection_levels)
    W = level_weights(sm, fp, cells, levels)
    lev = pair_levels(reach, levels)
    start = {int(f): float(grid.t1[inst.pair_slot[inst.pair_field == f]].min()) for f in np.unique(inst.pair_field)}
    seed = map_start_menu(inst, start, {f: 300.0 for f in start})
    args = (inst, lev, W, cfg.detection_coverage_weight, cfg.penalty)
    pairs = menu_start_pairs(*args, seed, None)
    return inst, pairs, _menu_value(*args, seed), _menu_value(*args, pairs)


def test_the_greedy_menu_start_is_feasible_never_worse_than_its_seed_and_shorter_when_near(data_dir) -> None:
    """(X9) on a real map: one pair per field, no position held twice, (X5) >= the 300 s seed's; near -> shorter."""
    sm = _map(data_dir)
    exposure = {}
    for k in (0.35, 2.5):
        inst, pairs, v_seed, v = _greedy_case(scaled(sm, k))
        assert pairs.size and v >= v_seed - 1e-12
        assert np.unique(inst.pair_field[pairs]).size == pairs.size
        held = np.concatenate([np.arange(s, s + n) for s, n in zip(inst.pair_slot[pairs], inst.pair_span[pairs])])
        assert held.size == np.unique(held).size
        exposure[k] = float(np.mean(inst.pair_exposure[pairs]))
    assert exposure[0.35] < exposure[2.5], exposure
