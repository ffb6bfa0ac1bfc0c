"""'As submitted today' (issue 55 item 3): each row's plan through SkyPortal's ZTF API the way its planner hands it on.

Issue 55 (grgfix, finding 3): the service's plan executed nothing "as submitted today" on 4 of 53 shared maps
(G476954: 0.000 against greedy's 0.512). The bench ran every plan as ONE list queue over its horizon (what
SkyPortal makes of one observation plan, a gwemopt plan's way today); a list queue has no times, so a block
whose filter pass is shorter than the cadence (5 fields at 300 s: 26 min) has its r visits run right after
its g visits, too soon to pair. The service does not hand SkyPortal one plan: it POSTs one plan per filter
pass (``[export] skyportal_plans = "per_pass"``, docs/design/submission.md T1), which SkyPortal queues as one
list queue per pass over that pass's window. Here a plan of two fields whose g and r passes are 2 x 200 s
long and a cadence apart (real map MS220722v, nside 64, the real telescope model).
"""

from __future__ import annotations

import pytest
from astropy.time import TimeDelta

from mushrooms.evaluation.bench.scoring import execution_cells_under
from mushrooms.evaluation.skyportal_queue import skyportal_queue
from mushrooms.scheduler_core import PlanningConfig, prepare_problem
from mushrooms.scheduler_core.plan.document import EventInfo, Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.plan.exports import ExportConfig, to_skyportal_plans
from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues
from mushrooms.scheduler_core.sky.skymap import read_skymap

CFG = PlanningConfig(solver="greedy", nside=64, exposure_s=180.0, horizon_h=4.0)


@pytest.fixture(scope="module")
def scene(data_dir):
    sky = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=CFG.nside)
    start = sky.event_time + TimeDelta(9 * 3600.0, format="sec")
    problem = prepare_problem(sky, CFG, start)
    rows = problem.footprints.field_probability(problem.prob).argsort()[::-1][:2]
    obs = [Observation(int(problem.field_ids[r]), float(problem.ra[r]), float(problem.dec[r]), band,
                       t0 + 200.0 * i, CFG.exposure_s, 0)
           for band, t0 in (("g", 0.0), ("r", CFG.cadence_s)) for i, r in enumerate(rows)]
    plan = Plan(plan_id="mushrooms-0123456789abcdef", start=start,
                end=start + TimeDelta(CFG.horizon_s, format="sec"), observations=tuple(obs),
                metrics=PlanMetrics(coverage=problem.footprints.coverage({o.field_id for o in obs}, problem.prob),
                                    solver="greedy", status="greedy", mip_gap=None, runtime_s=0.0, n_fields=2,
                                    n_exposures=4),
                event=EventInfo(event_time=sky.event_time.utc.isot + "Z"),
                config={"filters": ["g", "r"], "cadence_s": CFG.cadence_s, "exposure_s": CFG.exposure_s})
    return plan, problem


def test_our_plan_as_submitted_today_is_what_its_skyportal_plans_execute(scene):
    plan, problem = scene
    cells = execution_cells_under(plan, CFG, problem.footprints, problem.prob)
    assert plan.metrics.coverage > 0
    assert cells["coverage_as_executed"] == pytest.approx(plan.metrics.coverage, abs=1e-6)
    # what SkyPortal's ZTF API queues for the plans the service POSTs (one per pass), run by the telescope model
    bodies = to_skyportal_plans(plan, ExportConfig(skyportal_allocation_id=1))
    assert len(bodies) == 2
    done = execute_plan_queues(plan, [skyportal_queue(b) for b in bodies])
    today = cadence_coverage(done, problem.footprints, problem.prob, ("g", "r"), CFG.cadence_s)
    assert today == pytest.approx(plan.metrics.coverage, abs=1e-6)
    assert cells["coverage_single_queue"] == pytest.approx(today, abs=1e-6)


def test_a_gwemopt_plan_as_submitted_today_is_one_list_queue(scene):
    """A plan made in SkyPortal (gwemopt's: no config) is one observation plan, one list queue: its r visits
    run right after its g visits."""
    plan, problem = scene
    cells = execution_cells_under(plan.with_(config=None), CFG, problem.footprints, problem.prob)
    assert cells["coverage_as_executed"] == pytest.approx(plan.metrics.coverage, abs=1e-6)
    assert cells["coverage_single_queue"] == 0.0
    assert cells["open_shutter_single_queue_s"] == 4 * CFG.exposure_s
