"""Filter sequences (docs/design/sequences.md, F0-F5, F6-F8): config, credit, greedy, checker, refusals.

The checker cases are hand-built plans at the zenith on a dark night (the
checker tests' control, with a third visit); the credit cases are worked
out by hand in minutes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, prepare_problem
from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.executed import ExecutedExposure
from mushrooms.scheduler_core.plan.document import Observation, Plan
from mushrooms.scheduler_core.sequences import covered_fields, sequence_progress
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

NEW_MOON = Time("2022-07-28T02:00:00", scale="utc")
T0 = 6 * 3600.0  # 08:00 UTC, the middle of the night
F687 = (687, 306.08789, 33.35)  # near the zenith at T0
F1685 = (1685, 307.14268, 29.75)
GRG = PlanningConfig(filters=("g", "r", "g"))


def obs(f, filt, start):
    return Observation(field_id=f[0], ra=f[1], dec=f[2], filter=filt, start=float(start), exposure_s=300.0, block=0)


def plan_of(observations):
    return Plan(plan_id="test", start=NEW_MOON, end=NEW_MOON + TimeDelta(24 * 3600, format="sec"),
                observations=tuple(sorted(observations, key=lambda o: o.start)), metrics=None)


def grg_control():
    """Two fields, g then r then g, each visit 1860 s after the one before; every gap >= its overhead."""
    return [obs(F687, "g", T0), obs(F1685, "g", T0 + 360), obs(F687, "r", T0 + 1860), obs(F1685, "r", T0 + 2220),
            obs(F687, "g", T0 + 3720), obs(F1685, "g", T0 + 4080)]


def done(field, filt, seconds):
    """An executed exposure ``seconds`` after the plans' start."""
    return ExecutedExposure(field[0], filt, NEW_MOON + TimeDelta(seconds, format="sec"), 300.0, 1.0, "processed")


def minutes(field_id, *visits):
    t0 = Time("2026-05-01T04:00:00", scale="utc")
    return [ExecutedExposure(field_id, f, t0 + TimeDelta(m * 60, format="sec"), 180.0, 1.0, "processed")
            for f, m in visits]


# ----------------------------------------------------------------- F0: the setting

@pytest.mark.parametrize("filters", [("g", "r", "g"), ("r", "g", "r"), ("g",), ("g", "r", "i", "r")])
def test_a_sequence_of_changing_ztf_filters_is_accepted(filters):
    assert PlanningConfig(filters=filters).filters == filters


@pytest.mark.parametrize("filters, words", [
    (("g", "g"), "visit 2 repeats"), ((), "1 to 8 visits"), (("g", "r") * 5, "1 to 8 visits"),
    (("g", "z"), "ZTF filters"), ("gr", "a list of ZTF filters")])
def test_a_bad_sequence_is_refused_in_one_line(filters, words):
    with pytest.raises(ValueError, match=words):
        PlanningConfig(filters=filters)


def test_the_exposure_menu_needs_a_pair():
    with pytest.raises(ValueError, match="exposure_menu_s needs a pair"):
        PlanningConfig(filters=("g", "r", "g"), exposure_menu_s=(180.0, 300.0))


# ----------------------------------------------------------------- F1, F2: credit worked by hand

def test_g_then_r_a_cadence_apart_covers_and_leaves_the_third_visit():
    record = minutes(700, ("g", 0), ("r", 35), ("g", 45))  # the g at 45 min is only 10 min after the r
    assert covered_fields(record, ("g", "r", "g"), cadence_s=1800.0) == {700}
    p = sequence_progress(record, ("g", "r", "g"), cadence_s=1800.0)[700]
    assert p.done == 2 and p.last.isot == "2026-05-01T04:35:00.000" and p.first.isot == "2026-05-01T04:00:00.000"


def test_a_third_visit_a_cadence_after_the_second_completes_the_sequence():
    p = sequence_progress(minutes(700, ("g", 0), ("r", 35), ("g", 70)), ("g", "r", "g"), cadence_s=1800.0)[700]
    assert p.done == 3 and p.last.isot == "2026-05-01T05:10:00.000"


