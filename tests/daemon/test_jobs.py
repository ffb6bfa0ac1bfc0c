"""JobRunner and OutboxRetrier with real threads and a real APScheduler."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import pytest
from apscheduler.schedulers.background import BackgroundScheduler

from mushrooms.daemon.jobs import JobRunner, OutboxRetrier


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
        time.sleep(0.02)


def test_newer_job_for_the_same_superevent_stops_the_running_one(scheduler) -> None:
    events: list[tuple[int, str]] = []
    started = {1: threading.Event(), 2: threading.Event(), 3: threading.Event()}

    def run(job: Job, should_stop) -> str:
        started[job.job_id].set()
        end = time.monotonic() + (30 if job.job_id == 1 else 0.2)
        while time.monotonic() < end:  # a solver loop polling its stop flag
            if should_stop():
                events.append((job.job_id, "stopped"))
                return "stopped"
            time.sleep(0.01)
        events.append((job.job_id, "done"))
        return "done"

    runner = JobRunner(run, scheduler, max_jobs=2, deadline_s=600)
    assert runner.submit(Job(1, "S1"), received_at=time.time())
    assert started[1].wait(5)
    assert not runner.submit(Job(1, "S1"))  # the same job again is not run twice
    assert runner.submit(Job(2, "S1"))  # newer sky map, same superevent
    assert runner.submit(Job(3, "S2"))  # another superevent is independent
    wait(lambda: not runner.busy())
    assert (1, "stopped") in events and (2, "done") in events and (3, "done") in events
    assert events.index((1, "stopped")) < events.index((2, "done"))
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
    result = {}

    def run(job, should_stop):
        end = time.monotonic() + 30
        while not should_stop() and time.monotonic() < end:
            time.sleep(0.01)
        result["stopped"] = should_stop()

    runner = JobRunner(run, scheduler, deadline_s=0.5)
    runner.submit(Job(1, "S1"))
    wait(lambda: "stopped" in result)
    assert result["stopped"] is True


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


def test_outbox_retrier_backs_off_until_the_publish_works(scheduler) -> None:
    calls: list[float] = []

    def flush():
        calls.append(time.monotonic())
        if len(calls) < 3:
            raise ConnectionError("broker down")
        return 0

    r = OutboxRetrier(flush, scheduler, initial_s=0.2, max_s=1.0)
    assert r.drain() is False
    wait(lambda: len(calls) >= 3)
    gaps = [b - a for a, b in zip(calls, calls[1:])]
    assert gaps[1] > gaps[0] * 1.5  # exponential back-off
    time.sleep(0.5)
    assert len(calls) == 3  # no retry once the outbox is empty


def test_cancel_stops_the_running_job_of_a_superevent(scheduler) -> None:
    result = {}
    started = threading.Event()

    def run(job, should_stop):
        started.set()
        end = time.monotonic() + 30
        while not should_stop() and time.monotonic() < end:
            time.sleep(0.01)
        result["stopped"] = should_stop()

    runner = JobRunner(run, scheduler)
    runner.submit(Job(1, "S1"))
    assert started.wait(5)
    assert runner.cancel("S1", "withdraw")
    wait(lambda: "stopped" in result)
    assert result["stopped"] is True
    assert not runner.cancel("S1", "withdraw")  # nothing left to cancel
