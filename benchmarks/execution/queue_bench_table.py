#!/usr/bin/env python
"""The executed-coverage table and picture from ``mushrooms bench`` CSVs (rows with ``coverage_as_executed``).

Per solver row: planned coverage (the checker's ``coverage``), what ZTF's
scheduler keeps of it as cadence-valid pairs (the executor model, clear
night) with the old export (one list queue, ``coverage_single_queue``) and
the queue set (``coverage_as_executed``), the queue set with the telescope
free 15/30/60 min late, the maps where the executed coverage is below 0.9 x
the planned one, and the queues per revision.  Ratios are sums over the
maps (executed / planned).  Writes the picture planned vs executed per map.

    python benchmarks/execution/queue_bench_table.py OUT.png A.csv [B.csv ...]
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict

KEYS = ("coverage_single_queue", "coverage_as_executed", "coverage_late_15", "coverage_late_30", "coverage_late_60")


def _num(v):
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def load(paths):
    rows = defaultdict(list)  # (file tag, solver) -> rows
    for path in paths:
        tag = path.rsplit("/", 1)[-1].removesuffix(".csv")
        for r in csv.DictReader(open(path)):
            if _num(r.get("coverage")) is None or _num(r.get("coverage_as_executed")) is None:
                continue
            rows[tag, r["solver"]].append(r)
    return rows


def table(rows) -> list[str]:
    head = ("| run | solver | maps | planned (sum) | old export: one list queue | queue set | late 15 | late 30 "
            "| late 60 | maps < 0.9 x planned (old -> new) | queues per revision |")
    out = [head, "|" + "---|" * (head.count("|") - 1)]
    for (tag, solver), rs in sorted(rows.items()):
        planned = sum(_num(r["coverage"]) for r in rs)
        ratio = {k: sum(_num(r[k]) or 0.0 for r in rs) / planned if planned else 0.0 for k in KEYS}
        low_old = sum((_num(r["coverage_single_queue"]) or 0.0) < 0.9 * _num(r["coverage"]) for r in rs)
        low_new = sum((_num(r["coverage_as_executed"]) or 0.0) < 0.9 * _num(r["coverage"]) for r in rs)
        k = sorted(int(_num(r["n_queues"]) or 0) for r in rs)
        median = k[len(k) // 2]
        out.append(f"| {tag} | {solver} | {len(rs)} | {planned:.3f} | x{ratio[KEYS[0]]:.3f} | x{ratio[KEYS[1]]:.3f} | "
                   f"x{ratio[KEYS[2]]:.3f} | x{ratio[KEYS[3]]:.3f} | x{ratio[KEYS[4]]:.3f} | {low_old} -> {low_new} | "
                   f"{k[0]}-{k[-1]} (median {median}) |")
    return out


def low_maps(rows) -> list[str]:
    out = []
    for (tag, solver), rs in sorted(rows.items()):
        low = [f"{r['skymap'].rsplit('skymaps/', 1)[-1]} ({_num(r['coverage_as_executed']):.3f} of "
               f"{_num(r['coverage']):.3f})" for r in rs
               if (_num(r["coverage_as_executed"]) or 0.0) < 0.9 * _num(r["coverage"])]
        out.append(f"{tag} {solver}: queue set < 0.9 x planned on {len(low)} map(s): {', '.join(low) or '-'}")
    return out


def picture(rows, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    palette = ["tab:blue", "tab:red", "tab:cyan", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:gray"]
    colours = dict(zip(sorted(rows), palette * 2))
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2), sharey=True)
    panels = [("on time", [("coverage_single_queue", "o", "none", "one list queue (old)"),
                           ("coverage_as_executed", "o", None, "queue set (new)")]),
              ("telescope free 60 min late", [("coverage_late_60", "s", None, "queue set, 60 min late")])]
    for ax, (title, series) in zip(axes, panels):
        for (tag, solver), rs in sorted(rows.items()):
            x = [_num(r["coverage"]) for r in rs]
            for key, marker, face, label in series:
                y = [_num(r[key]) or 0.0 for r in rs]
                c = colours[tag, solver]
                ax.scatter(x, y, marker=marker, s=22, edgecolors=c, facecolors=c if face is None else face, linewidths=0.9,
                           label=f"{solver} ({tag.replace('bench_', '')}): {label}")
        ax.plot([0, 1], [0, 1], color="0.3", lw=0.8)
        ax.plot([0, 1], [0, 0.9], color="0.6", lw=0.8, ls="--")
        ax.set_xlim(0, 1.02)
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("planned coverage (plan's fields, g+r)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("executed cadence-valid coverage (pairs >= 30 min)")
    axes[0].legend(fontsize=6.5, loc="upper left")
    axes[1].legend(fontsize=6.5, loc="upper left")
    fig.suptitle("Planned vs executed per map (ZTF's scheduler modelled; solid line: equal, dashed: 0.9 x)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def main(argv) -> int:
    rows = load(argv[1:])
    print("\n".join(table(rows)))
    print()
    print("\n".join(low_maps(rows)))
    picture(rows, argv[0])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