def test_a_sequence_cut_after_its_first_visit_or_too_close_is_not_credited():
    assert covered_fields(minutes(700, ("g", 0)), ("g", "r", "g"), cadence_s=1800.0) == set()
    assert covered_fields(minutes(700, ("g", 0), ("r", 20)), ("g", "r", "g"), cadence_s=1800.0) == set()
    assert sequence_progress(minutes(700, ("g", 0), ("r", 20)), ("g", "r", "g"), cadence_s=1800.0) == {}


def test_the_covering_pair_may_come_in_either_order():
    p = sequence_progress(minutes(700, ("r", 0), ("g", 40)), ("g", "r", "g"), cadence_s=1800.0)[700]
    assert p.done == 2 and p.last.isot == "2026-05-01T04:40:00.000"


def test_a_one_filter_sequence_is_covered_by_one_visit():
    assert covered_fields(minutes(700, ("r", 0)) + minutes(701, ("g", 0)), ("g",)) == {701}


# ----------------------------------------------------------------- F6-F8: the checker by hand

def test_the_hand_built_grg_plan_passes_and_is_refused_as_a_pair(flat_map):
    assert check_plan(plan_of(grg_control()), flat_map, GRG).ok
    # the pair's checker sees two g exposures of each field: the third is no part of a g-r pair rule,
    # but the same plan under r-g-r is out of sequence for both fields
    report = check_plan(plan_of(grg_control()), flat_map, PlanningConfig(filters=("r", "g", "r")))
    assert report.counts == {"cadence": 2}
    assert "field 687 is observed in g-r-g, not the sequence r-g-r" in report.problems[0]


def test_a_third_visit_short_of_the_cadence_or_missing_is_refused(flat_map):
    o = grg_control()
    o[4] = dataclasses.replace(o[4], start=T0 + 1860 + 1799)
    report = check_plan(plan_of(o), flat_map, GRG)
    assert report.counts == {"cadence": 1} and "687: r and g only 1799 s apart" in report.problems[0]
    o[4] = dataclasses.replace(o[4], start=T0 + 1860 + 1800)
    assert check_plan(plan_of(o), flat_map, GRG).ok
    report = check_plan(plan_of(grg_control()[:4] + grg_control()[5:]), flat_map, GRG)
    # (F10) cut short though its window holds the third visit
    assert len(report.problems) == 1
    assert report.problems[0].startswith("cadence: field 687 stops short of the sequence g-r-g, though its next visit (g)")


def test_a_covered_field_may_get_its_third_visit_only_a_cadence_after_its_second(flat_map):
    executed = [done(F687, "g", T0 - 4000), done(F687, "r", T0 - 2140)]  # 1860 s apart: covered
    third = [obs(F687, "g", T0 - 2140 + 1800)]
    assert check_plan(plan_of(third), flat_map, GRG, executed=executed).ok
    early = [obs(F687, "g", T0 - 2140 + 1700)]
    report = check_plan(plan_of(early), flat_map, GRG, executed=executed)
    assert report.counts == {"repeat": 1} and "does not follow its executed visits" in report.problems[0]
    again = [obs(F687, "r", T0), obs(F687, "g", T0 + 1860)]  # r-g after g-r: not a continuation
    report = check_plan(plan_of(again), flat_map, GRG, executed=executed)
    assert report.counts == {"repeat": 1} and "not a continuation of g-r-g" in report.problems[0]


def test_a_complete_field_planned_again_is_a_repeat(flat_map):
    executed = [done(F687, "g", T0 - 6000), done(F687, "r", T0 - 4140), done(F687, "g", T0 - 2280)]
    report = check_plan(plan_of([obs(F687, "g", T0)]), flat_map, GRG, executed=executed)
    assert report.counts == {"repeat": 1}


def test_a_field_done_in_one_filter_is_planned_anew_in_the_whole_sequence(flat_map):
    executed = [done(F687, "g", T0 - 4000)]
    whole = [o for o in grg_control() if o.field_id == 687]
    assert check_plan(plan_of(whole), flat_map, GRG, executed=executed).ok
    report = check_plan(plan_of(whole[1:]), flat_map, GRG, executed=executed)
    assert report.counts == {"cadence": 1}


