"""``mushrooms replay``: the archived notices, in time order, through the daemon's path."""

from __future__ import annotations

import json
import shutil

import pytest

from mushrooms.cli import main as cli_main
from mushrooms.daemon.intake.replay import collect_notices, order_notices

from replay_helpers import NOTICES, raw


@pytest.fixture
def fast_config(tmp_path):
    path = tmp_path / "config.toml"
    path.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\ntime_step_s = 600.0\nmin_gain = 0.0\nmin_coverage = 0.0\n')
    return path


def lines_of(capsys):
    return [line for line in capsys.readouterr().out.splitlines() if line.strip()]


def test_replay_lvk_json_directory(tmp_path, fast_config, capsys):
    out = tmp_path / "out"
    rc = cli_main(["replay", str(NOTICES / "json"), "--allow-mock", "--out", str(out), "--config", str(fast_config)])
    assert rc == 0
    lines = lines_of(capsys)
    assert [line.split()[0] for line in lines] == [  # time order; INITIAL before UPDATEs created the same second
        "MS181101ab-earlywarning.json", "MS181101ab-preliminary.json", "MS181101ab-initial.json",
        "MS181101ab-ext-update.json", "MS181101ab-update.json", "MS181101ab-retraction.json"]
    # the Fermi coincidence UPDATE moves the plan onto the joint map; the GW-only UPDATE keeps it there
    assert [line.split()[3] for line in lines] == ["plan", "duplicate", "duplicate", "rerun", "duplicate",
                                                   "withdraw"]
    plan_id = lines[0].split()[4].removeprefix("plan_id=")
    joint_id = lines[3].split()[4].removeprefix("plan_id=")
    assert "coverage=" in lines[0] and "latency_s=" in lines[0]
    files = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    documents = [f for f in files if f.endswith(".json")]
    assert len(documents) == 3 and {f"{plan_id}.json", f"{joint_id}.json"} <= set(documents)
    # each published plan has its summary for a person beside it, text and page
    assert sorted(set(files) - set(documents)) == sorted(f"{p}.{x}" for p in (plan_id, joint_id) for x in ("html", "txt"))
    plan = json.loads((out / f"{plan_id}.json").read_text())
    assert plan["type"] == "plan" and plan["event"]["alert_type"] == "EARLYWARNING"
    assert plan["event"]["localization"] == "gw" and plan["event"]["external_coinc"] is None
    joint = json.loads((out / f"{joint_id}.json").read_text())
    assert joint["supersedes"] == plan_id and joint["event"]["localization"] == "combined"
    assert joint["event"]["skymap_sha256"].startswith("1e087b1837bd")
    assert joint["event"]["external_coinc"]["observatory"] == "Fermi"
    [wfile] = [f for f in files if f.startswith("withdrawal-")]
    w = json.loads((out / wfile).read_text())
    assert set(w) >= {"type", "superevent_id", "plan_ids", "reason", "created"}
    assert w["type"] == "withdrawal" and w["plan_ids"] == [plan_id, joint_id]


def test_replay_without_allow_mock_ignores_mocks(tmp_path, fast_config, capsys):
    rc = cli_main(["replay", str(NOTICES / "json" / "MS181101ab-preliminary.json"),
                   str(NOTICES / "live" / "S230528ay-preliminary.json"),
                   "--out", str(tmp_path / "o"), "--config", str(fast_config)])
    assert rc == 0
    lines = lines_of(capsys)
    assert [line.split()[3] for line in lines] == ["ignore", "ignore"]
    assert "mock" in lines[0] and "group Burst not in CBC" in lines[1]


