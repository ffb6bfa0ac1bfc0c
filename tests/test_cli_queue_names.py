"""One queue-naming rule on the command line (issue 52, finding 9).

``mushrooms plan -o P.json --queue Q.json`` writes the queue set; the plan's
``.txt`` and ``.html`` beside it must name those queues, and ``mushrooms
submit --dry-run P.json`` must send those same names: one rule
(:func:`mushrooms.scheduler_core.plan.exports.queue_name_base`) for the
plan tool, the submit tool, the summaries and the daemon (its side:
``tests/daemon/test_queue_names_shown.py``).  Real processes, a real sky map.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def mushrooms(*args: str, cwd: Path | None = None, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600, env=env)


def _names(text: str) -> list[str]:
    return re.findall(r"\bToO_[A-Za-z0-9_.-]+", text)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("names")
    r = mushrooms("plan", str(MAP), "--solver", "greedy", "--start", "2022-07-23T02:00:00Z", "--set",
                  "scheduler.nside=64", "-o", str(out / "plan.json"), "--queue", str(out / "queue.json"))
    assert r.returncode == 0, r.stderr
    queue = json.loads((out / "queue.json").read_text())
    return out, [q["queue_name"] for q in (queue if isinstance(queue, list) else [queue])], r


def test_the_plan_summary_names_the_queues_plan_queue_writes(planned):
    out, names, r = planned
    assert len(names) >= 2
    txt = (out / "plan.txt").read_text()
    line = [x for x in txt.splitlines() if x.startswith("Queue")]
    assert line, txt
    assert _names(line[0])[0] == names[0] and _names(line[0])[-1] == names[-1], (line, names)
    assert f"{len(names)} queues" in line[0]
    assert _names((out / "plan.html").read_text()) == names
    assert _names(r.stdout)[:1] == names[:1]  # the printed summary too


def test_submit_sends_the_names_plan_queue_writes(planned, tmp_path):
    out, names, _ = planned
    cfg = tmp_path / "config.toml"
    cfg.write_text('[submit]\ntarget = "kowalski"\nurl = "http://127.0.0.1:9"\n')
    r = mushrooms("submit", str(out / "plan.json"), "--dry-run", "--force", "--config", str(cfg))
    assert r.returncode == 0, r.stderr
    requests = json.loads(r.stdout)
    requests = requests if isinstance(requests, list) else [requests]
    assert [q["body"]["queue_name"] for q in requests] == names


def test_one_function_names_every_queue():
    """No module but exports.py spells the ``ToO_<subprogram>_`` rule (the daemon, the tools, the summaries
    call :func:`queue_name_base`)."""
    root = Path(__file__).resolve().parents[1] / "mushrooms"
    spelled = [str(p.relative_to(root)) for p in root.rglob("*.py")
               if re.search(r"f\"ToO_\{[^}]*subprogram", p.read_text())]
    assert spelled == ["scheduler_core/plan/exports.py"], spelled
