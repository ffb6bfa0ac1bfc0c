"""Submission end to end: the real daemon, the loopback Kafka broker, the Kowalski contract server.

``mushrooms run`` in a subprocess plans real notices (greedy, nside 64) and
its submitter thread talks to the contract server of ``contract_servers.py``
(threaded pytest-httpserver on 127.0.0.1, run by this test process).
Kill points are reached deterministically: ``submit_fault_run.py`` kills the
daemon with SIGKILL just before or just after its PUT; a kill during a
DELETE is made while the server, having applied the DELETE, holds its answer.

The fast scenario (notice -> PUT, update -> PUT new + DELETE old, retraction
-> DELETE) is in the default run; kills and faults are ``slow``.
"""

from __future__ import annotations

import json
import re
import sqlite3
import time
from pathlib import Path

import pytest

from contract_servers import KowalskiContract, loopback_server
from daemon_helpers import Daemon, notice_bytes, write_config

TOKEN = "daemon-s3cr3t-9f8e7d6c5b4a"
SID = "MS181101ab"
LATER = "2023-04-26T00:00:00Z"  # a retraction dated after the 2023 map an update relabels
FAULT_RUN = Path(__file__).with_name("submit_fault_run.py")


def _uniq(name: str) -> str:
    return f"{name}-{time.time_ns()}"


def _requests_by_revision(kowalski, names: dict[str, int]) -> list[tuple[str, int]]:
    """(method, revision) of the PUTs and DELETEs in order, one entry per run of requests on one set
    (``names``: name base -> revision, :meth:`Setup.bases`)."""
    out: list[tuple[str, int]] = []
    for line in kowalski.lines():
        method, _, name = line.split()[:3]
        revision = names.get(name.rsplit("_", 1)[0])
        if method in ("PUT", "DELETE") and revision is not None:
            step = (method, revision)
            if not out or out[-1] != step:
                out.append(step)
    return out


@pytest.fixture
def kowalski():
    server = loopback_server()
    contract = KowalskiContract(server, TOKEN)
    yield contract
    contract.release.set()
    server.clear()
    server.stop()


class Setup:
    def __init__(self, broker, tmp_path: Path, url: str, submit: str = "") -> None:
        self.broker = broker
        self.topic, self.out = _uniq("gwalert"), _uniq("plans")
        broker.ensure_topic(self.topic)
        broker.ensure_topic(self.out)
        extra = ("\n[submit]\ntarget = \"kowalski\"\nurl = \"" + url + "\"\ntimeout_s = 3.0\n"
                 "retry_initial_s = 0.5\nretry_max_s = 2.0\n" + submit)
        self.cfg = write_config(tmp_path / "config.toml", self.topic, self.out, _uniq("mushrooms"), extra)
        self.state = tmp_path / "state.sqlite"
        self.tmp = tmp_path
        self.args = ["--config", str(self.cfg), "--bootstrap", broker.bootstrap, "--state", str(self.state)]
        self.env = {"MUSHROOMS_SUBMIT_TOKEN": TOKEN}

    def daemon(self, daemons: list, wrapper_kill: str | None = None) -> Daemon:
        env = dict(self.env)
        if wrapper_kill:
            env["MUSHROOMS_TEST_SUBMIT_KILL"] = wrapper_kill
        d = Daemon(self.tmp, self.args, env=env, wrapper=FAULT_RUN if wrapper_kill else None)
        daemons.append(d)
        return d

    def send(self, name: str, sid: str | None = None, time_created: str | None = None) -> None:
        self.broker.produce(self.topic, notice_bytes(name, sid, time_created), key=(sid or name).encode())

    def rows(self, sql: str) -> list[tuple]:
        with sqlite3.connect(self.state) as c:
            return c.execute(sql).fetchall()

    def states(self, sid: str = SID) -> list[tuple]:
        return self.rows(f"SELECT queue_name || '_1', state FROM submissions WHERE superevent_id='{sid}' AND"
                         " queue_name IS NOT NULL ORDER BY revision")

    def bases(self, sid: str = SID) -> dict[str, int]:
        """The name base of each submitted set of ``sid`` (the one rule names it from its plan) -> its revision."""
        if not self.state.exists():
            return {}
        return dict(self.rows(f"SELECT queue_name, revision FROM submissions WHERE superevent_id='{sid}' AND"
                              " queue_name IS NOT NULL"))

    def name(self, sid: str, n: int) -> str:
        """Queue 1 of the ``n``-th submitted set of ``sid``."""
        (base,) = [b for b, r in self.bases(sid).items() if r == n]
        return f"{base}_1"

    def revisions(self, kowalski, sid: str = SID) -> list[int]:
        """The revisions of ``sid`` whose queues ZTF holds (each a set ``<base>_1`` ... ``<base>_K``)."""
        bases = self.bases(sid)
        return sorted({bases[n.rsplit("_", 1)[0]] for n in list(kowalski.queues) if n.rsplit("_", 1)[0] in bases})


