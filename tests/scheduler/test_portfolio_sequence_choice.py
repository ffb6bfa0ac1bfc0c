"""The hybrid's choice (Q15) weighs a g-r-g candidate by the coverage its sequences keep whole as executed (Q21).

Real map (MS220722v, nside 64), a real problem two hours into the night, the real telescope model. Two
candidate plans: one observes the likelier field in g-r-g with its third visit planned so close to the
horizon's end that ZTF's scheduler, a cadence and its margin after the executed r, cannot take it (F1
still credits the field by its g and r: more ``coverage_as_executed``); the other observes a less likely
field's whole sequence early enough. Issue 55 (grgfix, finding 2): the choice took the first.
"""

from __future__ import annotations

import pytest
from astropy.time import TimeDelta

from mushrooms.scheduler_core import PlanningConfig, prepare_problem
from mushrooms.scheduler_core.plan.document import EventInfo, Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.schedulers.as_executed import queue_coverages
from mushrooms.scheduler_core.problem import ScheduleResult
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.schedulers.portfolio.portfolio import choose_as_executed
from mushrooms.scheduler_core.sky.skymap import read_skymap

GRG = PlanningConfig(solver="hybrid", filters=("g", "r", "g"), exposure_s=180.0, nside=64, horizon_h=2.0,
                     min_gain=0.0)
#: Two hours before the map's morning twilight (its fields set at 13.9 h after the merger).
OFFSET_S = 11.5 * 3600.0


@pytest.fixture(scope="module")
def problem(data_dir):
    sky = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=GRG.nside)
    return prepare_problem(sky, GRG, sky.event_time + TimeDelta(OFFSET_S, format="sec"))


def _sequence(problem, row, times):
    fid, ra, dec = int(problem.field_ids[row]), float(problem.ra[row]), float(problem.dec[row])
    return [Observation(fid, ra, dec, band, float(t), GRG.exposure_s, 0) for band, t in zip(GRG.filters, times)]


def _executed(problem, result):
    """(coverage_as_executed, sequence_coverage_as_executed) of a candidate's plan: one run of its queues."""
    plan = Plan(plan_id="candidate", start=problem.start, end=problem.start + TimeDelta(problem.horizon_s, format="sec"),
                observations=result.observations, event=EventInfo(),
                metrics=PlanMetrics(coverage=0.0, solver="", status="", mip_gap=None, runtime_s=0.0, n_fields=0,
                                    n_exposures=len(result.observations)),
                config={"cadence_s": GRG.cadence_s, "filters": list(GRG.filters)})
    return queue_coverages(plan, problem.footprints, problem.prob)


def _candidate(observations, name):
    return ScheduleResult(observations=tuple(sorted(observations, key=lambda o: o.start)), solver=name,
                          status="greedy", mip_gap=None, runtime_s=0.0)


def test_a_candidate_whose_third_visits_are_lost_as_executed_loses_to_whole_sequences(problem):
    prob = problem.footprints.field_probability(problem.prob)
    likely, less = (int(r) for r in prob.argsort()[::-1][:2])
    assert prob[likely] > prob[less] > 0
    end = problem.horizon_s - GRG.exposure_s - 10.0  # the third g ends 10 s before the horizon
    c = GRG.cadence_s
    lost = _candidate(_sequence(problem, likely, (end - 2 * c - 5.0, end - c, end)), "lost_third")
    whole = _candidate(_sequence(problem, less, (0.0, c + 100.0, 2 * c + 200.0)), "whole")
    ran = {"greedy": lost, "slots": whole}
    covs = {n: published_coverage(problem, r) for n, r in ran.items()}
    assert covs["greedy"] > covs["slots"]
    # as executed the first keeps its g-r pair (F1) but not its third g; the second keeps its whole sequence
    pair, seq = _executed(problem, lost)
    assert pair == pytest.approx(covs["greedy"], abs=1e-6) and seq == 0.0
    assert _executed(problem, whole) == pytest.approx((covs["slots"], covs["slots"]), abs=1e-6)
    name, executed, _ = choose_as_executed(problem, ran, covs)
    assert name == "slots"
