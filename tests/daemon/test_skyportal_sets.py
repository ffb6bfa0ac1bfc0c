"""The SkyPortal target: a revision is one observation plan per filter pass, POSTed in order, deleted together (T2-T3).

Real plans from the notice pipeline (greedy), the real export
(:func:`~mushrooms.scheduler_core.plan.exports.to_skyportal_plans`), a real
SQLite store and SkyPortal's contract server on loopback
(``contract_servers.py``).  Kills are simulated in process (``Killed``): the
restart is a new store and submitter on the same file.
"""

from __future__ import annotations

import dataclasses
import json

import pytest

from contract_servers import SkyPortalContract
from mushrooms.daemon.submission.submitter import queue_name_base, submissions
from test_submissions import (SID, TOKEN, Killed, World, _config, _die_after, killed_during_the_deletes,  # noqa: F401
                              server)

MANUAL = "/api/observation_plan/manual"


@pytest.fixture
def skyportal(server):
    return SkyPortalContract(server, TOKEN)


@pytest.fixture
def world(tmp_path, skyportal):
    w = World(tmp_path / "state.sqlite", _config(skyportal.url, target="skyportal"))
    yield w
    w.store.close()


def names(world: World, revision: int) -> list[str]:
    """The plan names of an event's ``revision``-th set, as stored (``GW_<superevent>_<plan tag>_<k>``)."""
    (row,) = [s for s in submissions(world.store) if s.revision == revision]
    got = row.queue_names()
    base = queue_name_base("GW", row.plan_id, SID).removeprefix("ToO_")
    assert got == [f"{base}_{k}" for k in range(1, len(got) + 1)]
    return got


def test_a_revision_posts_its_plans_in_order_an_update_posts_the_new_set_then_deletes_the_old(world, skyportal):
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    first = names(world, 1)
    assert len(first) > 1
    assert skyportal.lines() == [f"POST {MANUAL} {n} -> 200" for n in first]
    assert [p["plan_name"] for p in skyportal.plans.values()] == first
    (row,) = submissions(world.store)
    assert row.state == "submitted" and row.remote_id == ",".join(str(i) for i in range(1, len(first) + 1))
    old_ids = list(skyportal.plans)
    world.notice("MS230425l-preliminary.json", SID)
    assert world.submitter.step() == 0
    second = names(world, 2)
    assert skyportal.lines()[len(first):] == ([f"POST {MANUAL} {n} -> 200" for n in second]
                                              + [f"DELETE /api/observation_plan/{i}  -> 200" for i in old_ids])
    assert [p["plan_name"] for p in skyportal.plans.values()] == second
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    assert world.submitter.step() == 0
    assert skyportal.plans == {}
    assert [s.state for s in submissions(world.store)] == ["replaced", "deleted"]
    n = len(skyportal.log)
    assert world.submitter.step() == 0 and len(skyportal.log) == n  # settled: nothing more is sent


def test_a_kill_after_a_post_of_a_set_imports_no_plan_twice_and_names_the_one_left_by_hand(world, skyportal):
    world.notice("MS181101ab-preliminary.json")
    _die_after(world.submitter.client, "post", nth=2)
    with pytest.raises(Killed):
        world.submitter.step()
    world.restart()
    assert world.submitter.step() == 0
    planned = names(world, 1)
    imported = [p["plan_name"] for p in skyportal.plans.values()]
    assert imported == planned  # each once, in order: the second was found by name, not sent again
    (row,) = submissions(world.store)
    assert row.state == "submitted" and "found by plan name" in row.reason
    assert [e["plan_name"] for e in skyportal.log if e["method"] == "POST"] == planned
    # its request id is unknown: a retraction removes every other plan and names that one for the operator
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    assert world.submitter.step() == 0
    assert [p["plan_name"] for p in skyportal.plans.values()] == [planned[1]]
    (row,) = submissions(world.store)
    assert row.state == "failed" and row.reason.endswith(f"remove plan(s) {planned[1]} by hand")


