"""Pure scheduling library: sky map in, checked ZTF plan out.

No Kafka, no daemon state, no globals: call it from a notebook (here the
packaged map, at a small resolution, on a night its sky is up):

>>> from importlib.resources import files
>>> from astropy.time import Time
>>> from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, read_skymap
>>> cfg = PlanningConfig(solver="greedy", nside=64)
>>> skymap = read_skymap(files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits",
...                      nside=cfg.nside)
>>> plan = make_plan(skymap, cfg, start=Time("2019-05-01T03:00:00", scale="utc"))
>>> check_plan(plan, skymap, cfg).ok
True
>>> doc = plan.to_document()  # the JSON plan document (docs/design/plan-format.md)
>>> doc["plan_id"] == plan.plan_id, len(doc["observations"]) == len(plan.observations)
(True, True)

The names below are imported on first use (PEP 562): importing a light
module of the package (:mod:`.config`, :mod:`.tables`, :mod:`.errors`) does
not load numpy, astropy or healpy through this ``__init__``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .lazy import lazy_exports

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from .config import PlanningConfig, SlewModel
    from .errors import InputError, PlanCheckError, SkyMapError
    from .plan.checker import CheckReport, check_plan
    from .plan.document import EventInfo, Observation, Plan, PlanMetrics, make_plan_id
    from .plan.exports import ExportConfig, to_skyportal, to_trigger_queue, to_trigger_queues
    from .plan.observability import NotObservable, not_observable
    from .planner import make_plan, run_scheduler
    from .prepare import prepare_problem
    from .problem import PlanningProblem, ScheduleResult
    from .schedulers.greedy.schedule import greedy_schedule
    from .sky.fields import FieldGrid, field_footprints, load_ztf_fields
    from .sky.footprints import Footprints
    from .sky.skymap import SkyMap, read_skymap
    from .sky.visibility import observability_windows
    from .sky.windows import Windows

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "CheckReport": ".plan.checker", "check_plan": ".plan.checker",
    "PlanningConfig": ".config", "SlewModel": ".config",
    "InputError": ".errors", "PlanCheckError": ".errors", "SkyMapError": ".errors",
    "FieldGrid": ".sky.fields", "field_footprints": ".sky.fields", "load_ztf_fields": ".sky.fields",
    "greedy_schedule": ".schedulers.greedy.schedule",
    "ExportConfig": ".plan.exports", "to_skyportal": ".plan.exports", "to_trigger_queue": ".plan.exports",
    "to_trigger_queues": ".plan.exports",
    "NotObservable": ".plan.observability", "not_observable": ".plan.observability",
    "EventInfo": ".plan.document", "Observation": ".plan.document", "Plan": ".plan.document",
    "PlanMetrics": ".plan.document", "make_plan_id": ".plan.document",
    "make_plan": ".planner", "run_scheduler": ".planner",
    "prepare_problem": ".prepare",
    "Footprints": ".sky.footprints",
    "PlanningProblem": ".problem", "ScheduleResult": ".problem",
    "Windows": ".sky.windows",
    "SkyMap": ".sky.skymap", "read_skymap": ".sky.skymap",
    "observability_windows": ".sky.visibility",
}

__all__ = [
    "CheckReport", "check_plan", "PlanningConfig", "SlewModel", "InputError", "PlanCheckError",
    "SkyMapError", "FieldGrid", "field_footprints", "load_ztf_fields", "greedy_schedule",
    "EventInfo", "Observation", "Plan", "PlanMetrics", "make_plan_id", "to_trigger_queue", "to_trigger_queues",
    "make_plan", "run_scheduler", "prepare_problem", "Footprints", "PlanningProblem",
    "ScheduleResult", "Windows", "SkyMap", "read_skymap", "observability_windows",
    "ExportConfig", "to_skyportal", "NotObservable", "not_observable",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
