"""``mushrooms run``: the long-running service.

Main thread: consume one notice, store the decision (durable), start or
supersede the superevent's planning job, then commit the offset; handle
signals and triggers between polls.  Worker threads plan and publish
(:mod:`~mushrooms.daemon.planning.jobs`).  APScheduler runs deadlines, outbox retries, the heartbeat
and the systemd watchdog ping.

Signals: SIGTERM/SIGINT stop cleanly (the notice in hand is finished and
committed, or left uncommitted; running jobs get a grace period and are
otherwise resumed at the next start); SIGHUP reloads the configuration;
SIGUSR1 picks up ``mushrooms trigger`` files.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import signal
import sys
import threading
import time
from datetime import datetime, timezone
from typing import Any, Callable

from apscheduler.schedulers.background import BackgroundScheduler

from .planning.jobs import JobRunner, OutboxDrain
from .ops.systemd import Notifier, watchdog_interval_s
from .sections import ServiceConfig
from .settings import RuntimePaths, resolve_paths
from .intake.trigger import (
    DaemonRunning, PidLock, dispatch, outcome_result, pending_triggers, read_trigger, write_result,
)
from .ops.announce import job_failed, submission_trouble
from .wiring import make_sink, open_pipeline, private_dir

__all__ = ["main", "Service", "setup_logging", "EXIT_STATE"]

log = logging.getLogger("mushrooms.daemon")

READY_WAIT_S = 60.0  # READY=1 waits this long (s) at most for the consumer group's partitions
TRIGGER_SCAN_S = 5.0  # triggers are also picked up without SIGUSR1, at this period (s)
WARM_INTERVAL_S = 1800.0  # the coming night's visibility is computed ahead at this period (s)
PRUNE_EVERY_S = 3600.0  # how often raw bytes no longer needed are pruned (s; also at start)

#: Exit status when the state file is unusable (empty, damaged, newer schema):
#: sysexits' EX_DATAERR; the unit's RestartPreventExitStatus= lists it, since a
#: restart cannot repair the file and would only loop.
EXIT_STATE = 65


# ---------------------------------------------------------------- logging
class _JournalFormatter(logging.Formatter):
    """One line per record; ``<N>`` syslog priority prefix under journald."""

    PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}

    def __init__(self, journald: bool) -> None:
        fmt = "%(levelname)s %(name)s: %(message)s" if journald else \
            "%(asctime)s %(levelname)s %(name)s: %(message)s"
        super().__init__(fmt)
        self.journald = journald

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record).replace("\n", " | ")
        if self.journald:
            return f"<{self.PRIORITY.get(record.levelno, 6)}>{text}"
        return text


def setup_logging(level: int | None = None) -> None:
    """Structured one-line logs on stdout (journald adds time and unit)."""
    root = logging.getLogger()
    if level is not None:
        root.setLevel(level)
    for h in list(root.handlers):
        root.removeHandler(h)
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(_JournalFormatter(journald=bool(os.environ.get("JOURNAL_STREAM"))))
    root.addHandler(handler)
    for noisy in ("apscheduler", "astropy"):
        logging.getLogger(noisy).setLevel(logging.WARNING)


# ---------------------------------------------------------------- the service
class Service:
    """The daemon: one instance per process.

    Built from plain objects by the tool layer (``mushrooms.tool.run``):

    Parameters
    ----------
    config : ServiceConfig
        The assembled configuration, command-line overrides included
        (its sections: ``scheduler``, ``policy``, ``daemon``, ``kafka``,
        ``outbound``, ``export``, ``submit``, and ``source``).
    paths : RuntimePaths
        The resolved runtime paths (:func:`~.settings.resolve_paths` of
        ``config.daemon``); fixed until a restart.
    reload : callable, optional
        Returns the configuration again (the file re-read, the same
        overrides) at SIGHUP; without it a SIGHUP keeps the running one.
    """

    def __init__(self, config: ServiceConfig, paths: RuntimePaths,
                 reload: Callable[[], ServiceConfig] | None = None) -> None:
        self.config = config
        self.paths = paths
        self._load = reload
        self.notifier = Notifier()
        self._stop = threading.Event()
        self._reload = threading.Event()
        self._triggers = threading.Event()
        self._last_loop = time.monotonic()
        self._started = time.monotonic()
        self._counts = {"notices": 0, "triggers": 0, "jobs": 0, "quarantined": 0}
        self.pipeline: Any = None
        self.consumer: Any = None
        self._closing = threading.Event()  # set once the store is being closed: no more retries touch it
        self._last_prune = 0.0
        self.submitter: Any = None
        self.submit_drain: Any = None  # [submit]: the submitter's thread (None when off)
        #: starting -> warming -> running -> stopping (``/healthz``, ``/readyz``)
        self.phase = "starting"
        from .. import __version__
        from .ops.metrics import ServiceMetrics

        #: the Prometheus registry and the hooks (docs/operations.md); served when metrics_address is set
        self.metrics = ServiceMetrics(__version__, self.paths.state)
        self.listener: Any = None
        self._ready_sent = False
        self._ready_wait_from = 0.0
        self._consuming = False
        self._trigger_answers: dict[int, Any] = {}  # job id -> trigger file whose answer waits for the job

    # signals only set flags; the main loop acts between polls
    def _on_signal(self, signum: int, frame: Any) -> None:
        if signum in (signal.SIGTERM, signal.SIGINT):
            if self._stop.is_set() and signum == signal.SIGINT:
                raise KeyboardInterrupt
            self._stop.set()
        elif signum == signal.SIGHUP:
            self._reload.set()
        elif signum == signal.SIGUSR1:
            self._triggers.set()

    def run(self) -> int:
        """Run until SIGTERM/SIGINT; returns the exit status."""
        submit_token, executed_token = self._tokens()  # fail fast, with one line, before touching any state
        lock = PidLock(self.paths.pid_file)
        try:
            lock.acquire()
        except DaemonRunning as exc:
            log.error("event=start_refused reason=%r", str(exc))
            return 1
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGUSR1):
            signal.signal(sig, self._on_signal)
        private_dir(self.paths.trigger_dir, self.config.daemon.group_readable)
        scheduler = self.scheduler = BackgroundScheduler(timezone="UTC")
        scheduler.start()
        opened = _Opened()
        try:
            refused = self._open_state(opened)
            if refused is not None:
                return refused
            self._start_parts(submit_token)
            self._start_timers(scheduler, executed_token)
            self._loop()
            return 0
        finally:
            self._stop_all(scheduler, lock, opened)

    def _tokens(self) -> tuple[str | None, str | None]:
        """Read the credentials the configuration needs (Kafka, submission, executed source); values never logged."""
        if not self.config.kafka.bootstrap:
            from .credentials import load_credentials

            load_credentials()
        submit_token = None
        if self.config.submit.enabled and not self.config.submit.dry_run:
            from .credentials import load_submit_token

            submit_token, source = load_submit_token()
            log.info("event=submit_token source=%s", source)
        return submit_token, self._executed_token()

    def _open_state(self, opened: "_Opened") -> int | None:
        """Open the pipeline on the state file and lock it; the exit status of a refused start, else None."""
        from .state.store import StateInUse, StoreError, lock_state
        from .planning.warm import SkyCache

        self.sky_cache = SkyCache()
        self.outbox = OutboxDrain(self._flush_outbox, self.config.outbound.retry_initial_s,
                                  self.config.outbound.retry_max_s)
        try:
            self.pipeline, opened.close = open_pipeline(self.config, self.paths, sky_cache=self.sky_cache,
                                                        on_outbox=self._queued)
        except StoreError as exc:  # empty, damaged, newer: one line, and a status Restart= does not loop on
            log.error("event=start_refused reason=%r", str(exc))
            return EXIT_STATE
        try:  # one daemon per state file, whatever its pid file says
            opened.state_lock = lock_state(self.paths.state)
        except StateInUse as exc:
            log.error("event=start_refused reason=%r", str(exc))
            return 1
        return None

    def _start_parts(self, submit_token: str | None) -> None:
        """Metrics, the submitter, the warm-up, the job runner; then what a crash left (outbox, jobs, triggers)."""
        self._observe()
        self._prune_raw()
        from .submission.submitter import open_submitter

        opened = open_submitter(self.config.submit, self.config.export, self.pipeline.store, submit_token,
                                on_outbox=self.outbox.kick, on_result=self._submission_result,
                                closing=self._closing.is_set)
        if opened is not None:
            self.submitter, self.submit_drain = opened
            self.submitter.on_trouble = lambda sub, error: submission_trouble(  # [notify]
                self.pipeline.sink, sub.superevent_id, sub.queue_name, sub.attempts, error)
            self.submit_drain.kick()  # reconcile what a crash left half done
        self.phase = "warming"
        self._warm_up(self.sky_cache)  # only once the state file is ours: a refused start is quick
        self.jobs = JobRunner(self._run_job, self.scheduler, self.config.daemon.max_jobs,
                              self.config.daemon.job_deadline_s, on_done=self._job_done,
                              on_failure=self._job_failed)
        log.info("event=service_starting pid=%d config=%s state=%s sink=%s triggers=%s",
                 os.getpid(), self.config.source, self.paths.state, self._sink_text(),
                 self.paths.trigger_dir)
        self.outbox.kick()  # what a crash left in the outbox goes out first

    def _start_timers(self, scheduler: BackgroundScheduler, executed_token: str | None) -> None:
        """Resume jobs, scan triggers, open the consumer and start the timed jobs; then ready."""
        scheduler.add_job(self._rewarm, "interval", seconds=WARM_INTERVAL_S, id="warm",
                          misfire_grace_time=None, coalesce=True)
        resumed = self.jobs.sync(self.pipeline.store.pending_jobs())
        if resumed:
            log.info("event=jobs_resumed count=%d", resumed)
        self._scan_triggers()
        from .kafka.consumer import NoticeConsumer

        self.consumer = NoticeConsumer(self.config.kafka, on_offset_jump=self._offset_jump,
                                       instance_id=self._instance_id(self.config))
        scheduler.add_job(self._heartbeat, "interval", seconds=self.config.daemon.heartbeat_s,
                          id="heartbeat", misfire_grace_time=None, coalesce=True)
        self._start_loop(executed_token)
        wd = watchdog_interval_s()
        if wd:
            scheduler.add_job(self._watchdog, "interval", seconds=wd, id="watchdog",
                              args=[wd], misfire_grace_time=None, coalesce=True)
        self.phase = "running"
        log.info("event=service_ready topics=%s watchdog_s=%s startup_s=%.2f partitions=%s",
                 ",".join(self.config.kafka.topics), f"{wd:.1f}" if wd else "-", time.monotonic() - self._started,
                 "assigned" if self.consumer.assigned else "waiting")
        self._ready_wait_from = time.monotonic()
        self._track_assignment()

    def _stop_all(self, scheduler: BackgroundScheduler, lock: PidLock, opened: "_Opened") -> None:
        """Stop in order: jobs (with grace), consumer, timers, submitter, outbox, state; leave as a crash if a job hangs."""
        self.phase = "stopping"
        self.notifier.stopping()
        log.info("event=service_stopping active_jobs=%s", ",".join(self._active()) or "-")
        if hasattr(self, "jobs"):
            finished = self.jobs.shutdown(self.config.daemon.stop_grace_s)
            if not finished:
                log.warning("event=jobs_left_pending reason='still running at stop; resumed at next start'")
        if self.consumer is not None:
            self.consumer.close()
        scheduler.shutdown(wait=False)
        if self.submit_drain is not None:
            self._closing_submit()
        if hasattr(self, "outbox"):
            self.outbox.close()
        unfinished = hasattr(self, "jobs") and self.jobs.busy()
        if self.pipeline is not None and opened.state_lock is not None:
            self._give_back_unfinished()
        if not unfinished:
            self._close_store(opened.close)
        if opened.state_lock is not None:
            opened.state_lock.release()
        if self.listener is not None:
            self.listener.close()
        lock.release()
        log.info("event=service_stopped unfinished_jobs=%s", "yes" if unfinished else "no")
        if unfinished:
            # worker threads cannot be interrupted; everything is durable, so
            # leave now as a crash would, and the next start resumes the job
            logging.shutdown()
            os._exit(0)

    def _loop(self) -> None:
        last_scan = time.monotonic()
        while not self._stop.is_set():
            self._last_loop = time.monotonic()
            if self._reload.is_set():
                self._reload.clear()
                self._do_reload()
            if self._triggers.is_set() or time.monotonic() - last_scan > TRIGGER_SCAN_S:
                self._triggers.clear()
                last_scan = time.monotonic()
                self._scan_triggers()
            received = self.consumer.poll()
            if received is not None:
                self._handle(received)
            if self._consuming != bool(self.consumer.assigned) or not self._ready_sent:
                self._track_assignment()

    # ------------------------------------------------------------ notices
    def _handle(self, received: Any) -> None:
        decision = None
        retries = self.config.daemon.accept_retries
        for attempt in range(1, retries + 1):
            try:
                decision = self.pipeline.accept(received.value, received.origin,
                                                received_at=datetime.fromtimestamp(received.received_at, timezone.utc))
                break
            except Exception as exc:
                log.error("event=store_failed origin=%s attempt=%d/%d error=%r", received.origin,
                          attempt, retries, f"{type(exc).__name__}: {exc}")
                if attempt < retries and self._stop.wait(min(2.0 ** attempt, 10.0)):
                    return  # stopping: leave it uncommitted, it is redelivered
        else:
            if not self._quarantine(received):
                self.consumer.rewind(received)  # keep it: retried on the next poll
                self._stop.wait(5.0)
                return
        self._counts["notices"] += 1
        self.metrics.notice(decision)
        started = self._start_jobs(decision, received.received_at)
        try:
            self.consumer.commit(received)
        except Exception as exc:  # e.g. partitions revoked by a rebalance: redelivery is harmless
            log.warning("event=commit_failed origin=%s error=%r (the notice is stored; a redelivery is a duplicate)",
                        received.origin, str(exc))
        self._after_decision(decision)
        log.info("event=notice origin=%s bytes=%d %s jobs_started=%d store_s=%.3f", received.origin,
                 len(received.value), _decision_fields(decision), started, time.time() - received.received_at)

    def _quarantine(self, received: Any) -> bool:
        """Keep the raw bytes of a message that cannot be stored; True if kept."""
        try:
            qdir = private_dir(self.paths.quarantine_dir, self.config.daemon.group_readable)
            name = received.origin.replace(":", "_").replace("/", "_") + ".bin"
            tmp = qdir / f".{name}.tmp"
            mode = 0o640 if self.config.daemon.group_readable else 0o600
            with open(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, mode), "wb") as fh:
                fh.write(received.value)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, qdir / name)
        except OSError as exc:
            log.critical("event=quarantine_failed origin=%s error=%r", received.origin, str(exc))
            return False
        self._counts["quarantined"] += 1
        log.error("event=notice_quarantined origin=%s file=%s", received.origin, qdir / name)
        return True

    # ------------------------------------------------------------ triggers
    def _scan_triggers(self) -> None:
        for path in pending_triggers(self.paths.trigger_dir):
            received_at = time.time()
            try:
                kind, payload = read_trigger(path)
                decision = dispatch(self.pipeline, kind, payload, origin=f"trigger:{path.name}")
            except Exception as exc:
                log.error("event=trigger_rejected file=%s error=%r", path.name, f"{type(exc).__name__}: {exc}")
                write_result(path, {"decision": "rejected", "reason": f"{type(exc).__name__}: {exc}"},
                             self.config.daemon.group_readable)
                bad = path.with_name(f".{path.name}.rejected")
                os.replace(path, bad)
                continue
            self._counts["triggers"] += 1
            self.metrics.notice(decision, source="trigger")
            job = getattr(decision, "job", None)
            if job is not None:  # answered once the job's first plan is out (or it failed)
                self._trigger_answers[job.job_id] = path
            else:
                write_result(path, outcome_result(decision), self.config.daemon.group_readable)
            started = self._start_jobs(decision, received_at)
            path.unlink(missing_ok=True)
            self._after_decision(decision)
            log.info("event=trigger file=%s kind=%s %s jobs_started=%d", path.name, kind,
                     _decision_fields(decision), started)

    # ------------------------------------------------------------ jobs and outbox
    def _start_jobs(self, decision: Any, received_at: float) -> int:
        """Start the decision's planning job (superseding the superevent's
        running one) or stop a job the decision cancelled (retraction)."""
        if decision is None:
            return 0
        job = getattr(decision, "job", None)
        if job is not None:
            return int(self.jobs.submit(job, received_at=received_at))
        sid = getattr(decision, "superevent_id", None)
        if sid and getattr(decision, "cancelled_jobs", ()):
            self.jobs.cancel(sid, reason=str(getattr(decision, "action", "cancelled")))
        return 0

    def _after_decision(self, decision: Any) -> None:
        """A withdrawal waits in the outbox: the drain publishes it, off the consume loop (and the
        submitter deletes the event's queues)."""
        if getattr(decision, "withdrawal_id", None) or getattr(decision, "action", None) == "withdraw":
            self.outbox.kick(now=True)
            if self.submit_drain is not None:
                self.submit_drain.kick(now=True)

    def _queued(self) -> None:
        """A plan (or another message) was stored: publish it, and submit it when [submit] is on."""
        self.outbox.kick()
        if self.submit_drain is not None:
            self.submit_drain.kick()

    def _submission_result(self, state: str, target: str) -> None:
        """Hook for metrics: one call per submission transition (counts by result)."""
        key = f"submissions_{state}"
        self._counts[key] = self._counts.get(key, 0) + 1
        self.metrics.submission(state)

    def _closing_submit(self) -> None:
        """Stop the submitter before the store closes (a request in flight ends within [submit] timeout_s)."""
        self.submit_drain.close(timeout_s=self.config.submit.timeout_s + 1.0)

    def _run_job(self, job: Any, should_stop: Callable[[], bool]) -> Any:
        # a stopping service does not cut plans short: they get a grace period,
        # and a job still running at exit stays pending and resumes at the next start;
        # staged: the optimisation is queued behind newer events' first plans
        outcome = self.pipeline.run_job(job, should_stop, staged=True)
        self._answer_trigger(job, outcome_result(job, outcome))
        if getattr(outcome, "decision", None) == "failed":  # [notify]
            job_failed(self.pipeline.sink, getattr(job, "superevent_id", None), outcome.reason)
        return outcome

    def _answer_trigger(self, job: Any, result: dict[str, Any]) -> None:
        """A job a trigger started: tell ``mushrooms trigger`` how its first plan went."""
        path = self._trigger_answers.pop(getattr(job, "job_id", None), None)
        if path is not None:
            write_result(path, result, self.config.daemon.group_readable)

    def _job_done(self, job: Any, outcome: Any, info: dict[str, Any]) -> None:
        self._counts["jobs"] += 1
        self.metrics.job_finished(outcome, info)

    # ------------------------------------------------------------ the loop ([loop], docs/design/executed.md)
    def _executed_token(self) -> str | None:
        """The token of a URL source of executed observations (None: no loop, or a file/directory source)."""
        loop = getattr(self.config, "loop", None)
        if loop is None or not loop.enabled or not str(loop.source.location).startswith(("http://", "https://")):
            return None
        from .credentials import load_executed_token

        token, source = load_executed_token()  # the value is never logged
        log.info("event=executed_token source=%s", source)
        return token

    def _start_loop(self, token: str | None) -> None:
        """With ``[loop] executed_source`` set: poll it every ``poll_interval_s`` on the timer thread (and now)."""
        loop = getattr(self.config, "loop", None)
        nights = int(getattr(self.pipeline.planning, "nights", 1))
        if (loop is None or not loop.enabled) and nights > 1:
            # (L9) no executed source: the later nights are still re-planned at their twilights (L11)
            every = loop.poll_interval_s if loop is not None else 300.0
            self.scheduler.add_job(self._poll_nights, "interval", seconds=every, id="nights",
                                   next_run_time=datetime.now(timezone.utc), misfire_grace_time=None, coalesce=True,
                                   max_instances=1)
            log.info("event=night_replans nights=%d poll_interval_s=%g source=none", nights, every)
        if loop is None or not loop.enabled:
            return
        from .loop.poll import ExecutedLoop

        self.executed_loop = ExecutedLoop(loop, self.pipeline, token)
        self.scheduler.add_job(self._poll_executed, "interval", seconds=loop.poll_interval_s, id="executed",
                               next_run_time=datetime.now(timezone.utc), misfire_grace_time=None, coalesce=True,
                               max_instances=1)
        log.info("event=executed_loop source=%s poll_interval_s=%g max_slip_s=%g min_processed_fraction=%g",
                 self.executed_loop.reader.describe(), loop.poll_interval_s, loop.max_slip_s,
                 loop.min_processed_fraction)

    def _poll_nights(self) -> None:
        """Without an executed source: re-plan each event's later night once it has begun (never raises)."""
        if self._closing.is_set() or self._stop.is_set():
            return
        from astropy.time import Time

        from .loop.nights import record_night_replans

        try:
            accepted = record_night_replans(self.pipeline, Time.now())
        except Exception:
            log.exception("event=night_replans_failed")
            return
        for a in accepted:
            if a.job is not None:
                self.metrics.notice(a, source="loop")
                self._start_jobs(a, time.time())

    def _poll_executed(self) -> None:
        """One poll: read and store what was executed, start the re-plans it calls for (never raises)."""
        if self._closing.is_set() or self._stop.is_set():
            return
        try:
            self.executed_loop.pipeline = self.pipeline  # a SIGHUP builds a new pipeline on the same store
            poll = self.executed_loop.poll()
        except Exception:
            log.exception("event=executed_poll_failed")
            return
        if poll.error is None and poll.stored is not None:
            self.metrics.observations_read()
        for accepted in poll.jobs:
            self.metrics.notice(accepted, source="loop")
            self._start_jobs(accepted, time.time())

    # ------------------------------------------------------------ observability
    def _observe(self) -> None:
        """Count what the sink publishes, and open the metrics/health listener when configured."""
        from .ops.metrics import ObservedSink

        if not isinstance(self.pipeline.sink, ObservedSink):
            self.pipeline.sink = ObservedSink(self.pipeline.sink, self.metrics, self.pipeline.store.received_wall)
        self.metrics.watch(
            jobs=lambda: self.jobs.counts() if hasattr(self, "jobs") else {},
            brokers=self._broker_states,
            lag=lambda: dict(self.consumer.health.lag) if self.consumer is not None else {},
            loop_age=lambda: time.monotonic() - self._last_loop,
            assigned=lambda: len(self.consumer.assigned) if self.consumer is not None else 0,
        )
        address = self.config.daemon.metrics_address
        if not address or self.listener is not None:
            return
        from .ops.health import LIVENESS_DEFAULT_S, HealthServer, liveness, service_checks
        from .settings import parse_address

        host, port = parse_address(address)
        limit = watchdog_interval_s()
        limit = max(2 * limit, 3 * self.config.kafka.poll_timeout_s) if limit else LIVENESS_DEFAULT_S
        try:
            self.listener = HealthServer(host, port, self.metrics,
                                         liveness(lambda: self.phase, lambda: time.monotonic() - self._last_loop,
                                                  limit), service_checks(self)).start()
        except OSError as exc:  # the plans matter more than the metrics: run on, say so loudly
            log.error("event=metrics_unavailable address=%s error=%r", address, str(exc))
            return
        log.info("event=metrics_listening address=%s:%d paths=/metrics,/healthz,/readyz", *self.listener.address)

    def _broker_states(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.consumer is not None:
            out["consumer"] = self.consumer.health.up
        sink = getattr(self.pipeline, "sink", None)
        if getattr(sink, "health", None) is not None:
            serve = getattr(sink, "serve_callbacks", None)
            if serve is not None:
                serve()
            out["sink"] = sink.health.up
        return out

    def _offset_jump(self, topic: str, partition: int, expected: int, got: int, skipped: int, cause: str) -> None:
        """The consumer found messages gone: count them and keep a record for ``mushrooms status``."""
        self.metrics.offset_jump(topic, skipped)
        try:
            self.pipeline.store.record_incident("offset_jump", {
                "topic": topic, "partition": partition, "expected": expected, "got": got, "skipped": skipped,
                "cause": cause})
        except Exception as exc:
            log.error("event=incident_not_stored kind=offset_jump error=%r", f"{type(exc).__name__}: {exc}")

    def _track_assignment(self) -> None:
        """Tell systemd the truth: READY=1 once partitions are assigned (or after READY_WAIT_S), STATUS on changes."""
        topics = ",".join(self.config.kafka.topics)
        assigned = bool(self.consumer.assigned)
        waited = time.monotonic() - self._started
        if assigned and not self._consuming:
            log.info("event=consuming partitions=%s since_start_s=%.2f", " ".join(
                f"{t}[{p}]" for t, p in sorted(self.consumer.assigned)), waited)
        elif self._consuming and not assigned:
            log.warning("event=not_consuming reason='partitions revoked; waiting for the group to assign them'")
        self._consuming = assigned
        status = (f"consuming {topics}" if assigned else
                  f"NOT consuming yet: waiting for the consumer group to assign partitions of {topics}")
        if not self._ready_sent:
            if assigned or time.monotonic() - self._ready_wait_from > READY_WAIT_S:
                self._ready_sent = True
                self.notifier.ready(status)
        else:
            self.notifier.status(status)

    def _job_failed(self, job: Any, error: str) -> None:
        """A job raised past the pipeline: record it as failed (a failure on our side: the map may be planned again)."""
        self._answer_trigger(job, {"decision": "failed", "reason": f"internal error: {error}",
                                  "superevent_id": getattr(job, "superevent_id", None)})
        job_failed(self.pipeline.sink, getattr(job, "superevent_id", None), f"internal error: {error}")
        try:
            self.pipeline.store.fail_job(job.job_id, f"internal error: {error}", retry_same_map=True)
        except Exception as exc:
            log.error("event=job_failure_not_stored job=%s error=%r", getattr(job, "job_id", "-"), str(exc))

    # ------------------------------------------------------------ warm state
    def _warm_up(self, cache: Any) -> Any:
        """Imports, grid, footprints and tonight's visibility, and one throw-away plan, before consuming."""
        t0 = time.perf_counter()
        cache.warm(self.config.scheduler)
        t_cache = time.perf_counter() - t0
        try:  # the first alert must not pay for first calls (checker, greedy, MILP imports)
            from ..bundled import demo_skymap_path
            from ..scheduler_core import read_skymap
            from ..scheduler_core.anytime import FIRST_SOLVER, checked_plan
            from ..scheduler_core.planner import run_scheduler

            if self.config.scheduler.solver != FIRST_SOLVER:
                from ..scheduler_core.schedulers import block_schedule  # noqa: F401
            from astropy.time import Time

            skymap = read_skymap(demo_skymap_path(), nside=self.config.scheduler.nside)
            problem = cache.prepare(skymap, self.config.scheduler, Time.now())
            checked_plan(problem, run_scheduler(problem, FIRST_SOLVER), skymap, FIRST_SOLVER)
        except Exception as exc:  # warming is an optimisation, never a reason not to start
            log.warning("event=warm_up_plan_failed error=%r", f"{type(exc).__name__}: {exc}")
        log.info("event=warm_up cache_s=%.2f total_s=%.2f", t_cache, time.perf_counter() - t0)
        return cache

    def _rewarm(self) -> None:
        """Compute the coming night's visibility before an alert needs it."""
        try:
            self.sky_cache.warm(self.config.scheduler)
        except Exception:
            log.exception("event=warm_failed")

    def _flush_outbox(self) -> Any:
        if self._closing.is_set():  # a retry that fires during shutdown: the next start publishes it
            return 0
        return self.pipeline.flush_outbox()

    def _close_store(self, close: Callable[[], None]) -> None:
        """Close sink and store once no publish is running; later retries do nothing."""
        self._closing.set()
        store = getattr(self.pipeline, "store", None)
        publishing = getattr(store, "publish_lock", None)
        took = publishing.acquire(timeout=self.config.outbound.delivery_timeout_s + 5.0) if publishing else False
        try:
            close()
        finally:
            if took:
                publishing.release()

    def _give_back_unfinished(self) -> None:
        """A clean stop: jobs still running are not starts that died (they resume, uncounted)."""
        try:
            released = self.pipeline.store.release_unfinished()
        except Exception as exc:
            log.warning("event=release_failed error=%r", f"{type(exc).__name__}: {exc}")
            return
        if released:
            log.info("event=jobs_released jobs=%s reason='clean stop; resumed at the next start'",
                     ",".join(map(str, released)))

    def _prune_raw(self) -> None:
        """Forget raw bytes no longer needed (rejected and planned notices, :meth:`Store.prune_raw`)."""
        self._last_prune = time.monotonic()
        try:
            n = self.pipeline.store.prune_raw(self.config.daemon.rejected_raw_retention_s,
                                              self.config.daemon.planned_raw_retention_s)
        except Exception as exc:
            log.warning("event=prune_failed error=%r", f"{type(exc).__name__}: {exc}")
            return
        if n:
            log.info("event=raw_pruned notices=%d rejected_retention_s=%.0f planned_retention_s=%.0f", n,
                     self.config.daemon.rejected_raw_retention_s, self.config.daemon.planned_raw_retention_s)

    # ------------------------------------------------------------ timed work
    def _heartbeat(self) -> None:
        up = time.monotonic() - self._started
        active = self._active()
        health = getattr(self.consumer, "health", None)
        self._broker_states()  # serves the sink's statistics callbacks between publishes
        consuming = "" if getattr(self.consumer, "assigned", True) else "NOT consuming (no partitions), "
        status = (f"{consuming}{health.status_text() + ', ' if health else ''}up {up / 3600:.1f} h, "
                  f"{self._counts['notices']} notices, {self._counts['jobs']} jobs done, "
                  f"active: {','.join(active) or 'none'}")
        self.notifier.status(status)
        log.info("event=heartbeat uptime_s=%.0f broker=%s notices=%d triggers=%d jobs_done=%d quarantined=%d "
                 "active=%s loop_age_s=%.1f", up, health.describe() if health else "-", self._counts["notices"],
                 self._counts["triggers"], self._counts["jobs"], self._counts["quarantined"],
                 ",".join(active) or "-", time.monotonic() - self._last_loop)
        if time.monotonic() - self._last_prune > PRUNE_EVERY_S:
            self._prune_raw()
        if hasattr(self, "jobs"):
            self.jobs.check_workers()

    def _watchdog(self, interval_s: float) -> None:
        age = time.monotonic() - self._last_loop
        if age < max(2 * interval_s, 3 * self.config.kafka.poll_timeout_s):
            self.notifier.watchdog()
        else:
            log.error("event=watchdog_withheld loop_age_s=%.1f", age)

    def _do_reload(self) -> None:
        self.notifier.reloading()
        try:
            new = self._load() if self._load is not None else self.config
            sink = self.pipeline.sink if new.outbound == self.config.outbound else make_sink(new.outbound)
        except Exception as exc:  # a bad file, bad sink settings, a missing password: keep running as before
            log.error("event=reload_failed error=%r (keeping the running configuration)", str(exc))
            self.notifier.ready("reload failed; old configuration kept")
            return
        if resolve_paths(new.daemon) != self.paths:
            log.warning("event=reload_partial reason='state, trigger and pid paths change only at restart'")
            new = dataclasses.replace(new, daemon=dataclasses.replace(new.daemon, state_path=str(self.paths.state)))
        from .intake.pipeline import NoticePipeline

        self.pipeline = NoticePipeline(new.policy, new.scheduler, self.pipeline.store, sink, daemon=new.daemon,
                                       sky_cache=self.sky_cache, on_outbox=self._queued,
                                       loop=getattr(new, "loop", None))
        if getattr(new, "loop", None) != getattr(self.config, "loop", None):
            log.warning("event=reload_partial reason='[loop] source and poll interval change at the next start'")
        if new.submit != self.config.submit:
            log.warning("event=reload_partial reason='[submit] changes apply at the next start'")
        self._observe()
        if new.kafka != self.config.kafka:
            from .kafka.consumer import NoticeConsumer

            self.consumer.close()
            self.consumer = NoticeConsumer(new.kafka, on_offset_jump=self._offset_jump,
                                           instance_id=self._instance_id(new))
        if new.daemon.heartbeat_s != self.config.daemon.heartbeat_s:
            self.scheduler.reschedule_job("heartbeat", trigger="interval", seconds=new.daemon.heartbeat_s)
        self.config = new
        self.notifier.ready("configuration reloaded")
        log.info("event=config_reloaded source=%s", new.source)

    def _instance_id(self, config: Any) -> str | None:
        """Static group membership: stable per installation (``[kafka] instance_id``, else host + state path)."""
        from .settings import group_instance_id

        return group_instance_id(config.kafka, self.paths.state)

    def _active(self) -> list[str]:
        return self.jobs.active() if hasattr(self, "jobs") else []

    def _sink_text(self) -> str:
        out = self.config.outbound
        return f"kafka:{out.bootstrap}/{out.topic}" if out.sink == "kafka" else f"directory:{out.directory}"


def _decision_fields(decision: Any) -> str:
    if decision is None:
        return "decision=quarantined"
    fields = []
    for name in ("superevent_id", "alert_type", "action", "kind", "reason", "plan_id"):
        value = getattr(decision, name, None)
        if value is None and isinstance(decision, dict):
            value = decision.get(name)
        if value is not None:
            value = getattr(value, "value", value)
            text = str(value)
            fields.append(f"{'decision' if name in ('action', 'kind') else name}="
                          + (repr(text) if " " in text or not text else text))
    return " ".join(fields) or f"decision={decision!r}"


def main(load: Callable[[], ServiceConfig]) -> int:
    """Entry point of ``mushrooms run``: logging, offline astropy, then the service until SIGTERM.

    Parameters
    ----------
    load : callable
        Returns the configuration (the tool layer's config file plus the
        command-line overrides); called now, and again at every SIGHUP.
    """
    from ..offline import configure_astropy_offline

    # Earth-orientation tables come from the installed astropy-iers-data
    # package: a service must never stall on (or fail for) a download.  First:
    # importing astropy installs its logger class, which must own the "astropy"
    # logger before setup_logging quietens it
    configure_astropy_offline()
    level = logging.getLogger().level or logging.INFO
    setup_logging(level)
    config = load()
    return Service(config, resolve_paths(config.daemon), reload=load).run()


@dataclasses.dataclass
class _Opened:
    """What :meth:`Service.run` opened on the state file, for the stop to close."""

    close: Callable[[], None] = lambda: None
    state_lock: Any = None
