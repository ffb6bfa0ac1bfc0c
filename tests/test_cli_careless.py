"""The CLI catches a careless user's mistakes: one clear line, exit 2, before any work."""

from __future__ import annotations

import json
import logging
import warnings
from pathlib import Path

import pytest

from mushrooms.cli import build_parser, main
from mushrooms.tool.common import quiet_time_warnings
from mushrooms.tool.plan import parse_start, warn_if_far_from_merger
from mushrooms.tool.config import resolve_config_path
from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.plan.schema import validate_document

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
NOTICES = DATA / "notices" / "json"
FAST = '[scheduler]\nsolver = "greedy"\nnside = 64\ntime_step_s = 600.0\n'


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("argv", [["--debug", "check", "p", "m"], ["check", "p", "m", "--debug"],
                                  ["check", "--debug", "p", "m"]])
def test_global_options_before_or_after_the_subcommand(argv):
    args = build_parser().parse_args(argv)
    assert args.debug is True and args.command == "check"
    args = build_parser().parse_args(["check", "p", "m", "--log-level", "WARNING"])
    assert args.log_level == "WARNING" and args.debug is False


def test_bad_log_level_is_one_line(capsys):
    assert main(["check", "p.json", "m.fits", "--log-level", "LOUD"]) == 2
    assert "--log-level 'LOUD'" in capsys.readouterr().err


@pytest.mark.parametrize("text, message", [
    ('[scheduler]\nairmass_max = "2"\n', "[scheduler] airmass_max = '2': expected a number, got string"),
    ("[scheduler]\nn_blocks_max = 2.5\n", "[scheduler] n_blocks_max = 2.5: expected an integer, got float"),
    ('[policy]\nallow_mock = "yes"\n', "[policy] allow_mock = 'yes': expected a boolean, got string"),
    ('[scheduler]\nfilters = ["g", "x"]\n', "filters must be ZTF filters (g, r, i)"),
    ("[scheduler]\nfilters = [1, 2]\n", "expected an array of strings"),
    ('[export]\nprogram = "MSIP"\n', "program must be Partnership or Caltech"),
])
def test_config_errors_name_key_value_and_type(tmp_path, capsys, text, message):
    cfg = write(tmp_path / "bad.toml", text)
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(tmp_path / "p.json")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not (tmp_path / "p.json").exists()


@pytest.mark.parametrize("option", ["-o", "--queue", "--skyportal", "--plot"])
@pytest.mark.parametrize("where, message", [("/proc/mushrooms-test/x.json", "does not exist"),
                                            ("/proc/x.json", "cannot write in /proc"),
                                            ("{tmp}/missing/x.json", "does not exist"),
                                            ("{tmp}", "is a directory")])
def test_output_paths_are_checked_before_any_work(tmp_path, capsys, caplog, option, where, message):
    target = where.format(tmp=tmp_path)
    argv = ["plan", str(MAP), "--config", str(write(tmp_path / "c.toml", FAST + "\n[export]\nskyportal_allocation_id = 1\n"))]
    argv += [option, target] + (["-o", str(tmp_path / "p.json")] if option != "-o" else [])
    with caplog.at_level(logging.INFO):
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and option.split("/")[0] in err
    assert not (tmp_path / "missing").exists()  # not created silently
    assert not any("read " in r.getMessage() for r in caplog.records)  # failed before reading the sky map


def test_skyportal_without_an_allocation_fails_first(tmp_path, capsys):
    cfg = write(tmp_path / "c.toml", FAST)
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(tmp_path / "p.json"),
                 "--skyportal", str(tmp_path / "sp.json")]) == 2
    assert "skyportal_allocation_id" in capsys.readouterr().err


@pytest.mark.parametrize("text, iso", [
    ("2022-07-23T04:00:00+02:00", "2022-07-23T02:00:00.000"),
    ("2022-07-23T02:00:00Z", "2022-07-23T02:00:00.000"),
    ("2022-07-23 02:00:00", "2022-07-23T02:00:00.000"),
    ("2022-07-22T21:00:00-05:00", "2022-07-23T02:00:00.000"),
    ("59783.083333333336", "2022-07-23T02:00:00.000"),
])
def test_start_accepts_iso_offsets_and_mjd(text, iso):
    assert parse_start(text).isot == iso


@pytest.mark.parametrize("text", ["tomorrow", "2022-13-01T00:00:00", "-5", "2022-07-23T02:00:00+25:00"])
def test_bad_start_is_one_line(text):
    with pytest.raises(InputError, match="--start"):
        parse_start(text)


