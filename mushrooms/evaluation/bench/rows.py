"""The benchmark's result rows: one per (sky map, solver), their columns and the CSV file.

A row is a flat mapping with the keys :data:`COLUMNS` plus the efficiency
columns of each light curve (``efficiency_<lc>``, and the paired
differences ``_diff`` / ``_differr``, ``_v1`` ...).  Values are written as
they are; :func:`fmt` rounds floats and turns non-finite numbers and None
into empty cells, :func:`num` reads a cell back as a finite float or None.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Any, Iterable, Mapping

__all__ = ["COLUMNS", "TEXT_COLUMNS", "make_row", "fmt", "num", "write_csv", "read_csv"]

#: CSV columns, in order (the first nine are the issue's required ones).
COLUMNS = (
    "skymap", "solver", "coverage", "efficiency_optimistic", "efficiency_conservative",
    "n_exposures", "runtime_s", "status", "valid",
    "coverage_reported", "n_fields", "schedule_length_s", "first_exposure_s", "mip_gap",
    "prepare_s", "solve_s", "solver_detail", "n_problems", "first_problem",
    "area90_deg2", "distmean_mpc", "n_injections", "distance_source", "start", "note",
    "bound", "coverage_over_bound",
    "expected_detections",
    "detection_stage",
    "objective",
    "coverage_diff", "exposure_mix", "exposure_mean_s", "arm",
    "coverage_as_executed", "coverage_single_queue", "coverage_late_15", "coverage_late_30", "coverage_late_60",
    "n_queues",
    "coverage_pairs", "open_shutter_s", "open_shutter_executed_s", "open_shutter_single_queue_s", "commit",
)

#: Columns :func:`read_csv` keeps as text.
TEXT_COLUMNS = frozenset({"skymap", "solver", "status", "solver_detail", "first_problem", "start", "note",
                          "distance_source", "objective", "detection_stage", "exposure_mix", "arm", "commit"})

#: Prefixes of further columns kept by :func:`make_row` and written after the nine required ones: each light
#: curve's efficiency (and its paired differences) and exact expected detections (``expected_<lc>``).
EXTRA_PREFIXES = ("efficiency_", "expected_")


def make_row(skymap: str, solver: str, **values: Any) -> dict[str, Any]:
    """A row of :data:`COLUMNS` (empty cells) with ``values`` filled in; unknown keys are dropped.

    Keys starting with ``efficiency_`` or ``expected_`` are kept even when not in
    :data:`COLUMNS` (the columns of further light curves and the paired differences).
    """
    row = {c: "" for c in COLUMNS}
    row.update(skymap=skymap, solver=solver)
    row.update({k: v for k, v in values.items() if k in row or k.startswith(EXTRA_PREFIXES)})
    return row


def fmt(x: Any, digits: int = 6) -> Any:
    """A cell: floats rounded to ``digits``, None and non-finite floats empty, the rest as is."""
    if x is None:
        return ""
    if isinstance(x, float):
        return "" if not math.isfinite(x) else round(x, digits)
    return x


def num(v: Any) -> float | None:
    """A cell as a finite float, or None (empty, not a number, infinite)."""
    if v is None or v == "":
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def write_csv(rows: Iterable[Mapping[str, Any]], path: str | Path) -> None:
    """Write rows with the :data:`COLUMNS` header (atomic replace).

    Efficiency and expected-detection columns of the light curves and the
    paired differences (``efficiency_<name>...``, ``expected_<name>...``)
    follow the nine required columns.
    """
    rows = list(rows)
    extra = [k for k in dict.fromkeys(k for r in rows for k in r) if k.startswith(EXTRA_PREFIXES) and k not in COLUMNS]
    columns = list(COLUMNS[:9]) + extra + list(COLUMNS[9:])
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in columns})
    os.replace(tmp, path)


def read_csv(path: str | Path) -> list[dict[str, Any]]:
    """Read a results CSV back, numbers as floats, ``valid`` as bool."""
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            out.append({k: _cell(k, v) for k, v in r.items()})
    return out


def _cell(key: str, value: str) -> Any:
    """One CSV cell read back: text columns as they are, ``valid`` a bool, numbers floats (None when empty)."""
    if key == "valid":
        return value == "True"
    if key in TEXT_COLUMNS:
        return value
    try:
        return float(value) if value != "" else None
    except ValueError:
        return value