def test_a_kill_during_the_deletes_is_finished_by_the_restart(world, skyportal):
    killed_during_the_deletes(world)
    gone_id = int(skyportal.log[-1]["path"].rsplit("/", 1)[1])
    world.restart()
    assert world.submitter.step() == 0
    assert [p["plan_name"] for p in skyportal.plans.values()] == names(world, 2)
    assert [s.state for s in submissions(world.store)] == ["replaced", "submitted"]
    repeat = [line for line in skyportal.lines() if line.startswith(f"DELETE /api/observation_plan/{gone_id} ")]
    assert repeat == [f"DELETE /api/observation_plan/{gone_id}  -> 200",
                      f"DELETE /api/observation_plan/{gone_id}  -> 400"]  # then plan_names: not there, done


def test_a_refused_plan_of_a_set_takes_the_accepted_ones_back_and_is_rejected(world, skyportal):
    skyportal.faults["POST"] = [None, 400]
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    first = names(world, 1)
    assert skyportal.lines() == [f"POST {MANUAL} {first[0]} -> 200", f"POST {MANUAL} {first[1]} -> 400",
                                 "DELETE /api/observation_plan/1  -> 200",
                                 "GET /api/observation_plan/plan_names  -> 200"]  # the refused one: not there
    assert skyportal.plans == {}
    (row,) = submissions(world.store)
    assert row.state == "rejected" and row.reason.startswith(first[1])


def test_the_submit_tool_posts_every_plan_of_the_set_and_names_each(world, skyportal, tmp_path, capsys, monkeypatch):
    from mushrooms.cli import main

    world.notice("MS181101ab-preliminary.json")
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps(world.store.plans()[-1]["document"]))
    config = tmp_path / "c.toml"
    config.write_text("[export]\nskyportal_allocation_id = 7\n")
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    assert main(["submit", str(plan), "--config", str(config), "--target", "skyportal", "--url", skyportal.url,
                 "--queue-name", "ToO_GW_manual"]) == 0
    posted = [p["plan_name"] for p in skyportal.plans.values()]
    assert len(posted) > 1 and posted == [f"GW_manual_{k}" for k in range(1, len(posted) + 1)]
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[1] for line in out] == posted and all(line.startswith("submitted ") for line in out)


def test_a_row_written_before_sets_is_looked_up_by_its_plan_name_and_removed_by_its_id(tmp_path, skyportal):
    config = _config(skyportal.url, target="skyportal")
    w = World(tmp_path / "state.sqlite", dataclasses.replace(
        config, export=dataclasses.replace(config.export, skyportal_plans="single")))
    try:
        w.notice("MS181101ab-preliminary.json")
        w.submitter.adopt()
        with w.store.transaction() as c:  # the body as stored before sets: one plan, not a list
            (body,) = json.loads(c.execute("SELECT body FROM submissions").fetchone()[0])
            c.execute("UPDATE submissions SET body=?", (json.dumps(body),))
        _die_after(w.submitter.client, "post")
        with pytest.raises(Killed):
            w.submitter.step()
        w.restart()
        assert w.submitter.step() == 0
        (row,) = submissions(w.store)
        one = queue_name_base("GW", row.plan_id, SID).removeprefix("ToO_")
        assert [p["plan_name"] for p in skyportal.plans.values()] == [one]  # not imported twice
        w.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
        assert w.submitter.step() == 0
        (row,) = submissions(w.store)
        assert row.state == "failed" and row.reason.endswith(f"remove plan(s) {one} by hand")
        assert [p["plan_name"] for p in skyportal.plans.values()] == [one]  # said, not claimed removed
    finally:
        w.store.close()


def test_a_delete_answered_302_fails_the_row_and_one_answered_200_not_json_is_retried(world, skyportal):
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    n = len(skyportal.plans)
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    skyportal.hang_s, skyportal.drip_s = 0.3, 0.1
    skyportal.faults["DELETE"] = ["drip"]  # a 200 whose body is blanks: not known to be removed
    assert world.submitter.step() == 1
    assert len(skyportal.plans) == n and submissions(world.store)[0].state == "submitted"
    skyportal.faults["DELETE"] = [None, 302]  # the first plan removed, the second's DELETE redirected
    assert world.submitter.step() == 0
    (row,) = submissions(world.store)
    assert row.state == "failed" and "302" in row.reason and len(skyportal.plans) == n - 1
