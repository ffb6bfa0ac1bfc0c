"""Planning jobs: one per superevent, superseded by a newer sky map.

Each job runs :meth:`NoticePipeline.run_job` in a worker thread with a
``should_stop`` callable that the scheduler polls.  A newer job for the same
superevent sets the old job's stop flag and starts at once; the old job's
scheduler returns at its next poll and the pipeline records it as
superseded.  APScheduler runs the timed work: each job's solver deadline,
the outbox retries with exponential back-off, and the heartbeat.

Why threads and not a child process per job: the scheduler contract
(``make_plan(..., should_stop=...)``) is cooperative and polled inside the
solver loops (HiGHS callbacks, greedy steps), so a stop is honoured within
a fraction of a second; a thread starts in microseconds (a spawned process
would re-import astropy and ligo.skymap, seconds) and shares the store and
the sink, so a cancelled job ends through the pipeline's own bookkeeping
instead of being killed half way through a store write.  A job that
ignores its stop flag is reported at its deadline.
"""

from __future__ import annotations

import logging
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from typing import Any, Callable, Iterable

from apscheduler.schedulers.background import BackgroundScheduler

__all__ = ["JobRunner", "OutboxRetrier", "job_key", "describe_outcome"]

log = logging.getLogger(__name__)

RunJob = Callable[[Any, Callable[[], bool]], Any]


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
    stop: threading.Event = field(default_factory=threading.Event)
    reason: str = ""
    started_at: float | None = None
    future: Future | None = None


