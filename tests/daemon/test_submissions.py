"""Submission to ZTF's queue: the lifecycle against the contract servers, in process.

Real plans (the notice pipeline with the greedy scheduler on the sample
notices' BAYESTAR maps), a real SQLite store, and the Kowalski / SkyPortal
contract servers of ``contract_servers.py`` on loopback.  The daemon end
to end is in ``test_submit_daemon.py``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path

import pytest

from contract_servers import KowalskiContract, SkyPortalContract
from daemon_helpers import notice_bytes
from mushrooms.tool.config import Config, ConfigError, load_config
from mushrooms.daemon.credentials import CredentialsError, load_submit_token
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.submission.remote import make_client
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.daemon.submission.submitter import Submitter, queue_name_base, submissions
from mushrooms.daemon.submission.settings import SubmitConfig
from mushrooms.handlers.policy import PolicyConfig
from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.plan import exports
from mushrooms.scheduler_core.plan.exports import ExportConfig
from mushrooms.scheduler_core.plan.schema import validate_document

TOKEN = "s3cr3t-token-0123456789abcdef"


@pytest.fixture(autouse=True)
def one_queue_per_revision(monkeypatch):
    """These tests pin the submitter's lifecycle (PUT, replace, DELETE, crashes, 409s) request by request, on a set
    of one queue per revision; the sets of several queues the real export gives are in ``test_submission_sets.py``
    and ``test_a_revision_of_the_real_export_puts_every_queue_of_its_set`` below."""
    monkeypatch.setattr(exports, "to_trigger_queues", lambda plan, export=ExportConfig(), name_base=None, **kw:
                        [exports.to_trigger_queue(plan, export, queue_name=f"{name_base}_1")])


def planned(world: "World", n: int, sid: str | None = None) -> str:
    """The name base of the event's ``n``-th stored plan (the one rule: its plan id names it)."""
    plan_id = world.store.connection().execute("SELECT plan_id FROM plans WHERE superevent_id = ? ORDER BY seq"
                                               " LIMIT 1 OFFSET ?", (sid or SID, n - 1)).fetchone()[0]
    return queue_name_base("GW", plan_id, sid or SID)


def qn(world: "World", revision: int) -> str:
    """The one queue of the event's ``revision``-th submitted set (the placeholder set has K = 1)."""
    (row,) = [s for s in submissions(world.store) if s.revision == revision]
    return row.queue_name + "_1"
SID = "MS181101ab"


def _config(url: str, target: str = "kowalski", **submit) -> Config:
    return Config(
        scheduler=PlanningConfig(solver="greedy", nside=64, time_step_s=600.0, min_gain=0.0, min_coverage=0.0),
        policy=PolicyConfig(allow_mock=True, max_notice_age_s=0, max_event_age_s=0),
        export=ExportConfig(skyportal_allocation_id=7),
        submit=SubmitConfig(target=target, url=url, timeout_s=submit.pop("timeout_s", 2.0),
                            retry_initial_s=0.05, retry_max_s=0.2, **submit),
    )


@pytest.fixture
def server(loopback):
    return loopback


@pytest.fixture
def kowalski(server):
    return KowalskiContract(server, TOKEN)


@pytest.fixture
def skyportal(server):
    return SkyPortalContract(server, TOKEN)


class World:
    """A pipeline, its store and a submitter, as the daemon wires them (minus the threads)."""

    def __init__(self, path: Path, config: Config) -> None:
        self.path, self.config = path, config
        self.store = Store(path)
        self.sink = MemorySink()
        self.pipeline = NoticePipeline.from_config(config, self.store, self.sink)
        self.submitter = self.new_submitter()

    def new_submitter(self) -> Submitter:
        client = make_client(self.config.submit.target, self.config.submit.url, TOKEN, self.config.submit.timeout_s)
        return Submitter(self.store, self.config.submit, self.config.export, client)

    def notice(self, name: str, sid: str | None = None, time_created: str | None = None) -> None:
        out = self.pipeline.handle(notice_bytes(name, sid, time_created), f"test:{name}")
        assert out.decision in ("plan", "rerun", "withdraw", "ignore"), out

    def states(self) -> list[tuple[str | None, str]]:
        return [(s.queue_names()[0], s.state) for s in submissions(self.store) if s.state != "skipped"]

    def documents(self) -> list[dict]:
        rows = self.store.connection().execute("SELECT body FROM outbox WHERE kind='submission' ORDER BY outbox_id")
        return [json.loads(r[0]) for r in rows]

    def restart(self) -> None:
        self.store.close()
        self.__init__(self.path, self.config)


