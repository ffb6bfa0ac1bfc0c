"""The slot-assignment MILP: a hand-solved instance, eligibility, warm start, post-processing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import Time

from conftest_milp import check_observations, random_problem, slot_hand_problem, tiny_config
from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.sky.windows import Windows
from mushrooms.scheduler_core.schedulers.slots.schedule import map_start, slot_portfolio, slot_rows, slot_schedule, time_slot_plan
from mushrooms.scheduler_core.schedulers.slots.model import (block_length_s, build_slot_model, decode_slots, make_slot_grid,
                                            observable_segments, slot_instance, start_vector)
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp

# Hand-solved instance.  Exposure 100 s, slew estimate 10 s (s = 110 s), filter change 30 s,
# cadence 250 s, no margin: a block of n = 2 positions has D = max(2 s + 30, 250) = 250 s and
# L = 250 + 220 + 30 = 500 s; its slots start at (t1, t2) = (T, T + 250) and (T + 110, T + 360).
# Horizon 1000 s: blocks at 0 and 500 s, four slots.  Fields 1, 2, 5 are visible in [0, 470] s
# only, so only block 0 (whose last exposure ends at 460 s) can hold them: two of the three.
# Fields 3 and 4 are visible all the time.  Coverage (pixel probabilities in brackets):
# f1 = {0 (.12), 1 (.2)}, f2 = {1, 2 (.1)}, f3 = {3 (.15)}, f4 = {4 (.05)}, f5 = {5 (.1), 6 (.12)}.
# Best two of {1, 2, 5}: {1, 5} = .32 + .22 = .54 (> {2, 5} = .52 > {1, 2} = .42); with 3 and 4:
HAND_OPTIMUM = 0.54 + 0.15 + 0.05
HAND_FIELDS = {1, 3, 4, 5}


def hand_problem(backend: str = "highs") -> PlanningProblem:
    return slot_hand_problem((470.0, 470.0, 1000.0, 1000.0, 470.0), milp_backend=backend)


def test_hand_grid_has_the_designed_slots():
    problem = hand_problem()
    grid = make_slot_grid(observable_segments(problem), problem.config, 2, "start")
    assert block_length_s(2, problem.config) == pytest.approx(500.0)
    assert grid.block_start.tolist() == [0.0, 500.0]
    assert grid.t1.tolist() == [0.0, 110.0, 500.0, 610.0]
    assert grid.t2.tolist() == [250.0, 360.0, 750.0, 860.0]


@pytest.mark.parametrize("backend", ["highs", "gurobi"])
def test_hand_instance_is_solved_to_its_known_optimum(backend):
    problem = hand_problem(backend)
    grid = make_slot_grid(observable_segments(problem), problem.config, 2, "start")
    inst = slot_instance(problem, np.arange(5), grid)
    model = build_slot_model(inst)
    res = solve_milp(model.milp, backend, time_limit_s=20, mip_gap=0.0)
    assert res.backend == backend and res.status == "optimal"
    assert res.objective == pytest.approx(HAND_OPTIMUM)
    chosen = {int(problem.field_ids[inst.rows[inst.pair_field[k]]]) for _, ks in decode_slots(model, res.x)
              for k in ks}
    assert chosen == HAND_FIELDS


def test_hand_instance_end_to_end_plan_is_valid_and_optimal():
    problem = hand_problem()
    result = slot_schedule(problem)
    assert check_observations(problem, result.observations) == []
    fields = {o.field_id for o in result.observations}
    assert fields == HAND_FIELDS
    assert problem.footprints.coverage(fields, problem.prob) == pytest.approx(HAND_OPTIMUM)


@pytest.mark.parametrize("seed", range(5))
def test_eligibility_never_admits_an_exposure_outside_a_window(seed):
    problem = random_problem(seed, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0,
                                                      slot_positions=(1, 2, 3)))
    rows = np.arange(len(problem.field_ids))
    exp = problem.config.exposure_s
    w = problem.windows
    n_pairs = 0
    for grid in slot_portfolio(problem, rows):
        inst = slot_instance(problem, rows, grid)
        fid = problem.field_ids[inst.rows[inst.pair_field]]
        t1, t2 = grid.t1[inst.pair_slot], grid.t2[inst.pair_slot]
        for f, a, b, w1, w2 in zip(fid, t1, t2, inst.pair_window1, inst.pair_window2):
            assert w.field_ids[w1] == f and w.field_ids[w2] == f
            assert w.start[w1] <= a and a + exp <= w.end[w1]
            assert w.start[w2] <= b and b + exp <= w.end[w2]
            assert b - a >= problem.config.cadence_s
        # and every (field, slot) pair left out really has an exposure outside all windows
        admitted = set(zip(inst.pair_field.tolist(), inst.pair_slot.tolist()))
        for f in range(inst.n_fields):
            for s in range(grid.n_slots):
                inside = (w.contains(problem.field_ids[inst.rows[f]], grid.t1[s], grid.t1[s] + exp)
                          and w.contains(problem.field_ids[inst.rows[f]], grid.t2[s], grid.t2[s] + exp))
                assert inside == ((f, s) in admitted)
        n_pairs += inst.n_pairs
    assert n_pairs > 0


@pytest.mark.parametrize("seed", range(4))
def test_slot_plans_of_random_problems_follow_the_rules(seed):
    problem = random_problem(seed, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0,
                                                      slot_positions=(1, 2, 3)))
    result = slot_schedule(problem, start=greedy_schedule(problem))
    assert result.observations
    assert check_observations(problem, result.observations) == []


def test_warm_start_incumbent_is_never_worse_than_greedy(skymap_220722v):
    from mushrooms.scheduler_core import PlanningConfig, prepare_problem

    cfg = PlanningConfig(milp_backend="highs")
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    greedy = greedy_schedule(problem)
    g_cov = problem.footprints.coverage({o.field_id for o in greedy.observations}, problem.prob)
    rows = slot_rows(problem, np.array([o.field_id for o in greedy.observations]))
    first = {}
    for o in greedy.observations:
        first[o.field_id] = min(o.start, first.get(o.field_id, np.inf))
    f_of = {int(problem.field_ids[r]): f for f, r in enumerate(rows)}
    mapped_full = 0
    for grid in slot_portfolio(problem, rows)[:2]:
        inst = slot_instance(problem, rows, grid)
        model = build_slot_model(inst)
        pairs = map_start(inst, {f_of[fid]: t for fid, t in first.items()})
        x0 = start_vector(model, pairs)
        start_obj = float(model.milp.c @ x0)
        # a feasible start: every row within its bounds
        ax = model.milp.A @ x0
        assert np.all(ax <= model.milp.row_hi + 1e-9) and np.all(ax >= model.milp.row_lo - 1e-9)
        if len(pairs) == len(first):
            mapped_full += 1
            assert start_obj == pytest.approx(g_cov, abs=1e-9)
        # stopped almost at once, the solver still returns at least its start
        res = solve_milp(model.milp, "highs", time_limit_s=0.01, mip_gap=0.0, start=x0)
        assert res.has_solution and res.objective >= start_obj - 1e-6  # solver tolerances
    assert mapped_full >= 1  # greedy's plan fits the grid on this map
    result = slot_schedule(problem, start=greedy)
    for g in result.details["grids"]:
        if g["start_objective"] is not None:
            assert g["objective"] >= g["start_objective"] - 1e-6


def test_post_processing_drops_a_field_pushed_out_of_its_window():
    # slew estimate 0 s but real overheads >= 8 s readout: the second slot of the block drifts
    # 8 s late; field 2's window ends exactly where its planned second exposure ends.
    cfg = tiny_config(horizon_h=1000.0 / 3600.0, slot_margin_s=0.0, slot_positions=(2,), penalty=0.0,
                      slew_estimate_s=0.0, n_fields=None)
    problem = hand_problem()
    problem = dataclasses.replace(problem, config=cfg)
    grid = make_slot_grid(observable_segments(problem), cfg, 2, "start")
    t2_last = grid.t2[1]
    windows = Windows(np.array([1, 2]), np.zeros(2), np.array([1000.0, t2_last + cfg.exposure_s]))
    problem = dataclasses.replace(problem, windows=windows)
    inst = slot_instance(problem, np.arange(2), grid)
    model = build_slot_model(inst)
    k0 = np.flatnonzero((inst.pair_field == 0) & (inst.pair_slot == 0))[0]
    k1 = np.flatnonzero((inst.pair_field == 1) & (inst.pair_slot == 1))[0]
    obs, dropped, _ = time_slot_plan(problem, model, start_vector(model, np.array([k0, k1])))
    assert dropped == [2]
    assert {o.field_id for o in obs} == {1}
    assert check_observations(problem, obs) == []


def test_slot_portfolio_stops_when_asked(monkeypatch):
    import mushrooms.scheduler_core.schedulers.slots.schedule as ss

    problem = random_problem(1, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0,
                                                   slot_positions=(1, 2, 3)))
    greedy = greedy_schedule(problem)
    stopped = slot_schedule(problem, should_stop=lambda: True, start=greedy)
    assert stopped.status == "interrupted" and stopped.details["grids"] == [] and not stopped.observations
    # asked to stop once the first grid is solved: the later grids are never solved
    solved: list = []
    real = ss.solve_milp

    def counting(*args, **kwargs):
        solved.append(real(*args, **kwargs))
        return solved[-1]

    monkeypatch.setattr(ss, "solve_milp", counting)
    result = slot_schedule(problem, should_stop=lambda: bool(solved), start=greedy)
    assert len(result.details["grids"]) == 1 < len(slot_portfolio(problem, slot_rows(problem)))
    assert result.status == "interrupted" and result.observations
    assert check_observations(problem, result.observations) == []
