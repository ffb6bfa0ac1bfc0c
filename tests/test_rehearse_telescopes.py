"""``mushrooms rehearse`` with two telescopes configured (issue 53 item 4): the loopback broker, the real
service, MS181101ab's PRELIMINARY made live; ZTF's revision and LS4's part both in the outbox and told."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

NOTICE = Path(__file__).resolve().parent / "data" / "notices" / "json" / "MS181101ab-preliminary.json"
ROOT = Path(__file__).resolve().parents[1]


def test_a_rehearsal_with_ztf_and_ls4_lists_both_parts(tmp_path):
    cfg = tmp_path / "config.toml"
    cfg.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\ntelescopes = ["ztf", "ls4"]\n\n'
                   '[daemon]\nheartbeat_s = 2\n')
    env = {k: v for k, v in os.environ.items() if not k.startswith("MUSHROOMS_SUBMIT")}
    env["PYTHONPATH"] = str(ROOT)
    out = tmp_path / "rehearsal"
    r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "rehearse", str(NOTICE), "--config", str(cfg),
                        "--out", str(out), "--dry-run", "--set", 'submit.target="kowalski"',
                        "--set", 'submit.url="http://127.0.0.1:9"'],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "rehearsal passed: MS181101ab revision 1 final" in r.stdout
    assert "telescope part: ls4 (target_list): " in r.stdout
    ztf = [json.loads(p.read_text()) for p in (out / "outbox").glob("mushrooms-*.json")]
    assert [d["type"] for d in ztf] == ["plan"] and "telescopes" not in ztf[0]["config"]
    (part,) = (out / "outbox" / "telescopes" / "MS181101ab").glob("*/ls4/part.json")
    doc = json.loads(part.read_text())
    assert doc["telescope"] == "ls4" and doc["state"] in ("exported", "not_observable")  # the live sky decides
    if doc["state"] == "exported":
        assert (part.parent / "targets.csv").is_file() and (part.parent / "targets.json").is_file()