def test_a_start_far_from_the_merger_is_one_warning_without_erfa_noise(caplog):
    quiet_time_warnings()
    merger = parse_start("2018-11-01T22:22:46")
    for text, far in (("1990-01-01T00:00:00", "years before"), ("1800-01-01T00:00:00", "years before"),
                      ("2100-01-01T00:00:00", "years after"), ("2018-11-02T02:00:00", None)):
        caplog.clear()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            quiet_time_warnings()
            start = parse_start(text)
            with caplog.at_level(logging.WARNING):
                warn_if_far_from_merger(start, merger)
            from astropy.coordinates import AltAz, get_body

            from mushrooms.scheduler_core.sky.visibility import site

            get_body("sun", start, site()).transform_to(AltAz(obstime=start, location=site()))
        lines = [r.getMessage() for r in caplog.records]
        if far is None:
            assert lines == []
        else:
            assert any(far in line for line in lines) and len(lines) <= 2
        assert [str(w.message) for w in caught if "ERFA" in str(w.message) or "IERS" in str(w.message)] == []


def test_replay_exits_nonzero_when_an_input_is_missing_or_empty(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    cfg = write(tmp_path / "c.toml", FAST)
    assert main(["replay", str(tmp_path / "nope.json"), "--out", str(tmp_path / "o1"), "--config", str(cfg)]) == 2
    assert "nope.json: no such file or directory" in capsys.readouterr().err
    assert main(["replay", str(empty), "--out", str(tmp_path / "o2"), "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert "no notice files" in err and "outbox" in err and "state" in err


def test_replay_documents_follow_the_schema_withdrawal_included(tmp_path, capsys):
    cfg = write(tmp_path / "c.toml", FAST)
    out = tmp_path / "out"
    assert main(["replay", str(NOTICES), "--allow-mock", "--out", str(out), "--config", str(cfg)]) == 0
    docs = [json.loads(p.read_text()) for p in sorted(out.glob("*.json"))]
    kinds = {d["type"] for d in docs}
    assert "withdrawal" in kinds and kinds & {"plan", "not_observable"}
    for d in docs:
        validate_document(d)


def test_config_file_rule_and_the_log_says_which(tmp_path, monkeypatch, caplog):
    here = tmp_path / "here"
    here.mkdir()
    env_cfg = write(tmp_path / "env.toml", FAST)
    assert resolve_config_path("x.toml", {}, here) == (Path("x.toml"), "--config")
    assert resolve_config_path(None, {"MUSHROOMS_CONFIG": str(env_cfg)}, here)[0] == env_cfg
    assert resolve_config_path(None, {}, here) == (None, "no --config, no $MUSHROOMS_CONFIG, no ./config.toml")
    local = write(here / "config.toml", '[scheduler]\nairmass_max = "bad"\n')
    assert resolve_config_path(None, {}, here)[0] == local
    # ./config.toml is used (here it is bad, so the command says so and names it)
    monkeypatch.chdir(here)
    monkeypatch.delenv("MUSHROOMS_CONFIG", raising=False)
    with caplog.at_level(logging.INFO, logger="mushrooms.config"):
        assert main(["check", "p.json", str(MAP)]) == 2
    assert any("config.toml in the working directory" in r.getMessage() for r in caplog.records)


def _trigger(tmp_path, *extra, config_text=FAST):
    cfg = write(tmp_path / "c.toml", config_text)
    return main(["trigger", *extra, "--config", str(cfg), "--allow-mock", "--state", str(tmp_path / "s.sqlite"),
                 "--outbox", str(tmp_path / "outbox")])


def test_trigger_force_plans_past_the_policy_with_the_reason_logged(tmp_path, capsys, caplog):
    notice = str(NOTICES / "MS181101ab-preliminary.json")  # years old: the policy ignores it
    assert _trigger(tmp_path, notice) == 0
    captured = capsys.readouterr()
    assert "ignore" in captured.out and "max_notice_age_s" in captured.out
    assert f"state {tmp_path / 's.sqlite'}" in captured.err and "outbox" in captured.err
    assert not list((tmp_path / "outbox").glob("*.json"))
    with caplog.at_level(logging.WARNING):
        assert _trigger(tmp_path, notice, "--force") == 0
    assert any("event=trigger_forced" in r.getMessage() and "max_notice_age_s" in r.getMessage()
               for r in caplog.records)
    out = capsys.readouterr().out
    assert "forced by operator" in out and "1 job(s) run here" in out
    docs = [json.loads(p.read_text()) for p in (tmp_path / "outbox").glob("*.json")]
    assert len(docs) == 1 and docs[0]["type"] in ("plan", "not_observable")


def test_trigger_warns_on_a_retracted_event(tmp_path, capsys):
    accept_old = FAST + "\n[policy]\nmax_notice_age_s = 0\nmax_event_age_s = 0\n"
    assert _trigger(tmp_path, str(NOTICES / "MS181101ab-preliminary.json"), config_text=accept_old) == 0
    assert _trigger(tmp_path, str(NOTICES / "MS181101ab-retraction.json"), config_text=accept_old) == 0
    capsys.readouterr()
    assert _trigger(tmp_path, "MS181101ab", config_text=accept_old) == 0
    err = capsys.readouterr().err
    assert "warning: MS181101ab was retracted" in err


def test_check_uses_the_plans_embedded_configuration(tmp_path, capsys):
    ri = write(tmp_path / "ri.toml", FAST + 'filters = ["r", "i"]\n')
    gr = write(tmp_path / "gr.toml", FAST)
    plan = tmp_path / "plan.json"
    assert main(["plan", str(MAP), "--config", str(ri), "-o", str(plan), "--start", "2022-07-23T02:00:00Z"]) == 0
    doc = json.loads(plan.read_text())
    assert doc["type"] == "plan" and doc["config"]["filters"] == ["r", "i"]
    capsys.readouterr()
    assert main(["check", str(plan), str(MAP)]) == 0  # the plan's own config: r and i are allowed
    assert ": OK:" in capsys.readouterr().out
    assert main(["check", str(plan), str(MAP), "--config", str(gr)]) == 1  # an explicit config wins
    assert "FAILED" in capsys.readouterr().out


def test_plan_of_an_unobservable_map_writes_not_observable_and_no_queue(tmp_path, capsys):
    cfg = write(tmp_path / "c.toml", FAST + "\n[export]\nskyportal_allocation_id = 3\n")
    out = tmp_path / "no.json"
    from mushrooms.bundled import demo_skymap_path

    assert main(["plan", str(demo_skymap_path()), "--config", str(cfg), "-o", str(out), "--queue",
                 str(tmp_path / "q.json"), "--skyportal", str(tmp_path / "sp.json")]) == 0  # the bundled map: next to the Sun
    text = capsys.readouterr().out
    assert "NOT OBSERVABLE" in text and "q.json: not written (--queue): nothing to observe" in text
    assert not (tmp_path / "q.json").exists() and not (tmp_path / "sp.json").exists()
    doc = json.loads(out.read_text())
    validate_document(doc)
    assert doc["type"] == "not_observable" and doc["sky"]["daylight"] > 0.9


def test_plan_writes_queue_and_skyportal_from_the_same_plan(tmp_path, capsys):
    cfg = write(tmp_path / "c.toml", FAST + '\n[export]\nskyportal_allocation_id = 3\nuser = "bob"\n')
    paths = {k: tmp_path / f"{k}.json" for k in ("plan", "queue", "sp")}
    assert main(["plan", str(MAP), "--config", str(cfg), "--start", "2022-07-23T02:00:00Z", "-o", str(paths["plan"]),
                 "--queue", str(paths["queue"]), "--skyportal", str(paths["sp"])]) == 0
    plan, queue, sp = (json.loads(p.read_text()) for p in paths.values())
    obs = plan["observations"]
    queues = queue if isinstance(queue, list) else [queue]  # the set of timed queues, in submission order
    targets = [t for q in queues for t in q["targets"]]
    assert sorted((t["field_id"], t["filter_id"]) for t in targets) == sorted(
        (o["field_id"], {"g": 1, "r": 2, "i": 3}[o["filter"]]) for o in obs)
    plans = sp if isinstance(sp, list) else [sp]  # one SkyPortal plan per queue of the set, in submission order
    assert ["ToO_" + p["payload"]["queue_name"] for p in plans] == [q["queue_name"] for q in queues]
    planned = [p for one in plans for p in one["observation_plans"][0]["planned_observations"]]
    assert [p["field_id"] for p in planned] == [t["field_id"] for t in targets]
    assert all(p["dateobs"] + "Z" == obs[p["planned_observation_id"]]["start"] for p in planned)
    assert all(q["user"] == "bob" for q in queues) and {p["allocation_id"] for p in plans} == {3}


def test_the_demo_output_directory_is_ignored_by_git():
    # `mushrooms demo` writes mushrooms-demo/ in the working directory: a checkout's `git status` stays clean
    import shutil
    import subprocess

    root = Path(__file__).resolve().parents[1]
    if shutil.which("git") is None or not (root / ".git").exists():
        pytest.skip("not a git checkout")
    for path in ("mushrooms-demo/plan.png", "mushrooms-demo/outbox/x.json", "mushrooms-demo/state.sqlite"):
        r = subprocess.run(["git", "check-ignore", "-q", path], cwd=root, timeout=60)
        assert r.returncode == 0, f"{path} is not ignored"
