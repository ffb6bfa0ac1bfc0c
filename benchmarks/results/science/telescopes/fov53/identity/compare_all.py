"""Compare every JSON document of two refactor_identity.sh trees after refactor_compare.scrub, clock-bound or not.

    python compare_all.py BEFORE_DIR AFTER_DIR GLOB
The hybrid plans count work seconds (deterministic = true), so they repeat exactly; this also
prints each plan's metrics.upper_bound (the certified bound) on both sides.
"""
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[6] / "benchmarks" / "identity"))
from refactor_compare import scrub  # noqa: E402

before, after, glob = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
same = differ = 0
for a in sorted(before.glob(glob)):
    b = after / a.name
    da, db = (json.loads(p.read_text()) for p in (a, b))
    ok = scrub(da) == scrub(db)
    same, differ = same + ok, differ + (not ok)
    ub = [d.get("metrics", {}).get("upper_bound") if isinstance(d, dict) else None for d in (da, db)]
    pid = [d.get("plan_id") if isinstance(d, dict) else None for d in (da, db)]
    print(f"{'same' if ok else 'DIFFER':7s} {a.name}  plan_id {pid[0]} / {pid[1]}  upper_bound {ub[0]} / {ub[1]}")
print(f"{same + differ} documents: {same} identical, {differ} differing")
