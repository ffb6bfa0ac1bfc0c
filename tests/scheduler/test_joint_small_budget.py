"""A joint plan's step given less budget than the detection stage's share (issue 53, J6).

The ascent gives a telescope's step ``min(time_limit_s, left)``; near the end of the budget that is below
``detection_time_limit_s``, and the step's configuration was refused (ValueError, seen with ZTF and
DECam on S230518h: ``detection_time_limit_s (0.5 s) must be less than time_limit_s (0.466884 s)``).
"""

from __future__ import annotations

from importlib.resources import files

from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers.joint.ascent import plan_alone

NIGHT = Time("2019-05-01T03:00:00", scale="utc")
DEMO = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"


def test_a_step_with_less_budget_than_the_detection_share_still_plans():
    cfg = PlanningConfig(solver="slots", nside=64, horizon_h=12.0, time_limit_s=2.0, detection_time_limit_s=0.5,
                         bound_time_limit_s=1.0, deterministic=True)
    problem = prepare_problem(read_skymap(DEMO, nside=64), cfg, NIGHT)
    result, spent = plan_alone(problem, None, 0.3)  # ValueError before the fix
    assert result.observations and spent >= 0.0
    assert {o.field_id for o in result.observations} <= set(problem.field_ids.tolist())
