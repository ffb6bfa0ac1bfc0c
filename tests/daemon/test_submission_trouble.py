"""``on_trouble`` (the ``[notify]`` message of submission trouble) is told once per trouble (issue 52 follow-up).

It fired on every failed request of a row still at ``attempts == 1``: a PUT
counts an attempt, a DELETE does not, so a row whose one PUT was accepted and
whose DELETE (after an update) kept failing notified at every pass of the
back-off, all night.  And the first failure of a set's second queue (the row
at ``attempts == 2``) was never told at all.  Now a row tells each of its
troubles once: its submission, and its removal; kept in the state file.

Kowalski's contract server on loopback; a real store and submitter.
"""

from __future__ import annotations

from test_submission_sets import names, sets  # noqa: F401 (fixture)
from test_submission_late import UPDATE
from test_submissions import kowalski, one_queue_per_revision, qn, server, world  # noqa: F401 (fixtures)


def _told(world) -> list[tuple]:
    told: list[tuple] = []
    world.submitter.on_trouble = lambda sub, error, *action: told.append((sub.revision, error, *action))
    return told


def test_a_failing_delete_is_told_once_however_many_passes_retry_it(world, kowalski):
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0  # revision 1 (a set of one queue) accepted in one attempt: attempts == 1
    told = _told(world)
    kowalski.faults_by_name["DELETE", qn(world, 1)] = [503] * 4
    world.notice(*UPDATE)
    for _ in range(4):
        assert world.submitter.step() == 1  # revision 2 in; revision 1's DELETE retried
    assert world.submitter.step() == 0
    assert list(kowalski.queues) == [qn(world, 2)]
    assert len(told) == 1, told
    assert told[0][0] == 1 and "503" in told[0][1] and told[0][2:] == ("removed",), told
    world.restart()  # told once, also across a restart
    told = _told(world)
    kowalski.faults_by_name["DELETE", qn(world, 2)] = [503] * 2
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    world.submitter.step()
    world.submitter.step()
    assert world.submitter.step() == 0 and kowalski.queues == {}
    assert [t[0] for t in told] == [2], told


def test_a_failing_put_is_told_once_also_when_it_is_not_the_rows_first_attempt(sets, world, kowalski):
    told = _told(world)
    kowalski.faults_by_name["PUT", "ToO_GW_MS181101ab_*_2"] = [503] * 3  # queue 1 of the set in, queue 2 fails three times
    world.notice("MS181101ab-preliminary.json")
    for _ in range(3):
        assert world.submitter.step() == 1
    assert world.submitter.step() == 0 and sorted(kowalski.queues) == names(world, 1)
    assert len(told) == 1 and told[0][2:] == ("submitted",), told
