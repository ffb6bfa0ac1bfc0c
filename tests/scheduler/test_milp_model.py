"""The block-division MILP: a hand-solved instance, both backends, b_size, the adapter."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from conftest_milp import TINY_BLOCKS, TINY_OPTIMUM, check_observations, random_problem, tiny_config, tiny_problem
from mushrooms.scheduler_core.schedulers.blocks.model import (BlockParams, block_size, build_block_model, decode_blocks,
                                             heuristic_start)
from mushrooms.scheduler_core.sky.cells import merge_cells
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.schedulers.blocks.schedule import make_candidates, shortlist_footprints
from mushrooms.scheduler_core.schedulers.milp.solvers import MilpModel, gurobi_fully_licensed, solve_milp


def _tiny_model(config=None):
    problem = tiny_problem(config)
    params = BlockParams.from_config(problem.config)
    rows = np.arange(len(problem.field_ids))
    cells = merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob)
    cand = make_candidates(problem, rows, params.least_duration_s(params.b_size))
    return problem, build_block_model(cand, cells, len(rows), params), cand, cells, params


def _blocks_as_field_sets(problem, model, cand, x):
    return [set(problem.field_ids[cand.field[b.candidates]].tolist()) for b in decode_blocks(model, x)]


@pytest.mark.parametrize("backend", ["highs", "gurobi"])
def test_tiny_instance_reaches_the_hand_optimum(backend):
    problem, model, cand, _, _ = _tiny_model()
    assert model.milp.n_vars < 2000 and model.milp.n_rows < 2000  # fits Gurobi's pip licence
    res = solve_milp(model.milp, backend, time_limit_s=20, mip_gap=0.0)
    assert res.backend == backend
    assert res.status == "optimal"
    assert res.objective == pytest.approx(TINY_OPTIMUM, abs=1e-6)
    assert res.gap == pytest.approx(0.0, abs=1e-6)
    assert res.time_to_first_s is not None
    assert _blocks_as_field_sets(problem, model, cand, res.x) == list(TINY_BLOCKS)
    t = model.t(res.x)
    assert t[1] >= 3000.0 - 1e-6  # the second block waits for field 5's window


def test_both_backends_agree_on_random_instances():
    for seed in range(3):
        problem = random_problem(seed)
        params = BlockParams.from_config(problem.config)
        rows = np.arange(len(problem.field_ids))
        cells = merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob)
        cand = make_candidates(problem, rows, params.least_duration_s(params.b_size))
        model = build_block_model(cand, cells, len(rows), params)
        h = solve_milp(model.milp, "highs", time_limit_s=30, mip_gap=0.0)
        g = solve_milp(model.milp, "gurobi", time_limit_s=30, mip_gap=0.0)
        assert h.status == g.status == "optimal"
        assert h.objective == pytest.approx(g.objective, abs=1e-6)


def test_penalty_and_block_gap_change_the_optimum():
    # without a penalty field 4 (0.05) is worth taking: it joins the first block
    problem, model, cand, _, _ = _tiny_model(tiny_config(penalty=0.0))
    res = solve_milp(model.milp, "highs", mip_gap=0.0)
    assert res.objective == pytest.approx(0.8, abs=1e-6)
    # a gap after the first block longer than the night leaves one block only
    problem, model, cand, _, _ = _tiny_model(tiny_config(block_gap_s=3000.0))
    res = solve_milp(model.milp, "highs", mip_gap=0.0)
    assert len(decode_blocks(model, res.x)) == 1


def test_block_size_follows_the_cadence():
    assert block_size(PlanningConfig()) == 6                      # ceil((1800 - 120) / 310) = ceil(5.42)
    assert block_size(tiny_config()) == 2                          # (250 - 30) / 110 = 2 exactly
    assert block_size(PlanningConfig(cadence_s=3600.0)) == 12      # ceil(3480 / 310) = ceil(11.2)
    assert block_size(PlanningConfig(exposure_s=30.0, cadence_s=1800.0)) == 42  # ceil(1680 / 40)
    assert block_size(PlanningConfig(cadence_s=100.0)) == 1        # the filter change alone suffices


def test_unused_blocks_cost_no_time_and_block_durations_follow_their_size():
    problem, model, cand, _, params = _tiny_model(tiny_config(n_blocks_max=4))
    res = solve_milp(model.milp, "highs", mip_gap=0.0)
    blocks = decode_blocks(model, res.x)
    assert len(blocks) == 2
    d = model.d(res.x)
    used = np.zeros(4, bool)
    used[: len(blocks)] = True
    assert np.all(d[~used] == pytest.approx(0.0, abs=1e-6))
    for b in blocks:
        assert b.duration_s >= params.least_duration_s(b.candidates.size) - 1e-6


def test_heuristic_start_is_feasible_and_no_better_than_the_optimum():
    for seed in range(4):
        problem = random_problem(seed)
        params = BlockParams.from_config(problem.config)
        rows = np.arange(len(problem.field_ids))
        cells = merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob)
        cand = make_candidates(problem, rows, params.least_duration_s(params.b_size))
        model = build_block_model(cand, cells, len(rows), params)
        x0 = heuristic_start(model, cand, cells, params)
        assert x0 is not None
        assert model.coverage_objective(x0) > 0
        res = solve_milp(model.milp, "highs", mip_gap=0.0, start=x0)
        assert res.objective >= model.coverage_objective(x0) - 1e-9


def _knapsack(n: int, seed: int = 3) -> MilpModel:
    rng = np.random.default_rng(seed)
    A = sp.csr_matrix(rng.integers(5, 60, (6, n)).astype(float))
    return MilpModel(rng.integers(5, 60, n).astype(float), A, np.full(6, -np.inf), A.sum(axis=1).A1 / 3,
                     np.zeros(n), np.ones(n), np.ones(n, bool))


@pytest.mark.parametrize("backend", ["highs", "gurobi"])
def test_should_stop_interrupts_the_solver(backend):
    res = solve_milp(_knapsack(80), backend, time_limit_s=60, mip_gap=0.0, should_stop=lambda: True)
    assert res.status == "interrupted"


def test_gurobi_size_limit_falls_back_to_highs(caplog):
    if gurobi_fully_licensed():
        pytest.skip("a full Gurobi licence is present here")
    model = _knapsack(2500)
    with caplog.at_level("WARNING"):
        res = solve_milp(model, "gurobi", time_limit_s=5)
    assert res.backend == "highs"
    assert "gurobi fallback" in res.note
    assert res.has_solution
    assert sum("solving with HiGHS" in r.message for r in caplog.records) == 1
    assert solve_milp(model, "auto", time_limit_s=5).backend == "highs"


def test_an_absolute_gap_stops_the_solve_once_the_bound_is_that_close():
    model = _knapsack(200, seed=5)  # proving the optimum takes HiGHS about 40 s
    tight = solve_milp(model, "highs", time_limit_s=5, mip_gap=0.0)
    assert tight.status == "time_limit"
    loose = solve_milp(model, "highs", time_limit_s=5, mip_gap=0.0, abs_gap=50.0)
    assert loose.status == "optimal"  # the bound within 50 of the incumbent: proven to within that
    assert 0.0 <= loose.bound - loose.objective <= 50.0 + 1e-6
    assert loose.objective >= tight.bound - 50.0 - 1e-6


@pytest.mark.parametrize("backend", ["highs", "gurobi"])
def test_a_cutoff_the_bound_cannot_reach_stops_the_solve(backend):
    model = _knapsack(200, seed=5)  # optimum 3373; proving it takes HiGHS about 40 s
    res = solve_milp(model, backend, time_limit_s=20, mip_gap=0.0, cutoff=4000.0)
    assert res.status == "cutoff"
    assert res.bound is None or res.bound < 4000.0
