"""A telescope part's SkyPortal observation plan request (``queue = "skyportal"``, issue 53 item 4).

:func:`part_request` is what :mod:`~mushrooms.daemon.planning.parts` writes as
``skyportal_request.json`` in the part's folder; :func:`manual_body` turns it,
with the telescope's allocation, into the body of SkyPortal's ``POST
/api/observation_plan/manual`` (``ObservationPlanManualRequestHandler.post``,
skyportal/skyportal @ 8bd346c ``skyportal/handlers/api/observation_plan.py``
lines 1365-1513: the keys read are ``dateobs`` or ``gcnevent_id``,
``localization_name`` or ``localization_id``, ``payload``, ``status``,
``allocation_id``, ``plan_name`` and ``observation_plans[0]``'s
``validity_window_start``/``_end``, ``status`` and ``planned_observations[]``
with ``dateobs``, ``field_id``, ``exposure_time``, ``weight``, ``filt``,
``planned_observation_id``, ``overhead_per_exposure``).

The request is named ``<telescope>_<superevent>_<plan tag>`` (``plan_name`` and
``payload.queue_name``): SkyPortal's plan names are unique
(``EventObservationPlan.plan_name``, ``skyportal/models/observation_plan.py``
line 297), the plan tag (12 hex digits of the plan id) makes every part's name
its own, and the name is what finds the request again after a crash
(:meth:`~mushrooms.daemon.submission.remote.SkyPortalPlans.find`).
"""

from __future__ import annotations

import re
from typing import Any, Mapping

from ...handlers.text import storable

__all__ = ["part_request", "manual_body", "request_name"]

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")


def request_name(telescope: str, superevent_id: str | None, plan_id: str) -> str:
    """``<telescope>_<superevent>_<plan tag>``: the part's SkyPortal plan name (``[A-Za-z0-9._-]``, <= 120 characters)."""
    from ...scheduler_core.plan.exports import plan_tag

    parts = [_UNSAFE.sub("_", str(telescope))[:40], _UNSAFE.sub("_", str(superevent_id or "map"))[:64],
             plan_tag(plan_id)]
    return "_".join(parts)


def part_request(plan: Any, telescope: Any) -> dict[str, Any]:
    """The part's observation plan request, as written in its folder (all but the allocation).

    Parameters
    ----------
    plan : Plan
        The telescope's plan (observations in order, absolute times from its document).
    telescope : TelescopeDescription
        ``execution.skyportal_instrument`` and the filters' ``skyportal_name``.
    """
    from ...scheduler_core.plan.target_list import target_rows

    names = {f: (t.skyportal_name or f) for f, t in telescope.filters.items()}
    rows = target_rows(plan)
    planned, previous_end = [], None
    for i, (r, o) in enumerate(zip(rows, plan.observations)):
        overhead = 0.0 if previous_end is None else min(max(o.start - previous_end, 0.0), 600.0)
        previous_end = o.end
        planned.append({"planned_observation_id": i, "dateobs": r["start"].rstrip("Z"), "field_id": r["field_id"],
                        "ra": r["ra"], "dec": r["dec"], "exposure_time": r["exposure_s"],
                        "filt": storable(names.get(r["filter"], r["filter"]), 32),
                        "weight": 0.0 if o.probability is None else round(float(o.probability), 6),
                        "overhead_per_exposure": int(round(overhead))})
    name = request_name(telescope.name, plan.event.superevent_id, plan.plan_id)
    start, end = plan.start.utc.isot[:23], plan.end.utc.isot[:23]
    return {"type": "skyportal_observation_plan_request", "sent": False,
            "why_not_sent": "written at export; [submit_parts] sends it with the telescope's allocation when "
                            "enabled (the state file's part_requests row says what became of it)",
            "instrument": storable(telescope.execution.skyportal_instrument or telescope.name, 100),
            "plan_id": plan.plan_id, "plan_name": name, "dateobs": (plan.event.event_time or "").rstrip("Z"),
            "localization_name": storable(plan.event.skymap_name or "healpix", 200),
            "validity_window_start": start, "validity_window_end": end,
            "planned_observations": planned}


def manual_body(request: Mapping[str, Any], allocation_id: int, status: str = "complete") -> dict[str, Any]:
    """The ``POST /api/observation_plan/manual`` body of a written request, for ``allocation_id``.

    Raises
    ------
    ValueError
        The request has no event time, no name or no planned observation.
    """
    name, dateobs, planned = request.get("plan_name"), request.get("dateobs"), request.get("planned_observations")
    if not isinstance(name, str) or not name:
        raise ValueError("the written request has no plan_name")
    if not isinstance(dateobs, str) or not dateobs:
        raise ValueError("the plan has no event time: SkyPortal finds the event by its dateobs")
    if not isinstance(planned, list) or not planned:
        raise ValueError("the plan has no observations")
    keep = ("planned_observation_id", "dateobs", "field_id", "exposure_time", "filt", "weight",
            "overhead_per_exposure")
    window = (str(request["validity_window_start"]), str(request["validity_window_end"]))
    return {"dateobs": dateobs, "localization_name": request.get("localization_name") or "healpix",
            "allocation_id": int(allocation_id), "plan_name": name, "status": status,
            "payload": {"queue_name": name, "start_date": window[0].replace("T", " ")[:19],
                        "end_date": window[1].replace("T", " ")[:19],
                        "filters": ",".join(sorted({str(p["filt"]) for p in planned})),
                        "field_ids": ",".join(str(p["field_id"]) for p in planned)},
            "observation_plans": [{"validity_window_start": window[0], "validity_window_end": window[1],
                                   "status": status, "planned_observations": [{k: p[k] for k in keep}
                                                                             for p in planned]}]}
