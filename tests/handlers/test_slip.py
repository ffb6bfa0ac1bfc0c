"""The loop's re-plan rule (``docs/design/executed.md`` L3-L5) on small plan documents."""

from __future__ import annotations

from astropy.time import Time, TimeDelta

from mushrooms.handlers.slip import slip_of
from mushrooms.scheduler_core.executed import ExecutedExposure

T0 = Time("2025-05-14T04:00:00", scale="utc")


def at(s: float) -> Time:
    return T0 + TimeDelta(s, format="sec")


def iso(s: float) -> str:
    return at(s).isot + "Z"


#: Three fields: 600 and 601 in g, then in r a cadence later; 602 in g last. One exposure = 300 s.
PLAN = {"type": "plan", "start": iso(-600), "end": iso(86400), "observations": [
    {"field_id": 600, "filter": "g", "start": iso(0)}, {"field_id": 601, "filter": "g", "start": iso(310)},
    {"field_id": 600, "filter": "r", "start": iso(1900)}, {"field_id": 601, "filter": "r", "start": iso(2210)},
    {"field_id": 602, "filter": "g", "start": iso(2520)}]}


def done(field_id: int, filt: str, s: float, fraction: float = 1.0, status: str = "processed") -> ExecutedExposure:
    return ExecutedExposure(field_id, filt, at(s), 300.0, fraction, status)


def test_on_time_when_every_observation_due_was_executed_late_by_less_than_the_limit():
    record = [done(600, "g", 40), done(601, "g", 350)]
    slip = slip_of(PLAN, record, at(1900 + 600), max_slip_s=900)
    assert not slip.replan and slip.executed == 2 and slip.planned == 5 and round(slip.slip_s) == 600


def test_slipped_when_the_first_observation_not_executed_is_later_than_max_slip_s():
    record = [done(600, "g", 40), done(601, "g", 350)]
    slip = slip_of(PLAN, record, at(1900 + 901), max_slip_s=900)
    assert slip.replan and "slipped by 901 s" in slip.reason and slip.executed == 2


def test_a_list_queue_running_out_of_order_matches_by_field_and_filter():
    # the queue took 601 g before 600 g: both planned observations are executed (L3 pairs by field and filter)
    record = [done(601, "g", 0), done(600, "g", 310)]
    assert slip_of(PLAN, record, at(1800), max_slip_s=900).executed == 2


def test_a_failed_exposure_re_plans_until_a_later_one_of_the_pair_is_done():
    failed = done(600, "g", 0, fraction=0.0, status="failed")
    slip = slip_of(PLAN, [failed], at(400), max_slip_s=900)
    assert slip.replan and slip.failed == (failed,) and "1 exposure(s) failed" in slip.reason
    made_up = slip_of(PLAN, [failed, done(600, "g", 620), done(601, "g", 930)], at(1300), max_slip_s=900)
    assert not made_up.replan and made_up.failed == ()
    # partial below the done rule counts as a failure of the pair; above it, as done
    assert slip_of(PLAN, [done(600, "g", 0, fraction=0.3)], at(400), 900).replan
    assert not slip_of(PLAN, [done(600, "g", 0, fraction=0.6)], at(400), 900).replan


def test_exposures_outside_the_plan_or_before_its_start_do_not_count():
    record = [done(600, "g", -7200), done(700, "g", 0, fraction=0.0, status="failed")]
    slip = slip_of(PLAN, record, at(200), max_slip_s=900)
    assert not slip.replan and slip.executed == 0


def test_a_plan_whose_window_ended_or_that_plans_nothing_never_re_plans():
    assert not slip_of(PLAN, [], at(86401), max_slip_s=0).replan
    assert not slip_of({"type": "not_observable", "start": iso(0), "end": iso(10)}, [], at(5), 0).replan
