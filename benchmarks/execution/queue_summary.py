#!/usr/bin/env python
"""Summarise queue_variants.py JSON lines: per map and in total, executed / planned (cadence-valid pairs).

    python benchmarks/execution/queue_summary.py FILE.jsonl
"""

import json
import sys


def main(path: str) -> int:
    rows = [json.loads(line) for line in open(path) if '"planned"' in line]
    keys = [k for k in rows[0] if "@" in k]
    print("map | planned | " + " | ".join(keys) + " | K")
    for r in rows:
        k = next((v for n, v in r.items() if n.startswith("K_passes")), "")
        print(f"{r['map']} | {r['planned']:.4f} | " + " | ".join(f"{r[c]:.4f}" for c in keys) + f" | {k}")
    total = sum(r["planned"] for r in rows)
    print(f"ALL ({len(rows)} maps) | {total:.4f} | " + " | ".join(f"x{sum(r[c] for r in rows) / total:.3f}" for c in keys))
    for c in keys:
        if c.startswith(("single@0", "passes_1800@0")):
            low = [r["map"] for r in rows if r[c] < 0.9 * r["planned"]]
            print(f"maps with {c} < 0.9 x planned: {len(low)}: {', '.join(low)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
