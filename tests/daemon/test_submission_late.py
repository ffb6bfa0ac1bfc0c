"""Queues whose fate the submitter cannot see: a PUT applied after the client's deadline, a 409 on our own queue.

Issue 52, findings 1 and 4 and the LOW item "settling a set DELETEs names
never PUT".  Real plans from the notice pipeline, a real store, Kowalski's
contract server on loopback (``contract_servers.py``): its ``"late"`` fault
holds a PUT unanswered past the client's ``[submit] timeout_s`` and applies
it only when the test says so (:attr:`~contract_servers.KowalskiContract.land`),
so no step depends on the machine's speed.  Queue sets of K = 3
(``test_submission_sets.three_queues``).

What Kowalski really does (``skyportal/kowalski`` @ 51d0078,
``kowalski/api/handlers/ztf.py``; docs/design/submission.md): a PUT on a name
the mountain already holds is a 409; the queue list is the mountain's, whose
list queues lose a target once it is observed (``ztf_sim`` ``QueueManager.py``
``ListQueueManager._remove_requests``) and are dropped once empty or expired
(``Scheduler.remove_empty_and_expired_queues``).
"""

from __future__ import annotations

import json

import pytest

from mushrooms.daemon.state.views import oldest_pending_submission
from mushrooms.daemon.submission.submitter import submissions
from test_submission_sets import names, sets  # noqa: F401 (fixture)
from test_submissions import SID, World, _config, _die_after, Killed, kowalski, server, world  # noqa: F401

UPDATE = ("MS230425l-preliminary.json", SID)
RETRACTION = "MS181101ab-retraction.json"
LATER = "2023-04-26T00:00:00Z"  # after the 2023 map the update uses: decisions follow creation order


def _states(w: World) -> list[tuple[int, str]]:
    return [(s.revision, s.state) for s in submissions(w.store) if s.revision is not None]


def _deletes(kowalski) -> list[str]:
    return [e["queue_name"] for e in kowalski.log if e["method"] == "DELETE"]


@pytest.fixture
def late(sets, tmp_path, kowalski):
    """A world whose first PUT (queue 1 of revision 1) is applied by Kowalski only after the client gave up."""
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, timeout_s=1.0))
    kowalski.hang_s = 60.0
    kowalski.faults_by_name["PUT", f"ToO_GW_{SID}_*_1"] = ["late"]  # queue 1 of the first plan (named by its id)
    try:
        w.notice("MS181101ab-preliminary.json")
        assert w.submitter.step() == 1  # no answer within the deadline: waits for a retry
        assert kowalski.late_held.wait(10)
        assert kowalski.queues == {}  # not applied yet
        yield w
    finally:
        kowalski.land.set()
        w.store.close()


def _land(kowalski, w: World) -> None:
    kowalski.land.set()
    assert kowalski.landed.wait(10)
    assert names(w, 1)[0] in kowalski.queues


def test_a_put_that_lands_after_the_deadline_is_deleted_when_it_appears_after_an_update(sets, late, kowalski):
    late.notice(*UPDATE)
    late.submitter.step()  # revision 2 accepted; revision 1's queue is not listed (yet)
    before_landing = _states(late)
    waiting = oldest_pending_submission(late.store.connection())
    _land(kowalski, late)  # the slow mountain link applies revision 1's PUT now
    late.submitter.step()
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(late, 2), "revision 1's late queue is left live beside revision 2"
    assert before_landing == [(1, "pending"), (2, "submitted")], "said replaced while its queue could still land"
    assert waiting is None, "a superseded queue watched for is not a submission waiting (readiness)"
    assert _states(late) == [(1, "replaced"), (2, "submitted")]
    assert late.submitter.step() == 0 and late.submitter.watching == 0


def test_a_late_queue_is_deleted_while_a_newer_revision_is_still_being_retried(sets, late, kowalski):
    late.notice(*UPDATE)
    late.submitter.step()  # revision 2 accepted; revision 1 watched
    kowalski.faults["PUT"] = [503] * 50  # revision 3's PUTs fail for now
    late.notice("MS181101ab-ext-update.json", SID, time_created="2024-01-01T00:00:00Z")
    assert late.submitter.step() == 1
    _land(kowalski, late)
    assert late.submitter.step() == 1  # revision 3 still waits for a retry ...
    print("\n".join(kowalski.lines()))
    assert names(late, 1)[0] not in kowalski.queues, "the late queue waited for revision 3"  # ... revision 1's is gone
    assert sorted(kowalski.queues) == names(late, 2)
    assert _states(late) == [(1, "replaced"), (2, "submitted"), (3, "pending")]


def test_a_put_that_lands_after_the_deadline_of_a_retracted_event_is_deleted_after_a_restart(sets, late, kowalski):
    late.notice(RETRACTION, time_created=LATER)
    late.submitter.step()  # the retraction settles revision 1: its queue is not listed (yet)
    before_landing = _states(late)
    late.restart()  # what is watched for is in the state file
    _land(kowalski, late)
    late.submitter.step()
    print("\n".join(kowalski.lines()))
    assert kowalski.queues == {}, "a queue is left live for a retracted event"
    assert before_landing == [(1, "pending")], "said deleted while its queue could still land"
    assert _states(late) == [(1, "deleted")]
    assert [d["state"] for d in late.documents()] == ["deleted"]


