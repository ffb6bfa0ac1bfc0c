"""The following nights (docs/design/replan.md N1-N3): validity windows at twilight, later nights on the earlier ones."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, EarthLocation, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan
from mushrooms.scheduler_core.executed import done_pairs
from mushrooms.scheduler_core.nights import as_planned, plan_nights
from mushrooms.scheduler_core.plan.checker import P48_SITE
from mushrooms.scheduler_core.sky.twilight import NIGHT_GRID_S, night_windows

CFG = PlanningConfig(solver="greedy", nights=2)


def sun_alt(times: Time) -> np.ndarray:
    """The Sun's altitude (deg) at the P48, from the checker's own site (not the planner's)."""
    lat, lon, height = P48_SITE
    here = EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)
    return get_body("sun", times, here).transform_to(AltAz(obstime=times, location=here)).alt.deg


@pytest.mark.parametrize("start", ["2022-07-22T20:00:00", "2026-01-10T18:30:00"])
def test_night_windows_run_from_evening_to_morning_twilight(start):
    windows = night_windows(Time(start, scale="utc"), CFG, 3)
    assert len(windows) == 3
    ends = []
    for evening, morning in windows:
        hours = (morning - evening).to_value("h")
        assert 6.0 < hours < 14.0  # a Palomar night between the solstices
        inside = evening + TimeDelta(np.linspace(0, (morning - evening).to_value("s"), 50), format="sec")
        assert (sun_alt(inside) <= CFG.sun_alt_max_deg + 0.01).all()
        outside = Time([evening - TimeDelta(2 * NIGHT_GRID_S, format="sec"),
                        morning + TimeDelta(2 * NIGHT_GRID_S, format="sec")])
        assert (sun_alt(outside) > CFG.sun_alt_max_deg).all()  # the twilights to within the grid
        ends.append((evening, morning))
    for (_, m1), (e2, _) in zip(ends, ends[1:]):
        assert 8.0 < (e2 - m1).to_value("h") < 18.0  # one day between, no night skipped


def test_a_night_under_way_starts_at_the_start_and_a_darker_sun_limit_shortens_the_night():
    start = Time("2022-07-23T08:00:00", scale="utc")
    (evening, morning), = night_windows(start, CFG, 1)
    assert 0 <= (evening - start).to_value("s") < NIGHT_GRID_S
    (e18, m18), = night_windows(start - TimeDelta(6 * 3600, format="sec"),
                                dataclasses.replace(CFG, sun_alt_max_deg=-18.0), 1)
    (e12, m12), = night_windows(start - TimeDelta(6 * 3600, format="sec"), CFG, 1)
    assert e18 > e12 and m18 < m12


@pytest.fixture(scope="module")
def two_nights(skymap_220722v):
    return plan_nights(skymap_220722v, CFG)


def test_each_night_has_its_own_plan_within_its_twilights(two_nights, skymap_220722v):
    windows = night_windows(skymap_220722v.event_time, CFG, 2)
    assert len(two_nights) == 2
    for plan, (evening, morning) in zip(two_nights, windows):
        assert abs((plan.start - evening).to_value("s")) < 1e-3 and abs((plan.end - morning).to_value("s")) < 1e-3
        horizon = (plan.end - plan.start).to_value("s")
        assert all(0 <= o.start and o.end <= horizon + 1e-6 for o in plan.observations)
        assert plan.config["horizon_h"] == pytest.approx(horizon / 3600.0)
    assert two_nights[0].plan_id != two_nights[1].plan_id


def test_the_second_night_is_planned_on_what_the_first_achieved(two_nights, skymap_220722v):
    first, second = two_nights
    assert first.observations  # this map is observable on the first night
    before = as_planned(first)
    night2_cfg = PlanningConfig.from_mapping(second.config)
    report = check_plan(second, skymap_220722v, night2_cfg, executed=before)
    assert report.ok, report.problems
    pairs = done_pairs(before, CFG.filters, cadence_s=CFG.cadence_s)
    assert set(pairs.both) == set(first.field_ids)
    assert not set(second.field_ids) & set(first.field_ids)  # (N3) no field of night 1 again
    assert second.metrics.coverage_executed == pytest.approx(first.metrics.coverage, abs=1e-5)


