"""Issue 53 item 2: ``mushrooms plan MAP --telescopes ztf,ls4`` plans the telescopes together; ``mushrooms check`` checks it.

Real processes, real sky maps (the tests' northern map; a shared southern map, bns_o3/18, where ZTF reaches
20 % of the probability and LS4 55 %), real descriptions; the joint document's metrics are recomputed
by the checker with its own geometry.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"
NORTH = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
SOUTH = Path("/work/shared/data/skymaps/simulated/bns_o3/18.fits")


def mushrooms(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True, timeout=900)


def _joint(tmp_path: Path, skymap: Path) -> tuple[Path, dict]:
    config = tmp_path / "config.toml"
    config.write_text("[scheduler]\nnside = 64\ntime_limit_s = 2.0\ndetection_time_limit_s = 0.5\n")
    r = mushrooms("plan", str(skymap), "--telescopes", "ztf,ls4", "--config", str(config), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 0, r.stderr
    return tmp_path / "p.joint.json", json.loads((tmp_path / "p.joint.json").read_text())


@pytest.mark.parametrize("where", ["north", "south"])
def test_ztf_and_ls4_planned_together_pass_the_check(tmp_path, where):
    skymap = NORTH if where == "north" else SOUTH
    if not skymap.is_file():
        pytest.skip("the shared sky maps are not here")
    path, doc = _joint(tmp_path, skymap)
    assert doc["type"] == "joint_plan" and doc["telescopes"] == ["ztf", "ls4"]
    m = doc["metrics"]
    assert m["union"] <= m["upper_bound"] and m["union"] >= max(m["share"].values()) > 0
    assert {o["telescope"] for o in doc["observations"]} == {"ztf", "ls4"}
    assert [p["config"].get("telescopes", ["ztf"]) for p in doc["plans"]] == [["ztf"], ["ls4"]]
    for name, part in zip(("p.json", "p.ls4.json"), doc["plans"]):  # each part is also where it goes alone
        assert json.loads((tmp_path / name).read_text())["plan_id"] == part["plan_id"]
    r = mushrooms("check", str(path), str(skymap))
    assert r.returncode == 0 and "OK: joint plan of ztf, ls4" in r.stdout, (r.stdout, r.stderr)
    if where == "south":  # ZTF barely sees it: LS4's share is most of the union
        assert m["share"]["ls4"] > 2 * m["share"]["ztf"]


def test_a_joint_document_claiming_more_than_its_parts_fails_the_check(tmp_path):
    path, doc = _joint(tmp_path, NORTH)
    doc["metrics"]["union"] = doc["metrics"]["upper_bound"] + 0.01
    doc["observations"][0]["telescope"] = "ls4" if doc["observations"][0]["telescope"] == "ztf" else "ztf"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = mushrooms("check", str(bad), str(NORTH))
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "metrics.union" in r.stdout and "above the certified upper bound" in r.stdout
    assert "observations: not the parts' observations" in r.stdout


def test_a_joint_plan_of_several_nights_is_refused_in_one_line(tmp_path):
    """A joint plan plans one night: ``[scheduler] nights = 2`` is one line and exit 2, before any work."""
    config = tmp_path / "config.toml"
    config.write_text('[scheduler]\nnside = 64\nnights = 2\nsolver = "greedy"\n')
    r = mushrooms("plan", str(NORTH), "--telescopes", "ztf,ls4", "--config", str(config), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [line for line in r.stderr.splitlines() if line.strip() and " INFO " not in line]  # the log aside
    assert len(lines) == 1 and "nights" in lines[0] and "Traceback" not in r.stderr
    assert not (tmp_path / "p.json").exists()
