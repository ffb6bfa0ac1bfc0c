"""The benchmark's paper-style figures (PNG, Agg backend), read from the rows.

``coverage_scatter.png``: per-map coverage of MUSHROOMS (hybrid, else
slots, blocks, greedy) against the baseline (gwemopt, else greedy), with
y = x.  ``efficiency_vs_area.png``: percent improvement in efficiency of
best-of(MUSHROOMS, baseline) over the baseline against the 90 % area.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from .compare import by_map, scored
from .rows import num

__all__ = ["make_plots"]

Pairs = list[tuple[Mapping[str, Any], Mapping[str, Any]]]


def make_plots(rows: Sequence[Mapping[str, Any]], directory: str | Path) -> list[Path]:
    """Paper-style figures (PNG, Agg backend): the coverage scatter and the efficiency gain against the area.

    Returns
    -------
    list of pathlib.Path
        Files written (none when fewer than two solvers have plans).
    """
    import matplotlib

    matplotlib.use("Agg")

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    solvers = set(str(r["solver"]) for r in rows if scored(r))
    ours = next((s for s in ("hybrid", "slots", "blocks", "milp", "greedy") if s in solvers), None)
    base = next((s for s in ("gwemopt", "greedy") if s in solvers and s != ours), None)
    if ours is None or base is None:
        return []
    pairs = [(sol[ours], sol[base]) for sol in by_map(rows).values()
             if scored(sol.get(ours)) and scored(sol.get(base))]
    return [_coverage_scatter(pairs, ours, base, directory / "coverage_scatter.png"),
            _efficiency_vs_area(pairs, ours, base, directory / "efficiency_vs_area.png")]


def _valid(row: Mapping[str, Any]) -> bool:
    return row.get("valid") in (True, "True")


def _coverage_scatter(pairs: Pairs, ours: str, base: str, out: Path) -> Path:
    """Coverage of ours (x) against the baseline's (y), one point per map, hollow where a plan is invalid."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 5))
    ok = [bool(_valid(a) and _valid(b)) for a, b in pairs]
    for flag, style in ((True, dict(c="C0", label="both plans valid")),
                        (False, dict(facecolors="none", edgecolors="C3", label="a plan fails the checker"))):
        x = [num(a["coverage"]) for (a, _), v in zip(pairs, ok) if v == flag]
        y = [num(b["coverage"]) for (_, b), v in zip(pairs, ok) if v == flag]
        if x:
            ax.scatter(x, y, s=16, **style)
    ax.plot([0, 1], [0, 1], color="gold", lw=1.5, label="y = x")
    ax.set_xlabel(f"probability coverage, {ours}")
    ax.set_ylabel(f"probability coverage, {base}")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_title(f"{len(pairs)} sky maps (below the line: {ours} better)")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _efficiency_gains(pairs: Pairs, lightcurve: str) -> tuple[list[float], list[float]]:
    """(90 % areas, percent gain of best-of(ours, baseline) over the baseline) of the maps that have both."""
    xs, ys = [], []
    for a, b in pairs:
        area = num(a.get("area90_deg2"))
        ea, eb = num(a.get(f"efficiency_{lightcurve}")), num(b.get(f"efficiency_{lightcurve}"))
        if area is None or ea is None or eb is None or eb <= 0:
            continue
        hybrid = ea if num(a["coverage"]) >= num(b["coverage"]) else eb
        xs.append(area)
        ys.append(100.0 * (hybrid - eb) / eb)
    return xs, ys


def _efficiency_vs_area(pairs: Pairs, ours: str, base: str, out: Path) -> Path:
    """Efficiency gain of best-of(ours, baseline) over the baseline against the 90 % area, per light curve."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    plotted = 0
    for k, marker in (("conservative", "o"), ("optimistic", "^")):
        xs, ys = _efficiency_gains(pairs, k)
        ax.scatter(xs, ys, s=16, marker=marker, label=f"{k} light curve", alpha=0.8)
        plotted += len(xs)
    ax.axhline(0, color="grey", lw=0.8)
    if plotted:  # a log axis needs a point (no map with a nonzero baseline efficiency: an empty figure)
        ax.set_xscale("log")
    ax.set_xlabel("90% credible area (deg$^2$)")
    ax.set_ylabel(f"efficiency gain of best({ours},{base})\nover {base} (%)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