@pytest.fixture
def world(tmp_path, kowalski):
    w = World(tmp_path / "state.sqlite", _config(kowalski.url))
    yield w
    w.store.close()


def test_notice_update_and_retraction_put_replace_then_delete(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    r1 = qn(world, 1)
    assert list(kowalski.queues) == [r1]
    body = kowalski.queues[r1]
    assert body["queue_type"] == "list" and body["user"] == "mushrooms" and body["targets"]
    assert kowalski.log[0]["authorization"] == f"Bearer {TOKEN}"

    world.notice("MS230425l-preliminary.json", SID)  # an updated sky map: a new plan supersedes
    assert world.submitter.step() == 0
    r2 = qn(world, 2)
    assert list(kowalski.queues) == [r2]
    assert kowalski.lines()[1:] == [f"PUT /api/triggers/ztf {r2} -> 200", f"DELETE /api/triggers/ztf {r1} -> 200"]
    assert world.states() == [(r1, "replaced"), (r2, "submitted")]

    # dated after the relabelled 2023 map it retracts: decisions follow creation order
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    assert world.submitter.step() == 0
    assert kowalski.queues == {}
    assert kowalski.lines()[-1] == f"DELETE /api/triggers/ztf {r2} -> 200"
    assert world.states() == [(r1, "replaced"), (r2, "deleted")]
    docs = world.documents()
    assert [(d["queue_name"] + "_1", d["state"]) for d in docs] == [(r1, "submitted"), (r2, "submitted"),
                                                                     (r1, "replaced"), (r2, "deleted")]
    for d in docs:
        validate_document(d)
    assert world.submitter.step() == 0 and len(kowalski.log) == 4  # nothing left to do: nothing sent


def test_a_newer_plan_not_yet_accepted_keeps_the_old_queue(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    world.notice("MS230425l-preliminary.json", SID)
    kowalski.faults["PUT"] = [500, 503]
    assert world.submitter.step() == 1  # r2 waits for a retry; r1 stays queued
    assert list(kowalski.queues) == [qn(world, 1)]
    assert world.submitter.step() == 1
    assert world.submitter.step() == 0
    assert list(kowalski.queues) == [qn(world, 2)]
    assert [e["method"] for e in kowalski.log] == ["PUT", "PUT", "PUT", "PUT", "DELETE"]


class Killed(BaseException):
    """Stands for kill -9 in process: nothing after it runs (the restart is a new Store and Submitter)."""


def _die_after(obj, name: str, nth: int = 1) -> None:
    """``obj.name`` is killed right after its ``nth`` call reached the server."""
    real, calls = getattr(obj, name), []

    def call(*a, **k):
        answer = real(*a, **k)
        calls.append(1)
        if len(calls) == nth:
            raise Killed(name)
        return answer

    setattr(obj, name, call)


def test_crash_after_the_put_before_the_commit_counts_the_409_with_the_same_content(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    _die_after(world.submitter.client, "put")
    with pytest.raises(Killed):
        world.submitter.step()
    (row,) = submissions(world.store)
    assert row.state == "pending" and row.attempts == 1  # the attempt was committed before the PUT
    world.restart()
    assert world.submitter.step() == 0
    r1 = qn(world, 1)
    assert kowalski.lines() == [f"PUT /api/triggers/ztf {r1} -> 200", f"PUT /api/triggers/ztf {r1} -> 409",
                                "GET /api/triggers/ztf  -> 200"]
    (row,) = submissions(world.store)
    assert row.state == "submitted" and "same content" in row.reason and row.queue_names() == [r1]


def killed_during_the_deletes(world: World) -> None:
    """Revision 1 submitted, revision 2 of a new map accepted, then a kill right after the first DELETE."""
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    world.notice("MS230425l-preliminary.json", SID)
    _die_after(world.submitter.client, "delete")
    with pytest.raises(Killed):
        world.submitter.step()


def test_crash_during_the_delete_is_finished_by_the_restart(world, kowalski) -> None:
    killed_during_the_deletes(world)
    r1, r2 = qn(world, 1), qn(world, 2)
    assert list(kowalski.queues) == [r2]
    world.restart()
    assert world.states() == [(r1, "submitted"), (r2, "submitted")]
    assert world.submitter.step() == 0
    assert world.states() == [(r1, "replaced"), (r2, "submitted")]
    assert kowalski.lines()[-2:] == [f"DELETE /api/triggers/ztf {r1} -> 400", "GET /api/triggers/ztf  -> 200"]
    assert list(kowalski.queues) == [r2]


def test_a_409_with_other_content_is_a_rejection(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    r1 = planned(world, 1) + "_1"  # the name the plan will be sent as, taken by another queue before it is sent
    kowalski.queues[r1] = {"queue_name": r1, "validity_window_mjd": [1.0, 2.0], "targets": []}
    world.submitter.step()
    (row,) = submissions(world.store)
    assert row.state == "rejected" and row.http_status == 409 and "other content" in row.reason


def test_a_refusal_is_recorded_logged_once_published_and_never_retried(world, kowalski, caplog) -> None:
    kowalski.faults["PUT"] = [400]
    world.notice("MS181101ab-preliminary.json")
    with caplog.at_level(logging.INFO, logger="mushrooms"):
        assert world.submitter.step() == 0
        assert world.submitter.step() == 0
    errors = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 1 and "event=submission_rejected" in errors[0].getMessage()
    (row,) = submissions(world.store)
    assert row.state == "rejected" and row.http_status == 400 and "injected 400" in row.answer
    assert [e["method"] for e in kowalski.log] == ["PUT"]  # not retried
    (doc,) = world.documents()
    validate_document(doc)
    assert doc["state"] == "rejected" and doc["answer"] == "injected 400" and doc["plan_id"] == row.plan_id


def test_a_body_kowalski_refuses_is_rejected_with_its_text(world, kowalski, monkeypatch) -> None:
    import mushrooms.daemon.submission.submitter as subs

    real = subs.build_body
    monkeypatch.setattr(subs, "build_body",
                        lambda *a: [{k: v for k, v in q.items() if k != "queue_type"} for q in real(*a)])
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    (row,) = submissions(world.store)
    assert row.state == "rejected" and "queue_type: field required" in row.reason


@pytest.mark.parametrize("fault", [500, "hang"])
def test_server_errors_and_timeouts_are_retried_until_accepted(tmp_path, kowalski, fault) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, timeout_s=0.5))
    try:
        kowalski.hang_s = 2.0
        kowalski.faults["PUT"] = [fault]
        w.notice("MS181101ab-preliminary.json")
        assert w.submitter.step() == 1
        (row,) = submissions(w.store)
        assert row.state == "pending" and row.attempts == 1
        assert (row.http_status == 500) if fault == 500 else ("timed out" in row.answer or "deadline" in row.answer)
        assert w.submitter.step() == 0
        (row,) = submissions(w.store)
        assert row.state == "submitted" and row.attempts == 2
        # after a timeout the server may have taken the first PUT: it did not here, once is once
        assert list(kowalski.queues) == [qn(w, 1)]
    finally:
        kowalski.release.set()
        w.store.close()


@pytest.mark.parametrize("submit, reason", [
    ({}, "alert type EARLYWARNING not in [submit] alert_types"),
    ({"min_coverage": 0.999}, "below [submit] min_coverage"),
    ({"max_exposures": 1}, "more than [submit] max_exposures 1"),
])
def test_gates(tmp_path, kowalski, submit, reason) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, **submit))
    try:
        w.notice("MS181101ab-earlywarning.json" if not submit else "MS181101ab-preliminary.json")
        assert w.submitter.step() == 0
        (row,) = submissions(w.store)
        assert row.state == "skipped" and reason in row.reason and row.queue_name is None
        assert kowalski.log == []
    finally:
        w.store.close()


