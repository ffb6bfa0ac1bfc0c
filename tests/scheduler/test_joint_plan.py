"""One coordinated plan for several telescopes on one map (issue 53 item 2; telescopes.md section 5, J1-J8).

Until the planner reads telescope descriptions, two ZTF problems on different
field grids stand in for two telescopes: the primary grid (ids below 1000)
and the secondary grid (ids 1000 and up), which overlap on the sky, with
different filters and cadences; the same grid twice; and a grid the night
cannot reach (a telescope with no window).  Real HiGHS, the packaged map.
"""

from __future__ import annotations

import dataclasses
import json
from importlib.resources import files
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.budget import new_clock
from mushrooms.scheduler_core.plan.checker import check_plan
from mushrooms.scheduler_core.planner import build_plan
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.portfolio.portfolio import slots_from_greedy
from mushrooms.scheduler_core.sky.fields import FieldGrid, load_ztf_fields

NIGHT = Time("2019-05-01T03:00:00", scale="utc")
DEMO = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"


def _config(**kw) -> PlanningConfig:
    return PlanningConfig(solver="slots", nside=64, horizon_h=12.0, time_limit_s=1.0, detection_time_limit_s=0.5, bound_time_limit_s=1.0,
                          deterministic=True, **kw)


def _sub_grid(keep) -> FieldGrid:
    grid = load_ztf_fields()
    sel = keep(grid)
    return FieldGrid(grid.ids[sel], grid.ra[sel], grid.dec[sel])


PRIMARY = (lambda g: g.ids < 1000)
SECONDARY = (lambda g: g.ids >= 1000)
UNREACHABLE = (lambda g: (g.ids < 1000) & (g.dec < -28.0))  # below the band once dec_min is -20


@pytest.fixture(scope="module")
def skymap():
    return read_skymap(DEMO, nside=64)


@pytest.fixture(scope="module")
def two_telescopes(skymap):
    """Primary grid in g-r at 30 min; secondary grid in r-i at 40 min, 240 s exposures."""
    a = prepare_problem(skymap, _config(), NIGHT, grid=_sub_grid(PRIMARY))
    b = prepare_problem(skymap, _config(filters=("r", "i"), cadence_s=2400.0, exposure_s=240.0), NIGHT,
                        grid=_sub_grid(SECONDARY))
    return [a, b]


@pytest.fixture(scope="module")
def joint_two(two_telescopes):
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    return joint_schedule(two_telescopes)


def _lone(problem):
    """The telescope planned alone, with its own budget (the single-telescope slot scheduler from greedy)."""
    return slots_from_greedy(dataclasses.replace(problem, clock=new_clock(problem.config.deterministic)))


def _fields(result) -> set[int]:
    return {o.field_id for o in result.observations}


def test_the_joint_objective_counts_a_pixel_once(skymap):
    """(J1, J2) Two telescopes with the same grid observing the same field: its probability counts once."""
    from mushrooms.scheduler_core.schedulers.joint.model import build_joint_model, joint_instance

    same = [prepare_problem(skymap, _config(), NIGHT, grid=_sub_grid(PRIMARY)) for _ in range(2)]
    inst = joint_instance(same)
    model = build_joint_model(inst)
    # one eligible pair of the same field for each telescope
    common = set(inst.parts[0].rows[inst.parts[0].pair_field]) & set(inst.parts[1].rows[inst.parts[1].pair_field])
    row = min(common)
    pairs = [int(np.flatnonzero(part.rows[part.pair_field] == row)[0]) for part in inst.parts]
    x = model.start_vector([[pairs[0]], [pairs[1]]])
    once = same[0].footprints.coverage([same[0].field_ids[row]], same[0].prob)
    assert model.milp.c @ x == pytest.approx(once, abs=1e-9)
    assert np.all(model.milp.A @ x <= model.milp.row_hi + 1e-9) and np.all(model.milp.A @ x >= model.milp.row_lo - 1e-9)
    # (J4) each telescope's rows and columns carry its name: an LP file names every row and column once
    from mushrooms.scheduler_core.schedulers.milp.rows import column_names, row_names

    names = row_names(model.milp.row_blocks)
    assert len(set(names)) == model.milp.n_rows and len(set(column_names(model.milp.col_families))) == model.milp.n_vars
    t0, t1 = inst.names
    assert t0 != t1
    assert {b.name for b in model.milp.row_blocks} == {f"{t0}: S1 one field per position", f"{t0}: S2 each field at most once",
                                                       f"{t1}: S1 one field per position", f"{t1}: S2 each field at most once",
                                                       "J2 coverage through any telescope"}
    # and the whole joint plan of the twins: the union counts each pixel once
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    res = joint_schedule(same)
    assert res.metrics.union <= res.bound.value
    both = _fields(res.schedules[0]) | _fields(res.schedules[1])
    assert res.metrics.union == pytest.approx(same[0].footprints.coverage(both, same[0].prob), abs=1e-9)
    assert res.metrics.union <= sum(res.metrics.share) + 1e-12
    assert res.metrics.more_than_once == pytest.approx(sum(res.metrics.share) - res.metrics.union, abs=1e-9)


