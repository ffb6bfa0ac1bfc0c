"""[scheduler] max_open_shutter_s: a plan's exposures add up to at most the open-shutter budget (S4, issue 55).

Greedy stops before the field whose visits would pass the cap; the slot
MILPs carry the S4 row; the portfolio keeps no candidate over it; the
checker refuses a plan over it; unset, every plan is today's.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, read_skymap

MAP_MULTIORDER = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def _open_s(plan) -> float:
    return sum(o.exposure_s for o in plan.observations)


@pytest.fixture(scope="module")
def map64():
    return read_skymap(MAP_MULTIORDER, nside=64)


@pytest.fixture(scope="module")
def greedy_free(map64):
    return make_plan(map64, PlanningConfig(solver="greedy", nside=64))


def test_greedy_under_a_cap_stops_before_the_field_that_would_pass_it(map64, greedy_free):
    free_s = _open_s(greedy_free)
    cap = 3000.0  # five g-r sequences of 300 s (600 s each)
    assert free_s > 2 * cap  # the premise: the uncapped plan spends more
    config = PlanningConfig(solver="greedy", nside=64, max_open_shutter_s=cap)
    plan = make_plan(map64, config)
    assert 0 < _open_s(plan) <= cap
    assert _open_s(plan) + 2 * config.exposure_s > cap  # it filled the budget: one more field would pass it
    assert check_plan(plan, map64, config).ok
    # the fields it took are the uncapped plan's first ones (same walk, stopped early)
    first = [o.field_id for o in greedy_free.observations if o.filter == "g"][:len(plan.observations) // 2]
    assert sorted(o.field_id for o in plan.observations if o.filter == "g") == sorted(first)


def test_a_cap_larger_than_the_plan_changes_nothing(map64, greedy_free):
    plan = make_plan(map64, PlanningConfig(solver="greedy", nside=64, max_open_shutter_s=604800.0))
    assert plan.observations == greedy_free.observations
    assert "max_open_shutter_s" not in PlanningConfig().record()  # unset: the plan document and id of before
    assert PlanningConfig(max_open_shutter_s=3600.0).record()["max_open_shutter_s"] == 3600.0


def test_the_slot_model_carries_the_cap_as_its_s4_row(map64, greedy_free):
    from mushrooms.scheduler_core import prepare_problem
    from mushrooms.scheduler_core.schedulers.slots.grid import make_slot_grid, observable_segments
    from mushrooms.scheduler_core.schedulers.slots.model import build_slot_model, slot_instance

    def model(cap):
        cfg = PlanningConfig(solver="slots", nside=64, max_open_shutter_s=cap)
        problem = prepare_problem(map64, cfg, greedy_free.start)
        rows = np.arange(min(40, len(problem.field_ids)))
        return build_slot_model(slot_instance(problem, rows, make_slot_grid(observable_segments(problem, rows), cfg, 6)))

    capped, free = model(2400.0), model(None)
    names = [b.name for b in capped.milp.row_blocks]
    assert "S4 open-shutter cap" in names and "S4 open-shutter cap" not in [b.name for b in free.milp.row_blocks]
    b = capped.milp.row_blocks[names.index("S4 open-shutter cap")]
    row = capped.milp.A.tocsr()[b.start:b.stop].toarray()[0]
    K = capped.instance.n_pairs
    assert np.all(row[:K] == 600.0) and np.all(row[K:] == 0.0)  # two 300 s passes per pair, nothing else
    assert capped.milp.row_hi[b.start] == 2400.0


def test_the_service_under_a_cap_spends_at_most_it_and_executes_at_least_greedy(map64):
    """The hybrid (the service's solver) under a cap: within it, checked, and executing at least what greedy
    under the same cap executes (its Q15 choice keeps the candidate executing most; greedy is one)."""
    small = dict(nside=64, time_limit_s=3.0, detection_time_limit_s=1.0, bound_time_limit_s=0.5,
                 max_open_shutter_s=4800.0)
    config = PlanningConfig(solver="hybrid", **small)
    plan = make_plan(map64, config)
    greedy = make_plan(map64, dataclasses.replace(config, solver="greedy"))
    assert 0 < _open_s(plan) <= 4800.0 and 0 < _open_s(greedy) <= 4800.0
    report = check_plan(plan, map64, config)
    assert report.ok, report.problems
    assert plan.metrics.coverage_as_executed >= greedy.metrics.coverage_as_executed - 1e-9
    # the certified bound of the uncapped problem stays an upper bound of the capped one
    assert plan.metrics.upper_bound is None or plan.metrics.coverage <= plan.metrics.upper_bound + 1e-9


def test_the_checker_refuses_a_plan_over_the_cap(map64, greedy_free):
    config = PlanningConfig(solver="greedy", nside=64, max_open_shutter_s=1200.0)
    report = check_plan(greedy_free, map64, config)
    assert not report.ok
    assert any(p.startswith("open shutter: ") and "pass max_open_shutter_s = 1200 s" in p for p in report.problems)


@pytest.mark.parametrize("value, why", [("0", "outside its range [1, 604800] s"), ("-60", "outside its range [1, 604800] s"),
                                        ('"two hours"', "expected a number")])
def test_a_bad_cap_is_one_line_exit_2(tmp_path, capsys, value, why):
    from mushrooms.cli import main

    code = main(["plan", str(MAP_MULTIORDER), "-o", str(tmp_path / "p.json"),
                 "--set", f"scheduler.max_open_shutter_s={value}"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "max_open_shutter_s" in err and why in err, err


def test_the_block_milp_alone_is_refused_under_a_cap(tmp_path, capsys):
    from mushrooms.cli import main

    code = main(["plan", str(MAP_MULTIORDER), "-o", str(tmp_path / "p.json"), "--solver", "blocks",
                 "--set", "scheduler.max_open_shutter_s=3600"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "S4" in err, err