class JobRunner:
    """Run planning jobs, one per superevent, newest sky map wins.

    Parameters
    ----------
    run_job : callable
        ``run_job(job, should_stop) -> Outcome`` (the pipeline's).
    scheduler : BackgroundScheduler
        Started APScheduler instance for the deadlines.
    max_jobs : int
        Worker threads (superevents planned at the same time).
    deadline_s : float
        Stop request this long (s) after a job starts.
    on_done : callable, optional
        Called with ``(job, outcome_or_None, info)`` after each job, in the
        worker thread (used to flush the outbox at once).
    """

    def __init__(
        self,
        run_job: RunJob,
        scheduler: BackgroundScheduler,
        max_jobs: int = 2,
        deadline_s: float = 300.0,
        on_done: Callable[[Any, Any, dict[str, Any]], None] | None = None,
    ) -> None:
        self._run_job = run_job
        self._scheduler = scheduler
        self._deadline_s = float(deadline_s)
        self._on_done = on_done
        self._pool = ThreadPoolExecutor(max_workers=max_jobs, thread_name_prefix="plan")
        self._lock = threading.Lock()
        self._current: dict[str, _Running] = {}  # superevent -> newest job
        self._known: set[str] = set()  # job keys already submitted by this process
        self._retired: list[_Running] = []  # superseded jobs still winding down

    # -- submission -------------------------------------------------------
    def submit(self, job: Any, received_at: float | None = None) -> bool:
        """Start ``job`` now; stop the superevent's older job if any.

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
            entry = _Running(key=key, superevent_id=sid, job=job, received_at=received_at)
            self._current[sid] = entry
            if old is not None and not (old.future and old.future.done()):
                old.reason = "superseded"
                old.stop.set()
                self._retired.append(old)
                log.info("event=job_superseded superevent_id=%s job=%s by_job=%s", sid, old.key, key)
            entry.future = self._pool.submit(self._execute, entry)
        log.info("event=job_queued superevent_id=%s job=%s", sid, key)
        return True

    def cancel(self, superevent_id: str, reason: str) -> bool:
        """Ask the superevent's running job to stop (e.g. the event was retracted).

        Returns True when a job was running or queued.
        """
        with self._lock:
            entry = self._current.get(superevent_id)
            if entry is None or (entry.future is not None and entry.future.done()):
                return False
            entry.reason = reason
            entry.stop.set()
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

    # -- execution --------------------------------------------------------
    def _execute(self, entry: _Running) -> None:
        if entry.stop.is_set():
            log.info("event=job_skipped superevent_id=%s job=%s reason=%s",
                     entry.superevent_id, entry.key, entry.reason or "stopped")
            return
        entry.started_at = time.time()
        wait_s = entry.started_at - entry.received_at if entry.received_at else None
        log.info("event=job_started superevent_id=%s job=%s wait_s=%s",
                 entry.superevent_id, entry.key, _fmt(wait_s))
        deadline = self._scheduler.add_job(
            self._deadline, "date",
            run_date=datetime.now(timezone.utc) + timedelta(seconds=self._deadline_s),
            args=[entry], id=f"deadline:{entry.key}:{entry.started_at}", misfire_grace_time=None,
        )
        outcome = None
        info: dict[str, Any] = {}
        try:
            outcome = self._run_job(entry.job, entry.stop.is_set)
            info = describe_outcome(outcome)
        except Exception as exc:  # a failed job must never take the service down
            info = {"error": f"{type(exc).__name__}: {exc}"}
            log.exception("event=job_failed superevent_id=%s job=%s error=%r",
                          entry.superevent_id, entry.key, info["error"])
        finally:
            try:
                deadline.remove()
            except Exception:  # already fired
                pass
        end = time.time()
        info["latency_s"] = round(end - entry.received_at, 3) if entry.received_at else None
        info["run_s"] = round(end - entry.started_at, 3)
        if entry.stop.is_set():
            info.setdefault("stopped", entry.reason or "stop")
        log.info("event=job_done superevent_id=%s job=%s %s", entry.superevent_id, entry.key,
                 " ".join(f"{k}={_fmt(v)}" for k, v in info.items()))
        with self._lock:
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
        if entry.future is not None and entry.future.done():
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

    def busy(self) -> bool:
        """True while any job (current or superseded) has not finished."""
        with self._lock:
            entries = list(self._current.values()) + list(self._retired)
        return any(e.future is not None and not e.future.done() for e in entries)

    def shutdown(self, grace_s: float, cancel: bool = False) -> bool:
        """Stop taking jobs and wait up to ``grace_s`` (s) for running ones.

        With ``cancel`` the running jobs are asked to stop first.  A job
        still running at the end stays pending in the store and is resumed
        at the next start.  Returns True when every job finished.
        """
        with self._lock:
            entries = list(self._current.values()) + list(self._retired)
        if cancel:
            for e in entries:
                e.reason = e.reason or "shutdown"
                e.stop.set()
        for e in entries:  # queued jobs that never started are left pending
            if e.future is not None and e.future.cancel():
                log.info("event=job_left_pending superevent_id=%s job=%s", e.superevent_id, e.key)
        end = time.monotonic() + grace_s
        while self.busy() and time.monotonic() < end:
            time.sleep(0.1)
        finished = not self.busy()
        self._pool.shutdown(wait=False, cancel_futures=True)
        return finished


class OutboxRetrier:
    """Drain the outbox now, and again with exponential back-off on failure.

    Parameters
    ----------
    flush : callable
        ``flush()`` publishes pending outbox rows; it raises, or returns a
        count of rows still pending, when some could not be published.
    scheduler : BackgroundScheduler
        Started APScheduler instance.
    initial_s, max_s : float
        First and largest back-off delay (s).
    """

    JOB_ID = "outbox-retry"

    def __init__(self, flush: Callable[[], Any], scheduler: BackgroundScheduler,
                 initial_s: float = 2.0, max_s: float = 300.0) -> None:
        self._flush = flush
        self._scheduler = scheduler
        self._initial_s = float(initial_s)
        self._max_s = float(max_s)
        self._delay_s = self._initial_s
        self._lock = threading.Lock()

    def drain(self) -> bool:
        """Try once now; on failure schedule the next attempt.  True if empty."""
        with self._lock:
            try:
                left = self._flush()
                ok = not (isinstance(left, int) and not isinstance(left, bool) and left > 0)
                error = None if ok else f"{left} message(s) still pending"
            except Exception as exc:
                ok, error = False, f"{type(exc).__name__}: {exc}"
            if ok:
                self._delay_s = self._initial_s
                return True
            delay = self._delay_s
            self._delay_s = min(self._delay_s * 2.0, self._max_s)
            log.warning("event=publish_failed error=%r retry_in_s=%.1f", error, delay)
            self._scheduler.add_job(
                self.drain, "date", run_date=datetime.now(timezone.utc) + timedelta(seconds=delay),
                id=self.JOB_ID, replace_existing=True, misfire_grace_time=None,
            )
            return False


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3f}"
    text = str(value)
    return repr(text) if (" " in text or not text) else text