def _wait(predicate, timeout_s: float, d: Daemon, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not predicate():
        d.alive()
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}:\n{d.text()[-3000:]}")
        time.sleep(0.1)


def _set_names(s: "Setup", sid: str, revision: int) -> list[str]:
    """The queue names of ``sid``'s revision ``revision``, in set order (from its stored body)."""
    (body,), = s.rows(f"SELECT body FROM submissions WHERE superevent_id='{sid}' AND revision={revision}")
    return [q["queue_name"] for q in json.loads(body)]


def _no_duplicates(kowalski: KowalskiContract) -> None:
    accepted = [e["queue_name"] for e in kowalski.log if e["method"] == "PUT" and e["status"] == 200]
    assert len(accepted) == len(set(accepted)), kowalski.lines()


def test_notice_update_and_retraction_through_the_daemon(broker, daemons, tmp_path, kowalski) -> None:
    s = Setup(broker, tmp_path, kowalski.url)
    d = s.daemon(daemons)
    d.wait_log("event=service_ready", 120)
    s.send("MS181101ab-preliminary.json", SID)
    _wait(lambda: s.revisions(kowalski) == [1], 180, d, "the first queue set")
    s.send("MS230425l-preliminary.json", SID)  # an updated sky map
    _wait(lambda: s.revisions(kowalski) == [2], 180, d, "the second set to replace the first")
    r1, r2 = s.name(SID, 1), s.name(SID, 2)
    s.send("MS181101ab-retraction.json", SID, "2023-04-26T00:00:00Z")  # after the 2023 map it retracts
    _wait(lambda: not kowalski.queues and any(e["method"] == "DELETE" and str(e.get("queue_name")).startswith(r2[:-1])
                                              for e in kowalski.log), 120, d, "the retraction's DELETE")
    _wait(lambda: s.states() == [(r1, "replaced"), (r2, "deleted")], 30, d, "the states")
    assert d.stop() == 0
    print("\n".join(kowalski.lines()))
    assert _requests_by_revision(kowalski, s.bases()) == [("PUT", 1), ("PUT", 2), ("DELETE", 1), ("DELETE", 2)]
    assert all(line.endswith("-> 200") for line in kowalski.lines())
    assert all(e["authorization"] == f"Bearer {TOKEN}" for e in kowalski.log)
    text = d.text()
    assert "event=submission_submitted" in text and "event=submission_replaced" in text
    assert TOKEN not in text
    for f in tmp_path.iterdir():
        if f.is_file():
            assert TOKEN.encode() not in f.read_bytes(), f
    docs = [json.loads(r[0]) for r in s.rows("SELECT body FROM outbox WHERE kind='submission' ORDER BY outbox_id")]
    assert [(x["queue_name"] + "_1", x["state"]) for x in docs] == [(r1, "submitted"), (r2, "submitted"),
                                                             (r1, "replaced"), (r2, "deleted")]
    assert s.rows("SELECT COUNT(*) FROM outbox WHERE published_at IS NULL") == [(0,)]


