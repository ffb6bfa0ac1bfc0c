"""The area words of the service's part plans: summary, page, parts' lines and webhook words (issue 53).

Reads ``ls4``, ``winter`` and ``decam`` ``_part_plan.json`` of a folder (the
tests' ``tests/daemon/data``: MS181101ab planned with four telescopes) and
prints each summary's ``Area`` line, whether its page says the covered area,
and the parts' lines and webhook words of the three parts (their plans
copied into a temporary folder, as the service's outbox holds them).

    PYTHONPATH=TREE python benchmarks/science/covered_area_lines.py tests/daemon/data > OUT
"""

from __future__ import annotations

import datetime as dt
import json
import sys
import tempfile
from pathlib import Path

from mushrooms.daemon.planning.parts import parts_lines, parts_words
from mushrooms.report.page import summary_html
from mushrooms.report.summary import summary_text

NOW = dt.datetime(2026, 12, 6, 21, 0, tzinfo=dt.timezone.utc)


def main(data: Path) -> None:
    tmp = Path(tempfile.mkdtemp())
    parts = []
    for name in ("ls4", "winter", "decam"):
        doc = json.loads((data / f"{name}_part_plan.json").read_text())
        text = summary_text(doc, now=NOW)
        print(f"{name}: " + [line for line in text.splitlines() if line.startswith("Area")][0])
        print(f"{name} page has 'the fields cover': {'the fields cover' in summary_html(doc, now=NOW)}")
        (tmp / name).mkdir()
        (tmp / name / "plan.json").write_text(json.dumps(doc))
        parts.append({"telescope": name, "queue": "target_list", "state": "exported", "plan_id": doc["plan_id"],
                      "folder": f"{tmp}/{name}"})
    print("\n".join(line.replace(str(tmp), "<folder>") for line in parts_lines(parts)))
    print("webhook: " + parts_words(parts))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
