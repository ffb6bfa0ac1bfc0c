"""Stage (d) of a study, in pictures: the paper's figures (PNG, Agg backend), from the result rows.

The coverage scatter and the efficiency gain against the 90 % area, for all
maps and for the similar-length subset (the bench's
:func:`~mushrooms.evaluation.bench.plots.make_plots`), the solve-time
histogram per solver and the 90 % area histograms of all maps and of the
subset.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from ..bench.compare import by_map, scored
from ..bench.plots import make_plots
from ..bench.rows import num
from .tables import comparison_pair, similar_length_maps

__all__ = ["make_figures"]

Rows = Sequence[Mapping[str, Any]]


def make_figures(rows: Rows, directory: str | Path) -> list[Path]:
    """The paper's figures (PNG): coverage scatter and efficiency vs 90 % area (all maps and the
    similar-length subset, the bench's :func:`~mushrooms.evaluation.bench.plots.make_plots`), the solve-time
    histogram per solver and the 90 % area histograms of all maps and of the subset.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    import matplotlib

    matplotlib.use("Agg")

    directory = Path(directory)
    written = make_plots(rows, directory)
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    ours, base = comparison_pair(solvers)
    subset = similar_length_maps(rows, ours, base) if ours and base else set()
    if subset:
        written += make_plots([r for r in rows if r["skymap"] in subset], directory / "similar_length")
    times = {s: [x for x in (num(r.get("solve_s")) for r in rows if r["solver"] == s and scored(r))
                 if x is not None and x > 0] for s in solvers}
    times = {s: t for s, t in times.items() if t}
    if times:
        written.append(_solve_time_hist(times, directory / "solve_time_hist.png"))
    area = {name: num(next(iter(sol.values())).get("area90_deg2")) for name, sol in by_map(rows).items()}
    area = {k: v for k, v in area.items() if v is not None and v > 0}
    if area and ours and base:
        written.append(_area_hist(area, subset, ours, base, directory / "area_hist_similar_length.png"))
    return written


def _solve_time_hist(times: Mapping[str, list[float]], out: Path) -> Path:
    """Histogram of the solve time per map (s, log bins), one step line per solver."""
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(6, 4))
    lo = min(min(t) for t in times.values())
    hi = max(max(t) for t in times.values())
    bins = np.geomspace(lo * 0.9, hi * 1.1, 25)
    for s, t in times.items():
        ax.hist(t, bins=bins, histtype="step", lw=1.5, label=f"{s} (median {np.median(t):.2f} s, mean {np.mean(t):.2f} s)")
    ax.set_xscale("log")
    ax.set_xlabel("solve time per map (s, wall clock)")
    ax.set_ylabel("sky maps")
    ax.set_title(f"solve time, {max(len(t) for t in times.values())} sky maps")
    return _save_histogram(fig, ax, out)


def _area_hist(area: Mapping[str, float], subset: set[str], ours: str, base: str, out: Path) -> Path:
    """Histograms of the 90 % credible area of all maps and of the similar-length subset."""
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(6, 4))
    bins = np.geomspace(min(area.values()) * 0.9, max(area.values()) * 1.1, 20)
    ax.hist(list(area.values()), bins=bins, alpha=0.5, label=f"all maps ({len(area)})")
    ax.hist([v for k, v in area.items() if k in subset], bins=bins, alpha=0.7,
            label=f"similar length, {ours} vs {base} ({sum(1 for k in area if k in subset)})")
    ax.set_xscale("log")
    ax.set_xlabel("90% credible area (deg$^2$)")
    ax.set_ylabel("sky maps")
    return _save_histogram(fig, ax, out)


def _save_histogram(fig: Any, ax: Any, out: Path) -> Path:
    """Finish a histogram of map counts (integer ticks, legend) and write it."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
