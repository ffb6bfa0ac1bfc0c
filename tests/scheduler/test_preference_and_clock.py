"""Issue 24: the merger clock (scheduler_core.clock) and the rule R1-R3 (scheduler_core.preference)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core.clock import CLOCK_TOLERANCE_S, merger_clock, on_merger_clock
from mushrooms.scheduler_core.plan.document import EventInfo
from mushrooms.scheduler_core.preference import is_preferred
from mushrooms.scheduler_core.sky.skymap import read_skymap

MAP = "MS220722v_bayestar.multiorder.fits"


# ---------------------------------------------------------------- the rule R1-R3

@pytest.mark.parametrize("objective", ["coverage", "detection"])
def test_a_tie_in_expected_detections_is_decided_by_coverage(objective) -> None:
    # the measured symptom of issue 24: 0.0000 detections against 0.0000, coverage 0.5692 against 0.5556
    assert is_preferred(0.5692, 0.0, 0.5556, 0.0, 0.005, objective, coverage_floor=0.98 * 0.5556)
    # a tie within the margin (not only exact zeros), either way round
    assert is_preferred(0.60, 0.101, 0.55, 0.104, 0.005, objective, coverage_floor=0.98 * 0.55)
    # more coverage than the margin is needed, as for the coverage objective
    assert not is_preferred(0.553, 0.0, 0.550, 0.0, 0.005, objective, coverage_floor=0.98 * 0.55)
    # equal plans never replace each other, even with a zero margin
    assert not is_preferred(0.55, 0.1, 0.55, 0.1, 0.0, objective, coverage_floor=0.0)


def test_detections_beyond_the_margin_win_within_the_floor_and_fewer_never_win() -> None:
    assert is_preferred(0.54, 0.12, 0.55, 0.10, 0.005, "detection", coverage_floor=0.98 * 0.55)
    assert not is_preferred(0.50, 0.12, 0.55, 0.10, 0.005, "detection", coverage_floor=0.98 * 0.55)  # below X6
    assert not is_preferred(0.70, 0.09, 0.55, 0.10, 0.005, "detection", coverage_floor=0.0)  # fewer detections
    # the coverage objective, or no distance layers, looks at coverage only
    assert not is_preferred(0.54, 0.12, 0.55, 0.10, 0.005, "coverage")
    assert is_preferred(0.56, None, 0.55, 0.10, 0.005, "detection")


# ---------------------------------------------------------------- the merger clock

def test_the_notice_clock_wins_and_a_disagreement_is_logged_once_with_both_values(data_dir, caplog) -> None:
    sm = read_skymap(data_dir / "skymaps" / MAP, nside=64)
    notice = sm.event_time + TimeDelta(3 * 365.25 * 86400, format="sec")  # a live copy of an archived event
    caplog.set_level(logging.WARNING, logger="mushrooms.scheduler_core.clock")
    clocked, event = on_merger_clock(sm, EventInfo(superevent_id="S1", event_time=notice.isot + "Z"))
    assert event.merger_time_source == "notice"
    assert abs((Time(event.event_time.rstrip("Z"), scale="utc") - notice).to_value("sec")) < 1e-3
    assert abs((clocked.event_time - notice).to_value("sec")) < 1e-3
    assert clocked.sha256 == sm.sha256 and np.array_equal(clocked.prob, sm.prob)
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 1 and "S1" in warned[0] and notice.isot[:19] in warned[0] \
        and sm.event_time.isot[:19] in warned[0]
    # applying it again (the planner does, on the pipeline's already clocked map) logs nothing new
    again, event2 = on_merger_clock(clocked, event)
    assert again is clocked and event2 == event and len(caplog.records) == 1


def test_without_a_notice_the_map_clock_is_used_and_small_disagreements_are_quiet(data_dir, caplog) -> None:
    sm = read_skymap(data_dir / "skymaps" / MAP, nside=64)
    caplog.set_level(logging.WARNING, logger="mushrooms.scheduler_core.clock")
    same, event = on_merger_clock(sm, None)
    assert same is sm and event.merger_time_source == "skymap" and event.event_time.startswith(sm.event_time.isot[:19])
    near = merger_clock(sm.event_time + TimeDelta(CLOCK_TOLERANCE_S / 2, format="sec"), sm.event_time)
    assert near.source == "notice" and not caplog.records
    assert merger_clock(None, None).time is None
