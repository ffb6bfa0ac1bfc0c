"""The command line end to end: real processes, real files, plan invariants, bad input."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def mushrooms(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    r = mushrooms("plan", str(MAP), "--solver", "greedy", "--start", "2022-07-23T02:00:00Z",
                  "-o", str(out / "plan.json"), "--queue", str(out / "queue.json"), "--plot", str(out / "plan.png"))
    assert r.returncode == 0, r.stderr
    return out, r


def test_plan_writes_a_checked_plan_queue_and_picture(planned):
    out, r = planned
    doc = json.loads((out / "plan.json").read_text())
    assert doc["start"] == "2022-07-23T02:00:00.000Z"
    assert doc["metrics"]["solver"] == "greedy" and doc["metrics"]["n_exposures"] == len(doc["observations"])
    assert "checked" in r.stdout
    queue = json.loads((out / "queue.json").read_text())  # the set the daemon submits: a list, in order
    queues = queue if isinstance(queue, list) else [queue]
    assert sum(len(q["targets"]) for q in queues) <= len(doc["observations"])
    tag = doc["plan_id"].removeprefix("mushrooms-")[:12]  # a bare sky map: ToO_<subprogram>_<plan tag>_<k>
    assert [q["queue_name"] for q in queues] == [f"ToO_GW_{tag}_{k}" for k in range(1, len(queues) + 1)]
    windows = [q["validity_window_mjd"] for q in queues]
    assert all(lo < hi for lo, hi in windows) and [w[0] for w in windows] == sorted(w[0] for w in windows)
    png = (out / "plan.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20000


def test_plan_invariants_hold_in_the_written_document(planned):
    out, _ = planned
    doc = json.loads((out / "plan.json").read_text())
    obs = doc["observations"]
    starts = [o["start"] for o in obs]
    assert starts == sorted(starts)
    assert all(doc["start"] <= s <= doc["end"] for s in starts)
    by_field: dict[int, set[str]] = {}
    for o in obs:
        by_field.setdefault(o["field_id"], set()).add(o["filter"])
    assert all(f == {"g", "r"} for f in by_field.values())


def test_check_accepts_the_plan_and_rejects_a_tampered_one(planned, tmp_path):
    out, _ = planned
    r = mushrooms("check", str(out / "plan.json"), str(MAP))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "OK" in r.stdout
    doc = json.loads((out / "plan.json").read_text())
    doc["observations"][1]["start"] = doc["observations"][0]["start"]  # two exposures at once
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    r = mushrooms("check", str(bad), str(MAP))
    assert r.returncode == 1
    assert "overlap" in r.stdout or "order" in r.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["plan", "/nonexistent/map.fits"], "sky map not found"),
        (["plan", __file__], "not a FITS file"),
        (["plan", str(MAP), "--start", "next tuesday"], "not an ISO-8601 time"),
        (["plan", str(MAP), "--config", "/nonexistent.toml"], "cannot read config"),
        (["check", "/nonexistent/plan.json", str(MAP)], "plan not found"),
        (["check", __file__, str(MAP)], "is not JSON"),
    ],
    ids=["missing-map", "not-fits", "bad-start", "missing-config", "missing-plan", "plan-not-json"],
)
def test_bad_input_gets_one_line_and_exit_2(args, message):
    r = mushrooms(*args)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [line for line in r.stderr.splitlines() if "error" in line]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert "Traceback" not in r.stderr


def test_truncated_and_unnormalised_maps_are_refused(tmp_path):
    import healpy as hp
    import numpy as np

    truncated = tmp_path / "truncated.fits"
    truncated.write_bytes(MAP.read_bytes()[:40000])
    r = mushrooms("plan", str(truncated), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "truncated" in r.stderr and "Traceback" not in r.stderr

    half = tmp_path / "half.fits"
    hp.write_map(half, np.full(hp.nside2npix(16), 0.5 / hp.nside2npix(16)), nest=True, dtype=np.float64,
                 column_names=["PROB"])
    r = mushrooms("plan", str(half), "--start", "2022-07-23T02:00:00", "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "sum to 0.5" in r.stderr
    assert not (tmp_path / "p.json").exists()

    temperature = tmp_path / "cmb.fits"  # a HEALPix map, but not a probability map
    hp.write_map(temperature, np.ones(hp.nside2npix(16)), nest=True, dtype=np.float64)
    r = mushrooms("plan", str(temperature), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "has no PROB column" in r.stderr


def test_bad_config_key_is_named(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[scheduler]\nexposure = 30\n")
    r = mushrooms("plan", str(MAP), "--config", str(cfg))
    assert r.returncode == 2 and "unknown [scheduler] key(s): exposure" in r.stderr


def test_demo_plans_the_bundled_notice_end_to_end(tmp_path):
    """README command 1 (with the fast scheduler): the bundled notice through the service's path."""
    r = mushrooms("demo", "--solver", "greedy", "--out", str(tmp_path / "d"))
    assert r.returncode == 0, r.stderr
    [plan_file] = list((tmp_path / "d" / "outbox").glob("mushrooms-*.json"))
    doc = json.loads(plan_file.read_text())
    assert doc["type"] == "plan" and doc["event"]["superevent_id"] == "MS260605l"
    assert doc["event"]["localization"] == "gw" and doc["event"]["external_coinc"] is None
    # an ~8 deg2 map observable in the horizon: the plan covers nearly all of it
    assert doc["metrics"]["coverage"] > 0.99 and doc["observations"]
    assert (tmp_path / "d" / "plan.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "d" / "state.sqlite").is_file()
    assert doc["plan_id"] in r.stdout


def test_plan_with_a_deadline_writes_the_best_plan_found_by_then(tmp_path, planned):
    """A deadline that has passed before the optimiser starts: the greedy plan is written, as revision 1."""
    out, _ = planned
    r = mushrooms("plan", str(MAP), "--solver", "hybrid", "--start", "2022-07-23T02:00:00Z",
                  "--deadline", "0.001", "-o", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "plan.json").read_text())
    greedy = json.loads((out / "plan.json").read_text())
    assert doc["metrics"]["solver"] == "greedy" and doc["revision"] == 1 and doc["final"] is True
    assert [(o["field_id"], o["filter"], o["start"]) for o in doc["observations"]] == \
        [(o["field_id"], o["filter"], o["start"]) for o in greedy["observations"]]
    bad = mushrooms("plan", str(MAP), "--deadline", "-3", "-o", str(tmp_path / "x.json"))
    assert bad.returncode == 2 and "--deadline" in bad.stderr and "Traceback" not in bad.stderr


