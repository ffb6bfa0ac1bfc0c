"""What SkyPortal's ZTF API sends to ZTF's queue for an imported observation plan (a model of the neighbour).

Written from skyportal/skyportal @ 01fabb98b7e54e55c96d03148f7906375cc3084f
(BSD-3-Clause), ``skyportal/facility_apis/ztf.py``,
``_build_observation_plan_payload``: one list queue named ``"ToO_" +
payload.queue_name``, valid from ``Time(payload.start_date, format="iso")``
to ``Time(payload.end_date, format="iso")``, whose targets are the plan's
planned observations in their order, each at its field's grid position.
Used to execute a SkyPortal submission with the telescope model
(``docs/design/submission.md``, (T1)).
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
