"""Worker threads never die of a job: real threads, real APScheduler."""

from __future__ import annotations

import math

import pytest

from mushrooms.daemon.planning.jobs import JobRunner

from test_jobs import Job, scheduler, wait  # noqa: F401  (the fixture)


@pytest.mark.parametrize("deadline_s", [1e12, math.inf, math.nan])
def test_a_deadline_beyond_any_date_does_not_kill_the_worker(scheduler, deadline_s) -> None:  # noqa: F811
    """``job_deadline_s = 1e12 / inf / nan`` raised OverflowError outside the job's try: every job stayed pending."""
    done = []
    runner = JobRunner(lambda job, stop: "ok", scheduler, max_jobs=1, deadline_s=deadline_s,
                       on_done=lambda job, outcome, info: done.append((job.job_id, outcome)))
    for i in range(3):
        runner.submit(Job(i, f"S{i}"))
    wait(lambda: len(done) == 3)
    assert [o for _, o in done] == ["ok"] * 3
    assert all(w.is_alive() for w in runner._workers)


def test_an_error_in_the_runner_around_the_job_is_that_jobs_failure(scheduler) -> None:  # noqa: F811
    failures, done = [], []
    runner = JobRunner(lambda job, stop: "ok", scheduler, max_jobs=1,
                       on_done=lambda job, outcome, info: done.append(job.job_id),
                       on_failure=lambda job, error: failures.append((job.job_id, error)))
    real = runner._scheduler.add_job
    calls = {"n": 0}

    def flaky(*a, **k):  # the runner's own bookkeeping (not the job) raises once
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("scheduler refused the deadline")
        return real(*a, **k)

    runner._scheduler.add_job = flaky
    try:
        runner.submit(Job(1, "S1"))
        runner.submit(Job(2, "S2"))
        wait(lambda: len(done) == 2)
    finally:
        runner._scheduler.add_job = real
    assert failures == [(1, "RuntimeError: scheduler refused the deadline")]
    assert runner.active() == [] and not runner.busy()


def test_a_job_failure_is_handed_to_on_failure(scheduler) -> None:  # noqa: F811
    failures = []

    def run(job, stop):
        raise ValueError("bad plan")

    runner = JobRunner(run, scheduler, max_jobs=1, on_failure=lambda job, error: failures.append((job.job_id, error)))
    runner.submit(Job(7, "S7"))
    wait(lambda: failures)
    assert failures == [(7, "ValueError: bad plan")]


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_dead_worker_thread_is_replaced(scheduler) -> None:  # noqa: F811
    done = []

    def run(job, stop):
        if job.job_id == 1:
            raise SystemExit("a thread-ending exception")  # not an Exception: it ends the thread
        return "ok"

    runner = JobRunner(run, scheduler, max_jobs=1, on_done=lambda job, outcome, info: done.append(job.job_id))
    runner.submit(Job(1, "S1"))
    wait(lambda: not runner._workers[0].is_alive())
    assert not runner.busy()  # the job that ended its thread is finished (failed), not left running
    runner.submit(Job(2, "S2"))
    wait(lambda: 2 in done)
    assert runner.replaced_workers == 1