def test_earlywarning_is_submitted_when_asked(tmp_path, kowalski) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, alert_types=("EARLYWARNING", "PRELIMINARY")))
    try:
        w.notice("MS181101ab-earlywarning.json")
        w.submitter.step()
        assert [s.state for s in submissions(w.store)] == ["submitted"]
    finally:
        w.store.close()


def test_the_dry_run_sends_nothing_and_logs_the_request_redacted(tmp_path, kowalski, caplog) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, dry_run=True))
    try:
        w.notice("MS181101ab-preliminary.json")
        with caplog.at_level(logging.INFO, logger="mushrooms"):
            w.submitter.step()
        assert kowalski.log == []
        (row,) = submissions(w.store)
        assert row.state == "skipped" and row.reason == "dry run"
        (line,) = [r.getMessage() for r in caplog.records if "event=submission_dry_run" in r.getMessage()]
        request = json.loads(line.split("request=", 1)[1])
        assert request["method"] == "PUT" and request["url"] == kowalski.url + "/api/triggers/ztf"
        assert request["headers"]["Authorization"] == "Bearer ***"
        assert request["body"]["queue_name"] == planned(w, 1) + "_1"
        assert TOKEN not in caplog.text
    finally:
        w.store.close()


def test_the_token_is_never_in_logs_state_or_documents(world, kowalski, caplog, tmp_path) -> None:
    kowalski.faults["PUT"] = [500]
    with caplog.at_level(logging.DEBUG):
        world.notice("MS181101ab-preliminary.json")
        world.submitter.step()
        world.submitter.step()
        world.notice("MS181101ab-retraction.json")
        world.submitter.step()
    assert any(e["authorization"] == f"Bearer {TOKEN}" for e in kowalski.log)  # it was sent, in the header
    assert TOKEN not in caplog.text
    assert TOKEN not in repr(world.submitter.client)
    world.store.close()
    for f in tmp_path.iterdir():
        assert TOKEN.encode() not in f.read_bytes(), f
    world.store = Store(world.path)
    assert TOKEN not in json.dumps(world.documents())


