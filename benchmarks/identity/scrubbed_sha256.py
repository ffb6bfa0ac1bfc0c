"""sha256 of every plan document of two ``refactor_identity.sh`` trees, before and after, side by side.

The hash is of the document without what a run cannot repeat (``refactor_compare.scrub``: creation
instants, wall times), as canonical JSON (sorted keys, no spaces); the plan id is the document's own.

    python benchmarks/identity/scrubbed_sha256.py BEFORE_DIR AFTER_DIR
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from refactor_compare import scrub  # noqa: E402


def digest(path: Path) -> tuple[str, str]:
    doc = json.loads(path.read_text())
    text = json.dumps(scrub(doc), sort_keys=True, separators=(",", ":"))
    return str(doc.get("plan_id", "-")) if isinstance(doc, dict) else "-", hashlib.sha256(text.encode()).hexdigest()


def main(argv: list[str]) -> int:
    before, after = (Path(a) for a in argv[1:3])
    names = sorted(str(p.relative_to(before)) for p in before.rglob("*.json")
                   if p.name.startswith("plan_") or "outbox" in p.parts or p.parent.name.startswith("replay"))
    print(f"{'document':58s} {'plan id':27s} {'sha256 before (scrubbed)':18s} {'after':18s} same")
    bad = 0
    for name in names:
        (id_a, h_a), (id_b, h_b) = digest(before / name), digest(after / name) if (after / name).exists() else ("-", "")
        same = h_a == h_b and id_a == id_b
        bad += not same
        print(f"{name:58s} {id_a:27s} {h_a[:16]:18s} {h_b[:16]:18s} {'yes' if same else 'NO'}")
    print(f"\n{len(names)} documents, {len(names) - bad} with the same plan id and scrubbed sha256")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