def test_revisit_counts_only_the_night_s_own_exposures():
    # (N4) the pure rule both plan_nights and the daemon's night re-plans apply
    from mushrooms.scheduler_core.executed import ExecutedExposure
    from mushrooms.scheduler_core.nights import counted_for_night

    evening = Time("2022-07-23T04:00:00", scale="utc")
    earlier = ExecutedExposure(818, "g", evening - TimeDelta(20 * 3600, format="sec"), 300.0, 1.0, "processed")
    tonight = ExecutedExposure(818, "r", evening + TimeDelta(600, format="sec"), 300.0, 1.0, "processed")
    assert counted_for_night([earlier, tonight], evening, revisit=False) == [earlier, tonight]  # (N2)
    assert counted_for_night([earlier, tonight], evening, revisit=True) == [tonight]


def test_revisit_plans_the_second_night_on_the_whole_map_again(two_nights, skymap_220722v):
    first, second = two_nights
    again = plan_nights(skymap_220722v, dataclasses.replace(CFG, revisit=True))
    assert again[0].observations == first.observations  # night 1 the same plan
    night2 = again[1]
    report = check_plan(night2, skymap_220722v, PlanningConfig.from_mapping(night2.config))
    assert report.ok, report.problems  # a whole plan on its own: nothing of night 1 counted
    assert night2.config["revisit"] is True and "revisit" not in second.config
    assert set(night2.field_ids) & set(first.field_ids)  # (N4) night 1's fields observed again
    assert night2.metrics.coverage > second.metrics.coverage  # it covers anew what night 1 had covered
    assert not night2.metrics.coverage_executed  # nothing counted as done before the night


def test_revisit_false_keeps_plan_ids():
    # revisit is recorded only when true: the documents (and plan ids) of other plans do not change
    assert "revisit" not in PlanningConfig().record()
    assert PlanningConfig(revisit=True).record()["revisit"] is True


def astropy_night(start: Time, sun_limit_deg: float) -> tuple[Time, Time]:
    """The first night's window from astropy's Sun at every step of the same grid (the twilights' old way)."""
    from mushrooms.scheduler_core.sky.visibility import GRID_ANCHOR, NIGHT_S

    t0 = float((start - GRID_ANCHOR).to_value("s"))
    block = int(np.floor(t0 / NIGHT_S))
    for b in (block, block + 1):
        offsets = np.arange(b * NIGHT_S, (b + 1) * NIGHT_S, NIGHT_GRID_S)
        offsets = offsets[offsets >= t0 - 1e-6]
        times = GRID_ANCHOR + TimeDelta(offsets, format="sec")
        dark = np.flatnonzero(sun_alt(times) <= sun_limit_deg) if offsets.size else []
        if len(dark):
            return times[dark[0]], times[dark[-1]]
    raise AssertionError("no night")


@pytest.mark.parametrize("limit", [-12.0, -18.0])
def test_twilights_from_the_ephemeris_are_astropy_s_to_within_one_grid_step(limit):
    config = dataclasses.replace(CFG, sun_alt_max_deg=limit)
    moved = 0
    for day in range(0, 365, 23):  # the year round: short and long nights, both twilights
        start = Time("2026-01-03T18:00:00", scale="utc") + TimeDelta(day * 86400.0, format="sec")
        (evening, morning), = night_windows(start, config, 1)
        old_evening, old_morning = astropy_night(start, limit)
        for new, old in ((evening, old_evening), (morning, old_morning)):
            step = abs(float((new - old).to_value("s")))
            assert step <= NIGHT_GRID_S + 1e-3
            moved += step > 1e-3
    assert moved <= 4  # most twilights do not move at all