def test_cli_solver_choices_are_the_schedulers_names() -> None:
    """One registry: the CLI's choices, the config's validation, the planner and the bench read its names."""
    from mushrooms.cli import SOLVER_CHOICES
    from mushrooms.evaluation.bench import OURS, SOLVERS as BENCH_SOLVERS
    from mushrooms.scheduler_core.config import SOLVER_NAMES as CONFIG_NAMES
    from mushrooms.scheduler_core.planner import SOLVERS
    from mushrooms.scheduler_core.solvers_registry import SOLVER_NAMES

    assert tuple(SOLVER_CHOICES) == SOLVER_NAMES
    assert CONFIG_NAMES is SOLVER_NAMES and SOLVERS is SOLVER_NAMES and OURS is SOLVER_NAMES
    # service: the daemon's anytime flow (service-grg: under g-r-g at 180 s); gwemopt's rows (issue 55: named configurations)
    assert BENCH_SOLVERS == SOLVER_NAMES + ("service", "service-grg", "gwemopt", "gwemopt-repaired", "gwemopt-o4",
                                            "gwemopt-skyportal")
    assert all(name in SOLVER_CHOICES for name in SOLVER_NAMES) and "gwemopt" not in SOLVER_CHOICES and "service" not in SOLVER_CHOICES