@pytest.mark.slow
@pytest.mark.parametrize("point", ["before_put", "after_put"])
def test_kill9_around_the_put_then_restart(broker, daemons, tmp_path, kowalski, point) -> None:
    s = Setup(broker, tmp_path, kowalski.url)
    d1 = s.daemon(daemons, wrapper_kill=point)
    d1.wait_log("event=service_ready", 120)
    s.send("MS181101ab-preliminary.json", SID)
    d1.proc.wait(300)
    assert d1.proc.returncode == -9, d1.text()[-3000:]
    r1 = s.name(SID, 1)
    assert s.states() == [(r1, "pending")] and s.rows("SELECT attempts FROM submissions") == [(1,)]
    assert list(kowalski.queues) == ([] if point == "before_put" else [r1])
    d2 = s.daemon(daemons)
    _wait(lambda: s.states() == [(r1, "submitted")], 180, d2, "the restart to settle the submission")
    set_names = _set_names(s, SID, 1)
    assert sorted(kowalski.queues) == sorted(set_names)
    expected = ([] if point == "before_put" else
                [f"PUT /api/triggers/ztf {r1} -> 200", f"PUT /api/triggers/ztf {r1} -> 409",
                 "GET /api/triggers/ztf  -> 200"])
    expected += [f"PUT /api/triggers/ztf {n} -> 200" for n in set_names[point == "after_put":]]
    print(point, kowalski.lines())
    assert kowalski.lines() == expected
    assert d2.stop() == 0


@pytest.mark.slow
def test_kill9_during_the_delete_then_restart(broker, daemons, tmp_path, kowalski) -> None:
    s = Setup(broker, tmp_path, kowalski.url)
    d1 = s.daemon(daemons)
    d1.wait_log("event=service_ready", 120)
    s.send("MS181101ab-preliminary.json", SID)
    _wait(lambda: [st for _, st in s.states()] == ["submitted"], 180, d1, "the first queue")
    kowalski.block_after.add("DELETE")  # the server applies the DELETE, then holds its answer
    s.send("MS230425l-preliminary.json", SID)
    assert kowalski.blocked.wait(180), d1.text()[-3000:]
    d1.kill9()
    r1, r2 = s.name(SID, 1), s.name(SID, 2)
    kowalski.block_after.clear()
    kowalski.release.set()
    old, new = _set_names(s, SID, 1), _set_names(s, SID, 2)
    assert sorted(kowalski.queues) == sorted(old[1:] + new) and s.states() == [(r1, "submitted"), (r2, "submitted")]
    d2 = s.daemon(daemons)
    _wait(lambda: s.states() == [(r1, "replaced"), (r2, "submitted")], 180, d2, "the restart to finish the DELETE")
    print(kowalski.lines())
    restart = [f"DELETE /api/triggers/ztf {r1} -> 400", "GET /api/triggers/ztf  -> 200"]  # gone, not listed
    restart += [f"DELETE /api/triggers/ztf {n} -> 200" for n in old[1:]]
    assert kowalski.lines()[-len(restart) - 1:] == [f"DELETE /api/triggers/ztf {r1} -> 200"] + restart
    assert sorted(kowalski.queues) == sorted(new)
    _no_duplicates(kowalski)
    assert d2.stop() == 0