def test_joint_coverage_is_at_least_the_best_telescope_alone(two_telescopes, joint_two):
    """(J6) The coordinated plan covers at least what the better telescope covers alone on its own budget."""
    alone = [_lone(p) for p in two_telescopes]
    covs = [p.footprints.coverage(_fields(r), p.prob) for p, r in zip(two_telescopes, alone)]
    assert min(covs) > 0  # both telescopes can observe the map that night
    assert joint_two.metrics.union >= max(covs) - 1e-12
    assert joint_two.metrics.union > max(covs)  # the second telescope adds something


def test_joint_coverage_is_at_least_the_iterative_tiling_in_either_order(two_telescopes, joint_two):
    """(J6) gwemopt's iterative tiling, A then B or B then A, is a first sweep of the ascent: never above it."""
    from mushrooms.scheduler_core.schedulers.joint.ascent import iterative_tiling, union_of

    prob = two_telescopes[0].prob
    for order in ([0, 1], [1, 0]):
        tiled = iterative_tiling([two_telescopes[i] for i in order], prob)
        assert joint_two.metrics.union >= union_of([two_telescopes[i] for i in order], tiled, prob) - 1e-12


def test_joint_bound_holds_and_is_below_the_sum_of_the_telescopes_bounds(two_telescopes, joint_two):
    """(J7, J8) union <= published joint bound <= min(sum of U4, total probability)."""
    bound = joint_two.bound
    u4 = sum(coverage_upper_bound(p).value for p in two_telescopes)
    assert joint_two.metrics.union <= bound.value
    assert bound.value <= u4 + 1e-12
    assert bound.value <= float(two_telescopes[0].prob.sum()) + 1e-12
    assert bound.value == pytest.approx(min(bound.joint, bound.sum_of_telescopes, bound.total), abs=1e-12)


def test_a_telescope_with_no_window_gets_an_empty_schedule_and_the_other_plans_alone(skymap):
    """(J6) One telescope sees nothing: its schedule is empty, the other's is its plan alone."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    a = prepare_problem(skymap, _config(), NIGHT, grid=_sub_grid(PRIMARY))
    blind = prepare_problem(skymap, _config(dec_min_deg=-20.0), NIGHT, grid=_sub_grid(UNREACHABLE))
    assert blind.field_ids.size == 0
    res = joint_schedule([a, blind])
    assert res.schedules[1].observations == ()
    alone = _lone(a)
    assert [(o.field_id, o.filter, o.start) for o in res.schedules[0].observations] == \
        [(o.field_id, o.filter, o.start) for o in alone.observations]
    assert res.metrics.share[1] == 0.0 and res.metrics.more_than_once == 0.0
    assert res.metrics.union <= res.bound.value


def test_each_telescopes_part_passes_the_single_telescope_plan_checks(two_telescopes, joint_two, skymap):
    """(J4) Each telescope's schedule obeys its own windows, overheads, filters and cadence (the plan checker)."""
    for problem, part in zip(two_telescopes, joint_two.schedules):
        assert part.observations
        plan = build_plan(problem, part, skymap, "slots")
        report = check_plan(plan, skymap, problem.config)
        assert report.ok, report.problems
        assert {o.filter for o in plan.observations} == set(problem.config.filters)
    # the metrics add up: each telescope's share, its own share, the part covered by both
    m = joint_two.metrics
    assert m.union == pytest.approx(sum(m.own) + m.more_than_once, abs=1e-9)