def test_queue_names_are_stable_across_restarts(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.submitter.adopt()
    before = [(s.plan_id, s.queue_name) for s in submissions(world.store)]
    world.restart()
    assert world.submitter.adopt() == []  # nothing new: the row is not made again
    world.submitter.step()
    world.notice("MS230425l-preliminary.json", SID)
    world.restart()
    world.submitter.step()
    after = [(s.plan_id, s.queue_name) for s in submissions(world.store)]
    assert after[0] == before[0] and after[1][1] == queue_name_base("GW", after[1][0], SID)
    assert list(kowalski.queues) == [qn(world, 2)]


def test_plans_superseded_before_they_were_sent_are_never_sent(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.notice("MS230425l-preliminary.json", SID)  # both stored before the submitter ran (e.g. it was down)
    world.submitter.step()
    assert [s.state for s in submissions(world.store)] == ["skipped", "submitted"]
    assert [e["method"] for e in kowalski.log] == ["PUT"]
    assert list(kowalski.queues) == [qn(world, 1)]  # the first revision the submitter saw


def _single_plan(url: str) -> Config:
    """SkyPortal with one observation plan per revision (``[export] skyportal_plans = "single"``; the per-pass
    sets are in ``test_skyportal_sets.py``)."""
    config = _config(url, target="skyportal")
    return dataclasses.replace(config, export=dataclasses.replace(config.export, skyportal_plans="single"))


def test_skyportal_import_and_removal(tmp_path, skyportal) -> None:
    w = World(tmp_path / "state.sqlite", _single_plan(skyportal.url))
    try:
        w.notice("MS181101ab-preliminary.json")
        assert w.submitter.step() == 0
        (row,) = submissions(w.store)
        assert row.state == "submitted" and row.remote_id == "1"
        plan = skyportal.plans[1]
        base = queue_name_base("GW", row.plan_id, SID).removeprefix("ToO_")
        assert plan["plan_name"] == base and plan["payload"]["queue_name"] == base
        assert skyportal.log[0]["authorization"] == f"token {TOKEN}"
        w.notice("MS181101ab-retraction.json")
        w.submitter.step()
        assert skyportal.plans == {} and [s.state for s in submissions(w.store)] == ["deleted"]
    finally:
        w.store.close()


def test_skyportal_interrupted_post_is_looked_up_by_name(tmp_path, skyportal) -> None:
    w = World(tmp_path / "state.sqlite", _single_plan(skyportal.url))
    try:
        w.notice("MS181101ab-preliminary.json")
        _die_after(w.submitter.client, "post")
        with pytest.raises(Killed):
            w.submitter.step()
        w.restart()
        w.submitter.step()
        assert len(skyportal.plans) == 1  # not imported twice
        (row,) = submissions(w.store)
        assert row.state == "submitted" and "found by plan name" in row.reason
    finally:
        w.store.close()


def test_submit_config_is_validated_and_the_token_comes_from_the_environment(tmp_path) -> None:
    for text, message in [
        ('[submit]\ntarget = "telescope"\n', "target must be one of"),
        ('[submit]\ntarget = "kowalski"\n', "url must be an http(s) URL"),
        ('[submit]\ntarget = "kowalski"\nurl = "https://u:p@k.example"\n', "must not carry credentials"),
        ('[submit]\ntimeout_s = nan\n', "timeout_s must be a finite number"),
        ('[submit]\nmin_coverage = 1.5\n', "min_coverage must be in [0, 1]"),
        ('[submit]\ntoken = "x"\n', "unknown [submit] key(s): token"),
    ]:
        p = tmp_path / "c.toml"
        p.write_text(text)
        with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
            load_config(p)
    assert load_submit_token({"MUSHROOMS_SUBMIT_TOKEN": "abc"}) == ("abc", "env:MUSHROOMS_SUBMIT_TOKEN")
    (tmp_path / "creds").mkdir()
    (tmp_path / "creds" / "submit_token").write_text("fromcred\n")
    assert load_submit_token({"CREDENTIALS_DIRECTORY": str(tmp_path / "creds"), "MUSHROOMS_SUBMIT_TOKEN": "abc"}) \
        == ("fromcred", "credential:submit_token")
    with pytest.raises(CredentialsError, match="MUSHROOMS_SUBMIT_TOKEN"):
        load_submit_token({})
    assert not dataclasses.replace(SubmitConfig()).enabled


def _plan_file(world: World, tmp_path: Path) -> Path:
    world.notice("MS181101ab-preliminary.json")
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(world.store.plans()[-1]["document"]))
    return path


def test_submit_tool_dry_run_prints_the_request_redacted_and_sends_nothing(world, kowalski, tmp_path, capsys,
                                                                         monkeypatch) -> None:
    from mushrooms.cli import main

    plan = _plan_file(world, tmp_path)
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    assert main(["submit", str(plan), "--target", "kowalski", "--url", kowalski.url, "--dry-run"]) == 0
    out = capsys.readouterr().out
    (request,) = json.loads(out)
    assert request["method"] == "PUT" and request["headers"]["Authorization"] == "Bearer ***"
    doc = json.loads(plan.read_text())
    assert request["body"]["queue_name"] == queue_name_base("GW", doc["plan_id"], SID) + "_1" and TOKEN not in out
    assert kowalski.log == []


def test_submit_and_queue_tools_against_the_contract_server(world, kowalski, tmp_path, capsys, monkeypatch) -> None:
    from mushrooms.cli import main

    plan = _plan_file(world, tmp_path)
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    args = ["--url", kowalski.url]
    assert main(["submit", str(plan), "--target", "kowalski", "--queue-name", "ToO_GW_manual", *args]) == 0
    assert main(["submit", str(plan), "--target", "kowalski", "--queue-name", "ToO_GW_manual", *args]) == 0  # 409 same
    assert "already queued with the same content" in capsys.readouterr().out
    assert main(["queue", "list", *args]) == 0
    assert "ToO_GW_manual_1  " in capsys.readouterr().out
    assert main(["queue", "delete", "ToO_GW_manual_1", *args]) == 0
    assert main(["queue", "delete", "ToO_GW_manual_1", *args]) == 1
    assert "refused: 400: ZTF queue delete attempt rejected" in capsys.readouterr().err
    assert kowalski.queues == {}
    monkeypatch.delenv("MUSHROOMS_SUBMIT_TOKEN")
    assert main(["queue", "list", *args]) == 2  # no token: one line, exit 2
    assert "MUSHROOMS_SUBMIT_TOKEN" in capsys.readouterr().err
    assert TOKEN not in json.dumps(kowalski.lines())


def test_a_dry_run_after_a_real_run_sends_nothing_either(tmp_path, kowalski) -> None:
    path = tmp_path / "state.sqlite"
    w = World(path, _config(kowalski.url))
    w.notice("MS181101ab-preliminary.json")
    w.submitter.step()
    w.store.close()
    w = World(path, _config(kowalski.url, dry_run=True))  # the operator switches to a dry run
    try:
        w.notice("MS181101ab-retraction.json")
        assert w.submitter.step() == 0
        assert [e["method"] for e in kowalski.log] == ["PUT"]  # no DELETE sent
        assert list(kowalski.queues) == [qn(w, 1)]
    finally:
        w.store.close()


def test_a_revision_of_the_real_export_puts_every_queue_of_its_set(world, kowalski, monkeypatch) -> None:
    monkeypatch.undo()  # the real export: one timed queue per filter pass
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    (row,) = submissions(world.store)
    names = row.queue_names()
    assert len(names) > 1 and names == [f"{queue_name_base('GW', row.plan_id, SID)}_{k}" for k in range(1, len(names) + 1)]
    assert list(kowalski.queues) == names
    assert [line.split()[:3] for line in kowalski.lines()] == [["PUT", "/api/triggers/ztf", n] for n in names]
    windows = [kowalski.queues[n]["validity_window_mjd"] for n in names]
    assert all(a < b for a, b in windows)
