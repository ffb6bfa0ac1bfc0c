"""A g-r-g re-plan whose next visits delay the rest of the plan keeps every field within its rules (F3, F9).

Real maps, real greedy, the real re-plan entry point and the real checker:
with a short pair separation (``pair_max_s``) the delay a third visit
makes room with stretches the fields it splits; what then breaks its
field's span, window or ``latest_s`` goes (F9) and the re-plan is one the
checker accepts with the executed record.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, read_skymap
from mushrooms.scheduler_core.executed import ExecutedExposure
from mushrooms.scheduler_core.plan.sequence_check import covered_by_record
from mushrooms.scheduler_core.replan import plan_remaining
from mushrooms.scheduler_core.sky.windows import Windows

from tests_paths import MAP_220722V

G483432 = Path("/work/shared/data/skymaps/public/G483432_bayestar.multiorder.fits")

NEW_MOON = Time("2022-07-28T02:00:00", scale="utc")  # the checker's hand-built plans
SPAN_S = 4000.0  # a g-r-g takes at least two cadences (3600 s): little room for a delay
GRG = PlanningConfig(solver="greedy", filters=("g", "r", "g"), exposure_s=180.0, pair_max_s=SPAN_S)


@pytest.fixture(scope="module", params=[MAP_220722V, G483432], ids=["MS220722v", "G483432"])
def grg(request):
    if not request.param.is_file():
        pytest.skip(f"{request.param} is not here")
    skymap = read_skymap(request.param, nside=GRG.nside)
    return skymap, make_plan(skymap, GRG)


def executed_of(plan, observations, status="processed"):
    return [ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s,
                             1.0 if status == "processed" else 0.0, status) for o in observations]


def first_two_visits(plan, block):
    """A block's g and r visits: the telescope stopped before its third (g) pass."""
    mine = [o for o in plan.observations if o.block == block]
    r0 = min(o.start for o in mine if o.filter == "r")
    return [o for o in mine if not (o.filter == "g" and o.start > r0)]


def assert_within_rules(replan, executed, config):
    """Every planned field: a continuation by its span's end, else a run of the sequence within the span."""
    done = {}
    for e in executed:
        done.setdefault(e.field_id, {}).setdefault(e.filter, []).append(float((e.start - replan.start).to_value("s")))
    covered = covered_by_record({f: {b: np.array(t) for b, t in per.items()} for f, per in done.items()},
                                config.filters, config.cadence_s, config.pair_separation_s)
    for fid in {o.field_id for o in replan.observations}:
        mine = sorted((o for o in replan.observations if o.field_id == fid), key=lambda o: o.start)
        first = covered[fid][0] if fid in covered else mine[0].start
        assert mine[-1].start - first <= config.pair_separation_s + 1e-3, fid
        assert all(b.start - a.start >= config.cadence_s - 1e-3 for a, b in zip(mine, mine[1:])), fid


@pytest.mark.parametrize("blocks", [(1,), (0, 1, 2)], ids=["clouds-over-the-first-block", "two-blocks-done"])
def test_a_replan_making_room_for_third_visits_stretches_no_field_past_its_span(grg, blocks):
    skymap, plan = grg
    *whole, half = blocks
    ran = [o for o in plan.observations if o.block in whole] + first_two_visits(plan, half)
    executed = executed_of(plan, ran)
    start = max(e.end for e in executed)
    replan = plan_remaining(skymap, GRG, start, executed)  # raised PlanCheckError when a shift stretched a field
    report = check_plan(replan, skymap, GRG, executed=executed)
    assert report.ok, report.problems
    assert_within_rules(replan, executed, GRG)
    # the third visits of the half-done block still go out, most of them
    thirds = {o.field_id for o in replan.observations} & {o.field_id for o in first_two_visits(plan, half)}
    assert len(thirds) >= len({o.field_id for o in first_two_visits(plan, half)}) // 2