# ----------------------------------------------------------------- F4: greedy plans it, the pair's MILPs refuse it

@pytest.fixture(scope="module")
def grg_plan(skymap_220722v):
    return make_plan(skymap_220722v, PlanningConfig(solver="greedy", filters=("g", "r", "g"), exposure_s=180.0))


def test_greedy_visits_every_field_g_r_g_each_a_cadence_after_the_last(grg_plan, skymap_220722v):
    by_field: dict[int, list[Observation]] = {}
    for o in grg_plan.observations:
        by_field.setdefault(o.field_id, []).append(o)
    assert by_field and grg_plan.metrics.n_exposures == sum(len(v) for v in by_field.values())
    for visits in by_field.values():
        visits.sort(key=lambda o: o.start)
        # the whole sequence, or (F10) cut where no window holds the third visit (the checker's F10, below)
        assert [o.filter for o in visits] in (["g", "r", "g"], ["g", "r"])
        assert all(b.start - a.start >= 1800.0 - 1e-6 for a, b in zip(visits, visits[1:]))
        assert len({o.block for o in visits}) == 1
    assert sum(len(v) == 3 for v in by_field.values()) > len(by_field) / 2
    cfg = PlanningConfig(filters=("g", "r", "g"), exposure_s=180.0)
    assert check_plan(grg_plan, skymap_220722v, cfg).ok


def test_a_grg_plan_covers_less_than_the_pair_in_the_same_night(grg_plan, skymap_220722v):
    """Its whole sequences do: the sequences F10 cut at the night's end cover as pairs."""
    pair = make_plan(skymap_220722v, PlanningConfig(solver="greedy", exposure_s=180.0))
    visits: dict[int, int] = {}
    for o in grg_plan.observations:
        visits[o.field_id] = visits.get(o.field_id, 0) + 1
    footprints = field_footprints(load_ztf_fields(), skymap_220722v.nside)
    whole = footprints.coverage([f for f, n in visits.items() if n == 3], skymap_220722v.prob)
    assert 0 < whole < pair.metrics.coverage
    assert grg_plan.metrics.upper_bound is None or grg_plan.metrics.coverage <= grg_plan.metrics.upper_bound


def test_the_pair_schedulers_refuse_a_sequence_and_the_hybrid_skips_them(skymap_220722v):
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.blocks.schedule import milp_schedule

    cfg = PlanningConfig(filters=("g", "r", "g"), time_limit_s=5.0, bound_time_limit_s=0.0, objective="coverage")
    problem = prepare_problem(skymap_220722v, cfg, skymap_220722v.event_time)
    with pytest.raises(InputError, match="the block MILP plans each field in two filters"):
        milp_schedule(problem)
    result = run_scheduler(problem, "hybrid")
    assert result.details["skipped_for_sequence"] == ["slots_paced", "lns"]  # blocks: off (hybrid_blocks)
    assert [e.name for e in result.portfolio][0] == "greedy"
    with pytest.raises(InputError, match="block MILP"):
        run_scheduler(problem, "blocks")


def test_one_filter_plans_one_visit_per_field_and_publishes_its_own_bound(skymap_220722v):
    plan = make_plan(skymap_220722v, PlanningConfig(filters=("r",), solver="hybrid", time_limit_s=4.0,
                                                    objective="coverage"))
    assert {o.filter for o in plan.observations} == {"r"}
    assert len(plan.field_ids) == plan.metrics.n_exposures
    # (U5, U6, V8 of milp.md) one exposure a field: a bound of its own (there was none before)
    assert plan.metrics.coverage <= plan.metrics.upper_bound <= 1.0


# ----------------------------------------------------------------- F3: room for a next visit

