"""The telescope model's queue executor (Q1-Q10) against hand-worked cases on a real night at Palomar.

Epoch 2026-03-20 06:00 UTC: the Sun is 47 deg down, the local sidereal
time about 150.9 deg.  Fields on the meridian are up; a field 66 deg east
of it at Dec 0 rises through airmass 2.5 some 20 min later.  Rise times and
the Sun's altitude are found here independently with astropy's AltAz.
"""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core.executed import done_pairs
from mushrooms.scheduler_core.sky.visibility import site
from mushrooms.scheduler_core.telescope import TelescopeTiming, execute_queues, queue_set_from_payloads
from mushrooms.scheduler_core.telescope.executor import executed_exposures
from mushrooms.scheduler_core.telescope.rules import FIRST_WINS_RULES
from palomar_queues import EPOCH, LST, NIGHT_S, TIMING, UP_A, UP_B, queue, run, target



def rise_s(ra, dec, max_airmass=2.5):
    """First second after the epoch (10 s grid) with airmass below ``max_airmass``, from astropy."""
    times = EPOCH + TimeDelta(np.arange(0, NIGHT_S, 10.0), format="sec")
    alt = SkyCoord(ra * u.deg, dec * u.deg).transform_to(AltAz(obstime=times, location=site())).alt.deg
    up = np.flatnonzero(1.0 / np.sin(np.radians(np.maximum(alt, 1e-3))) < max_airmass)
    return float(up[0] * 10.0)


RISING = target(103, LST + 66.0, 0.0)


def test_a_field_not_yet_risen_is_passed_over_and_taken_once_up():
    qs, done = run([queue("q_1", [RISING, UP_A, UP_B])])
    order = [int(qs.field_id[d.target]) for d in done]
    assert order == [101, 102, 103]  # (Q2) the first observable in list order; the rising one stays queued
    rise = rise_s(RISING["ra"], RISING["dec"])
    assert rise > 600.0  # it really was below airmass 2.5 when the queue began
    late = done[2].start_s - rise
    # (Q3) the survey held the telescope in steps until then; the pointing was lost (a mean slew after it)
    assert -TIMING.survey_step_s <= late <= 60.0 + TIMING.survey_step_s + TIMING.lost_pointing_slew_s


def test_a_filter_change_costs_the_exchange_then_the_readout():
    same = target(104, LST, 0.0)
    qs, done = run([queue("q_1", [same, dict(same, filter_id=2)])])
    gap = done[1].start_s - (done[0].start_s + done[0].exposure_s)
    # (Q7) 135 s exchange, then the longest of the 8 s readout and the short tracking slews
    assert gap == pytest.approx(TIMING.filter_change_s + TIMING.slew.readout_s, abs=1e-6)
    # the same field in one filter: only the readout
    qs, done = run([queue("q_1", [same, dict(same, field_id=105)])])
    assert done[1].start_s - done[0].start_s - done[0].exposure_s == pytest.approx(TIMING.slew.readout_s, abs=1e-6)


def test_one_list_queue_squeezes_the_second_visit_below_the_cadence():
    g = [UP_A, UP_B]
    r = [dict(t, filter_id=2) for t in g]
    qs, done = run([queue("q_1", g + r)])
    ex = executed_exposures(qs, done, EPOCH)
    assert len(ex) == 4
    assert set(done_pairs(ex, cadence_s=0.0).both) == {101, 102}
    assert not done_pairs(ex, cadence_s=1800.0).both  # back to back: minutes apart, worth nothing
    # the same as two timed queues, the second opening half an hour after the first: the pairs hold
    qs, done = run([queue("q_1", g), queue("q_2", r, opens_s=1800.0 + 60.0)])
    ex = executed_exposures(qs, done, EPOCH)
    assert set(done_pairs(ex, cadence_s=1800.0).both) == {101, 102}


def test_a_window_that_opens_later_holds_its_queue_and_first_wins_takes_the_first_submitted():
    later = [target(106, LST + 5.0, 20.0)]
    first_wins = TelescopeTiming(rules=FIRST_WINS_RULES)  # a switch with a break (ztf_sim's takes the last: Q1)
    qs, done = run([queue("q_1", [UP_A]), queue("q_2", later, opens_s=1200.0), queue("q_3", [UP_B])],
                   timing=first_wins)
    by_field = {int(qs.field_id[d.target]): d.start_s for d in done}
    assert by_field[101] < by_field[102] < by_field[106]  # (Q1) submission order among the open queues
    # q_2 opened at 1200 s, after the survey had the telescope (steps of one survey exposure)
    assert 1200.0 <= by_field[106] <= 1200.0 + TIMING.survey_step_s + TIMING.lost_pointing_slew_s + 1e-6


def test_a_closed_window_drops_what_is_left_and_exposures_may_end_after_it():
    long = [target(110 + k, LST + k, 33.0, exposure=300.0) for k in range(4)]
    qs, done = run([queue("q_1", long, closes_s=500.0)])
    starts = [d.start_s for d in done]
    assert len(done) == 2  # chosen at 0 and ~308 s; at ~616 s the window has closed
    assert starts[1] < 500.0 < starts[1] + done[1].exposure_s


def test_nothing_is_observed_with_the_sun_up():
    day = Time("2026-03-20T20:00:00", scale="utc")  # 13:00 at Palomar
    lst = float(day.sidereal_time("apparent", longitude=site().lon).deg)
    mjd = (day + TimeDelta([0.0, 12 * 3600.0], format="sec")).mjd
    payload = {"queue_name": "q_1", "validity_window_mjd": [float(mjd[0]), float(mjd[1])],
               "targets": [target(120, lst + 100.0, 30.0)]}
    qs = queue_set_from_payloads([payload], day)
    done = execute_queues(qs, day, 0.0, 12 * 3600.0)
    assert len(done) == 1
    t = day + TimeDelta(done[0].start_s, format="sec")
    sun = get_body("sun", t, site()).transform_to(AltAz(obstime=t, location=site())).alt.deg
    assert sun < TIMING.sun_alt_max_deg  # (Q9)
    before = t - TimeDelta(180.0, format="sec")
    assert get_body("sun", before, site()).transform_to(AltAz(obstime=before, location=site())).alt.deg > -13.0


def test_a_slower_telescope_takes_longer_between_exposures():
    qs, fast = run([queue("q_1", [UP_A, target(130, LST + 40.0, 10.0)])])
    _, slow = run([queue("q_1", [UP_A, target(130, LST + 40.0, 10.0)])], timing=TIMING.scaled(1.2))
    gap = [d[1].start_s - d[0].start_s - d[0].exposure_s for d in (fast, slow)]
    assert gap[0] > TIMING.slew.readout_s  # a 40 deg slew: the axes, not the readout
    assert gap[1] == pytest.approx(1.2 * gap[0], rel=0.02)
