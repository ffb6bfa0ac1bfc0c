"""ScheduleResult's typed fields, the solver registry and the hybrid as a composition (best_of)."""

from __future__ import annotations

import dataclasses
import time

import pytest

from conftest_milp import random_problem, tiny_config
from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.problem import ScheduleResult
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
from mushrooms.scheduler_core.schedulers.portfolio.portfolio import BLOCKS_LIMIT_S, MIN_BLOCKS_S, Stage, best_of, reaches_bound
from mushrooms.scheduler_core.schedulers.as_executed import AS_EXECUTED_MEMO
from mushrooms.scheduler_core.solvers_registry import SOLVER_NAMES, get_scheduler, register, registered


def _problem(seed: int, min_gain: float = 0.0):
    """min_gain 0: the hybrid stops at the bound only when its plan is optimal (V6), so it keeps the full run's plan."""
    return random_problem(seed, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0,
                                                   time_limit_s=20.0, mip_gap=0.0, min_gain=min_gain))


def test_the_registry_names_every_scheduler_and_refuses_others_with_the_old_message():
    assert SOLVER_NAMES == ("greedy", "slots", "blocks", "hybrid", "milp")
    assert set(registered()) == set(SOLVER_NAMES)  # every name has its scheduler (planner imported)
    assert all(callable(get_scheduler(name)) for name in SOLVER_NAMES)
    assert get_scheduler("greedy") is greedy_schedule
    with pytest.raises(ValueError):
        register("annealing", greedy_schedule)  # only under a registry name
    with pytest.raises(InputError) as err:
        get_scheduler("annealing")
    assert str(err.value) == "unknown solver 'annealing'; choose one of greedy, slots, blocks, hybrid, milp"
    with pytest.raises(InputError, match="unknown solver 'annealing'"):
        run_scheduler(_problem(0), "annealing")


def test_every_milp_scheduler_fills_the_certified_bound_and_its_own_mip_bound():
    problem = _problem(1)
    exact = certified_upper_bound(problem)  # min(U4, V), as plans publish it
    greedy = run_scheduler(problem, "greedy")
    assert greedy.upper_bound is None and greedy.mip_bound is None  # as published before: greedy has neither
    assert greedy.dropped_by_slews == () and greedy.portfolio == () and greedy.detection is None
    for name in ("slots", "blocks", "milp", "hybrid"):
        result = run_scheduler(problem, name)
        assert result.upper_bound is not None, name
        assert result.upper_bound.value == pytest.approx(exact.value) and result.upper_bound.method == exact.method
        assert result.upper_bound.value <= coverage_upper_bound(problem).value
        assert published_coverage(problem, result) <= result.upper_bound.value + 1e-9
        assert isinstance(result.dropped_by_slews, tuple)
        if name != "hybrid" or result.portfolio_choice != "greedy":
            assert isinstance(result.mip_bound, float), name  # the MILP's bound on its objective
            assert result.mip_bound >= result.details["objective"] - 1e-9
    assert run_scheduler(problem, "slots").grid is not None


def _old_hybrid(problem, should_stop=None):
    """The hybrid of f999d02's run_scheduler (a string branch), as reference: (winner name, its result)."""
    from mushrooms.scheduler_core.schedulers.blocks.schedule import milp_schedule
    from mushrooms.scheduler_core.schedulers.slots.schedule import slot_schedule

    t0 = time.perf_counter()
    budget = problem.config.time_limit_s
    greedy = greedy_schedule(problem, should_stop)
    left = budget - (time.perf_counter() - t0)
    slots = slot_schedule(problem, should_stop, start=greedy, time_limit_s=max(left, 0.0))
    candidates = [("greedy", greedy), ("slots", slots)]
    left = budget - (time.perf_counter() - t0)
    if left >= MIN_BLOCKS_S:
        timed = dataclasses.replace(problem, config=dataclasses.replace(
            problem.config, time_limit_s=min(left, BLOCKS_LIMIT_S), objective="coverage"))
        candidates.append(("blocks", milp_schedule(timed, should_stop)))
    covs = {name: published_coverage(problem, r) for name, r in candidates}
    return max(candidates, key=lambda nr: (covs[nr[0]], -[n for n, _ in candidates].index(nr[0])))


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_the_hybrid_composition_keeps_the_winner_the_string_branch_kept(seed):
    problem = _problem(seed)
    name, best = _old_hybrid(problem)
    assert best.status in ("optimal", "greedy")  # solved to the end: the comparison is deterministic
    result = run_scheduler(problem, "hybrid")
    # the stages left once a plan reaches the certified bound are skipped; the winner is the same
    skipped = result.details.get("skipped_at_bound", [])
    assert [e.name for e in result.portfolio] + skipped == ["greedy", "slots", "slots_paced", "lns"]  # no blocks
    if skipped:
        assert reaches_bound(max(e.coverage for e in result.portfolio), result.upper_bound)
    assert all(e.status in ("optimal", "greedy") for e in result.portfolio if e.name != "lns")
    lns = [e for e in result.portfolio if e.name == "lns"]
    if lns and lns[0].status == "improved":  # the LNS re-solves beat every plan of the old hybrid
        assert result.portfolio_choice == "lns" and lns[0].coverage > published_coverage(problem, best)
        return
    assert all(e.status == "no_improvement" for e in lns)  # its plan is then its seed
    # the hybrid then chooses on the coverage ZTF's scheduler executes (Q15): the old winner unless another
    # candidate's queues execute better
    executed = result.details["coverage_as_executed"]
    if result.portfolio_choice != name:
        assert executed[result.portfolio_choice] > executed.get(name, -1.0) or name not in executed
        return
    assert result.solver == f"hybrid({best.solver})"
    assert result.observations == best.observations
    assert result.status == best.status and result.mip_gap == best.mip_gap and result.mip_bound == best.mip_bound
    covs = {e.name: e.coverage for e in result.portfolio}
    assert covs[name] == max(covs.values())


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_the_hybrid_stops_once_no_stage_can_add_min_gain_and_keeps_a_plan_within_it(seed):
    # on these instances greedy is within 0.001 of the certified bound but below it (the exact run goes on)
    exact = run_scheduler(_problem(seed), "hybrid")
    problem = _problem(seed, min_gain=0.001)
    result = run_scheduler(problem, "hybrid")
    bound = result.upper_bound
    greedy = result.portfolio[0].coverage
    assert not reaches_bound(greedy, bound) and reaches_bound(greedy, bound, 0.001)
    assert result.details["skipped_at_bound"] == ["slots", "slots_paced", "lns"]
    assert [e.name for e in result.portfolio] == ["greedy"] and result.portfolio_choice == "greedy"
    # what the full run found instead is at most min_gain more
    assert greedy <= published_coverage(problem, exact) <= greedy + 0.001


