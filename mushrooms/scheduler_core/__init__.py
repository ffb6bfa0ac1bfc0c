"""Pure scheduling library: sky map in, checked ZTF plan out.

No Kafka, no daemon state, no globals: call it from a notebook::

    from mushrooms.scheduler_core import read_skymap, make_plan, PlanningConfig
    cfg = PlanningConfig(solver="greedy")
    plan = make_plan(read_skymap("bayestar.multiorder.fits", nside=cfg.nside), cfg)
    plan.to_document()
"""

from .plan.checker import CheckReport, check_plan
from .config import PlanningConfig, SlewModel
from .errors import InputError, PlanCheckError, SkyMapError
from .sky.fields import FieldGrid, field_footprints, load_ztf_fields
from .schedulers.greedy import greedy_schedule
from .plan.exports import ExportConfig, to_skyportal, to_trigger_queue
from .plan.observability import NotObservable, not_observable
from .plan.document import EventInfo, Observation, Plan, PlanMetrics, make_plan_id
from .planner import make_plan, run_scheduler
from .prepare import prepare_problem
from .sky.footprints import Footprints
from .problem import PlanningProblem, ScheduleResult
from .sky.windows import Windows
from .sky.skymap import SkyMap, read_skymap
from .sky.visibility import observability_windows

__all__ = [
    "CheckReport", "check_plan", "PlanningConfig", "SlewModel", "InputError", "PlanCheckError",
    "SkyMapError", "FieldGrid", "field_footprints", "load_ztf_fields", "greedy_schedule",
    "EventInfo", "Observation", "Plan", "PlanMetrics", "make_plan_id", "to_trigger_queue",
    "make_plan", "run_scheduler", "prepare_problem", "Footprints", "PlanningProblem",
    "ScheduleResult", "Windows", "SkyMap", "read_skymap", "observability_windows",
    "ExportConfig", "to_skyportal", "NotObservable", "not_observable",
]