def test_problems_on_different_maps_or_resolutions_are_refused(two_telescopes, skymap):
    """A joint plan is of one map at one resolution: anything else is a clear ValueError, not a wrong plan."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    other = dataclasses.replace(two_telescopes[1], prob=np.roll(two_telescopes[1].prob, 7))
    with pytest.raises(ValueError, match="same sky map"):
        joint_schedule([two_telescopes[0], other])
    with pytest.raises(ValueError, match="at least one"):
        joint_schedule([])
    for bad in (np.ones(5), np.full(two_telescopes[0].prob.size, np.nan), -two_telescopes[0].prob):
        with pytest.raises(ValueError, match="weight"):
            joint_schedule(two_telescopes, weight=bad)


def test_a_one_visit_telescope_joins_the_plan_and_the_bound_still_holds(skymap):
    """(J3, J8) A telescope whose rule is one visit (one filter) is planned by greedy; the bound stays above the union."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    a = prepare_problem(skymap, _config(), NIGHT, grid=_sub_grid(PRIMARY))
    one = prepare_problem(skymap, _config(filters=("r",)), NIGHT, grid=_sub_grid(SECONDARY))
    res = joint_schedule([a, one])
    assert res.schedules[1].observations and {o.filter for o in res.schedules[1].observations} == {"r"}
    assert res.metrics.union <= res.bound.value <= res.bound.sum_of_telescopes + 1e-12
    plan = build_plan(one, res.schedules[1], skymap, "greedy")
    assert check_plan(plan, skymap, one.config).ok


def test_a_one_visit_telescopes_part_carries_its_own_bound(skymap):
    """(U5, U6 of milp.md) The one-visit part publishes U4 over one exposure a field (it published none before)."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    a = prepare_problem(skymap, _config(), NIGHT, grid=_sub_grid(PRIMARY))
    one = prepare_problem(skymap, _config(filters=("r",)), NIGHT, grid=_sub_grid(SECONDARY))
    res = joint_schedule([a, one])
    ub = res.schedules[1].upper_bound
    assert ub is not None and ub.method == "online"
    share = one.footprints.coverage({o.field_id for o in res.schedules[1].observations}, one.prob)
    assert 0 < share <= ub.value <= one.footprints.coverage(one.field_ids, one.prob) + 1e-9
    assert res.bound.per_telescope[1].value == ub.value


def test_make_joint_plans_gives_one_checked_plan_per_telescope(two_telescopes, skymap):
    """The planning layer: one plan per telescope, each through the checker, each under its own bound."""
    from mushrooms.scheduler_core.joint_plans import make_joint_plans

    plans, result = make_joint_plans(skymap, two_telescopes, names=("a", "b"))
    assert len(plans) == 2 and plans[0].plan_id != plans[1].plan_id
    for plan, share, problem in zip(plans, result.metrics.share, two_telescopes):
        assert plan.observations and plan.metrics.coverage == pytest.approx(share, abs=1e-6)  # the metrics as published
        assert plan.metrics.coverage <= plan.metrics.upper_bound
        assert check_plan(plan, skymap, problem.config).ok
    # the joint_plan document: each part as it is alone, the observations naming their telescope, the bound
    from mushrooms.scheduler_core.joint_plans import joint_document
    from mushrooms.scheduler_core.plan import strict_json
    from mushrooms.scheduler_core.plan.document import Plan

    doc = json.loads(strict_json.dumps(joint_document(plans, result)))
    assert doc["type"] == "joint_plan" and doc["telescopes"] == ["a", "b"]
    assert [part["plan_id"] for part in doc["plans"]] == [p.plan_id for p in plans]
    assert len(doc["observations"]) == sum(len(p.observations) for p in plans)
    assert [o["start"] for o in doc["observations"]] == sorted(o["start"] for o in doc["observations"])
    assert {o["telescope"] for o in doc["observations"]} == {"a", "b"}
    assert doc["metrics"]["union"] <= doc["metrics"]["upper_bound"]
    for part, problem in zip(doc["plans"], two_telescopes):
        again = Plan.from_document(part)
        assert "telescope" not in part["observations"][0]  # a part is the telescope's own plan document
        assert check_plan(again, skymap, problem.config).ok


def test_the_joint_plan_is_the_same_plan_run_again_on_the_work_budget(two_telescopes, joint_two):
    """(J6) Every stage on a work clock: the same inputs give the same plan (the load does not enter)."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    again = joint_schedule(two_telescopes)
    key = (lambda res: [[(o.field_id, o.filter, o.start) for o in s.observations] for s in res.schedules])
    assert key(again) == key(joint_two) and again.metrics == joint_two.metrics
    assert again.bound.value == joint_two.bound.value and again.details["spent_s"] == joint_two.details["spent_s"]


