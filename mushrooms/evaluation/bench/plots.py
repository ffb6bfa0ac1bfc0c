"""The benchmark's paper-style figures (PNG, Agg backend), read from the rows.

``coverage_scatter.png``: per-map coverage of MUSHROOMS (hybrid, else
slots, blocks, greedy) against the baseline (gwemopt, else greedy), with
y = x.  ``efficiency_vs_area.png``: percent improvement in efficiency of
best-of(MUSHROOMS, baseline) over the baseline against the 90 % area.
For each row under an arm (``hybrid@menu``) and its row without it
(``hybrid``): ``paired_<row>.png``, the per-map paired difference against the
map's mean distance (the injection efficiency with its 2-sigma Monte Carlo
error, and the exact expected detections, per light curve), and
``exposure_vs_distance_<row>.png``, the plan's probability-weighted mean
exposure (and the shortest and longest it took) against the mean distance.
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
    out = _arm_plots(rows, solvers, directory)
    ours = next((s for s in ("hybrid", "slots", "blocks", "milp", "greedy") if s in solvers), None)
    base = next((s for s in ("gwemopt", "greedy") if s in solvers and s != ours), None)
    if ours is None or base is None:
        return out
    pairs = [(sol[ours], sol[base]) for sol in by_map(rows).values()
             if scored(sol.get(ours)) and scored(sol.get(base))]
    return [_coverage_scatter(pairs, ours, base, directory / "coverage_scatter.png"),
            _efficiency_vs_area(pairs, ours, base, directory / "efficiency_vs_area.png")] + out


#: Light curves of the arm figures: (column suffix, marker, colour).
CURVES = (("optimistic", "^", "C0"), ("conservative", "o", "C1"), ("nsbh", "s", "C2"))


def _arm_plots(rows: Sequence[Mapping[str, Any]], solvers: set[str], directory: Path) -> list[Path]:
    """The two figures of every ``<row>@<arm>`` whose ``<row>`` was run too (pairs: (row, arm row) per map)."""
    out = []
    for s in sorted(solvers):
        ref, sep, arm = s.partition("@")
        if not sep or ref not in solvers:
            continue
        pairs = [(sol[ref], sol[s]) for sol in by_map(rows).values()
                 if scored(sol.get(ref)) and scored(sol.get(s)) and num(sol[s].get("distmean_mpc")) is not None]
        if not pairs:
            continue
        tag = s.replace("@", "_at_")
        out.append(_paired_figure(pairs, ref, s, directory / f"paired_{tag}.png"))
        out.append(_exposure_figure(pairs, ref, s, directory / f"exposure_vs_distance_{tag}.png"))
    return out


def _paired_figure(pairs: Pairs, ref: str, arm: str, out: Path) -> Path:
    """Per map: paired efficiency difference (2-sigma bars) and exact expected-detection difference vs distance."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.3), sharey=True)
    for k, marker, colour in CURVES:
        x, d, e, dx = [], [], [], []
        for a, b in pairs:
            dist = num(a.get("distmean_mpc"))
            diff, err = num(b.get(f"efficiency_{k}_diff")), num(b.get(f"efficiency_{k}_differr"))
            if diff is not None and err is not None:
                x.append(dist), d.append(diff), e.append(2 * err)
            ea, eb = num(a.get(f"expected_{k}")), num(b.get(f"expected_{k}"))
            if ea is not None and eb is not None:
                dx.append((dist, eb - ea))
        axes[0].errorbar(x, d, yerr=e, fmt=marker, color=colour, ms=4, capsize=2, alpha=0.8, label=k)
        axes[1].scatter([p for p, _ in dx], [q for _, q in dx], marker=marker, color=colour, s=18, alpha=0.8, label=k)
    for ax, what in zip(axes, ("injection efficiency (Monte Carlo, 2$\\sigma$ bars)", "exact expected detections (X1)")):
        ax.axhline(0, color="grey", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1e-2)  # most maps differ by < 0.01, a few by most of the probability
        ax.grid(True, which="major", axis="y", lw=0.3, alpha=0.6)
        ax.set_xlabel("map's mean distance (Mpc)")
        ax.set_title(what, fontsize=10)
        ax.legend(fontsize=8)
    axes[0].set_ylabel(f"{arm} $-$ {ref}, paired per map\n(symmetric log: linear within $\\pm$0.01)")
    fig.suptitle(f"{len(pairs)} sky maps: above 0, {arm} detects more", fontsize=11)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def _exposure_figure(pairs: Pairs, ref: str, arm: str, out: Path) -> Path:
    """The arm's probability-weighted mean exposure per map (bars: shortest to longest taken) vs distance."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for rows_of, name, style in ((lambda a, b: b, arm, dict(fmt="o", color="C3")),
                                 (lambda a, b: a, ref, dict(fmt="x", color="grey"))):
        x, y, lo, hi = [], [], [], []
        for a, b in pairs:
            r = rows_of(a, b)
            mean = num(r.get("exposure_mean_s"))
            lengths = [float(p.split(":")[0]) for p in str(r.get("exposure_mix") or "").split()]
            if mean is None or not lengths:
                continue
            x.append(num(r.get("distmean_mpc"))), y.append(mean)
            lo.append(mean - min(lengths)), hi.append(max(lengths) - mean)
        ax.errorbar(x, y, yerr=[lo, hi], ms=4, capsize=2, alpha=0.8, lw=0.8, label=name, **style)
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax.set_xscale("log")
    ax.set_yscale("log")
    seen = sorted({float(p.split(":")[0]) for _, b in pairs for p in str(b.get("exposure_mix") or "").split()}
                  | {float(p.split(":")[0]) for a, _ in pairs for p in str(a.get("exposure_mix") or "").split()})
    if seen:
        ax.set_yticks(seen)
        ax.yaxis.set_major_formatter(ScalarFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_ylim(min(seen) / 1.3, max(seen) * 1.3)
    ax.set_xlabel("map's mean distance (Mpc)")
    ax.set_ylabel("exposure (s): probability-weighted mean\nbars: shortest to longest in the plan")
    ax.set_title(f"{len(pairs)} sky maps: exposures {arm} chose", fontsize=11)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


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
