"""The merger clock (scheduler_core.clock) and the rule R1-R3 (scheduler_core.preference)."""

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
    # the symptom measured with the map's stale clock: 0.0000 detections against 0.0000, coverage 0.5692 against 0.5556
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


# ---------------------------------------------------------------- the rule R1-R3, as a property

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_p = st.floats(0.0, 1.0, allow_nan=False)


@settings(max_examples=400, deadline=None)
@given(c=_p, e=_p, dc=_p, de=_p, margin=st.floats(0.0, 0.05), eps=st.floats(0.0, 0.1))
def test_a_plan_with_as_many_detections_and_more_coverage_always_wins(c, e, dc, de, margin, eps) -> None:
    """Never kept over one with as many expected detections and more coverage (by the margin)."""
    c_new = min(1.0, c + margin + dc * (1.0 - c))
    e_new = min(1.0, e + de * (1.0 - e))
    if c_new - c < max(margin, 2e-9):
        return  # not more coverage by the margin (the candidate hit 1.0)
    for objective in ("detection", "coverage"):
        assert is_preferred(c_new, e_new, c, e, margin, objective, coverage_floor=(1 - eps) * c)
    assert not is_preferred(c, e, c_new, e_new, margin, "detection", coverage_floor=(1 - eps) * c_new) \
        or e - e_new >= margin  # and the incumbent it beat never wins back unless it expects more


def test_the_daemon_and_plan_supersede_rule_is_the_preference_rule() -> None:
    """anytime.is_better (the daemon's supersede, plan --deadline) is is_preferred on the published metrics."""
    import itertools

    from mushrooms.scheduler_core.anytime import is_better
    from mushrooms.scheduler_core.plan.document import Plan, PlanMetrics

    def plan(c: float, e: float | None) -> Plan:
        m = PlanMetrics(coverage=c, solver="greedy", status="greedy", mip_gap=None, mip_bound=None, runtime_s=0.0,
                        n_fields=1, n_exposures=2, expected_detections=e)
        return Plan(plan_id="mushrooms-0000000000000000", created="2026-01-01T00:00:00.000Z",
                    event=EventInfo(skymap_sha256="0" * 64), start="2026-01-01T00:00:00.000Z",
                    end="2026-01-02T00:00:00.000Z", observations=(), metrics=m, config={})

    values = [(0.40, 0.0), (0.405, 0.0), (0.45, 0.0), (0.45, 0.02), (0.43, 0.03), (0.30, 0.2), (0.45, None)]
    for (c1, e1), (c2, e2), objective in itertools.product(values, values, ("coverage", "detection")):
        want = is_preferred(c2, e2, c1, e1, 0.005, objective, coverage_floor=0.98 * c1)
        assert is_better(plan(c2, e2), plan(c1, e1), 0.005, objective, 0.02) == want, (c1, e1, c2, e2, objective)


def test_a_map_header_time_out_of_range_is_no_clock_and_the_notice_decides(caplog) -> None:
    caplog.set_level(logging.WARNING, logger="mushrooms.scheduler_core.clock")
    far = Time("2500-01-01T00:00:00", scale="utc")
    clock = merger_clock("2026-05-01T03:00:00Z", far, context="S9")
    assert clock.source == "notice" and clock.disagreement_s is None
    assert any("DATE-OBS" in r.getMessage() and "S9" in r.getMessage() for r in caplog.records)
    assert merger_clock(None, far).time is None