def test_the_joint_bound_holds_on_a_second_map_with_the_telescopes_competing_for_time():
    """(J7, J8) MS220722v from its merger time, 600 s and 480 s exposures (time binds): union <= bound <= sums."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    skymap = read_skymap(Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits",
                         nside=64)
    a = prepare_problem(skymap, _config(exposure_s=600.0), skymap.event_time, grid=_sub_grid(PRIMARY))
    b = prepare_problem(skymap, _config(filters=("r", "i"), cadence_s=2400.0, exposure_s=480.0), skymap.event_time,
                        grid=_sub_grid(SECONDARY))
    res = joint_schedule([a, b])
    assert res.metrics.union > 0
    assert res.metrics.union <= res.bound.value <= min(res.bound.sum_of_telescopes, res.bound.total) + 1e-12
    assert res.metrics.union >= max(union for union in (
        a.footprints.coverage(_fields(res.alone[0]), a.prob), b.footprints.coverage(_fields(res.alone[1]), b.prob)))


def test_what_is_done_weighs_nothing(two_telescopes):
    """(J5) Pixels an executed record covers weigh 0: a telescope whose every field is done plans nothing."""
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    a, b = two_telescopes
    weight = a.prob.copy()
    weight[b.footprints.union(b.field_ids)] = 0.0  # everything B could observe is done
    res = joint_schedule([a, b], weight=weight)
    assert res.schedules[1].observations == ()
    assert res.schedules[0].observations and res.bound.value <= float(weight.sum()) + 1e-9


def test_telescope_names_are_distinct():
    """Row and column names carry the telescope: two problems of one telescope are numbered, a repeat refused."""
    from types import SimpleNamespace

    from mushrooms.scheduler_core.schedulers.joint.cells import telescope_names

    assert telescope_names([SimpleNamespace(telescope="ztf"), SimpleNamespace(telescope="ls4")]) == ("ztf", "ls4")
    assert telescope_names([SimpleNamespace(telescope="ztf"), SimpleNamespace(telescope="ztf")]) == ("ztf0", "ztf1")
    assert telescope_names([SimpleNamespace(), SimpleNamespace()]) == ("t0", "t1")
    with pytest.raises(ValueError, match="distinct"):
        telescope_names([SimpleNamespace(), SimpleNamespace()], ["a", "a"])


def test_a_greedy_joint_plan_uses_no_milp_but_the_bound(two_telescopes):
    """``solver = "greedy"``: every step greedy's, no joint model; the plan still covers the best greedy plan alone."""
    from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
    from mushrooms.scheduler_core.schedulers.joint import joint_schedule

    res = joint_schedule(two_telescopes, greedy=True)
    assert {s.solver for s in res.schedules} == {"greedy"} and "joint_model" not in res.details
    best = max(p.footprints.coverage(_fields(greedy_schedule(p)), p.prob) for p in two_telescopes)
    assert best <= res.metrics.union <= res.bound.value