@pytest.mark.slow
def test_kill9_after_put_3_of_a_set_while_a_target_of_it_was_observed(broker, daemons, tmp_path, kowalski) -> None:
    """Issue 52, finding 4: SIGKILL after Kowalski accepted PUT #3 of a set, before the commit; meanwhile the
    telescope observes a target of queue #3, so the list shows it without that target.  The restart's PUT #3
    is a 409 on our own queue: the revision is kept, not rejected with its accepted queues deleted."""
    s = Setup(broker, tmp_path, kowalski.url)
    d1 = s.daemon(daemons, wrapper_kill="after_put:3")
    d1.wait_log("event=service_ready", 120)
    s.send("MS181101ab-preliminary.json", SID)
    d1.proc.wait(300)
    assert d1.proc.returncode == -9, d1.text()[-3000:]
    set_names = [q["queue_name"] for q in json.loads(s.rows("SELECT body FROM submissions WHERE revision=1")[0][0])]
    assert len(set_names) >= 3 and sorted(kowalski.queues) == sorted(set_names[:3])
    third = kowalski.queues[set_names[2]]
    assert len(third["targets"]) >= 2
    kowalski.queues[set_names[2]] = {**third, "targets": third["targets"][1:]}  # its first target observed
    d2 = s.daemon(daemons)
    _wait(lambda: s.rows("SELECT state FROM submissions WHERE revision=1")[0][0] != "pending", 180, d2,
          "the restart to settle the revision")
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == sorted(set_names), "the accepted queues of the revision were deleted"
    assert not [e for e in kowalski.log if e["method"] == "DELETE"]
    assert f"PUT /api/triggers/ztf {set_names[2]} -> 409" in kowalski.lines()
    assert s.states() == [(s.name(SID, 1), "submitted")]
    _no_duplicates(kowalski)
    assert d2.stop() == 0


def _late_then_settled(s: Setup, d: Daemon, kowalski, sid: str, settle: tuple[str, str, str | None],
                       end_states: list[str]) -> list[tuple]:
    """``sid``'s first PUT is applied by Kowalski only after the daemon's deadline (its retries answered 503);
    ``settle`` (a notice) settles that revision; then the late PUT lands.  The states seen before it landed."""
    pattern = f"ToO_GW_{sid}_*_1"  # queue 1 of sid's first plan (named after its plan id: not known yet)
    kowalski.land.clear(), kowalski.late_held.clear(), kowalski.landed.clear()
    kowalski.faults_by_name["PUT", pattern] = ["late"] + [503] * 5000
    s.send("MS181101ab-preliminary.json", sid)
    assert kowalski.late_held.wait(180), d.text()[-3000:]
    first = s.name(sid, 1)
    with kowalski._lock:  # from now on that queue only (the next plan's queue 1 matches the pattern too)
        kowalski.faults_by_name["PUT", first] = kowalski.faults_by_name.pop(("PUT", pattern))
    s.send(*settle)
    _wait(lambda: f"DELETE /api/triggers/ztf {first} -> 400" in kowalski.lines(), 180, d, "the settling DELETE")
    before = s.states(sid)
    kowalski.faults_by_name.pop(("PUT", first))
    kowalski.land.set()
    assert kowalski.landed.wait(30) and first in kowalski.queues
    _wait(lambda: first not in kowalski.queues, 60, d, f"the late queue {first} to be deleted once it appeared")
    _wait(lambda: [st for _, st in s.states(sid)] == end_states, 30, d, "the final states")
    return before


@pytest.mark.slow
def test_a_put_applied_after_the_deadline_is_deleted_after_an_update_and_after_a_retraction(broker, daemons, tmp_path,
                                                                                           kowalski) -> None:
    """Issue 52, finding 1, end to end: the daemon, the loopback broker, a Kowalski stand-in that applies a PUT
    after the client's ``timeout_s``.  An updated map, then (another event) a retraction settle the revision
    whose PUT had no answer; its queue lands afterwards and is deleted once it shows in the list, and the row
    claims ``replaced`` / ``deleted`` only then.  At the end only the update's queue set is live."""
    s = Setup(broker, tmp_path, kowalski.url)
    kowalski.hang_s = 120.0
    d = s.daemon(daemons)
    d.wait_log("event=service_ready", 120)
    other = "MS190425x"
    before_update = _late_then_settled(s, d, kowalski, SID, ("MS230425l-preliminary.json", SID, None),
                                       ["replaced", "submitted"])
    before_retraction = _late_then_settled(s, d, kowalski, other, ("MS181101ab-retraction.json", other, LATER),
                                           ["deleted"])
    r1, r2, o1 = s.name(SID, 1), s.name(SID, 2), s.name(other, 1)
    assert d.stop() == 0
    print("\n".join(kowalski.lines()))
    assert s.revisions(kowalski, SID) == [2] and s.revisions(kowalski, other) == []
    assert before_update == [(r1, "pending"), (r2, "submitted")] and before_retraction == [(o1, "pending")]
    assert "event=submission_watch" in d.text()
    _no_duplicates(kowalski)


