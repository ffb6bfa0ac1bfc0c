"""The completion steps of a re-plan (docs/design/replan.md P3-P7) on small hand-made fields."""

from __future__ import annotations

import numpy as np
import pytest

from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.plan.document import Observation
from mushrooms.scheduler_core.schedulers.completions import (
    PendingVisit, completion_pass, drop_repeats, insert_completions, swap_in_completions,
)
from mushrooms.scheduler_core.telescope.slew import overhead_time
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.windows import Windows

CFG = PlanningConfig(nside=1, horizon_h=2.0, exposure_s=100.0, slew_estimate_s=10.0, filter_change_s=30.0,
                     cadence_s=600.0, min_gain=0.01)
#: fields 1-5 on the equator, 5 deg apart; pixels (nside 1) 0..11
IDS = np.arange(1, 6)
MEMBERS = [[0], [1], [2], [3], [4]]
FOOTPRINTS = Footprints(1, IDS, np.arange(6), np.arange(5))
PROB = np.array([0.3, 0.2, 0.4, 0.05, 0.005] + [0.045 / 7] * 7)


def visit(fid, filt="r", due=0.0):
    return PendingVisit(fid, 5.0 * (fid - 1), 0.0, filt, due)


def open_windows(ids=IDS, start=0.0, end=7200.0):
    ids = np.asarray(ids)
    return Windows(ids, np.full(ids.size, start), np.full(ids.size, end))


def test_the_pass_takes_what_is_due_by_gain_keeping_the_filter_and_leaves_the_rest():
    visits = [visit(1, "r"), visit(2, "g"), visit(3, "r", due=5000.0), visit(4, "r"), visit(5, "r")]
    obs, left, uncovered = completion_pass(visits, FOOTPRINTS, PROB, open_windows(), CFG)
    # r holds more gain at the start (0.3 + 0.05 of fields 1 and 4), so r first, then the filter change to g
    assert [(o.field_id, o.filter) for o in obs] == [(1, "r"), (4, "r"), (2, "g")]
    assert obs[0].start == 0.0
    for a, b in zip(obs, obs[1:]):
        need = overhead_time(a.ra, a.dec, b.ra, b.dec, CFG.slew, CFG.filter_change_s if a.filter != b.filter else 0.0)
        assert b.start == pytest.approx(a.end + float(need))
    # field 3 is not due (it is left, still worth it); field 5 adds less than min_gain (dropped)
    assert [v.field_id for v in left] == [3]
    assert uncovered[[0, 1, 3]].sum() == 0 and uncovered[2] == PROB[2]


def test_the_pass_waits_at_most_one_exposure_for_a_window():
    near = Windows(np.array([1]), np.array([60.0]), np.array([7200.0]))
    obs, _, _ = completion_pass([visit(1)], FOOTPRINTS, PROB, near, CFG)
    assert [o.start for o in obs] == [60.0]
    far = Windows(np.array([1]), np.array([600.0]), np.array([7200.0]))
    obs, left, _ = completion_pass([visit(1)], FOOTPRINTS, PROB, far, CFG)
    assert obs == () and [v.field_id for v in left] == [1]


def pair(fid, t1, t2, block=0):
    ra = 5.0 * (fid - 1)
    return [Observation(fid, ra, 0.0, "g", t1, 100.0, block), Observation(fid, ra, 0.0, "r", t2, 100.0, block)]


def test_a_visit_not_due_goes_into_the_first_gap_at_or_after_its_due_time():
    plan = pair(1, 0.0, 700.0) + pair(2, 2000.0, 2700.0)  # gaps 100-700, 800-2000, 2100-2700
    obs, left = insert_completions(plan, [visit(3, "r", due=900.0)], FOOTPRINTS, PROB, open_windows(), CFG)
    assert left == ()
    new = [o for o in obs if o.field_id == 3]
    assert len(new) == 1 and new[0].start >= 900.0 and new[0].filter == "r"
    i = obs.index(new[0])
    assert obs[i - 1].end <= new[0].start and new[0].end <= obs[i + 1].start
    assert [o.start for o in obs] == sorted(o.start for o in obs)


def test_a_visit_with_no_gap_takes_the_place_of_a_field_adding_less_or_is_left():
    tight = sorted(pair(4, 0.0, 240.0) + pair(5, 110.0, 350.0), key=lambda o: o.start)  # no 100 s gap before 450 s
    config = PlanningConfig(nside=1, horizon_h=0.125, exposure_s=100.0, slew_estimate_s=10.0, filter_change_s=20.0,
                            cadence_s=100.0, min_gain=0.01)
    obs, left = insert_completions(tight, [visit(3, "r", due=100.0)], FOOTPRINTS, PROB, open_windows(), config)
    assert [v.field_id for v in left] == [3]
    obs, left = swap_in_completions(tight, left, FOOTPRINTS, PROB, open_windows(), config)
    assert left == ()
    assert {o.field_id for o in obs} == {3, 4}  # field 5 (0.005) gave way to field 3 (0.4), field 4 stays
    # a visit adding less than every planned field takes nobody's place
    obs, left = swap_in_completions(tight, [visit(5, "r", due=100.0)], FOOTPRINTS, PROB, open_windows(), config)
    assert [v.field_id for v in left] == [5] and obs == tuple(tight)


def test_a_half_done_field_planned_as_a_whole_pair_loses_its_repeat_only_when_the_other_filter_is_due():
    plan = pair(1, 0.0, 700.0) + pair(2, 100.0, 800.0)
    obs, fields = drop_repeats(plan, [visit(1, "r", due=600.0), visit(2, "r", due=900.0)])
    assert fields == (1,)
    assert [(o.field_id, o.filter) for o in obs] == [(1, "r"), (2, "g"), (2, "r")]