def test_replay_mixed_live_notices_with_bad_files(tmp_path, fast_config, capsys):
    """Real notices out of order, plus bad files: every file gets a line, the good ones a plan."""
    src = tmp_path / "in"
    src.mkdir()
    for rel in ("live/MS230425k-initial.json", "live/MS230425k-retraction.json",
                "live/MS230425k-preliminary.json", "live/S230528ay-preliminary.json"):
        shutil.copy(NOTICES / rel, src)
    (src / "a-truncated.json").write_bytes(raw("live/MS230425k-preliminary.json")[:4096])
    (src / "b-huge.json").write_bytes(b"{" + b" " * (50 * 1024 * 1024) + b"}")
    (src / "c-empty.json").write_bytes(b"")
    (src / "README.md").write_text("not a notice: skipped when a directory is given")
    state = tmp_path / "state.sqlite"
    rc = cli_main(["replay", str(src), str(tmp_path / "missing.json"), "--allow-mock", "--out", str(tmp_path / "o"),
                   "--config", str(fast_config), "--state", str(state)])
    assert rc == 2  # missing.json is missing: non-zero, yet every other file was replayed
    lines = lines_of(capsys)
    by_name = {line.split()[0]: line.split()[3] for line in lines}
    assert len(lines) == 8
    assert by_name == {
        "a-truncated.json": "rejected", "b-huge.json": "rejected", "c-empty.json": "rejected",
        "missing.json": "rejected",
        "MS230425k-preliminary.json": "plan", "MS230425k-retraction.json": "withdraw",
        "MS230425k-initial.json": "plan", "S230528ay-preliminary.json": "ignore"}
    order = [line.split()[0] for line in lines]
    assert order.index("MS230425k-preliminary.json") < order.index("MS230425k-retraction.json") \
        < order.index("MS230425k-initial.json") < order.index("S230528ay-preliminary.json")
    # file order is by name (upper case first); unparseable files keep their slots
    assert order[4:] == ["a-truncated.json", "b-huge.json", "c-empty.json", "missing.json"]
    assert state.exists()


def test_order_keeps_unparseable_notices_in_place():
    items = [(NOTICES / "x-bad", b"junk"),
             (NOTICES / "live/MS230425k-initial.json", raw("live/MS230425k-initial.json")),
             (NOTICES / "y-bad", None),
             (NOTICES / "live/MS230425k-preliminary.json", raw("live/MS230425k-preliminary.json"))]
    names = [p.name for p, _, _ in order_notices(items)]
    assert names == ["x-bad", "MS230425k-preliminary.json", "y-bad", "MS230425k-initial.json"]


def test_collect_notices_expands_directories(tmp_path):
    (tmp_path / "b.json").write_text("{}")
    (tmp_path / "a.avro").write_bytes(b"")
    (tmp_path / ".hidden.json").write_text("{}")
    (tmp_path / "notes.txt").write_text("")
    assert [p.name for p in collect_notices([tmp_path])] == ["a.avro", "b.json"]


def test_replay_is_a_library_call_with_the_shared_overrides(tmp_path, fast_config, capsys):
    # what the demo does: load the config, apply the command-line overrides in the one place, replay
    from mushrooms.tool.config import load_config
    from mushrooms.daemon.intake.replay import replay_notices
    from mushrooms.tool.overrides import override_config

    notice = NOTICES / "json" / "MS181101ab-preliminary.json"
    config = load_config(str(fast_config))
    report = replay_notices([notice], tmp_path / "strict", config)
    assert report.status == 0 and report.errors == ()
    assert [oc.decision for _, oc in report.results] == ["ignore"]  # a mock event, and mocks not allowed
    assert capsys.readouterr().out == ""  # the library prints nothing: the tool does
    mock_ok = override_config(config, allow_mock=True, solver="greedy")
    assert config.policy.allow_mock is False and mock_ok.policy.allow_mock is True  # the loaded one is untouched
    state = tmp_path / "state" / "s.sqlite"
    seen = []
    report = replay_notices([notice], tmp_path / "out", mock_ok, state=state,
                            on_outcome=lambda p, oc: seen.append((p.name, oc.decision)))
    assert report.status == 0 and report.state == state and report.counts() == {"plan": 1}
    assert seen == [(notice.name, "plan")]
    docs = [json.loads(p.read_text()) for p in (tmp_path / "out").glob("*.json")]
    assert state.exists() and [d["type"] for d in docs] == ["plan"]


@pytest.mark.parametrize("content, why", [(b"{not json", "not valid JSON"), (b"[1, 2]", "superevent_id"),
                                          (b"", "empty")])
def test_replay_of_a_malformed_notice_is_bad_input_exit_2_with_one_line(tmp_path, fast_config, capsys, content, why):
    # the README: bad input is one line on stderr and exit status 2; the good notices are replayed all the same
    bad = tmp_path / "bad.json"
    bad.write_bytes(content)
    good = NOTICES / "json" / "MS181101ab-preliminary.json"
    rc = cli_main(["replay", str(bad), str(good), "--allow-mock", "--out", str(tmp_path / "o"),
                   "--config", str(fast_config)])
    assert rc == 2
    out, err = capsys.readouterr()
    assert {line.split()[0]: line.split()[3] for line in out.splitlines() if line.strip()} == {
        "bad.json": "rejected", "MS181101ab-preliminary.json": "plan"}
    errors = [line for line in err.splitlines() if line.startswith("mushrooms replay: error:")]
    assert len(errors) == 1 and errors[0].startswith(f"mushrooms replay: error: {bad}: "), err
