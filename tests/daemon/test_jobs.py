"""JobRunner and OutboxDrain with real threads and a real APScheduler.

Deterministic: every test job blocks on an event the test releases, never on
a sleep, and no assertion compares wall-clock delays.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import pytest
from apscheduler.schedulers.background import BackgroundScheduler

from mushrooms.daemon.drain import OutboxDrain
from mushrooms.daemon.planning.jobs import JobRunner, Staged


@dataclass(frozen=True)
class Job:
    job_id: int
    superevent_id: str


@pytest.fixture
def scheduler():
    s = BackgroundScheduler(timezone="UTC")
    s.start()
    yield s
    s.shutdown(wait=False)


def wait(cond, timeout_s: float = 20.0) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < end, "condition not reached"
        time.sleep(0.01)


class Gate:
    """A test planner stage that blocks until released (or stopped), recording what ran."""

    def __init__(self) -> None:
        self.log: list[tuple[int, str]] = []
        self.entered: dict[tuple[int, str], threading.Event] = {}
        self.release: dict[tuple[int, str], threading.Event] = {}
        self._lock = threading.Lock()

    def _ev(self, table, key) -> threading.Event:
        with self._lock:
            return table.setdefault(key, threading.Event())

    def run(self, job_id: int, stage: str, should_stop) -> str:
        self._ev(self.entered, (job_id, stage)).set()
        release = self._ev(self.release, (job_id, stage))
        while not release.wait(0.01):  # a solver loop polling its stop flag
            if should_stop():
                self.log.append((job_id, f"{stage}:stopped"))
                return "stopped"
        self.log.append((job_id, stage))
        return "done"

    def open(self, job_id: int, stage: str) -> None:
        self._ev(self.release, (job_id, stage)).set()

    def reached(self, job_id: int, stage: str, timeout_s: float = 20.0) -> None:
        assert self._ev(self.entered, (job_id, stage)).wait(timeout_s), f"job {job_id} never reached {stage}"


def test_newer_job_for_the_same_superevent_stops_the_running_one(scheduler) -> None:
    gate = Gate()
    runner = JobRunner(lambda job, stop: gate.run(job.job_id, "first", stop), scheduler, max_jobs=2,
                       deadline_s=600)
    assert runner.submit(Job(1, "S1"), received_at=time.time())
    gate.reached(1, "first")
    assert not runner.submit(Job(1, "S1"))  # the same job again is not run twice
    assert runner.submit(Job(2, "S1"))  # newer sky map, same superevent: job 1 is asked to stop
    wait(lambda: (1, "first:stopped") in gate.log)
    assert runner.submit(Job(3, "S2"))  # another superevent is independent
    gate.reached(2, "first")
    gate.reached(3, "first")
    gate.open(2, "first")
    gate.open(3, "first")
    wait(lambda: not runner.busy())
    assert gate.log[0] == (1, "first:stopped") and {(2, "first"), (3, "first")} <= set(gate.log)
    assert runner.active() == []
    assert runner.shutdown(1)


def test_sync_starts_only_the_newest_pending_job_per_superevent(scheduler) -> None:
    ran: list[int] = []
    runner = JobRunner(lambda job, stop: ran.append(job.job_id), scheduler, max_jobs=1)
    n = runner.sync([Job(1, "S1"), Job(2, "S2"), Job(3, "S1")])
    wait(lambda: not runner.busy())
    assert n == 2 and sorted(ran) == [2, 3]
    assert runner.sync([Job(3, "S1")]) == 0  # already done by this process


def test_deadline_asks_the_job_to_stop(scheduler) -> None:
    gate = Gate()
    runner = JobRunner(lambda job, stop: gate.run(job.job_id, "first", stop), scheduler, deadline_s=0.5)
    runner.submit(Job(1, "S1"))
    wait(lambda: gate.log)  # never released: only the deadline can end it
    assert gate.log == [(1, "first:stopped")]


def test_a_failing_job_does_not_kill_the_runner(scheduler) -> None:
    done = []

    def run(job, should_stop):
        if job.job_id == 1:
            raise RuntimeError("boom")
        return "ok"

    runner = JobRunner(run, scheduler, on_done=lambda job, outcome, info: done.append((job.job_id, info)))
    runner.submit(Job(1, "S1"))
    runner.submit(Job(2, "S2"))
    wait(lambda: len(done) == 2)
    errors = {j: i.get("error") for j, i in done}
    assert errors[1] == "RuntimeError: boom" and errors[2] is None


def test_a_first_plan_runs_before_the_optimisation_of_an_older_event(scheduler) -> None:
    """One worker: A's first plan, then B's first plan (received later), then A's and B's optimisations."""
    gate = Gate()
    done = []

    def run(job, stop):
        gate.run(job.job_id, "first", stop)
        return Staged(f"first-{job.job_id}", lambda stop2: gate.run(job.job_id, "optimise", stop2))

    runner = JobRunner(run, scheduler, max_jobs=1, deadline_s=600,
                       on_done=lambda job, outcome, info: done.append(job.job_id))
    runner.submit(Job(1, "A"))
    gate.reached(1, "first")
    runner.submit(Job(2, "B"))  # arrives while A's first plan is being made
    assert runner.queued() == [("2", "first")]
    gate.open(1, "first")
    gate.reached(2, "first")  # B's first plan is taken before A's optimisation
    assert runner.queued() == [("1", "optimise")]
    for stage in ("first", "optimise"):
        for j in (2, 1):
            gate.open(j, stage)
    wait(lambda: len(done) == 2)
    assert gate.log == [(1, "first"), (2, "first"), (1, "optimise"), (2, "optimise")]


def optimising_a(scheduler) -> tuple[Gate, JobRunner]:
    """Two workers, staged jobs; job 1 (superevent A) has published its first plan and is optimising."""
    gate = Gate()

    def run(job, stop):
        gate.run(job.job_id, "first", stop)
        return Staged(None, lambda stop2: gate.run(job.job_id, "optimise", stop2))

    runner = JobRunner(run, scheduler, max_jobs=2, deadline_s=600)
    runner.submit(Job(1, "A"))
    gate.open(1, "first")
    gate.reached(1, "optimise")
    return gate, runner


def test_an_optimisation_never_takes_the_last_free_worker(scheduler) -> None:
    """Two workers, A optimising: B's and C's optimisations wait, their first plans do not."""
    gate, runner = optimising_a(scheduler)
    for j, sid in ((2, "B"), (3, "C")):
        gate.open(j, "first")
        runner.submit(Job(j, sid))
        wait(lambda j=j: (j, "first") in gate.log)  # served by the other worker
    assert runner.queued() == [("2", "optimise"), ("3", "optimise")]
    for j in (1, 2, 3):
        gate.open(j, "optimise")
    wait(lambda: not runner.busy())
    assert gate.log == [(1, "first"), (2, "first"), (3, "first"), (1, "optimise"), (2, "optimise"),
                        (3, "optimise")]


def test_a_newer_map_during_the_optimisation_stops_it(scheduler) -> None:
    gate, runner = optimising_a(scheduler)
    gate.open(2, "first")
    runner.submit(Job(2, "A"))  # a newer sky map for the same superevent
    wait(lambda: (1, "optimise:stopped") in gate.log and (2, "first") in gate.log)
    gate.open(2, "optimise")
    wait(lambda: not runner.busy())
    assert gate.log.index((1, "optimise:stopped")) < gate.log.index((2, "optimise"))


def test_outbox_drain_backs_off_until_the_publish_works() -> None:
    calls = []
    ok = threading.Event()

    def flush():
        calls.append(1)
        if len(calls) < 3:
            raise ConnectionError("broker down")
        ok.set()
        return 0

    d = OutboxDrain(flush, initial_s=0.05, max_s=1.0)
    try:
        d.kick()
        assert ok.wait(20)
        wait(d.idle)
        assert d.delays == [0.05, 0.1]  # exponential back-off, doubling
        assert d.failures == 2 and d.attempts == 3 and not d.retry_scheduled  # no retry once empty
    finally:
        d.close()


def test_outbox_drain_runs_outside_the_planning_thread() -> None:
    """A publish that hangs (dead broker) never blocks whoever kicks the drain."""
    unblock = threading.Event()
    entered = threading.Event()

    def flush():
        entered.set()
        unblock.wait(30)
        return 0

    d = OutboxDrain(flush, initial_s=0.05)
    try:
        d.kick()
        assert entered.wait(10)
        d.kick()  # returns at once although the drain is stuck in a publish
        d.kick(now=True)
        unblock.set()
        wait(lambda: d.attempts == 2 and d.idle())
    finally:
        d.close()


def test_cancel_stops_the_running_job_of_a_superevent(scheduler) -> None:
    gate = Gate()
    runner = JobRunner(lambda job, stop: gate.run(job.job_id, "first", stop), scheduler)
    runner.submit(Job(1, "S1"))
    gate.reached(1, "first")
    assert runner.cancel("S1", "withdraw")
    wait(lambda: gate.log)
    assert gate.log == [(1, "first:stopped")]
    wait(lambda: not runner.busy())
    assert not runner.cancel("S1", "withdraw")  # nothing left to cancel
