"""A plan as a target list, JSON and CSV: for a telescope without a queue API (``queue = "target_list"``).

One row per planned exposure, in plan order: field id, RA and Dec of the
field centre (deg, ICRS), filter, exposure (s) and start time (ISO UTC), the
columns an observer's script or a telescope's own scheduler takes.  Written
by ``mushrooms plan --targets FILE.json`` (and ``FILE.csv`` beside it);
``docs/design/telescopes.md`` section 4.
"""

from __future__ import annotations

import csv
import io
from typing import Any

from ..times import iso_utc
from .document import Plan

__all__ = ["TARGET_COLUMNS", "target_rows", "target_list_document", "target_list_csv"]

#: The columns of a target list, in order.
TARGET_COLUMNS = ("field_id", "ra", "dec", "filter", "exposure_s", "start")


def target_rows(plan: Plan) -> list[dict[str, Any]]:
    """One dict per exposure: :data:`TARGET_COLUMNS` (RA, Dec in deg to 1e-6, start ISO UTC)."""
    if not plan.observations:
        return []
    starts = plan.absolute_time([o.start for o in plan.observations])  # the plan document's own times
    return [{"field_id": int(o.field_id), "ra": round(float(o.ra), 6), "dec": round(float(o.dec), 6),
             "filter": o.filter, "exposure_s": float(o.exposure_s), "start": iso_utc(t)}
            for o, t in zip(plan.observations, starts)]


def target_list_document(plan: Plan, telescope: str) -> dict[str, Any]:
    """The JSON target list: the plan's id, telescope, horizon and its rows."""
    return {"type": "target_list", "plan_id": plan.plan_id, "telescope": telescope,
            "start": iso_utc(plan.start), "end": iso_utc(plan.end), "columns": list(TARGET_COLUMNS),
            "targets": target_rows(plan)}


def target_list_csv(plan: Plan) -> str:
    """The CSV target list: a header line of :data:`TARGET_COLUMNS`, one line per exposure."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=TARGET_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(target_rows(plan))
    return out.getvalue()