def test_a_next_visit_is_put_in_front_of_the_plan_and_what_follows_it_moves_by_one_delay():
    from mushrooms.scheduler_core.schedulers.completions import PendingVisit, shift_in_completions
    from mushrooms.scheduler_core.telescope.slew import overhead_time
    from mushrooms.scheduler_core.sky.windows import Windows

    cfg = PlanningConfig(exposure_s=300.0)
    plan = [obs(F1685, "g", 1000.0), obs(F1685, "r", 2900.0)]
    v = PendingVisit(687, F687[1], F687[2], "g", due_s=900.0, worth=0.01)
    wide = Windows(np.array([687, 1685]), np.array([0.0, 0.0]), np.array([20000.0, 20000.0]))
    placed, left = shift_in_completions(plan, [v], wide, cfg)
    # by hand: the visit at its due time 900 s; the next exposure then needs 900 + 300 + o(687 -> 1685)
    o = float(overhead_time(F687[1], F687[2], F1685[1], F1685[2], cfg.slew, 0.0))
    delay = 900.0 + 300.0 + o - 1000.0
    assert left == () and [(x.field_id, x.filter) for x in placed] == [(687, "g"), (1685, "g"), (1685, "r")]
    assert placed[0].start == 900.0
    assert [x.start for x in placed[1:]] == pytest.approx([1000.0 + delay, 2900.0 + delay])
    # a field one of whose moved exposures leaves its window is dropped, all of it
    tight = Windows(np.array([687, 1685]), np.array([0.0, 0.0]), np.array([20000.0, 3200.0 + delay / 2]))
    placed, left = shift_in_completions(plan, [v], tight, cfg)
    assert left == () and [(x.field_id, x.start) for x in placed] == [(687, 900.0)]
    # a visit that adds coverage (no worth) is not this function's: it comes back
    pair = dataclasses.replace(v, worth=None)
    assert shift_in_completions(plan, [pair], wide, cfg) == (tuple(plan), (pair,))


def test_the_skyportal_payload_names_the_sequence(grg_plan):
    from mushrooms.scheduler_core.plan.exports import ExportConfig, to_skyportal

    body = to_skyportal(grg_plan, ExportConfig(skyportal_allocation_id=7))
    assert body["payload"]["filters"] == "g,r,g"
    assert [p["filt"] for p in body["observation_plans"][0]["planned_observations"]][:1] == ["ztfg"]


def test_the_config_file_takes_a_sequence_and_refuses_a_repeat(tmp_path):
    from mushrooms.tool.config import load_config

    good = tmp_path / "grg.toml"
    good.write_text('[scheduler]\nfilters = ["r", "g", "r"]\n')
    assert load_config(str(good)).scheduler.filters == ("r", "g", "r")
    bad = tmp_path / "gg.toml"
    bad.write_text('[scheduler]\nfilters = ["g", "g", "r"]\n')
    with pytest.raises(Exception, match="visit 2 repeats the one before it"):
        load_config(str(bad))


def test_a_cut_whose_next_visit_fits_only_within_the_checkers_tolerance_is_accepted(flat_map):
    """(F10) the checker asks whether the next visit was clearly observable: by its tolerances, not within them.

    Seen on o4real 93d1ca04c7f14645/0 (g-r-g, greedy): a field's window ended as the Moon came within 20 deg;
    the planner cut its sequence there, and the checker, allowing 0.1 deg, found a next visit 'possible'
    for 20 more minutes and refused the plan. Here with the airmass: the largest allowed sits 0.005 below
    the airmass at the end of the earliest next visit (widened by a time step), inside the 0.01 tolerance.
    """
    from mushrooms.scheduler_core.plan.check_geometry import P48_SITE, conditions

    cut = grg_control()[:4] + grg_control()[5:]  # F687 stops after g and r
    end = T0 + 1860 + 1800 + 300 + GRG.time_step_s
    airmass = float(conditions(NEW_MOON, np.array([end]), np.array([F687[1]]), np.array([F687[2]]), P48_SITE).airmass[0])
    assert 1.0 < airmass < 1.5
    edge = dataclasses.replace(GRG, airmass_max=airmass - 0.005)
    assert check_plan(plan_of(cut), flat_map, edge).ok
    clear = dataclasses.replace(GRG, airmass_max=airmass + 0.03)  # clearly observable: the cut is refused
    assert any("(F10)" in p for p in check_plan(plan_of(cut), flat_map, clear).problems)
