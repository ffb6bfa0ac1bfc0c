"""``mushrooms plan SKYMAP --executed FILE --start TIME`` end to end: real processes, a real map, the real checker."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from astropy.time import Time, TimeDelta

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def mushrooms(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def replanned(tmp_path_factory):
    """A greedy plan, its first 10 exposures executed (one of them only partly reduced), a re-plan 2 h later."""
    out = tmp_path_factory.mktemp("replan")
    r = mushrooms("plan", str(MAP), "--solver", "greedy", "--start", "2022-07-23T02:00:00Z", "-o", str(out / "plan.json"))
    assert r.returncode == 0, r.stderr
    first = json.loads((out / "plan.json").read_text())
    lines = []
    for i, o in enumerate(first["observations"][:10]):
        fraction = 0.25 if i == 9 else 1.0  # the last one: 16 of 64 quadrants, not done
        lines.append(json.dumps({"field_id": o["field_id"], "filter": o["filter"], "start": o["start"],
                                 "exposure_s": o["exposure_s"], "processed_fraction": fraction,
                                 "status": "processed"}))
    (out / "executed.jsonl").write_text("\n".join(lines) + "\n")
    start = Time(first["observations"][9]["end"]) + TimeDelta(2 * 3600, format="sec")
    r = mushrooms("plan", str(MAP), "--solver", "greedy", "--executed", str(out / "executed.jsonl"),
                  "--start", start.isot + "Z", "-o", str(out / "replan.json"), "--queue", str(out / "queue.json"))
    assert r.returncode == 0, r.stderr
    return out, first, start, r


def test_the_replan_starts_after_the_start_repeats_no_done_pair_and_passes_the_checker(replanned, skymap_map):
    from mushrooms.handlers.executed import read_jsonl
    from mushrooms.scheduler_core import PlanningConfig, check_plan
    from mushrooms.scheduler_core.executed import done_pairs
    from mushrooms.scheduler_core.plan.document import Plan

    out, first, start, r = replanned
    doc = json.loads((out / "replan.json").read_text())
    plan = Plan.from_document(doc)
    executed = read_jsonl(out / "executed.jsonl")
    config = PlanningConfig.from_mapping(doc["config"])
    assert abs((plan.start - start).to_value("s")) < 1e-3
    assert all(o.start >= 0 for o in plan.observations) and plan.observations
    report = check_plan(plan, skymap_map, config, executed=executed)
    assert report.ok, report.problems
    pairs = done_pairs(executed, config.filters, cadence_s=config.cadence_s)
    assert len(pairs.both) >= 3
    assert not {o.field_id for o in plan.observations} & set(pairs.both)
    # the partly reduced exposure did not count: its field is half done, not done
    partial = first["observations"][9]["field_id"]
    assert partial in pairs.one and partial not in pairs.both
    for fid, visits in pairs.one.items():
        mine = [o for o in plan.observations if o.field_id == fid]
        other = [o for o in mine if o.filter != visits.filters[0]]
        assert not mine or other
        if mine and len({o.filter for o in mine}) == 1:
            assert min(plan.absolute_time(o.start).unix for o in other) >= visits.earliest.unix + config.cadence_s - 1e-3
    m = doc["metrics"]
    assert m["coverage_executed"] > 0 and 0 < m["coverage"] and m["coverage"] + m["coverage_executed"] <= 1
    # the summary says what was done, what this plan adds and the total, in words
    assert "Done       " in r.stdout and "Added      this plan adds" in r.stdout and "Total      " in r.stdout
    assert " done (total " in r.stdout and "half-done fields completed" in r.stdout and "checked" in r.stdout
    queue = json.loads((out / "queue.json").read_text())
    queues = queue if isinstance(queue, list) else [queue]  # the set of timed queues, in submission order
    assert sum(len(q["targets"]) for q in queues) == len(doc["observations"])


def test_the_replan_id_names_the_executed_record(replanned):
    out, first, _, _ = replanned
    doc = json.loads((out / "replan.json").read_text())
    assert doc["plan_id"] != first["plan_id"]


@pytest.mark.parametrize("args, words", [
    (["--executed", "missing.jsonl"], "missing.jsonl"),
    (["--executed", "skyportal:https://skyportal.example.org"], "reads files only"),
    (["--executed", "bogus:thing"], "bogus:thing"),
    (["--min-processed-fraction", "0.5"], "needs --executed"),
    (["--executed", "x.jsonl", "--deadline", "5"], "do not go together"),
])
def test_bad_executed_options_get_one_clear_line(tmp_path, args, words):
    r = mushrooms("plan", str(MAP), "-o", str(tmp_path / "p.json"), *args)
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_malformed_executed_file_is_refused(tmp_path):
    bad = tmp_path / "executed.jsonl"
    bad.write_text("this is not json\n")
    r = mushrooms("plan", str(MAP), "--executed", str(bad), "--start", "2022-07-23T06:00:00Z", "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr


def test_plan_help_names_executed():
    r = mushrooms("plan", "--help")
    assert r.returncode == 0 and "--executed" in r.stdout and "--min-processed-fraction" in r.stdout


@pytest.fixture(scope="module")
def skymap_map():
    from mushrooms.scheduler_core import PlanningConfig, read_skymap

    return read_skymap(MAP, nside=PlanningConfig().nside)


def test_check_accepts_the_replan_with_its_record_and_refuses_it_without(replanned):
    out, _, _, _ = replanned
    ok = mushrooms("check", str(out / "replan.json"), str(MAP), "--executed", str(out / "executed.jsonl"))
    assert ok.returncode == 0 and "OK" in ok.stdout, ok.stdout + ok.stderr
    bare = mushrooms("check", str(out / "replan.json"), str(MAP))
    assert bare.returncode == 1 and "give its --executed record" in bare.stderr


def test_plan_with_two_nights_writes_one_document_and_queue_per_night(tmp_path):
    (tmp_path / "config.toml").write_text("[scheduler]\nnights = 2\nsolver = \"greedy\"\n")
    r = mushrooms("plan", str(MAP), "--config", str(tmp_path / "config.toml"), "-o", str(tmp_path / "plan.json"),
                  "--queue", str(tmp_path / "queue.json"))
    assert r.returncode == 0, r.stderr
    first = json.loads((tmp_path / "plan.json").read_text())
    second = json.loads((tmp_path / "plan.night2.json").read_text())
    assert first["end"] < second["start"] and 20 < (Time(second["start"]) - Time(first["start"])).to_value("h") < 28
    for doc in (first, second):
        assert all(doc["start"] <= o["start"] and o["end"] <= doc["end"] for o in doc["observations"])
    assert not {o["field_id"] for o in second["observations"]} & {o["field_id"] for o in first["observations"]}
    assert (tmp_path / "queue.night2.json").is_file()
    assert "night 1 of 2" in r.stdout and "night 2 of 2" in r.stdout


def test_a_grg_replan_from_the_command_line_gives_each_field_done_in_g_and_r_its_third_visit(tmp_path):
    """``[scheduler] filters = ["g", "r", "g"]``: the g and r visits of a block executed, the re-plan keeps the g."""
    (tmp_path / "grg.toml").write_text('[scheduler]\nfilters = ["g", "r", "g"]\nexposure_s = 180.0\nsolver = "greedy"\n')
    config = ["--config", str(tmp_path / "grg.toml")]
    r = mushrooms("plan", str(MAP), *config, "--start", "2022-07-23T02:00:00Z", "-o", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    first = json.loads((tmp_path / "plan.json").read_text())
    block0 = [o for o in first["observations"] if o["block"] == 0]
    visits = {f: [o["filter"] for o in block0 if o["field_id"] == f] for f in {o["field_id"] for o in block0}}
    assert all(v in (["g", "r", "g"], ["g", "r"]) for v in visits.values())  # (F10) cut where no window holds a third
    whole = {f for f, v in visits.items() if len(v) == 3}
    assert whole
    first_r = min(Time(o["start"]).unix for o in block0 if o["filter"] == "r")
    done = [o for o in block0 if o["filter"] == "r" or Time(o["start"]).unix < first_r]
    (tmp_path / "executed.jsonl").write_text("".join(json.dumps(
        {"field_id": o["field_id"], "filter": o["filter"], "start": o["start"], "exposure_s": o["exposure_s"],
         "processed_fraction": 1.0, "status": "processed"}) + "\n" for o in done))
    start = max(Time(o["end"]) for o in done)
    r = mushrooms("plan", str(MAP), *config, "--executed", str(tmp_path / "executed.jsonl"),
                  "--start", start.isot + "Z", "-o", str(tmp_path / "replan.json"), "--queue", str(tmp_path / "q.json"))
    assert r.returncode == 0, r.stderr
    fields = {o["field_id"] for o in done}
    replan = json.loads((tmp_path / "replan.json").read_text())
    r_at = {o["field_id"]: Time(o["start"]) for o in done if o["filter"] == "r"}
    assert not {o["field_id"] for o in replan["observations"]} & (fields - whole)  # no window for their third visit
    kept = {o["field_id"] for o in replan["observations"]} & whole
    # one whole field's third visit, due as its window closes, may find no time (the greedy block after the
    # completion pass takes it: tests/scheduler/test_sequence_queues_replan.py allows the same)
    assert len(kept) >= len(whole) - 1
    assert f"{len(kept)} of {len(fields)} half-done fields completed" in r.stdout
    for fid in kept:
        mine = [o for o in replan["observations"] if o["field_id"] == fid]
        assert [o["filter"] for o in mine] == ["g"]
        assert (Time(mine[0]["start"]) - r_at[fid]).to_value("s") >= 1800.0 - 1e-3
    r = mushrooms("check", str(tmp_path / "replan.json"), str(MAP), "--executed", str(tmp_path / "executed.jsonl"))
    assert r.returncode == 0 and ": OK:" in r.stdout, r.stdout + r.stderr
