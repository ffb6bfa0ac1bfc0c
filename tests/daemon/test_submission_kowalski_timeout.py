"""Kowalski's own ``400 TimeoutError: `` is a request without an answer, not a refusal (issue 52 follow-up).

Kowalski forwards a PUT (or DELETE) to the mountain with a 10 s timeout
(``kowalski/api/handlers/ztf.py``); when that runs out, its ``error_middleware``
turns the exception into **400** ``"TimeoutError: "`` (docs/design/submission.md
Y0), while the mountain may still apply the request.  The submitter took it for
a refusal: the revision ``rejected`` and never retried, and a queue the
mountain applied afterwards stayed live, watched by no one.  Now such a queue is
*maybe live* (Y2): the PUT is retried (a repeat that finds it applied gets
Kowalski's 409 on our own queue, Y1), and a revision settled meanwhile watches
for it and deletes it when it appears.

Kowalski's contract server on loopback (``contract_servers.py``): its
``"mountain-timeout"`` fault answers that 400 at once and applies the request
only when the test says so, so no step depends on the machine's speed.
"""

from __future__ import annotations

from mushrooms.daemon.submission.submitter import submissions
from test_submission_late import LATER, RETRACTION, UPDATE, _deletes, _states
from test_submission_sets import names, sets  # noqa: F401 (fixture)
from test_submissions import kowalski, server, world  # noqa: F401 (fixtures)


def _first_put_times_out(world, kowalski) -> None:
    kowalski.faults_by_name["PUT", "ToO_GW_MS181101ab_*_1"] = ["mountain-timeout"]  # queue 1 of the first plan
    world.notice("MS181101ab-preliminary.json")
    waiting = world.submitter.step()
    print("\n".join(kowalski.lines()))
    (row,) = submissions(world.store)
    assert (row.state, waiting) == ("pending", 1), f"Kowalski's TimeoutError taken as a refusal: {row.reason}"
    assert names(world, 1)[0] in row.maybe_live() and kowalski.queues == {}


def _land(kowalski) -> None:
    kowalski.land.set()
    assert kowalski.landed.wait(10)


def test_a_put_kowalski_timed_out_is_retried_and_found_applied(sets, world, kowalski):
    _first_put_times_out(world, kowalski)
    _land(kowalski)  # the mountain applied it after Kowalski gave up
    assert world.submitter.step() == 0
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(world, 1) and _deletes(kowalski) == []
    (row,) = submissions(world.store)
    assert row.state == "submitted" and row.progress["put"] == names(world, 1)
    assert kowalski.lines()[:3] == [f"PUT /api/triggers/ztf {names(world, 1)[0]} -> 400",  # Kowalski's TimeoutError
                                    f"PUT /api/triggers/ztf {names(world, 1)[0]} -> 200 (applied after the client's deadline)",
                                    f"PUT /api/triggers/ztf {names(world, 1)[0]} -> 409"]  # the retry: ours, accepted


def test_a_put_kowalski_timed_out_that_lands_after_an_update_is_deleted(sets, world, kowalski):
    _first_put_times_out(world, kowalski)
    world.notice(*UPDATE)
    world.submitter.step()  # revision 2 accepted; revision 1's queue is not listed (yet): watched
    _land(kowalski)
    world.submitter.step()
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(world, 2), "revision 1's late queue is left live beside revision 2"
    assert _states(world) == [(1, "replaced"), (2, "submitted")]


def test_a_put_kowalski_timed_out_that_lands_after_a_retraction_is_deleted(sets, world, kowalski):
    _first_put_times_out(world, kowalski)
    world.notice(RETRACTION, time_created=LATER)
    world.submitter.step()
    _land(kowalski)
    world.submitter.step()
    print("\n".join(kowalski.lines()))
    assert kowalski.queues == {}, "a queue is left live for a retracted event"
    assert _states(world) == [(1, "deleted")]


def test_a_delete_kowalski_timed_out_is_retried_not_failed(sets, world, kowalski):
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    kowalski.faults_by_name["DELETE", names(world, 1)[0]] = ["mountain-timeout"]
    world.notice(*UPDATE)
    assert world.submitter.step() == 1  # revision 2 in; revision 1's DELETE has no answer yet
    _land(kowalski)  # the mountain removed it after Kowalski gave up
    assert world.submitter.step() == 0
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(world, 2)
    assert _states(world) == [(1, "replaced"), (2, "submitted")]
