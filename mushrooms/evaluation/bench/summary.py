"""The benchmark's summary table on stdout: means, medians, validity, wall times, wins and losses.

Read from the rows alone (those of a run, or :func:`~.rows.read_csv` of an
earlier CSV), so a summary can be remade without planning again.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .compare import SIMILAR_LENGTH, TIE_COVERAGE, TIE_EFFICIENCY, best_of, by_map, objective_of, scored, wins
from .rows import num

__all__ = ["summarize"]

Rows = Sequence[Mapping[str, Any]]
#: Rows compared first: the lower rank of a pair is the base it is compared with.
BASELINES = ("greedy", "gwemopt", "gwemopt-repaired")


def summarize(rows: Rows, eff_keys: Sequence[str] = ("optimistic", "conservative", "nsbh")) -> str:
    """The summary table: means, medians, validity, wall times, wins/losses.

    Parameters
    ----------
    rows : sequence of mapping
        Result rows (as written to the CSV).
    eff_keys : sequence of str
        Light-curve suffixes of the efficiency columns.

    Returns
    -------
    str
        A plain-text table for stdout (and the issue note).
    """
    rows = list(rows)
    solvers = [s for s in dict.fromkeys(str(r["solver"]) for r in rows)]
    extra = []
    block_name = next((b for b in ("blocks", "milp") if b in solvers), None)
    if block_name and "gwemopt" in solvers:
        extra = best_of(rows, block_name, "gwemopt")
    all_rows = rows + extra
    names = solvers + ([f"best({block_name},gwemopt)"] if extra else [])
    lines = [f"maps: {len(by_map(rows))}; coverage = probability in the planned fields (checker); "
             f"efficiency = detected/injected; times in s (wall clock)"]
    lines += _means_table(all_rows, names, eff_keys)
    lines += _missing_lines(rows)
    lines += _versus_lines(all_rows, names, eff_keys)
    lines += _paired_lines(rows, solvers, eff_keys)
    lines += paired_table(rows, solvers, eff_keys)
    if "gwemopt" in solvers:
        lines += _similar_length_lines(all_rows, names, eff_keys)
    return "\n".join(lines)


def _stat(values: list[float], fn: Callable[[Any], Any]) -> str:
    return f"{fn(values):.4f}" if values else "-"


def _values(rows: Rows, key: str) -> list[float]:
    """The finite numbers of one column."""
    return [x for x in (num(r.get(key)) for r in rows) if x is not None]


def _means_table(rows: Rows, names: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Header, rule and one line per solver of the rows with a plan."""
    head = (f"{'solver':<20}{'objective':<10}{'n':>4}{'valid':>6}{'cov mean':>10}{'cov med':>9}"
            + "".join(f"{'eff ' + k[:4] + ' mean':>15}" for k in eff_keys)
            + f"{'n_exp mean':>11}{'time med':>10}{'time mean':>10}{'cov/bound':>10}{'c/b med':>9}")
    lines = [head, "-" * len(head)]
    for s in names:
        rs = [r for r in rows if r["solver"] == s and scored(r)]
        cov = [num(r["coverage"]) for r in rs]
        effs = [_values(rs, f"efficiency_{k}") for k in eff_keys]
        rt, nexp, cb = _values(rs, "runtime_s"), _values(rs, "n_exposures"), _values(rs, "coverage_over_bound")
        valid = sum(1 for r in rs if r.get("valid") in (True, "True"))
        lines.append(
            f"{s:<20}{objective_of(rs):<10}{len(rs):>4}{valid:>6}{_stat(cov, np.mean):>10}{_stat(cov, np.median):>9}"
            + "".join(f"{_stat(e, np.mean):>15}" for e in effs)
            + f"{_stat(nexp, np.mean)[:-2] if nexp else '-':>11}{_stat(rt, np.median)[:-2] if rt else '-':>10}"
            + f"{_stat(rt, np.mean)[:-2] if rt else '-':>10}"
            + f"{_stat(cb, np.mean):>10}{_stat(cb, np.median):>9}"
        )
    return lines


