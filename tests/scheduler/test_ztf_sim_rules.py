"""The executor follows ztf_sim's main loop (issue 52, finding 12; Q1-Q3 of ``docs/design/executed.md``).

ztf_sim at c5ab409: ``simulate.py`` switches queues with ``check_for_timed_queue_and_switch``,
which takes the *last* valid, non-empty queue in submission order; a target below the horizon
passes ``_next_obs``'s airmass cut (its airmass is negative), its slew is refused and the
telescope waits 30 s and tries it again; in ``simulate.py`` a queue emptied inside its window raises
``QueueEmptyError`` and the survey takes one exposure before the next queue (an option here, Q3).  Epoch
2026-03-20 06:00 UTC at Palomar (the Sun 47 deg down); times found here with astropy.
"""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord
from astropy.time import TimeDelta

from mushrooms.scheduler_core.sky.visibility import site
from mushrooms.scheduler_core.telescope import TelescopeTiming
from palomar_queues import EPOCH, LST, NIGHT_S, TIMING, UP_A, UP_B, queue, target
from palomar_queues import done_by_field as run



def test_from_the_default_queue_the_last_open_queue_in_submission_order_is_taken():
    later = [target(106, LST + 5.0, 20.0)]
    done = run([queue("q_1", [UP_A]), queue("q_2", later, opens_s=1200.0), queue("q_3", [UP_B])])
    # check_for_timed_queue_and_switch has no break: q_3, submitted last, wins over q_1
    assert done[102].start_s < done[101].start_s < done[106].start_s
    assert done[102].start_s < 60.0
    assert 1200.0 <= done[106].start_s <= 1200.0 + TIMING.survey_step_s + TIMING.lost_pointing_slew_s + 1e-6


def test_as_simulate_py_runs_it_an_emptied_queue_costs_one_survey_exposure_before_the_next_queue():
    from mushrooms.scheduler_core.telescope.rules import SIMULATE_PY_RULES

    queues = [queue("q_1", [UP_A]), queue("q_2", [UP_B])]
    done = run(queues, timing=TelescopeTiming(rules=SIMULATE_PY_RULES))
    first, second = done[102], done[101]
    gap = second.start_s - (first.start_s + first.exposure_s)
    # QueueEmptyError from the emptied q_2, the survey's exposure, then q_1 from a lost pointing
    assert gap == pytest.approx(TIMING.survey_step_s + TIMING.lost_pointing_slew_s, abs=1e-6)
    # the default leaves an emptied queue at once (a server that runs the ToO switch every 10 s, Q3)
    done = run(queues)
    assert done[101].start_s - (done[102].start_s + done[102].exposure_s) < TIMING.survey_step_s


def _ha_limit_s(ra, ha_max_h=5.95):
    """Seconds after the epoch at which a setting target's hour angle reaches ha_max_h (astropy)."""
    times = EPOCH + TimeDelta(np.arange(0.0, NIGHT_S, 10.0), format="sec")
    ha = (times.sidereal_time("apparent", longitude=site().lon).deg - ra + 180.0) % 360.0 - 180.0
    return float(np.flatnonzero(ha >= ha_max_h * 15.0)[0] * 10.0)


def test_a_target_below_the_horizon_holds_its_queue_until_it_leaves_the_hour_angle_limit():
    setting = target(140, LST - 80.0, -25.0)  # 80 deg west of the meridian at Dec -25: set, |HA| < 5.95 h
    alt = SkyCoord(setting["ra"] * u.deg, -25.0 * u.deg).transform_to(AltAz(obstime=EPOCH, location=site())).alt.deg
    assert alt < 0.0  # below the horizon: ztf_sim's 1/cos(z) is negative and passes airmass < 2.5
    leaves = _ha_limit_s(setting["ra"])
    assert 1800.0 < leaves < 3000.0
    done = run([queue("q_1", [setting, UP_A, UP_B])])
    assert 140 not in done  # never slewed to
    # its slew is refused, the telescope waits 30 s and tries it again: UP_A waits until |HA| >= 5.95 h
    assert leaves - 60.0 <= done[101].start_s <= leaves + 60.0 + 30.0 + 30.0  # grid step, one retry, slew
    assert done[101].start_s < done[102].start_s


def test_a_refused_target_in_another_filter_changes_the_filter_once():
    setting = target(140, LST - 80.0, -25.0, filter_id=2)
    done = run([queue("q_1", [UP_A, setting, UP_B])])
    leaves = _ha_limit_s(setting["ra"])
    # UP_A (g), then the r target's exchange (135 s) and 30 s retries until it leaves; UP_B back in g
    assert done[101].start_s < 60.0
    assert leaves - 60.0 <= done[102].start_s - TIMING.filter_change_s <= leaves + 60.0 + 30.0
