"""The shared sky maps, one JSON line per map, resumable: the loop of the side-by-side benchmarks.

A benchmark gives a function that runs every arm on one map (the arm going first alternating with the
map's position) and returns a JSON-able row; rows already in the output file are read back, not rerun.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[2]
SKYMAPS = ROOT.parent / "shared" / "data" / "skymaps"


def shared_maps(given: list[Path] | None = None) -> list[Path]:
    """``given``, else every *.fits / *.fits.gz under ../shared/data/skymaps/{public,simulated}, sorted."""
    return list(given) if given else sorted(p for d in ("public", "simulated") for p in (SKYMAPS / d).rglob("*.fits*")
                                            if p.name.endswith((".fits", ".fits.gz")))


def map_key(path: Path) -> str:
    """A map's name in the rows: its folder and file name."""
    return f"{path.parent.name}/{path.name}"


def paired_rows(out: Path, maps: list[Path], run_map: Callable[[Path, int], dict],
                describe: Callable[[dict], str]) -> list[dict]:
    """Every map's row: read back from ``out`` (JSON lines) or ``run_map(path, i)`` and appended to it.

    ``describe(row)`` is the progress line printed to stderr after each new row.
    """
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if out.exists():
        done = {json.loads(line)["map"]: json.loads(line) for line in out.read_text().splitlines() if line}
    rows = []
    with open(out, "a") as fh:
        for i, path in enumerate(maps):
            key = map_key(path)
            if key in done:
                rows.append(done[key])
                continue
            row = run_map(path, i)
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            rows.append(row)
            print(f"[{i + 1}/{len(maps)}] {key}: {describe(row)}  (load {row['load']:.1f})", file=sys.stderr, flush=True)
    return rows


def write_summary(out: Path, what: str, text: str) -> None:
    """``text`` to ``out``.summary.txt under a line saying when, on how many cores, and ``what`` was run; printed too."""
    Path(f"{out}.summary.txt").write_text(
        f"# {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} {os.cpu_count()} cores; {what}\n{text}\n")
    print(text)
