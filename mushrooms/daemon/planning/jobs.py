"""Planning jobs: one per superevent, urgent work first, newest sky map wins.

Each job runs :meth:`NoticePipeline.run_job` in a worker thread with a
``should_stop`` callable that the scheduler polls.  A job has two stages:
its *first plan* (sky map, preparation, greedy, checker: about a second)
and, when the pipeline hands back a :class:`Staged`, its *optimisation*
(the configured MILP or hybrid, up to the solver's time limit).  Work waits
in a priority queue, not a FIFO: every first plan goes before any
optimisation, in order of receipt; and with two or more workers at most
``max_jobs - 1`` optimise at once, so one worker is always free for a new
event's first plan.

A newer job for the same superevent sets the old job's stop flag and is
queued at once; the old job returns at its next stage boundary or
scheduler poll (well within a second) and the pipeline records it as
superseded.  APScheduler runs each job's deadline (counted from the start
of its first stage, over both stages; a deadline too far away for a date,
e.g. ``inf``, means none).

Worker threads never die of a job: any exception raised while a job runs
(inside the planner or in the runner's own bookkeeping around it) is that
job's failure, logged and handed to ``on_failure`` (the daemon records it in
the store); and a worker thread that ended anyway is replaced at the next
submission.  Publishing is not done here: the
outbox has a drain of its own (:class:`~mushrooms.daemon.drain.OutboxDrain`), so a slow or dead
broker never holds a planning worker.

Why threads and not a child process per job: the scheduler contract
(``should_stop``) is cooperative and polled inside the solver loops (HiGHS
callbacks, greedy steps), so a stop is honoured within a fraction of a
second; a thread starts in microseconds (a spawned process would re-import
astropy and ligo.skymap, seconds) and shares the warm caches, the store and
the sink, so a cancelled job ends through the pipeline's own bookkeeping
instead of being killed half way through a store write.
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from typing import Any, Callable, Iterable

from apscheduler.schedulers.background import BackgroundScheduler

__all__ = ["JobRunner", "Staged", "job_key", "describe_outcome", "FIRST", "OPTIMISE"]

log = logging.getLogger("mushrooms.daemon.jobs")

RunJob = Callable[[Any, Callable[[], bool]], Any]

#: Queue priorities: a first plan goes before any optimisation.
FIRST, OPTIMISE = 0, 1


@dataclass(frozen=True)
class Staged:
    """A job's first stage is done; ``run(should_stop)`` is its optimisation, queued behind first plans.

    Attributes
    ----------
    outcome : Any
        The outcome of the first stage (revision 1 published).
    run : callable
        ``run(should_stop) -> outcome`` of the optimisation.
    """

    outcome: Any
    run: Callable[[Callable[[], bool]], Any]


def job_key(job: Any) -> str:
    """Stable identity of a stored job (its id, else its superevent and map)."""
    for name in ("job_id", "id"):
        value = getattr(job, name, None)
        if value is not None:
            return str(value)
    if isinstance(job, dict):
        for name in ("job_id", "id"):
            if job.get(name) is not None:
                return str(job[name])
    return f"{_superevent(job)}:{getattr(job, 'skymap_sha256', '')}"


def _superevent(job: Any) -> str:
    value = getattr(job, "superevent_id", None)
    if value is None and isinstance(job, dict):
        value = job.get("superevent_id")
    return str(value) if value else "-"


def describe_outcome(outcome: Any) -> dict[str, Any]:
    """The loggable fields of a pipeline ``Outcome`` (whatever its shape)."""
    out: dict[str, Any] = {}
    for name in ("kind", "action", "status", "decision", "plan_id", "reason", "supersedes"):
        value = getattr(outcome, name, None)
        if value is None and isinstance(outcome, dict):
            value = outcome.get(name)
        if value is not None:
            out[name] = getattr(value, "value", value)
    plan = getattr(outcome, "plan", None)
    if plan is not None and "plan_id" not in out:
        out["plan_id"] = getattr(plan, "plan_id", None)
    return out


@dataclass
class _Running:
    key: str
    superevent_id: str
    job: Any
    received_at: float | None
    seq: int = 0
    stop: threading.Event = field(default_factory=threading.Event)
    reason: str = ""
    started_at: float | None = None
    stage: int = FIRST
    work: Callable[[Callable[[], bool]], Any] | None = None  # the queued stage
    running: bool = False
    finished: bool = False
    deadline: Any = None


class JobRunner:
    """Run planning jobs from a priority queue, one per superevent, newest sky map wins.

    Parameters
    ----------
    run_job : callable
        ``run_job(job, should_stop) -> Outcome | Staged`` (the pipeline's,
        with ``staged=True``).
    scheduler : BackgroundScheduler
        Started APScheduler instance for the deadlines.
    max_jobs : int
        Worker threads (superevents planned at the same time).  With two or
        more, at most ``max_jobs - 1`` of them optimise at once.
    deadline_s : float
        Stop request this long (s) after a job's first stage starts.
    on_done : callable, optional
        Called with ``(job, outcome_or_None, info)`` after each job's last
        stage, in the worker thread (keep it short).
    on_failure : callable, optional
        Called with ``(job, error_text)`` when a job raised (the daemon
        records the failure in the store), in the worker thread.
    """

    def __init__(
        self,
        run_job: RunJob,
        scheduler: BackgroundScheduler,
        max_jobs: int = 2,
        deadline_s: float = 300.0,
        on_done: Callable[[Any, Any, dict[str, Any]], None] | None = None,
        on_failure: Callable[[Any, str], None] | None = None,
    ) -> None:
        self._run_job = run_job
        self._on_failure = on_failure
        self._scheduler = scheduler
        self._deadline_s = float(deadline_s)
        self._on_done = on_done
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._queue: list[_Running] = []
        self._optimising = 0
        self._max_optimising = max(1, int(max_jobs) - 1)
        self._closed = False
        self._seq = itertools.count()
        self._current: dict[str, _Running] = {}  # superevent -> newest job
        self._known: set[str] = set()  # job keys already submitted by this process
        self._retired: list[_Running] = []  # superseded jobs still winding down
        self._workers = [self._new_worker(i) for i in range(int(max_jobs))]
        self.replaced_workers = 0  # worker threads found dead and replaced (for operators and tests)

    def _new_worker(self, i: int) -> threading.Thread:
        w = threading.Thread(target=self._work, name=f"plan-{i}", daemon=True)
        w.start()
        return w

    def check_workers(self) -> int:
        """Replace worker threads that ended (the daemon calls it with its heartbeat); returns how many."""
        with self._lock:
            before = self.replaced_workers
            self._ensure_workers()
            if self.replaced_workers != before:
                self._wake.notify_all()
            return self.replaced_workers - before

    def _ensure_workers(self) -> None:
        """Replace worker threads that ended (lock held)."""
        for i, w in enumerate(self._workers):
            if not w.is_alive() and not self._closed:
                log.error("event=worker_replaced thread=%s reason='the worker thread had ended'", w.name)
                self._workers[i] = self._new_worker(i)
                self.replaced_workers += 1

    # -- submission -------------------------------------------------------
    def submit(self, job: Any, received_at: float | None = None) -> bool:
        """Queue ``job``'s first plan; stop the superevent's older job if any.

        Returns False when this job was already submitted.
        """
        key = job_key(job)
        sid = _superevent(job)
        with self._lock:
            if key in self._known:
                return False
            self._known.add(key)
            old = self._current.get(sid)
            if received_at is None:  # a resumed job: latency counts from its notice's receipt
                received_at = getattr(job, "received_wall", None)
            entry = _Running(key=key, superevent_id=sid, job=job, received_at=received_at, seq=next(self._seq))
            entry.work = lambda stop, e=entry: self._run_job(e.job, stop)
            self._current[sid] = entry
            if old is not None and not old.finished:
                old.reason = "superseded"
                old.stop.set()
                self._retired.append(old)
                log.info("event=job_superseded superevent_id=%s job=%s by_job=%s", sid, old.key, key)
            self._queue.append(entry)
            self._ensure_workers()
            self._wake.notify()
        log.info("event=job_queued superevent_id=%s job=%s", sid, key)
        return True

    def cancel(self, superevent_id: str, reason: str) -> bool:
        """Ask the superevent's running job to stop (e.g. the event was retracted).

        Returns True when a job was running or queued.
        """
        with self._lock:
            entry = self._current.get(superevent_id)
            if entry is None or entry.finished:
                return False
            entry.reason = reason
            entry.stop.set()
            self._wake.notify_all()
        log.info("event=job_cancelled superevent_id=%s job=%s reason=%s", superevent_id, entry.key, reason)
        return True

    def sync(self, jobs: Iterable[Any], received_at: float | None = None) -> int:
        """Submit the newest stored job of each superevent not yet running.

        ``jobs`` is the store's list of pending jobs (oldest first).  Returns
        the number of jobs started.
        """
        newest: dict[str, Any] = {}
        for job in jobs:
            newest[_superevent(job)] = job
        started = 0
        for job in newest.values():
            started += self.submit(job, received_at=received_at)
        return started

    # -- the queue ----------------------------------------------------------
    def _next(self) -> _Running | None:
        """Highest-priority runnable entry (lock held): stopped ones first (they end at once),
        then first plans, then optimisations while a worker stays free for first plans."""
        best = None
        for e in self._queue:
            if e.stop.is_set():
                rank = (-1, e.seq)
            elif e.stage == OPTIMISE and self._optimising >= self._max_optimising:
                continue
            else:
                rank = (e.stage, e.seq)
            if best is None or rank < best[0]:
                best = (rank, e)
        if best is None:
            return None
        self._queue.remove(best[1])
        return best[1]

    def _work(self) -> None:
        while True:
            with self._lock:
                while True:
                    if self._closed:
                        return
                    entry = self._next()
                    if entry is not None:
                        break
                    self._wake.wait()
                entry.running = True
                optimising = entry.stage == OPTIMISE
                self._optimising += optimising
            requeue = False
            try:
                requeue = self._execute(entry)
            except Exception as exc:  # the runner's own bookkeeping failed: still only this job's failure
                self._failed(entry, "runner", exc)
            except BaseException as exc:  # SystemExit and the like end this thread: the job still ends failed
                self._failed(entry, "runner", exc)
                raise
            finally:
                with self._lock:
                    entry.running = False
                    self._optimising -= optimising
                    if requeue:
                        self._queue.append(entry)
                    self._wake.notify_all()

    # -- execution --------------------------------------------------------
    def _execute(self, entry: _Running) -> bool:
        """Run the entry's queued stage; True when its optimisation must be queued next."""
        stage = "first" if entry.stage == FIRST else "optimise"
        if entry.stop.is_set() and entry.stage == FIRST:
            log.info("event=job_skipped superevent_id=%s job=%s reason=%s",
                     entry.superevent_id, entry.key, entry.reason or "stopped")
            self._finish(entry, None, {"stopped": entry.reason or "stop"})
            return False
        now = time.time()
        if entry.stage == FIRST:
            entry.started_at = now
            wait_s = now - entry.received_at if entry.received_at else None
            log.info("event=job_started superevent_id=%s job=%s wait_s=%s",
                     entry.superevent_id, entry.key, _fmt(wait_s))
            when = self._deadline_date()
            if when is not None:
                entry.deadline = self._scheduler.add_job(
                    self._deadline, "date", run_date=when,
                    args=[entry], id=f"deadline:{entry.key}:{entry.started_at}", misfire_grace_time=None,
                )
        else:
            log.info("event=job_optimising superevent_id=%s job=%s wait_s=%.3f",
                     entry.superevent_id, entry.key, now - (entry.received_at or now))
        outcome = None
        info: dict[str, Any] = {}
        work, entry.work = entry.work, None
        try:
            assert work is not None
            outcome = work(entry.stop.is_set)
            if isinstance(outcome, Staged):
                info = describe_outcome(outcome.outcome)
                info["stage_s"] = round(time.time() - now, 3)
                info["latency_s"] = round(time.time() - entry.received_at, 3) if entry.received_at else None
                log.info("event=job_first_plan superevent_id=%s job=%s %s", entry.superevent_id, entry.key,
                         " ".join(f"{k}={_fmt(v)}" for k, v in info.items()))
                with self._lock:
                    if not self._closed:
                        entry.stage, entry.work = OPTIMISE, outcome.run
                        return True
                log.info("event=job_left_pending superevent_id=%s job=%s reason='stopping before the optimisation'",
                         entry.superevent_id, entry.key)
                self._finish(entry, outcome.outcome, info)
                return False
            info = describe_outcome(outcome)
        except Exception as exc:  # a failed job must never take the service down
            self._failed(entry, stage, exc)
            return False
        self._finish(entry, outcome, info)
        return False

    def _deadline_date(self) -> datetime | None:
        """When the job's deadline fires; None when there is none (not finite, beyond a date)."""
        try:
            if not math.isfinite(self._deadline_s):
                raise OverflowError("not finite")
            return datetime.now(timezone.utc) + timedelta(seconds=self._deadline_s)
        except (OverflowError, ValueError) as exc:
            log.warning("event=job_deadline_unset deadline_s=%r reason=%r: the job runs without a deadline",
                        self._deadline_s, str(exc))
            return None

    def _failed(self, entry: _Running, stage: str, exc: BaseException) -> None:
        """A job raised: log it, have it recorded (``on_failure``) and finish it."""
        error = f"{type(exc).__name__}: {exc}"
        log.error("event=job_failed superevent_id=%s job=%s stage=%s error=%r", entry.superevent_id, entry.key,
                  stage, error, exc_info=exc)
        if self._on_failure is not None:
            try:
                self._on_failure(entry.job, error)
            except Exception:
                log.exception("event=job_failure_not_recorded job=%s", entry.key)
        try:
            self._finish(entry, None, {"error": error})
        except Exception:
            log.exception("event=job_finish_failed job=%s", entry.key)
            with self._lock:
                entry.finished = True
                if self._current.get(entry.superevent_id) is entry:
                    del self._current[entry.superevent_id]

    def _finish(self, entry: _Running, outcome: Any, info: dict[str, Any]) -> None:
        if entry.deadline is not None:
            try:
                entry.deadline.remove()
            except Exception:  # already fired
                pass
        end = time.time()
        info["latency_s"] = round(end - entry.received_at, 3) if entry.received_at else None
        info["run_s"] = round(end - entry.started_at, 3) if entry.started_at else 0.0
        if entry.stop.is_set():
            info.setdefault("stopped", entry.reason or "stop")
        log.info("event=job_done superevent_id=%s job=%s %s", entry.superevent_id, entry.key,
                 " ".join(f"{k}={_fmt(v)}" for k, v in info.items()))
        with self._lock:
            entry.finished = True
            if entry in self._retired:
                self._retired.remove(entry)
            if self._current.get(entry.superevent_id) is entry:
                del self._current[entry.superevent_id]
        if self._on_done is not None:
            try:
                self._on_done(entry.job, outcome, info)
            except Exception:
                log.exception("event=job_callback_failed job=%s", entry.key)

    def _deadline(self, entry: _Running) -> None:
        if entry.finished:
            return
        entry.reason = entry.reason or "deadline"
        entry.stop.set()
        log.warning("event=job_deadline superevent_id=%s job=%s deadline_s=%.0f",
                    entry.superevent_id, entry.key, self._deadline_s)

    # -- state ------------------------------------------------------------
    def active(self) -> list[str]:
        """Superevents with a job queued or running."""
        with self._lock:
            return sorted(self._current)

    def queued(self) -> list[tuple[str, str]]:
        """(job key, ``first``/``optimise``) of the waiting work, in the order it would run."""
        with self._lock:
            order = sorted(self._queue, key=lambda e: (-1 if e.stop.is_set() else e.stage, e.seq))
            return [(e.key, "first" if e.stage == FIRST else "optimise") for e in order]

    def counts(self) -> dict[str, int]:
        """Work waiting for a worker (``queued``) and stages being run (``running``), for the metrics."""
        with self._lock:
            running = sum(e.running for e in list(self._current.values()) + self._retired)
            return {"queued": len(self._queue), "running": running}

    def busy(self) -> bool:
        """True while any job (current or superseded) has not finished."""
        with self._lock:
            entries = list(self._current.values()) + list(self._retired)
        return any(not e.finished for e in entries)

    def shutdown(self, grace_s: float, cancel: bool = False) -> bool:
        """Stop taking jobs and wait up to ``grace_s`` (s) for running ones.

        With ``cancel`` the running jobs are asked to stop first.  Queued
        work that never started, and a job still running at the end, stay
        pending in the store and are resumed at the next start.  Returns
        True when every running job finished.
        """
        with self._lock:
            entries = list(self._current.values()) + list(self._retired)
            if cancel:
                for e in entries:
                    e.reason = e.reason or "shutdown"
                    e.stop.set()
            for e in self._queue:  # queued work that never started is left pending
                log.info("event=job_left_pending superevent_id=%s job=%s", e.superevent_id, e.key)
                e.finished = True
            self._queue.clear()
            self._closed = True
            self._wake.notify_all()
        end = time.monotonic() + grace_s
        while self._running() and time.monotonic() < end:
            time.sleep(0.05)
        return not self._running()

    def _running(self) -> bool:
        with self._lock:
            entries = list(self._current.values()) + list(self._retired)
        return any(e.running for e in entries)


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3f}"
    text = str(value)
    return repr(text) if (" " in text or not text) else text
