import datetime as dt, json, sys, tempfile
from pathlib import Path
from mushrooms.report.summary import summary_text
from mushrooms.report.page import summary_html
from mushrooms.daemon.planning.parts import parts_lines, parts_words
data = Path(sys.argv[1])
now = dt.datetime(2026, 12, 6, 21, 0, tzinfo=dt.timezone.utc)
tmp = Path(tempfile.mkdtemp())
parts = []
for name in ("ls4", "winter", "decam"):
    doc = json.loads((data / f"{name}_part_plan.json").read_text())
    text = summary_text(doc, now=now)
    print(f"{name}: " + [l for l in text.splitlines() if l.startswith("Area")][0])
    page = summary_html(doc, now=now)
    print(f"{name} page has 'the fields cover': {'the fields cover' in page}")
    (tmp / name).mkdir(); (tmp / name / "plan.json").write_text(json.dumps(doc))
    parts.append({"telescope": name, "queue": "target_list", "state": "exported", "plan_id": doc["plan_id"], "folder": f"{tmp}/{name}"})
print("\n".join(l.replace(str(tmp), "<folder>") for l in parts_lines(parts)))
print("webhook: " + parts_words(parts))