def _latency(text: str, sid: str) -> float:
    m = re.search(rf"event=job_done superevent_id={sid} .*?latency_s=([0-9.]+)", text)
    assert m, f"no job_done for {sid}"
    return float(m.group(1))


@pytest.mark.slow
def test_refusals_server_errors_and_a_hanging_server(broker, daemons, tmp_path, kowalski) -> None:
    """400 -> rejected; 409 with other content -> rejected; hang, hang, 500 -> retried until accepted;
    a third event is planned while the server hangs."""
    s = Setup(broker, tmp_path, kowalski.url)
    a, b, c = SID, "MS230425l", "MS260605l"
    kowalski.taken.add(f"ToO_GW_{c}_")  # c's first queue exists already, with other content (a 409 for it)
    kowalski.hang_s = 30.0
    d = s.daemon(daemons)
    d.wait_log("event=service_ready", 120)
    kowalski.faults["PUT"] = [400]
    s.send("MS181101ab-preliminary.json", a)
    _wait(lambda: [st for _, st in s.states(a)] == ["rejected"], 180, d, "the 400")
    kowalski.faults["PUT"] = ["hang", "hang", 500]
    s.send("MS230425l-preliminary.json", b)
    _wait(lambda: kowalski.hanging > 0, 180, d, "b's first PUT to hang")
    s.send("MS260605l-preliminary.json", c)  # planned while the server hangs
    d.wait_log(f"event=job_done superevent_id={c}", 180)
    hanging = kowalski.hanging
    assert hanging > 0  # c's plan was made while requests were held unanswered
    latency_c = _latency(d.text(), c)
    kowalski.release.set()
    _wait(lambda: [st for _, st in s.states(b)] == ["submitted"] and [st for _, st in s.states(c)] == ["rejected"],
          240, d, "b accepted after the retries, c refused with 409")
    assert d.stop() == 0
    text = d.text()
    errors = [line for line in text.splitlines() if " ERROR " in line]
    assert len(errors) == 2, errors  # one per refusal, never repeated
    assert sum("event=submission_rejected" in e for e in errors) == 2
    assert "injected 400" in s.rows(f"SELECT answer FROM submissions WHERE superevent_id='{a}'")[0][0]
    assert "409: a queue of that name exists with other content" in \
        s.rows(f"SELECT reason FROM submissions WHERE superevent_id='{c}'")[0][0]
    # the faults go to whichever PUT comes next (b's retries or c's first): together they took them all
    puts = [e["status"] for e in kowalski.log if e["method"] == "PUT" and e.get("queue_name") in (s.name(b, 1),
                                                                                                 s.name(c, 1))]
    assert sorted(puts) == [200, 409, 500, 504, 504], kowalski.lines()
    docs = [json.loads(r[0]) for r in s.rows("SELECT body FROM outbox WHERE kind='submission' ORDER BY outbox_id")]
    assert {(x["superevent_id"], x["state"], x["http_status"]) for x in docs} == {
        (a, "rejected", 400), (c, "rejected", 409), (b, "submitted", 200)}
    print(f"\nfirst-plan latency of {c} while the server hung ({hanging} request(s) unanswered): "
          f"{latency_c:.2f} s; of {a} (server answering): {_latency(text, a):.2f} s")
    print("\n".join(kowalski.lines()))
    assert TOKEN not in text
