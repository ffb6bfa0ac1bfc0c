"""Stage (d) of a study, in words: the paper's Tables 2-3 layout (Markdown), from the result rows."""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from ..bench.compare import SIMILAR_LENGTH, TIE_COVERAGE, TIE_EFFICIENCY, best_of, by_map, objective_of, scored, wins
from ..bench.rows import num

__all__ = ["similar_length_maps", "comparison_pair", "paper_tables"]


def _baselines(solvers: Sequence[str]) -> list[str]:
    return [b for b in ("greedy", "gwemopt", "gwemopt-repaired") if b in solvers]


def similar_length_maps(rows: Sequence[Mapping[str, Any]], a: str, b: str,
                        within: int = SIMILAR_LENGTH) -> set[str]:
    """The paper's similar-length subset: maps where ``a`` and ``b`` plan within ``within`` exposures."""
    out = set()
    for name, sol in by_map(rows).items():
        ra, rb = sol.get(a), sol.get(b)
        if scored(ra) and scored(rb):
            na, nb = num(ra.get("n_exposures")), num(rb.get("n_exposures"))
            if na is not None and nb is not None and abs(na - nb) <= within:
                out.add(name)
    return out


def comparison_pair(solvers: Sequence[str]) -> tuple[str | None, str | None]:
    """(ours, baseline) of the paper's comparison: the service's plan (else MUSHROOMS' best solver) against
    gwemopt, else greedy."""
    base = next((s for s in ("gwemopt", "gwemopt-repaired", "greedy") if s in solvers), None)
    ours = next((s for s in ("service", "hybrid", "blocks", "milp", "slots", "greedy") if s in solvers and s != base),
                None)
    return ours, base


def _table(rows: Sequence[Mapping[str, Any]], names: Sequence[str], baselines: Sequence[str],
           eff_keys: Sequence[str]) -> list[str]:
    head = ["solver", "objective", "maps", "coverage", "cov. executed"] + [f"eff. {k}" for k in eff_keys]
    head += ["n_exp", "cov/bound"]
    head += [f"vs {b}: cov W/L/T" for b in baselines] + [f"vs {b}: eff. {k[:4]} W/L/T" for b in baselines
                                                          for k in eff_keys]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in names:
        rs = [r for r in rows if r["solver"] == s and scored(r)]

        def mean(key: str, digits: int = 4) -> str:
            xs = [x for x in (num(r.get(key)) for r in rs) if x is not None]
            return f"{sum(xs) / len(xs):.{digits}f}" if xs else "-"

        cells = [s, objective_of(rs), str(len(rs)), mean("coverage"), mean("coverage_as_executed")]
        cells += [mean(f"efficiency_{k}") for k in eff_keys]
        cells += [mean("n_exposures", 1), mean("coverage_over_bound")]
        for b in baselines:
            cells.append("-" if b == s else "%d/%d/%d" % wins(rows, s, b, "coverage", TIE_COVERAGE))
        for b in baselines:
            for k in eff_keys:
                cells.append("-" if b == s else "%d/%d/%d" % wins(rows, s, b, f"efficiency_{k}",
                                                                         TIE_EFFICIENCY))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def paper_tables(rows: Sequence[Mapping[str, Any]],
                 eff_keys: Sequence[str] = ("optimistic", "conservative", "nsbh")) -> str:
    """The paper's Tables 2-3 layout (Markdown): all maps, then the similar-length subset.

    Per solver, and for the paper's hybrid best-of(ours, baseline): maps
    scored, mean coverage (planned, and as executed when the rows have
    ``coverage_as_executed``), mean efficiency per light curve, mean exposures,
    mean coverage over the certified bound, and wins/losses/ties against each
    baseline present (greedy, gwemopt, gwemopt-repaired).  The subset is the
    paper's: maps where ours and the baseline plan within
    :data:`~mushrooms.evaluation.SIMILAR_LENGTH` exposures of each other.
    """
    rows = [dict(r) for r in rows]
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    ours, base = comparison_pair(solvers)
    extra = best_of(rows, ours, base) if ours and base else []
    names = solvers + ([f"best({ours},{base})"] if extra else [])
    allrows = rows + extra
    baselines = _baselines(solvers)
    n_maps = len(by_map(rows))
    n_failed = sum(1 for r in rows if not scored(r))
    lines = [f"All maps ({n_maps}; {n_failed} (map, solver) result(s) without a plan). "
             "W/L/T: maps won/lost/tied against the baseline (coverage tie <= 1e-4, efficiency tie <= 1e-3).", ""]
    lines += _table(allrows, names, baselines, eff_keys)
    if ours and base:
        subset = similar_length_maps(rows, ours, base)
        lines += ["", f"Similar-length subset ({len(subset)} of {n_maps} maps: |n_exposures({ours}) - "
                      f"n_exposures({base})| <= {SIMILAR_LENGTH}, the paper's section 4.1).", ""]
        lines += _table([r for r in allrows if r["skymap"] in subset], names, baselines, eff_keys)
    return "\n".join(lines)
