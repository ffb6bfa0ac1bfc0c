"""milp_schedule end to end on hand-made problems: valid plans, the hand optimum, fallbacks."""

from __future__ import annotations

import pytest

import mushrooms.scheduler_core.schedulers.blocks.schedule as milp
from conftest_milp import TINY_BLOCKS, TINY_OPTIMUM, check_observations, random_problem, tiny_config, tiny_problem


@pytest.mark.parametrize("backend", ["highs", "gurobi"])
def test_tiny_problem_plan(backend):
    problem = tiny_problem(tiny_config(milp_backend=backend))
    result = milp.milp_schedule(problem)
    assert result.solver == f"milp:{backend}"
    assert result.status == "optimal"
    assert result.mip_gap == pytest.approx(0.0, abs=1e-6)
    assert check_observations(problem, result.observations) == []
    blocks = {}
    for o in result.observations:
        blocks.setdefault(o.block, set()).add(o.field_id)
    assert [blocks[b] for b in sorted(blocks)] == list(TINY_BLOCKS)
    # coverage of the plan = the MILP's coverage term (objective + penalty)
    fields = {o.field_id for o in result.observations}
    assert problem.footprints.coverage(fields, problem.prob) == pytest.approx(0.51 + 4 * 0.06)
    for key in ("model_size", "n_cells", "n_pixels", "time_to_first_s", "objective"):
        assert result.details[key] is not None
    assert result.mip_bound is not None


def test_short_block_waits_for_the_cadence():
    # one field only: the block is shorter than b_size and must wait before its second pass
    cfg = tiny_config(n_fields=1, penalty=0.0)
    problem = tiny_problem(cfg)
    result = milp.milp_schedule(problem)
    assert check_observations(problem, result.observations) == []
    g, r = sorted(result.observations, key=lambda o: o.start)
    assert g.field_id == r.field_id
    assert r.start - g.start == pytest.approx(cfg.cadence_s)


@pytest.mark.parametrize("seed", range(6))
def test_random_problems_give_valid_plans(seed):
    problem = random_problem(seed)
    result = milp.milp_schedule(problem)
    assert result.observations
    assert check_observations(problem, result.observations) == []
    assert result.status in ("optimal", "time_limit", "work_limit")


def _underestimated_slews(max_retries: int):
    # slew estimate 1 s (real overheads: 8 s readout, 11 s slew from field 3 to 5) and cadence
    # 232 s keep b_size = (232 - 30) / 101 = 2.  The MILP plans block {3, 5} at 3000 s for
    # 434 s, inside field 5's window [3000, 3440]; really it lasts until 3452 s.
    cfg = tiny_config(slew_estimate_s=1.0, cadence_s=232.0, max_retries=max_retries)
    problem = tiny_problem(cfg, window_5=(3000.0, 3440.0))
    return problem, milp.milp_schedule(problem)


def test_block_overrunning_a_window_is_resolved_with_a_gap():
    problem, result = _underestimated_slews(max_retries=2)
    assert result.details["retries"] == 1
    assert result.details["attempts"][0]["objective"] == pytest.approx(0.51)
    # the re-solve knows block 2 needs longer: field 5 no longer fits, field 3 joins block 1
    assert result.details["attempts"][1]["objective"] == pytest.approx(0.1 + 0.2 + 0.1 + 0.15 - 3 * 0.06)
    assert check_observations(problem, result.observations) == []
    assert {o.field_id for o in result.observations} == {1, 2, 3}
    assert result.dropped_by_slews == ()
    assert result.details["chosen_attempt"] == 1


def test_without_retries_the_offending_field_is_dropped():
    problem, result = _underestimated_slews(max_retries=0)
    assert result.details["retries"] == 0
    assert result.dropped_by_slews == (5,)
    assert check_observations(problem, result.observations) == []
    assert {o.field_id for o in result.observations} == {1, 2, 3}


def test_real_slews_longer_than_the_estimate_stay_valid_on_random_problems():
    for seed in range(6):
        cfg = tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0, slew_estimate_s=1.0,
                          max_retries=2)
        problem = random_problem(seed, config=cfg)
        result = milp.milp_schedule(problem)
        assert check_observations(problem, result.observations) == []
        assert result.details["retries"] <= 2


def test_no_incumbent_falls_back_to_greedy(monkeypatch):
    problem = random_problem(0)
    monkeypatch.setattr(milp, "heuristic_start", lambda *args: None)  # start cold ...
    result = milp.milp_schedule(problem, should_stop=lambda: True)    # ... and stop at once
    assert result.status == "no_incumbent_greedy_fallback"
    assert result.details["attempts"][0]["objective"] is None


def test_a_whole_call_budget_spent_by_the_first_solve_leaves_no_re_solve():
    # a portfolio's block stage: its re-solves come out of the stage's budget, not on top of it
    cfg = tiny_config(slew_estimate_s=1.0, cadence_s=232.0, max_retries=2)
    problem = tiny_problem(cfg, window_5=(3000.0, 3440.0))
    spent = milp.milp_schedule(problem, total_s=milp.MIN_RESOLVE_S / 100)
    assert spent.details["retries"] == 0
    assert spent.dropped_by_slews == (5,)  # the first solve's plan, its offending field dropped
    assert check_observations(problem, spent.observations) == []
    roomy = milp.milp_schedule(problem, total_s=60.0)
    assert roomy.details["retries"] == 1 and roomy.dropped_by_slews == ()


def test_a_cutoff_above_the_optimum_ends_the_solve_with_no_plan_and_one_below_changes_nothing():
    problem = tiny_problem(tiny_config())
    beaten = milp.milp_schedule(problem, cutoff=TINY_OPTIMUM + 0.01)  # the bound proves no plan reaches it
    assert beaten.status == "cutoff" and beaten.observations == ()
    assert beaten.mip_bound is None or beaten.mip_bound < TINY_OPTIMUM + 0.01
    reached = milp.milp_schedule(problem, cutoff=TINY_OPTIMUM - 0.01)
    plain = milp.milp_schedule(problem)
    assert reached.status == "optimal" and reached.observations == plain.observations


def test_the_hybrid_s_block_stage_stops_when_it_cannot_beat_the_best_plan_by_min_gain():
    import dataclasses

    from mushrooms.scheduler_core.schedulers.portfolio.portfolio import blocks_stage

    problem = tiny_problem(tiny_config(penalty=0.0, min_gain=0.001))
    alone = blocks_stage(problem, None, {}, 5.0)
    assert alone.observations and alone.status == "optimal"
    beaten = blocks_stage(problem, None, {"slots": alone}, 5.0)  # the same plan already found: it cannot gain
    assert beaten.status == "cutoff" and beaten.observations == ()
    gone = alone.observations[0].field_id
    thinner = dataclasses.replace(alone, observations=tuple(o for o in alone.observations if o.field_id != gone))
    assert blocks_stage(problem, None, {"slots": thinner}, 5.0).observations == alone.observations
