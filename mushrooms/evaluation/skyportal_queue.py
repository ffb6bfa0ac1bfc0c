"""What SkyPortal's ZTF API sends to ZTF's queue for an imported observation plan (a model of the neighbour).

Written from skyportal/skyportal @ 01fabb98b7e54e55c96d03148f7906375cc3084f
(BSD-3-Clause), ``skyportal/facility_apis/ztf.py``,
``_build_observation_plan_payload``: one list queue named ``"ToO_" +
payload.queue_name``, valid from ``Time(payload.start_date, format="iso")``
to ``Time(payload.end_date, format="iso")``, whose targets are the plan's
planned observations in their order, each at its field's grid position.
Used to execute a SkyPortal submission with the telescope model
(``docs/design/submission.md``, (T1)).

Checked again at skyportal 8bd346c (issue 55): a plan made by SkyPortal's
gwemopt path reaches ZTF the same way - ``send_observation_plan``
(``skyportal/handlers/api/observation_plan.py:200-365``; called by
``ObservationPlanSubmitHandler.post``, 1516-1546, and by a default plan's
auto-send) calls ``ZTFMMAAPI.send`` (``skyportal/facility_apis/ztf.py:849-917``),
which PUTs one payload to ``api/triggers/ztf``: the targets, queue name and
``validity_window_mjd`` of ``_build_observation_plan_payload`` (252-312: the
request's ``start_date`` to ``end_date``, the same times gwemopt planned over,
``skyportal/utils/observation_plan.py:385-391``) with ``queue_type`` ``list``
(891-897).  The planned observations keep the order they were stored in
(no ``order_by`` on the relationship, ``skyportal/models/observation_plan.py:321-325``):
gwemopt's time order.  The bench's ``coverage_single_queue``
(:func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queue` over the
plan's start and end) is this queue.
"""

from __future__ import annotations

from typing import Any, Mapping

from astropy.time import Time

from ..scheduler_core.sky.fields import load_ztf_fields

__all__ = ["skyportal_queue", "BANDS"]

#: SkyPortal's ZTF filter names as ZTF's queue filter ids.
BANDS = {"ztfg": 1, "ztfr": 2, "ztfi": 3}


def skyportal_queue(body: Mapping[str, Any]) -> dict[str, Any]:
    """The list queue SkyPortal's ZTF API sends for one ``POST /api/observation_plan/manual`` body.

    Raises
    ------
    ValueError
        A body without exactly one observation plan (SkyPortal refuses it too).
    """
    plans = body["observation_plans"]
    if len(plans) != 1:
        raise ValueError(f"SkyPortal queues a request of one observation plan, this one has {len(plans)}")
    grid = load_ztf_fields()
    where = {int(f): i for i, f in enumerate(grid.ids)}
    targets = []
    for k, o in enumerate(plans[0]["planned_observations"], start=1):
        i = where[int(o["field_id"])]
        targets.append({"request_id": k, "field_id": int(o["field_id"]), "ra": float(grid.ra[i]),
                        "dec": float(grid.dec[i]), "filter_id": BANDS[o["filt"]],
                        "exposure_time": float(o["exposure_time"])})
    window = [float(Time(body["payload"][k], format="iso", scale="utc").mjd) for k in ("start_date", "end_date")]
    return {"queue_name": "ToO_" + str(body["payload"]["queue_name"]), "queue_type": "list",
            "validity_window_mjd": window, "targets": targets}