def _missing_lines(rows: Rows) -> list[str]:
    """Per solver, the maps without a plan, counted by status."""
    missing: dict[str, list[str]] = {}
    for r in rows:
        if not scored(r):
            missing.setdefault(str(r["solver"]), []).append(str(r.get("status", ""))[:40])
    lines = []
    for s, sts in missing.items():
        counts: dict[str, int] = {}
        for x in sts:
            counts[x] = counts.get(x, 0) + 1
        lines.append(f"  {s}: {len(sts)} map(s) without a plan: " + ", ".join(f"{k} x{v}" for k, v in counts.items()))
    return lines


def _versus_lines(rows: Rows, names: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Wins/losses/ties of every pair of solvers (each against its base: greedy, then gwemopt's rows)."""
    lines = ["", "A vs B: maps where A wins/loses/ties against B (coverage tie <= 1e-4; efficiency tie <= 1e-3):"]

    def rank(name: str) -> int:  # the lower rank of a pair is the base it is compared with
        return BASELINES.index(name) if name in BASELINES else len(BASELINES) + names.index(name)

    for i, a in enumerate(names):
        for b in names[i + 1:]:
            base, s = sorted((a, b), key=rank)
            parts = [f"coverage {'%d/%d/%d' % wins(rows, s, base, 'coverage', TIE_COVERAGE)}"]
            for k in eff_keys:
                parts.append(f"eff_{k[:4]} {'%d/%d/%d' % wins(rows, s, base, f'efficiency_{k}', TIE_EFFICIENCY)}")
            lines.append(f"  {s} vs {base}: " + ", ".join(parts))
    return lines


def _mean_err(rows: Rows, key: str) -> tuple[float, float, int, int, int] | None:
    """Mean of per-map paired differences, its error, and maps better / worse beyond 2 sigma / total."""
    pairs = [(num(r.get(key)), num(r.get(key + "err"))) for r in rows]
    pairs = [(d, e) for d, e in pairs if d is not None and e is not None]
    if not pairs:
        return None
    d = np.array([x for x, _ in pairs])
    e = np.array([y for _, y in pairs])
    better = int(np.sum(d > 2 * e + 1e-12))
    worse = int(np.sum(d < -2 * e - 1e-12))
    return float(d.mean()), float(np.sqrt(np.sum(e ** 2)) / d.size), better, worse, d.size


def _paired_lines(rows: Rows, solvers: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Summary lines for the paired differences (vs the reference solver; v1 -> fixed source model)."""
    return _reference_lines(rows, solvers, eff_keys) + _v1_lines(rows, solvers, eff_keys)


def _reference_lines(rows: Rows, solvers: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Mean paired efficiency difference of each solver against the reference row."""
    diff_solvers = [s for s in solvers
                    if any(num(r.get(f"efficiency_{k}_diff")) is not None for r in rows if r["solver"] == s
                           for k in eff_keys)]
    if not diff_solvers:
        return []
    ref = [s for s in solvers if s not in diff_solvers]
    lines = ["", f"paired efficiency differences vs {ref[0] if ref else 'the reference'} (same injections; "
                 "error of the mean = sqrt(sum err^2)/maps; better/worse = beyond 2 sigma on that map):"]
    for s in diff_solvers:
        rs = [r for r in rows if r["solver"] == s]
        parts = []
        for k in eff_keys:
            m = _mean_err(rs, f"efficiency_{k}_diff")
            if m is not None:
                parts.append(f"{k} {m[0]:+.4f} ± {m[1]:.4f} (better {m[2]}, worse {m[3]} of {m[4]})")
        lines.append(f"  {s}: " + "; ".join(parts))
    return lines


def _v1_lines(rows: Rows, solvers: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """The first release's scores of the same plans against the fixed source model's."""
    if not any(num(r.get(f"efficiency_{k}_v1")) is not None for r in rows for k in eff_keys):
        return []
    lines = ["", "first-release scoring (v1: flat 300 s limits, dark before 0.202 d) -> fixed source model, "
                 "same plans (mean v1 -> mean new, paired change ± error):"]
    for s in solvers:
        rs = [r for r in rows if r["solver"] == s]
        parts = []
        for k in eff_keys:
            v1 = _values(rs, f"efficiency_{k}_v1")
            v2 = [num(r.get(f"efficiency_{k}")) for r in rs if num(r.get(f"efficiency_{k}_v1")) is not None]
            m = _mean_err(rs, f"efficiency_{k}_v1diff")
            if v1 and m is not None:
                parts.append(f"{k} {np.mean(v1):.4f} -> {np.mean(v2):.4f} ({m[0]:+.4f} ± {m[1]:.4f})")
        if parts:
            lines.append(f"  {s}: " + "; ".join(parts))
    return lines


def _similar_length_lines(rows: Rows, names: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """The paper's section 4.1 subset: maps where a solver plans within SIMILAR_LENGTH exposures of gwemopt."""
    lines = ["", f"similar-length subset (|n_exposures - gwemopt's| <= {SIMILAR_LENGTH}, the paper's section 4.1):"]
    for s in names:
        if s == "gwemopt":
            continue
        pairs = [(sol[s], sol["gwemopt"]) for sol in by_map(rows).values()
                 if scored(sol.get(s)) and scored(sol.get("gwemopt"))
                 and abs((num(sol[s].get("n_exposures")) or 0) - (num(sol["gwemopt"].get("n_exposures")) or 0))
                 <= SIMILAR_LENGTH]
        if not pairs:
            lines.append(f"  {s}: no map")
            continue
        parts = [f"{len(pairs)} maps", f"coverage {s} {np.mean([num(a['coverage']) for a, _ in pairs]):.4f}"
                 f" vs gwemopt {np.mean([num(b['coverage']) for _, b in pairs]):.4f}"]
        for k in eff_keys:
            ea = [num(a.get(f"efficiency_{k}")) for a, _ in pairs]
            eb = [num(b.get(f"efficiency_{k}")) for _, b in pairs]
            both = [(x, y) for x, y in zip(ea, eb) if x is not None and y is not None]
            if both:
                parts.append(f"eff_{k[:4]} {np.mean([x for x, _ in both]):.4f} vs {np.mean([y for _, y in both]):.4f}")
        lines.append(f"  {s}: " + ", ".join(parts))
    return lines


def _exact_diff(values: list[float], tie: float) -> tuple[float, float, int, int, int]:
    """Mean of exact per-map differences, its paired standard error over maps, maps above / below ``tie``, maps."""
    d = np.array(values)
    se = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("nan")
    return float(d.mean()), se, int(np.sum(d > tie)), int(np.sum(d < -tie)), d.size


def paired_table(rows: Rows, solvers: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Each row against the reference, per light curve: the injection efficiency and the exact expected
    detections of both, their paired difference and its standard error, the maps better / worse beyond
    their error, and the coverage beside them (rows with ``expected_<lc>_diff``: an arm against its
    fixed configuration, ``hybrid@menu`` against ``hybrid``).

    Efficiency: Monte Carlo per map (same injections), error of the mean sqrt(sum err^2)/maps, a map better
    / worse beyond 2 sigma of its own paired error.  Expected detections (X1) and coverage are exact per map:
    the error is the paired standard error over maps, a map better / worse beyond 1e-3 (coverage 1e-4).
    """
    paired = [s for s in solvers if any(num(r.get(f"expected_{k}_diff")) is not None
                                        for r in rows if r["solver"] == s for k in eff_keys)]
    if not paired:
        return []
    ref = next((s for s in solvers if s not in paired
                and any(num(r.get(f"expected_{k}")) is not None for r in rows if r["solver"] == s for k in eff_keys)),
               "the reference")
    per_map = by_map(rows)
    lines = ["", f"paired against {ref} (same maps, same injections): A = {ref}, B = the row; efficiency: "
                 "Monte Carlo, +- error of the mean, better/worse beyond 2 sigma on that map; E = exact expected "
                 f"detections (X1) and coverage: +- paired standard error over maps, better/worse beyond "
                 f"{TIE_EFFICIENCY:g} ({TIE_COVERAGE:g} coverage):"]
    for s in paired:
        pairs = [(m[ref], m[s]) for m in per_map.values() if scored(m.get(ref)) and scored(m.get(s))]
        lines.append(f"  {s} vs {ref}: {len(pairs)} maps, plans valid {sum(_ok(b) for _, b in pairs)}/{len(pairs)} "
                     f"(A {sum(_ok(a) for a, _ in pairs)}/{len(pairs)})")
        for k in eff_keys:
            a_eff = [num(a.get(f"efficiency_{k}")) for a, b in pairs if num(b.get(f"efficiency_{k}_diff")) is not None]
            m = _mean_err([b for _, b in pairs], f"efficiency_{k}_diff")
            ex = [(num(a.get(f"expected_{k}")), num(b.get(f"expected_{k}"))) for a, b in pairs]
            ex = [(x, y) for x, y in ex if x is not None and y is not None]
            if m is None or not ex:
                continue
            d = _exact_diff([y - x for x, y in ex], TIE_EFFICIENCY)
            ea, eb = float(np.mean([x for x, _ in ex])), float(np.mean([y for _, y in ex]))
            lines.append(f"    {k:<13} efficiency A {np.mean(a_eff):.4f} B {np.mean(a_eff) + m[0]:.4f} "
                         f"diff {m[0]:+.4f} ± {m[1]:.4f} (better {m[2]}, worse {m[3]} of {m[4]}) | "
                         f"E A {ea:.4f} B {eb:.4f} diff {d[0]:+.4f} ± {d[1]:.4f} x{eb / ea if ea > 0 else float('nan'):.3f} "
                         f"(better {d[2]}, worse {d[3]} of {d[4]})")
        cov = [(num(a["coverage"]), num(b["coverage"])) for a, b in pairs]
        d = _exact_diff([y - x for x, y in cov], TIE_COVERAGE)
        lines.append(f"    {'coverage':<13} A {np.mean([x for x, _ in cov]):.4f} B {np.mean([y for _, y in cov]):.4f} "
                     f"diff {d[0]:+.4f} ± {d[1]:.4f} (better {d[2]}, worse {d[3]} of {d[4]})")
        other = sum(bool(_lengths(b) - _lengths(a)) for a, b in pairs)
        em = _values([b for _, b in pairs], "exposure_mean_s")
        ea = _values([a for a, _ in pairs], "exposure_mean_s")
        lines.append(f"    {'exposures':<13} maps where B took exposures A did not {other}/{len(pairs)}; "
                     f"probability-weighted mean exposure median A {np.median(ea) if ea else float('nan'):.0f} s, "
                     f"B {np.median(em) if em else float('nan'):.0f} s; solve time median A "
                     f"{np.median(_values([a for a, _ in pairs], 'solve_s') or [np.nan]):.2f} s, B "
                     f"{np.median(_values([b for _, b in pairs], 'solve_s') or [np.nan]):.2f} s")
        sides = ([a for a, _ in pairs], [b for _, b in pairs])
        starved = [sum(_no_grid(r) and not _kept_reason(r) for r in side) for side in sides]
        decided = [[_kept_reason(r) for r in side if _kept_reason(r)] for side in sides]
        reasons = ", ".join(f"{k} {decided[1].count(k)}" for k in sorted(set(decided[1])))
        lines.append(f"    {'detection':<13} detection stage tried grids and solved no grid: A {starved[0]}, "
                     f"B {starved[1]} maps; kept by decision: A {len(decided[0])}, B {len(decided[1])} maps"
                     + (f" ({reasons})" if reasons else ""))
    return lines


def _ok(row: Mapping[str, Any]) -> bool:
    return row.get("valid") in (True, "True")


def _lengths(row: Mapping[str, Any]) -> set[str]:
    """The exposure lengths of a row's plan (from ``exposure_mix``)."""
    return {p.split(":")[0] for p in str(row.get("exposure_mix") or "").split()}


def _kept_reason(row: Mapping[str, Any]) -> str:
    """Why the detection stage kept the coverage plan without trying a grid (``coverage (<reason>); ...``), or ''."""
    stage = str(row.get("detection_stage") or "")
    if not stage.startswith("coverage (") or ")" not in stage:
        return ""
    return stage[len("coverage ("):stage.index(")")]


def _no_grid(row: Mapping[str, Any]) -> bool:
    """The row's detection stage ran but solved no grid (``detection_stage`` says ``0 grid(s) solved``)."""
    return "; 0 grid(s) solved" in str(row.get("detection_stage") or "")
