"""A population's figures from its ``results.csv`` rows (:mod:`.population_rows`): PNG, Agg backend.

* ``paired_by_distance_area.png``: per event, ours minus each baseline in
  coverage (planned, and as executed), against the true distance and the
  90 % area, BNS and NSBH marked apart;
* ``population.png``: the events' true distance and 90 % area by class, and
  each solver's planned and executed coverage per event.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from ..bench.compare import by_map, scored
from ..bench.rows import num
from .population_tables import BASELINES, complete_events

__all__ = ["population_figures"]

Rows = Sequence[Mapping[str, Any]]
#: Marker of each event class.
MARKERS = {"BNS": "o", "NSBH": "^"}


def population_figures(rows: Rows, directory: str | Path, ours: str = "service",
                       baselines: Sequence[str] = BASELINES, planned: str = "coverage") -> list[Path]:
    """Write the population's figures (events with every solver's row); the files written.

    ``baselines``: the rows ``ours`` is paired with, in order (those present);
    ``planned``: the column of planned coverage (the release: ``coverage_pairs``,
    every row counted by the pair rule).
    """
    import matplotlib

    matplotlib.use("Agg")
    rows = complete_events(rows)
    if not rows:
        return []
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    present = list(dict.fromkeys(str(r["solver"]) for r in rows))
    order = [s for s in (ours, *baselines) if s in present] + [s for s in present if s not in (ours, *baselines)]
    out = [_population(rows, directory / "population.png", order, planned)]
    if ours in present and any(b in present and b != ours for b in baselines):
        out.append(_paired(rows, ours, [b for b in baselines if b in present and b != ours],
                           directory / "paired_by_distance_area.png", planned))
    return out


def _differences(rows: Rows, a: str, b: str, key: str) -> list[tuple[float, float, float, str]]:
    """(distance, area, a − b in ``key``, class) per event both scored with ``key``."""
    out = []
    for sol in by_map([dict(r, skymap=r["event"]) for r in rows]).values():
        ra, rb = sol.get(a), sol.get(b)
        if scored(ra) and scored(rb):
            x, y = num(ra.get(key)), num(rb.get(key))
            if x is not None and y is not None:
                out.append((num(ra.get("distance_mpc")) or 0.0, num(ra.get("area90_deg2")) or 0.0, x - y,
                            str(ra.get("event_class"))))
    return out


def _paired(rows: Rows, ours: str, baselines: Sequence[str], path: Path, planned: str = "coverage") -> Path:
    """Rows: baselines; columns: against distance, against area; filled = planned, open = as executed."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(baselines), 2, figsize=(10, 3.0 * len(baselines)), squeeze=False)
    for i, b in enumerate(baselines):
        for key, filled in ((planned, True), ("coverage_executed", False)):
            d = _differences(rows, ours, b, key)
            for cls, marker in MARKERS.items():
                pts = [p for p in d if p[3] == cls]
                for j in (0, 1):
                    axes[i][j].scatter([p[j] for p in pts], [p[2] for p in pts], marker=marker, s=22,
                                       facecolors=f"C{list(MARKERS).index(cls)}" if filled else "none",
                                       edgecolors=f"C{list(MARKERS).index(cls)}",
                                       label=f"{cls}, {'planned' if filled else 'as executed'} ({len(pts)})")
        for j, label in ((0, "true distance (Mpc)"), (1, "90% credible area (deg$^2$)")):
            ax = axes[i][j]
            ax.axhline(0.0, color="k", lw=0.8)
            ax.set_xscale("log")
            ax.set_xlabel(label)
            ax.set_ylabel(f"coverage: {ours} − {b}")
        axes[i][1].legend(fontsize=7)
    fig.suptitle(f"{ours} against each baseline, per event ({len(by_map([dict(r, skymap=r['event']) for r in rows]))}"
                 " events)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _population(rows: Rows, path: Path, solvers: Sequence[str], planned: str = "coverage") -> Path:
    """Left: true distance against 90 % area by class; right: each solver's coverage, planned and executed."""
    import matplotlib.pyplot as plt
    import numpy as np

    events = {str(r["event"]): r for r in rows}
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    for k, (cls, marker) in enumerate(MARKERS.items()):
        ev = [r for r in events.values() if r.get("event_class") == cls]
        ax0.scatter([num(r.get("distance_mpc")) for r in ev], [num(r.get("area90_deg2")) for r in ev],
                    marker=marker, color=f"C{k}", s=22, label=f"{cls} ({len(ev)})")
    ax0.set_xscale("log")
    ax0.set_yscale("log")
    ax0.set_xlabel("true distance (Mpc)")
    ax0.set_ylabel("90% credible area (deg$^2$)")
    ax0.legend(fontsize=8)
    for i, s in enumerate(solvers):
        for key, dx, face in ((planned, -0.15, f"C{i}"), ("coverage_executed", 0.15, "none")):
            ys = [x for x in (num(r.get(key)) for r in rows if r["solver"] == s and scored(r)) if x is not None]
            if ys:
                ax1.scatter(i + dx + np.zeros(len(ys)), ys, s=14, facecolors=face, edgecolors=f"C{i}", alpha=0.7)
                ax1.plot([i + dx - 0.1, i + dx + 0.1], [np.mean(ys)] * 2, color="k", lw=2)
    ax1.set_xticks(range(len(solvers)), solvers, rotation=20, ha="right")
    ax1.set_ylabel("coverage per event")
    ax1.set_title(f"filled: planned ({planned}), open: as ZTF would execute it; bar: mean", fontsize=9)
    fig.suptitle(f"the population: {len(events)} events")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
