"""One CSV writer for the benchmark scripts' per-map tables.

The scripts rewrite their CSV after every map, so a run stopped half way
keeps the rows it has.  Columns: ``fieldnames`` when given, else every key
of the rows in the order first seen (rows may differ: a hybrid column only
on some maps); a row without a column leaves it empty.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

__all__ = ["write_rows"]


def write_rows(path: str | Path, rows: Iterable[Mapping[str, Any]], fieldnames: Sequence[str] | None = None) -> None:
    """Write ``rows`` to ``path`` as CSV with a header (nothing when there is no row)."""
    rows = list(rows)
    if not rows:
        return
    names = list(fieldnames) if fieldnames is not None else list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=names, restval="")
        w.writeheader()
        w.writerows(rows)