@pytest.mark.parametrize("seed", range(12))
def test_every_replan_of_a_random_executed_subset_passes_the_checker(grg, seed):
    skymap, plan = grg
    rng = np.random.default_rng(seed)
    obs = sorted(plan.observations, key=lambda o: o.start)
    cut = int(rng.integers(2, len(obs)))
    kept = [o for o in obs[:cut] if rng.random() < 0.85]
    failed = [o for o in obs[:cut] if o not in kept and rng.random() < 0.5]
    executed = executed_of(plan, kept) + executed_of(plan, failed, status="failed")
    start = plan.absolute_time(obs[cut - 1].end)
    replan = plan_remaining(skymap, GRG, start, executed)
    report = check_plan(replan, skymap, GRG, executed=executed)
    assert report.ok, report.problems
    assert_within_rules(replan, executed_of(plan, kept), GRG)


def test_greedy_keeps_each_g_r_g_within_a_short_pair_separation():
    skymap = read_skymap(MAP_220722V, nside=GRG.nside)
    tight = dataclasses.replace(GRG, pair_max_s=3800.0)  # two cadences and a little: batches re-timed smaller
    plan = make_plan(skymap, tight)  # raised PlanCheckError when greedy's passes spread a field past it
    assert plan.observations
    assert_within_rules(plan, [], tight)


def test_a_pair_separation_too_short_for_the_sequence_is_refused_in_one_line():
    with pytest.raises(ValueError, match=r"pair_max_s \(3000 s\) must be 0 or hold the sequence g-r-g: at least 2 x"):
        dataclasses.replace(GRG, pair_max_s=3000.0)


# ----------------------------------------------------------------- F9 by hand

F687 = (687, 306.08789, 33.35)
F1685 = (1685, 307.14268, 29.75)
F700 = (700, 310.0, 30.0)


def exposure(field, filt, start):
    from mushrooms.scheduler_core.plan.document import Observation

    return Observation(field[0], field[1], field[2], filt, float(start), 180.0, 0)


def test_a_stretched_field_keeps_its_credited_first_two_visits_and_a_lone_first_visit_goes():
    from mushrooms.scheduler_core.schedulers.completions import trim_to_rules

    wide = Windows(np.array([687, 1685, 700]), np.zeros(3), np.full(3, 30000.0))
    stretched = [exposure(F1685, "g", 0), exposure(F1685, "r", 1900), exposure(F1685, "g", 4200)]
    # its last g is 4200 s after its first: beyond the 4000 s span; g and r a cadence apart stay (F1: credited)
    assert trim_to_rules(stretched, {}, wide, GRG) == stretched[:2]
    # its r left its window: a lone g is credited nothing, the field goes
    no_r = Windows(np.array([1685, 1685]), np.array([0.0, 3000.0]), np.array([1000.0, 30000.0]))
    assert trim_to_rules(stretched, {}, no_r, GRG) == []
    # a continuation's next visit past its latest start goes; by it, it stays
    third = [exposure(F687, "g", 2500)]
    assert trim_to_rules(third, {687: 2400.0}, wide, GRG) == []
    assert trim_to_rules(third, {687: 2500.0}, wide, GRG) == third
    # what still holds its rules is left as it is
    fine = [exposure(F700, "g", 0), exposure(F700, "r", 1900), exposure(F700, "g", 3800)]
    assert trim_to_rules(fine, {}, wide, GRG) == fine


def test_the_checker_takes_the_first_two_visits_of_a_new_field_only_in_a_replan(flat_map):
    from mushrooms.scheduler_core.plan.document import Plan

    def plan_of(observations):
        return Plan(plan_id="test", start=NEW_MOON, end=NEW_MOON + TimeDelta(24 * 3600, format="sec"),
                    observations=tuple(observations), metrics=None)

    cfg = dataclasses.replace(GRG, exposure_s=180.0, pair_max_s=0.0)
    t = 6 * 3600.0
    cut = [exposure(F687, "g", t), exposure(F687, "r", t + 1900)]
    lone = [exposure(F687, "g", t)]
    other = [ExecutedExposure(1685, "g", NEW_MOON + TimeDelta(t - 4000, format="sec"), 180.0, 1.0,
                              "processed")]
    assert not check_plan(plan_of(cut), flat_map, cfg).ok  # a plan of its own plans the whole sequence (F6)
    assert check_plan(plan_of(cut), flat_map, cfg, executed=other).ok
    report = check_plan(plan_of(lone), flat_map, cfg, executed=other)
    assert report.counts == {"cadence": 1} and "nor its first two visits" in report.problems[0]