def test_a_put_that_never_lands_is_settled_once_its_queue_window_ended(sets, late, kowalski):
    late.notice(*UPDATE)
    late.submitter.step()
    watched = _states(late)
    with late.store.transaction() as c:  # the night passed: revision 1's queues' windows ended
        (plan_id, body), = c.execute("SELECT plan_id, body FROM submissions WHERE revision=1").fetchall()
        queues = [{**q, "validity_window_mjd": [50000.0, 50000.5]} for q in json.loads(body)]
        c.execute("UPDATE submissions SET body=? WHERE plan_id=?", (json.dumps(queues), plan_id))
    late.submitter.step()
    assert watched == [(1, "pending"), (2, "submitted")]
    (r1, r2) = submissions(late.store)
    assert (r1.state, r2.state) == ("replaced", "submitted") and "window ended" in r1.reason
    assert _deletes(kowalski) == [names(late, 1)[0]]  # asked once; then only the list was read
    assert late.submitter.step() == 0 and late.submitter.watching == 0


def test_a_refused_queue_of_a_set_deletes_only_the_queues_that_were_put(sets, world, kowalski):
    kowalski.faults["PUT"] = [None, 400]  # queue 1 accepted, queue 2 refused, queue 3 never sent
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    print("\n".join(kowalski.lines()))
    assert _deletes(kowalski) == [names(world, 1)[0]]
    assert _states(world) == [(1, "rejected")] and kowalski.queues == {}


def test_settling_an_older_set_deletes_what_was_put_or_may_be_live_never_what_was_not_sent(sets, world, kowalski):
    kowalski.faults["PUT"] = [None, 504]  # queue 1 accepted; queue 2 no answer (a gateway timeout); 3 not sent
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 1
    world.notice(*UPDATE)
    world.submitter.step()
    print("\n".join(kowalski.lines()))
    assert _deletes(kowalski) == names(world, 1)[:2]
    assert sorted(kowalski.queues) == names(world, 2)


@pytest.fixture
def killed_after_put_3(sets, world, kowalski):
    """kill -9 (in process) right after Kowalski accepted PUT #3 of revision 1, before the commit."""
    world.notice("MS181101ab-preliminary.json")
    _die_after(world.submitter.client, "put", nth=3)
    with pytest.raises(Killed):
        world.submitter.step()
    (row,) = submissions(world.store)
    assert row.state == "pending" and row.progress["put"] == names(world, 1)[:2]
    assert sorted(kowalski.queues) == names(world, 1)
    return world


def test_a_409_on_our_queue_whose_target_was_observed_keeps_the_revision(killed_after_put_3, kowalski):
    third = names(killed_after_put_3, 1)[2]
    listed = kowalski.queues[third]
    kowalski.queues[third] = {**listed, "targets": listed["targets"][1:]}  # the telescope took its first target
    killed_after_put_3.restart()
    killed_after_put_3.submitter.step()
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(killed_after_put_3, 1), "the accepted queues of the revision were deleted"
    assert _deletes(kowalski) == []
    (row,) = submissions(killed_after_put_3.store)
    assert row.state == "submitted" and "409" in row.reason and row.progress["put"] == names(killed_after_put_3, 1)


def test_a_409_on_a_name_this_revision_sent_is_ours_when_the_list_no_longer_shows_it(killed_after_put_3, kowalski):
    third = names(killed_after_put_3, 1)[2]
    del kowalski.queues[third]  # all its targets observed: the mountain dropped the empty queue ...
    kowalski.faults_by_name["PUT", third] = [409]  # ... after it answered the restart's PUT with 409
    killed_after_put_3.restart()
    killed_after_put_3.submitter.step()
    print("\n".join(kowalski.lines()))
    assert sorted(kowalski.queues) == names(killed_after_put_3, 1)[:2], "the accepted queues of the revision were deleted"
    assert _deletes(kowalski) == []
    assert _states(killed_after_put_3) == [(1, "submitted")]


def test_a_row_from_before_tried_was_kept_counts_its_first_queue_not_accepted_as_sent():
    from mushrooms.daemon.submission.rows import Submission

    named = [f"ToO_GW_{SID}_0123abcd_{k}" for k in (1, 2, 3)]
    set_ = [{"queue_name": n, "targets": [], "validity_window_mjd": [1.0, 2.0]} for n in named]
    row = Submission("p", SID, "kowalski", 1, "ToO_GW_r1", "pending", None, set_, None, None, None, 1,
                     "2026-01-01T00:00:00Z", None, None, None, {"put": named[:1]})
    assert row.maybe_sent() == set(named[:2])  # a set is PUT in order: the pass stopped at queue 2
    assert row.to_settle() == named[:2]  # queue 3 was never sent: never DELETEd
    refused = Submission(**{**row.__dict__, "progress": {"put": named[:1], "tried": named[:2],
                                                         "refused": named[1:2]}})
    assert refused.to_settle() == named[:1]


def test_the_submitter_thread_passes_again_while_a_queue_is_watched_for():
    import threading

    from mushrooms.daemon.submission.thread import _Recheck

    kicked = threading.Event()
    recheck = _Recheck(kicked.set, initial_s=0.01, max_s=0.04)
    recheck.after_pass(0)
    assert not kicked.wait(0.2)  # nothing watched: no pass is asked for
    recheck.after_pass(1)
    assert kicked.wait(10)  # watching: the drain is kicked again (hang guard only)
    kicked.clear()
    recheck.after_pass(1)
    assert kicked.wait(10)
