"""The slot MILP on a sequence of k visits (G1-G3): a hand-solved g-r-g instance, the pair unchanged, a real map.

Hand instance.  Exposure 100 s, slew estimate 10 s (s = 110 s), filter change 30 s, cadence 250 s, no
margin, g-r-g: a block of n = 2 positions has D = max(2 s + 30, 250) = 250 s and (G2, ends in g, no
change back) L = 2 * 250 + 220 = 720 s; its slots are (t1, t2, t3) = (0, 250, 500) and (110, 360, 610).
Horizon 1000 s: one block.  Windows: field 2 closes at 470 s (its third visit cannot fit), field 1 at
760 s (either slot's third visit ends before, with room for the real slews), the others never.  Eligible: fields 1, 3, 4, 5; two
slots; the best two are {1, 5} = .32 + .22 (over 3 = .15 and 4 = .05).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest_milp import slot_hand_problem
from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, prepare_problem
from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.plan.exports import FILTER_IDS, to_trigger_queues
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.schedulers.blocks.schedule import milp_schedule
from mushrooms.scheduler_core.schedulers.slots.schedule import slot_schedule
from mushrooms.scheduler_core.schedulers.slots.model import (block_length_s, make_slot_grid, observable_segments,
                                                       slot_instance)
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.sky.windows import Windows
from mushrooms.scheduler_core.schedulers.as_executed import execute_plan_queues, queue_coverage

def grg_hand_problem(**overrides) -> PlanningProblem:
    return slot_hand_problem((760.0, 470.0, 1000.0, 1000.0, 1000.0), **{"filters": ("g", "r", "g"), **overrides})


def test_a_grg_block_is_three_passes_a_cadence_apart_and_needs_no_filter_change_back():
    problem = grg_hand_problem()
    grid = make_slot_grid(observable_segments(problem), problem.config, 2, "start")
    assert block_length_s(2, problem.config) == pytest.approx(720.0)
    assert grid.block_start.tolist() == [0.0]
    assert grid.pass_starts.tolist() == [[0.0, 110.0], [250.0, 360.0], [500.0, 610.0]]
    # r-g-r ends in another filter than it starts: the change back is paid, as for the pair
    rgr = dataclasses.replace(problem.config, filters=("r", "g", "r"))
    assert block_length_s(2, rgr) == pytest.approx(720.0)
    grgr = dataclasses.replace(problem.config, filters=("g", "r", "g", "r"))
    assert block_length_s(2, grgr) == pytest.approx(3 * 250.0 + 220.0 + 30.0)


def test_the_pair_grid_has_no_later_pass():
    problem = grg_hand_problem(filters=("g", "r"))
    grid = make_slot_grid(observable_segments(problem), problem.config, 2, "start")
    assert grid.pass_starts.shape == (2, grid.n_slots)
    assert block_length_s(2, problem.config) == pytest.approx(250.0 + 220.0 + 30.0)


def test_a_field_whose_third_visit_leaves_its_window_is_not_eligible():
    problem = grg_hand_problem()
    grid = make_slot_grid(observable_segments(problem), problem.config, 2, "start")
    inst = slot_instance(problem, np.arange(5), grid)
    eligible = {int(problem.field_ids[inst.rows[f]]) for f in inst.pair_field}
    assert eligible == {1, 3, 4, 5}
    # the pair would take field 2: its first two visits fit
    pair = grg_hand_problem(filters=("g", "r"))
    pair_inst = slot_instance(pair, np.arange(5), make_slot_grid(observable_segments(pair), pair.config, 2, "start"))
    assert 2 in {int(pair.field_ids[pair_inst.rows[f]]) for f in pair_inst.pair_field}
    assert inst.windows().shape == (inst.n_pairs, 3)


def test_a_sequence_longer_than_the_pair_separation_is_not_eligible():
    # n = 4 positions: D = max(4 * 110 + 30, 250) = 470 s, the third visit 940 s after the first, over a
    # 600 s separation (two cadences, 500 s, would fit it: the config is accepted)
    problem = grg_hand_problem(pair_max_s=600.0, horizon_h=2000.0 / 3600.0, slot_positions=(4,))
    problem = dataclasses.replace(problem, windows=Windows(problem.field_ids, np.zeros(5), np.full(5, 2000.0)))
    grid = make_slot_grid(observable_segments(problem), problem.config, 4, "start")
    span = grid.pass_starts[-1] - grid.t1
    # a full block (spans 940 s) and, in the 620 s left, a partial one of 1 position (D = 250 s: 500 s)
    assert sorted(set(span.tolist())) == [500.0, 940.0]
    inst = slot_instance(problem, np.arange(5), grid)
    assert inst.n_pairs == 5 and set(span[inst.pair_slot].tolist()) == {500.0}
    wider = dataclasses.replace(problem, config=dataclasses.replace(problem.config, pair_max_s=940.0))
    assert slot_instance(wider, np.arange(5), grid).n_pairs == 5 * grid.n_slots


def test_a_sequence_whose_cadences_exceed_the_pair_separation_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"need 2 cadences of 1800 s within pair_max_s = 3000 s"):
        PlanningConfig(filters=("g", "r", "g"), pair_max_s=3000.0)
    assert PlanningConfig(filters=("g", "r"), pair_max_s=3000.0).pair_max_s == 3000.0  # one cadence: the pair fits


def test_the_hand_grg_instance_is_solved_to_its_known_optimum_each_field_g_r_g():
    problem = grg_hand_problem()
    result = slot_schedule(problem)
    assert result.status == "optimal"
    fields = {o.field_id for o in result.observations}
    assert fields == {1, 5}
    for fid in fields:
        visits = sorted((o for o in result.observations if o.field_id == fid), key=lambda o: o.start)
        assert [o.filter for o in visits] == ["g", "r", "g"]
        assert all(b.start - a.start >= 250.0 - 1e-6 for a, b in zip(visits, visits[1:]))
        assert all(problem.windows.contains(fid, o.start, o.start + o.exposure_s) for o in visits)


def test_one_filter_is_refused_by_the_slot_milp_and_a_sequence_by_the_block_milp():
    with pytest.raises(InputError, match="slot MILP plans a sequence of two or more filters"):
        slot_schedule(grg_hand_problem(filters=("g",)))
    with pytest.raises(InputError, match="the block MILP plans each field in two filters"):
        milp_schedule(grg_hand_problem())


# ----------------------------------------------------------------- a real map, the real HiGHS

GRG = PlanningConfig(filters=("g", "r", "g"), exposure_s=180.0, time_limit_s=6.0, objective="coverage",
                     bound_time_limit_s=0.0, deterministic=True)


@pytest.fixture(scope="module")
def grg_hybrid(skymap_220722v):
    return make_plan(skymap_220722v, dataclasses.replace(GRG, solver="hybrid"))


@pytest.fixture(scope="module")
def grg_greedy(skymap_220722v):
    return make_plan(skymap_220722v, dataclasses.replace(GRG, solver="greedy"))


def test_the_hybrid_plans_grg_with_the_slot_milp_and_skips_the_pair_stages(skymap_220722v):
    problem = prepare_problem(skymap_220722v, GRG, skymap_220722v.event_time)
    result = run_scheduler(problem, "hybrid")
    assert result.details["skipped_for_sequence"] == ["slots_paced", "lns"]  # blocks: off (hybrid_blocks)
    assert [e.name for e in result.portfolio][:2] == ["greedy", "slots"]
    assert next(e for e in result.portfolio if e.name == "slots").solver.startswith("slots:")


def test_the_hybrid_grg_plan_passes_the_checker_and_covers_at_least_greedys(grg_hybrid, grg_greedy,
                                                                            skymap_220722v):
    assert check_plan(grg_hybrid, skymap_220722v, GRG).ok
    assert grg_hybrid.metrics.coverage >= grg_greedy.metrics.coverage - 1e-9
    by_field: dict[int, list] = {}
    for o in grg_hybrid.observations:
        by_field.setdefault(o.field_id, []).append(o)
    assert grg_hybrid.metrics.n_exposures == sum(len(v) for v in by_field.values())
    for visits in by_field.values():
        visits.sort(key=lambda o: o.start)
        assert [o.filter for o in visits] in (["g", "r", "g"], ["g", "r"])  # (F10) cut only where the checker agrees
        assert all(b.start - a.start >= GRG.cadence_s - 1e-6 for a, b in zip(visits, visits[1:]))


def test_the_hybrid_grg_queues_run_in_sequence_and_the_executor_credits_f1(grg_hybrid, skymap_220722v):
    queues = to_trigger_queues(grg_hybrid)
    assert all(len({t["filter_id"] for t in q["targets"]}) == 1 for q in queues)
    sent = sorted((t["field_id"], t["filter_id"]) for q in queues for t in q["targets"])
    assert sent == sorted((o.field_id, FILTER_IDS[o.filter]) for o in grg_hybrid.observations)
    runs: dict[int, list] = {}
    for e in execute_plan_queues(grg_hybrid):
        runs.setdefault(e.field_id, []).append(e)
    credited = []
    for fid, visits in runs.items():
        visits.sort(key=lambda e: e.start.unix)
        assert [e.filter for e in visits] == ["g", "r", "g"][:len(visits)]
        g = [e.start.unix for e in visits if e.filter == "g"]
        r = [e.start.unix for e in visits if e.filter == "r"]
        if any(abs(a - b) >= GRG.cadence_s for a in g for b in r):  # (F1) g and r a cadence apart, either order
            credited.append(fid)
    assert credited
    footprints = field_footprints(load_ztf_fields(), GRG.nside)
    as_executed = queue_coverage(grg_hybrid, footprints, skymap_220722v.prob)
    assert as_executed == pytest.approx(footprints.coverage(credited, skymap_220722v.prob), abs=1e-9)
    assert as_executed == pytest.approx(grg_hybrid.metrics.coverage_as_executed, abs=1e-6)
    assert 0 < as_executed <= grg_hybrid.metrics.coverage + 1e-6


def test_the_portfolio_adds_the_grid_whose_pass_fills_the_cadence_and_keeps_the_default_at_300s():
    from mushrooms.scheduler_core.schedulers.blocks.model import cadence_block_size
    from mushrooms.scheduler_core.schedulers.slots.schedule import grid_positions

    default = PlanningConfig()
    assert cadence_block_size(default) == 6 and grid_positions(default) == list(default.slot_positions)
    at180 = PlanningConfig(exposure_s=180.0, filters=("g", "r", "g"))
    # (1800 - 120) / 190 = 8.8: 9 positions, a pass of 1710 s + 120 s filter change fills the 1800 s cadence
    assert cadence_block_size(at180) == 9
    assert grid_positions(at180) == [9, *default.slot_positions]