def _stub(name: str, observations, calls: list):
    def run(problem, should_stop, earlier, left_s):
        calls.append((name, tuple(earlier), left_s))
        return ScheduleResult(tuple(observations), f"stub:{name}", "optimal", 0.0, 0.0, {"who": name})
    return run


def test_best_of_keeps_the_most_covering_plan_the_earlier_on_a_tie_and_polls_the_stop_once(monkeypatch):
    import mushrooms.scheduler_core.schedulers.as_executed as coverage_module

    # the random problem starts at 00:00 UTC: the telescope model has 11 min of night in its 2 h, so what
    # its queues execute says nothing here; every candidate executes alike and planned coverage decides (Q15)
    monkeypatch.setattr(coverage_module, "queue_coverage", lambda *args, **kwargs: 0.0)
    problem = _problem(0)
    obs = greedy_schedule(problem).observations
    first = tuple(o for o in obs if o.field_id == obs[0].field_id)
    calls: list = []
    # a tie: the earlier stage wins
    tie = best_of("pf", Stage("a", _stub("a", obs, calls)), Stage("b", _stub("b", obs, calls)))(problem)
    assert tie.portfolio_choice == "a" and tie.solver == "pf(stub:a)"
    assert tie.details == {"who": "a", "stage_times_s": tie.details["stage_times_s"],  # the winner's, + times
                           "coverage_as_executed": tie.details["coverage_as_executed"],  # + the executor's
                           AS_EXECUTED_MEMO: tie.details[AS_EXECUTED_MEMO]}  # and the same by plan, for its document
    assert list(tie.details[AS_EXECUTED_MEMO].values()) == [tie.details["coverage_as_executed"]["a"]]
    assert list(tie.details["stage_times_s"]) == ["a", "b"] and min(tie.details["stage_times_s"].values()) >= 0
    assert [c[:2] for c in calls] == [("a", ()), ("b", ("a",))]  # each stage sees the ones before it
    assert all(0 < c[2] <= problem.config.time_limit_s for c in calls)
    # more coverage wins; a stage with a floor on the time left is skipped below it
    calls.clear()
    more = best_of("pf", Stage("a", _stub("a", first, calls)), Stage("b", _stub("b", obs, calls)),
                   Stage("c", _stub("c", obs, calls), min_left_s=1e9))(problem)
    assert more.portfolio_choice == "b" and [e.name for e in more.portfolio] == ["a", "b"]
    assert more.portfolio[0].coverage < more.portfolio[1].coverage
    # should_stop is polled once, only before a stage with a floor, and skips it when it says stop
    polls = []

    def stop() -> bool:
        polls.append(1)
        return True

    calls.clear()
    stopped = best_of("pf", Stage("a", _stub("a", first, calls)),
                      Stage("c", _stub("c", obs, calls), min_left_s=0.0))(problem, stop)
    assert len(polls) == 1 and [c[0] for c in calls] == ["a"] and stopped.portfolio_choice == "a"


def test_two_candidates_with_one_plan_cost_one_run_of_the_executor(monkeypatch):
    import mushrooms.scheduler_core.schedulers.as_executed as coverage_module

    problem = _problem(0)
    obs = greedy_schedule(problem).observations
    runs = []
    real = coverage_module.queue_coverage

    def counted(plan, *args, **kwargs):
        runs.append(plan.observations)
        return 0.5 * real(plan, *args, **kwargs)  # executes worse than planned: the second candidate is tried

    monkeypatch.setattr(coverage_module, "queue_coverage", counted)
    result = best_of("pf", Stage("a", _stub("a", obs, [])), Stage("b", _stub("b", obs, [])))(problem)
    executed = result.details["coverage_as_executed"]
    assert list(executed) == ["a", "b"] and executed["a"] == executed["b"]
    assert len(runs) == 1 and result.portfolio_choice == "a"
    # the published plan reuses the value too: building it runs the executor no more
    from mushrooms.scheduler_core.planner import _coverage_as_executed
    from mushrooms.scheduler_core.plan.document import sorted_observations
    from mushrooms.scheduler_core.schedulers.gain import drop_low_gain

    kept = sorted_observations(drop_low_gain(result, problem.footprints, problem.prob,
                                             problem.config.min_gain).observations)

    class _Plan:  # what _coverage_as_executed reads of a plan
        observations = kept

    assert _coverage_as_executed(_Plan(), problem, result) == pytest.approx((executed["a"],) * 2, abs=1e-6)
    assert len(runs) == 1
