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

Here: the lifecycle (start, main loop, stop order).  Beside it: the signal
flags (:mod:`~mushrooms.daemon.signals`), the timed work
(:mod:`~mushrooms.daemon.timers`), SIGHUP (:mod:`~mushrooms.daemon.reload`) and
the log format (:mod:`~mushrooms.daemon.ops.journal`).
"""

from __future__ import annotations

import logging
import sys
import os
import threading
import time
from datetime import datetime, timezone
from typing import Any, Callable

from apscheduler.schedulers.background import BackgroundScheduler

from .credentials import service_tokens
from .submission.parts_thread import parts_token
from .drain import OutboxDrain
from .outcomes import log_fields
from .intake.trigger import DaemonRunning, PidLock, dispatch, outcome_result, pending_triggers, read_trigger
from .intake.trigger import write_result
from .ops.announce import job_failed, submission_trouble
from .ops.journal import setup_logging
from .ops.systemd import Notifier, Readiness
from .ops.webhook_url import notify_url_usable
from .ops.watch import broker_states, observe
from .planning.jobs import JobRunner
from .reload import close_reloaded_sink, reload_service
from .sections import ServiceConfig
from .settings import RuntimePaths, resolve_paths
from .signals import Signals
from .timers import Timers
from .wiring import EXIT_STATE, StateOpened, open_state, private_dir, service_telescopes_problem

__all__ = ["main", "Service", "setup_logging", "EXIT_STATE"]

log = logging.getLogger("mushrooms.daemon")

READY_WAIT_S = 60.0  # READY=1 waits this long (s) at most for the consumer group's partitions
TRIGGER_SCAN_S = 5.0  # triggers are also picked up without SIGUSR1, at this period (s)



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
        #: returns the configuration again at SIGHUP (:func:`~mushrooms.daemon.reload.reload_service`)
        self.reload_config = reload
        self.notifier = Notifier()
        self.signals = Signals()  # stop, reload, triggers: set by the handlers, read by the main loop
        self.timers = Timers(self)
        self.last_loop = time.monotonic()  # when the main loop last turned (watchdog, liveness)
        self.started = time.monotonic()
        self.counts = {"notices": 0, "triggers": 0, "jobs": 0, "quarantined": 0}
        self.pipeline: Any = None
        self.consumer: Any = None
        self.closing = threading.Event()  # set once the store is being closed: no more retries touch it
        self.submitter: Any = None
        self.submit_drain: Any = None  # [submit]: the submitter's thread (None when off)
        self.parts_drain: Any = None  # [submit_parts]: the other telescopes' SkyPortal parts (None when off)
        #: starting -> warming -> running -> stopping (``/healthz``, ``/readyz``)
        self.phase = "starting"
        from .. import __version__
        from .ops.metrics import ServiceMetrics

        #: the Prometheus registry and the hooks (docs/operations.md); served when metrics_address is set
        self.metrics = ServiceMetrics(__version__, self.paths.state)
        self.listener: Any = None
        self.readiness = Readiness(self.notifier, READY_WAIT_S)
        self._trigger_answers: dict[int, Any] = {}  # job id -> trigger file whose answer waits for the job

    def run(self) -> int:
        """Run until SIGTERM/SIGINT; returns the exit status."""
        submit_token, executed_token = service_tokens(self.config)  # fail fast, with one line, before touching any state
        self._parts_token = parts_token(self.config)  # [submit_parts]: the same
        notify_url_usable(getattr(self.config, "notify", None))  # [notify]: a missing or unusable URL, the same
        lock = PidLock(self.paths.pid_file)
        try:
            lock.acquire()
        except DaemonRunning as exc:
            log.error("event=start_refused reason=%r", str(exc))
            return 1
        self.signals.install()
        private_dir(self.paths.trigger_dir, self.config.daemon.group_readable)
        scheduler = self.scheduler = BackgroundScheduler(timezone="UTC")
        scheduler.start()
        opened = StateOpened()
        try:
            refused = self._open_state(opened)
            if refused is not None:
                return refused
            if self._start_parts(submit_token):  # False: a stop came during the warm-up
                self._start_timers(scheduler, executed_token)
                self._loop()
            return 0
        finally:
            self._stop_all(scheduler, lock, opened)

    def _open_state(self, opened: StateOpened) -> int | None:
        """Open the pipeline on the state file and lock it; the exit status of a refused start, else None."""
        from .planning.warm import SkyCache

        self.sky_cache = SkyCache()
        self.outbox = OutboxDrain(self._flush_outbox, self.config.outbound.retry_initial_s,
                                  self.config.outbound.retry_max_s)
        self.pipeline, refused = open_state(self.config, self.paths, opened, sky_cache=self.sky_cache,
                                            on_outbox=self.queued)
        return refused

    def _start_parts(self, submit_token: str | None) -> bool:
        """Metrics, the submitter, the warm-up, the job runner, what a crash left; False: stopped in the warm-up."""
        self.observe()
        self.timers.prune_raw()
        from .submission.parts_thread import open_part_sender
        from .submission.thread import open_submitter

        opened = open_submitter(self.config.submit, self.config.export, self.pipeline.store, submit_token,
                                on_outbox=self.outbox.kick, on_result=self._submission_result,
                                closing=self.closing.is_set)
        if opened is not None:
            self.submitter, self.submit_drain = opened
            self.submitter.on_trouble = lambda sub, error, action: submission_trouble(  # [notify]
                self.pipeline.sink, sub.superevent_id, sub.queue_names(), sub.attempts, error, action)
            self.submit_drain.kick()  # reconcile what a crash left half done
        opened = open_part_sender(self.config, self.pipeline.store, getattr(self, "_parts_token", None),
                                  self.closing.is_set)
        if opened is not None:
            self.parts_drain = opened[1]
            self.parts_drain.kick()
        self.phase = "warming"
        log.info("event=warm_up_starting solver=%s nside=%d", self.config.scheduler.solver, self.config.scheduler.nside)
        self._warm_up(self.sky_cache)  # only once the state file is ours: a refused start is quick
        if self.signals.stop.is_set():  # systemd's stop during the warm-up: no job runner, no consumer
            log.info("event=start_abandoned phase=warming startup_s=%.2f", time.monotonic() - self.started)
            return False
        self.jobs = JobRunner(self._run_job, self.scheduler, self.config.daemon.max_jobs,
                              self.config.daemon.job_deadline_s, on_done=self._job_done, on_failure=self._job_failed)
        log.info("event=service_starting pid=%d config=%s state=%s sink=%s triggers=%s", os.getpid(),
                 self.config.source, self.paths.state, self._sink_text(), self.paths.trigger_dir)
        self.outbox.kick()  # what a crash left in the outbox goes out first
        return True

    def _start_timers(self, scheduler: BackgroundScheduler, executed_token: str | None) -> None:
        """Resume jobs, scan triggers, open the consumer and start the timed jobs; then ready."""
        self.timers.add_warm(scheduler)
        resumed = self.jobs.sync(self.pipeline.store.pending_jobs())
        if resumed:
            log.info("event=jobs_resumed count=%d", resumed)
        self._scan_triggers()
        from .kafka.consumer import NoticeConsumer

        self.consumer = NoticeConsumer(self.config.kafka, on_offset_jump=self.offset_jump,
                                       instance_id=self.instance_id(self.config))
        self.timers.add_heartbeat(scheduler)
        self.timers.start_loop(executed_token)
        wd = self.timers.add_watchdog(scheduler)
        self.phase = "running"
        log.info("event=service_ready topics=%s watchdog_s=%s startup_s=%.2f partitions=%s",
                 ",".join(self.config.kafka.topics), f"{wd:.1f}" if wd else "-", time.monotonic() - self.started,
                 "assigned" if self.consumer.assigned else "waiting")
        self.readiness.start_waiting()
        self._track_assignment()

    def _stop_all(self, scheduler: BackgroundScheduler, lock: PidLock, opened: StateOpened) -> None:
        """Stop in order: jobs (with grace), consumer, timers, submitter, outbox, state; leave as a crash if a job hangs."""
        self.phase = "stopping"
        self.notifier.stopping()
        log.info("event=service_stopping active_jobs=%s", ",".join(self.active()) or "-")
        if hasattr(self, "jobs"):
            finished = self.jobs.shutdown(self.config.daemon.stop_grace_s)
            if not finished:
                log.warning("event=jobs_left_pending reason='still running at stop; resumed at next start'")
        if self.consumer is not None:
            self.consumer.close()
        scheduler.shutdown(wait=False)
        if self.submit_drain is not None:
            self._closing_submit()
        if self.parts_drain is not None:
            self.parts_drain.close(timeout_s=self.config.submit_parts.timeout_s + 1.0)
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
        flags = self.signals
        while not flags.stop.is_set():
            self.last_loop = time.monotonic()
            if flags.reload.is_set():
                flags.reload.clear()
                reload_service(self)
            if flags.triggers.is_set() or time.monotonic() - last_scan > TRIGGER_SCAN_S:
                flags.triggers.clear()
                last_scan = time.monotonic()
                self._scan_triggers()
            received = self.consumer.poll()
            if received is not None:
                self._handle(received)
            if self.readiness.due(bool(self.consumer.assigned)):
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
                if attempt < retries and self.signals.stop.wait(min(2.0 ** attempt, 10.0)):
                    return  # stopping: leave it uncommitted, it is redelivered
        else:
            if not self._quarantine(received):
                self.consumer.rewind(received)  # keep it: retried on the next poll
                self.signals.stop.wait(5.0)
                return
        self.counts["notices"] += 1
        self.metrics.notice(decision)
        started = self.start_jobs(decision, received.received_at)
        try:
            self.consumer.commit(received)
        except Exception as exc:  # e.g. partitions revoked by a rebalance: redelivery is harmless
            log.warning("event=commit_failed origin=%s error=%r (the notice is stored; a redelivery is a duplicate)",
                        received.origin, str(exc))
        self._after_decision(decision)
        log.info("event=notice origin=%s bytes=%d %s jobs_started=%d store_s=%.3f", received.origin,
                 len(received.value), log_fields(decision), started, time.time() - received.received_at)

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
        self.counts["quarantined"] += 1
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
            self.counts["triggers"] += 1
            self.metrics.notice(decision, source="trigger")
            job = getattr(decision, "job", None)
            if job is not None:  # answered once the job's first plan is out (or it failed)
                self._trigger_answers[job.job_id] = path
            else:
                write_result(path, outcome_result(decision), self.config.daemon.group_readable)
            started = self.start_jobs(decision, received_at)
            path.unlink(missing_ok=True)
            self._after_decision(decision)
            log.info("event=trigger file=%s kind=%s %s jobs_started=%d", path.name, kind,
                     log_fields(decision), started)

    # ------------------------------------------------------------ jobs and outbox
    def start_jobs(self, decision: Any, received_at: float) -> int:
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
            if self.parts_drain is not None:
                self.parts_drain.kick(now=True)

    def queued(self) -> None:
        """A plan (or another message) was stored: publish it, and submit it when [submit] is on.

        The submitter is kicked by the outbox pass once it has published (or failed to publish: see
        :meth:`_flush_outbox`), so the observer on call hears of a plan before of its submission's
        trouble; only while the outbox waits out a back-off (the outbound broker is down) is it kicked
        here, at once: ZTF's queue does not wait for our own broker.
        """
        self.outbox.kick()
        if self.submit_drain is not None and self.outbox.retry_scheduled:
            self.submit_drain.kick()
        if self.parts_drain is not None:
            self.parts_drain.kick()

    def _submission_result(self, state: str, target: str) -> None:
        """Hook for metrics: one call per submission transition (counts by result)."""
        key = f"submissions_{state}"
        self.counts[key] = self.counts.get(key, 0) + 1
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
        self.counts["jobs"] += 1
        self.metrics.job_finished(outcome, info)

    # ------------------------------------------------------------ observability
    def observe(self) -> None:
        """Count what the sink publishes, and open the metrics/health listener when configured."""
        observe(self)

    def broker_states(self) -> dict[str, Any]:
        """Whether the consumer's and the sink's brokers are up."""
        return broker_states(self.consumer, getattr(self.pipeline, "sink", None))

    def offset_jump(self, topic: str, partition: int, expected: int, got: int, skipped: int, cause: str) -> None:
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
        self.readiness.track(self.consumer.assigned, self.config.kafka.topics, time.monotonic() - self.started)

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
        from .planning.warm import warm_up

        return warm_up(cache, self.config.scheduler, should_stop=self.signals.stop.is_set)

    def _flush_outbox(self) -> Any:
        if self.closing.is_set():  # a retry that fires during shutdown: the next start publishes it
            return 0
        try:
            return self.pipeline.flush_outbox()
        finally:  # published (and announced) first, then submitted: see :meth:`queued`
            if self.submit_drain is not None:
                self.submit_drain.kick()

    def _close_store(self, close: Callable[[], None]) -> None:
        """Close sink and store once no publish is running; later retries do nothing."""
        self.closing.set()
        store = getattr(self.pipeline, "store", None)
        publishing = getattr(store, "publish_lock", None)
        took = publishing.acquire(timeout=self.config.outbound.delivery_timeout_s + 5.0) if publishing else False
        try:
            close_reloaded_sink(self)  # a reload's sink: the closer of the start knows only the first one
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

    def instance_id(self, config: Any) -> str | None:
        """Static group membership: stable per installation (``[kafka] instance_id``, else host + state path)."""
        from .settings import group_instance_id

        return group_instance_id(config.kafka, self.paths.state)

    def active(self) -> list[str]:
        return self.jobs.active() if hasattr(self, "jobs") else []

    def _sink_text(self) -> str:
        out = self.config.outbound
        return f"kafka:{out.bootstrap}/{out.topic}" if out.sink == "kafka" else f"directory:{out.directory}"


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
    problem = service_telescopes_problem(config)
    if problem:  # (issue 53) ZTF first (its revisions), then every other telescope's part
        print(f"mushrooms run: error: {problem}", file=sys.stderr)
        return 2
    return Service(config, resolve_paths(config.daemon), reload=load).run()
