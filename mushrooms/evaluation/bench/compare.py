"""Rows of one map side by side: who has a plan, the paper's best-of, wins, losses and ties.

Shared by the benchmark's summary (:mod:`.summary`), its figures
(:mod:`.plots`) and the study's tables (:mod:`mushrooms.evaluation.study.tables`).
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

from .rows import num

__all__ = ["TIE_COVERAGE", "TIE_EFFICIENCY", "SIMILAR_LENGTH", "by_map", "scored", "best_of", "wins",
           "objective_of"]

#: Coverage differences at or below this count as a tie (absolute probability).
TIE_COVERAGE = 1e-4
#: Efficiency differences at or below this count as a tie.
TIE_EFFICIENCY = 1e-3
#: The paper's "similar schedule length" subset: exposure counts within this of gwemopt's.
SIMILAR_LENGTH = 6


def by_map(rows: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, Mapping[str, Any]]]:
    """``{skymap: {solver: row}}`` (maps in first-seen order)."""
    out: dict[str, dict[str, Mapping[str, Any]]] = {}
    for r in rows:
        out.setdefault(str(r["skymap"]), {})[str(r["solver"])] = r
    return out


def scored(r: Mapping[str, Any] | None) -> bool:
    """True for a row with a plan the checker scored (a coverage)."""
    return r is not None and num(r.get("coverage")) is not None


def best_of(rows: Iterable[Mapping[str, Any]], a: str, b: str) -> list[dict[str, Any]]:
    """The paper's hybrid: per map, the plan of ``a`` or ``b`` with more coverage (``a`` on a tie)."""
    out = []
    for sol in by_map(rows).values():
        ra, rb = sol.get(a), sol.get(b)
        if not (scored(ra) and scored(rb)):
            continue
        pick = ra if num(ra["coverage"]) >= num(rb["coverage"]) else rb
        d = dict(pick)
        d["solver"] = f"best({a},{b})"
        d["runtime_s"] = (num(ra.get("runtime_s")) or 0.0) + (num(rb.get("runtime_s")) or 0.0)
        out.append(d)
    return out


def wins(rows: Iterable[Mapping[str, Any]], solver: str, other: str, key: str, tie: float) -> tuple[int, int, int]:
    """Maps where ``solver`` beats / loses to / ties with ``other`` on column ``key`` (``tie``: the margin)."""
    w = l = t = 0
    for sol in by_map(rows).values():
        a, b = sol.get(solver), sol.get(other)
        if a is None or b is None:
            continue
        x, y = num(a.get(key)), num(b.get(key))
        if x is None or y is None:
            continue
        if x > y + tie:
            w += 1
        elif y > x + tie:
            l += 1
        else:
            t += 1
    return w, l, t


def objective_of(rows: Sequence[Mapping[str, Any]]) -> str:
    """The objective column of a summary line: the rows' one objective, ``mixed``, or ``-`` (older CSVs)."""
    found = sorted({str(r.get("objective") or "") for r in rows} - {""})
    return found[0] if len(found) == 1 else ("mixed" if found else "-")
