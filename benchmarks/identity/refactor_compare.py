"""Compare two output trees of ``refactor_identity.sh`` document by document.

Every JSON document is compared after removing what a run cannot repeat:
creation instants, wall times and latencies (``created``, ``runtime_s``,
``latency_s``, ``received_at``...). Plans made by a time-limited solver are
compared only when both runs report a status that does not depend on the
clock (``greedy`` or ``optimal``); otherwise the row says ``clock-bound``.

    python benchmarks/identity/refactor_compare.py BEFORE_DIR AFTER_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

VOLATILE = {"created", "runtime_s", "latency_s", "received_at", "published_at", "wall_s",
            "elapsed_s", "stage_times", "timings", "time_published"}
STABLE_STATUS = {"greedy", "optimal"}


def scrub(value):
    """The document without volatile keys (recursively)."""
    if isinstance(value, dict):
        return {k: scrub(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [scrub(v) for v in value]
    return value


def status(doc) -> str | None:
    metrics = doc.get("metrics") if isinstance(doc, dict) else None
    return metrics.get("status") if isinstance(metrics, dict) else None


def documents(root: Path) -> dict[str, object]:
    out = {}
    for p in sorted(root.rglob("*.json")):
        try:
            out[str(p.relative_to(root))] = json.loads(p.read_text())
        except ValueError:
            out[str(p.relative_to(root))] = p.read_text()
    return out


def main(argv: list[str]) -> int:
    before, after = (Path(a) for a in argv[1:3])
    a, b = documents(before), documents(after)
    rows, bad = [], 0
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            rows.append(f"MISSING  {name} ({'after' if name in a else 'before'} lacks it)"); bad += 1
            continue
        sa, sb = status(a[name]), status(b[name])
        same = scrub(a[name]) == scrub(b[name])
        if same:
            rows.append(f"same     {name}" + (f" [{sa}]" if sa else ""))
        elif sa not in STABLE_STATUS or sb not in STABLE_STATUS:
            rows.append(f"clock    {name} [{sa} / {sb}]: differs, solver stopped by the clock")
        else:
            rows.append(f"DIFFERS  {name} [{sa} / {sb}]"); bad += 1
    print("\n".join(rows))
    n_same = sum(r.startswith("same") for r in rows)
    print(f"\n{len(rows)} documents: {n_same} identical, {bad} differing where they must not, "
          f"{sum(r.startswith('clock') for r in rows)} clock-bound")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
