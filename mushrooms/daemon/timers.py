"""The service's timed work, on APScheduler's thread: heartbeat, systemd watchdog, the warm sky, raw-byte
pruning, and the executed-observation loop with its night re-plans ([loop], docs/design/executed.md).

Each job here never raises: a failure is logged and the next period tries again.  The service
(:class:`~mushrooms.daemon.service.Service`) owns the scheduler and its stop order; this module only
says what runs when.
"""

from __future__ import annotations

import logging
import threading
import time
from datetime import datetime, timezone
from typing import Any

from apscheduler.schedulers.background import BackgroundScheduler

from .ops.systemd import watchdog_interval_s

__all__ = ["Timers", "WARM_INTERVAL_S", "PRUNE_EVERY_S"]

log = logging.getLogger("mushrooms.daemon")

WARM_INTERVAL_S = 1800.0  # the coming night's visibility is computed ahead at this period (s)
PRUNE_EVERY_S = 3600.0  # how often raw bytes no longer needed are pruned (s; also at start)


class Timers:
    """What the service runs on its timer thread.

    Parameters
    ----------
    service : Service
        Read for its configuration, pipeline, metrics, consumer and jobs at
        each run (a SIGHUP replaces the pipeline and the configuration).
    """

    def __init__(self, service: Any) -> None:
        self.service = service
        self.last_prune = 0.0  # time.monotonic() of the last pruning
        self.executed_loop: Any = None  # [loop]: the executed-observation loop once started
        self.brokers: Any = None  # what the state file says of the brokers (ops.broker_record.BrokerRecord)
        self.warm_record: Any = None  # what it says of the warm-up plan (ops.warm_record.WarmPlanRecord)
        self._warm_lock = threading.Lock()  # one warm-up plan at a time (the re-warm, a reload's)

    # ------------------------------------------------------------ scheduling
    def add_warm(self, scheduler: BackgroundScheduler) -> None:
        """Record the start's warm-up plan; re-warm the coming night's visibility every :data:`WARM_INTERVAL_S`."""
        self.record_warm_plan()  # after a warm-up not stopped: for `mushrooms status` and systemd's STATUS
        scheduler.add_job(self.rewarm, "interval", seconds=WARM_INTERVAL_S, id="warm",
                          misfire_grace_time=None, coalesce=True)

    def add_heartbeat(self, scheduler: BackgroundScheduler) -> None:
        """The heartbeat every ``[daemon] heartbeat_s`` (rescheduled by a reload)."""
        scheduler.add_job(self.heartbeat, "interval", seconds=self.service.config.daemon.heartbeat_s,
                          id="heartbeat", misfire_grace_time=None, coalesce=True)

    def add_watchdog(self, scheduler: BackgroundScheduler) -> float | None:
        """Ping systemd's watchdog when the unit asks for one; the interval (s), or None."""
        wd = watchdog_interval_s()
        if wd:
            scheduler.add_job(self.watchdog, "interval", seconds=wd, id="watchdog",
                              args=[wd], misfire_grace_time=None, coalesce=True)
        return wd

    def start_loop(self, token: str | None) -> None:
        """With ``[loop] executed_source`` set: poll it every ``poll_interval_s`` on the timer thread (and now)."""
        service = self.service
        loop = getattr(service.config, "loop", None)
        nights = int(getattr(service.pipeline.planning, "nights", 1))
        if (loop is None or not loop.enabled) and nights > 1:
            # (L9) no executed source: the later nights are still re-planned at their twilights (L11)
            every = loop.poll_interval_s if loop is not None else 300.0
            service.scheduler.add_job(self.poll_nights, "interval", seconds=every, id="nights",
                                      next_run_time=datetime.now(timezone.utc), misfire_grace_time=None,
                                      coalesce=True, max_instances=1)
            log.info("event=night_replans nights=%d poll_interval_s=%g source=none", nights, every)
        if loop is None or not loop.enabled:
            return
        from .loop.poll import ExecutedLoop

        self.executed_loop = ExecutedLoop(loop, service.pipeline, token)
        service.scheduler.add_job(self.poll_executed, "interval", seconds=loop.poll_interval_s, id="executed",
                                  next_run_time=datetime.now(timezone.utc), misfire_grace_time=None,
                                  coalesce=True, max_instances=1)
        log.info("event=executed_loop source=%s poll_interval_s=%g max_slip_s=%g min_processed_fraction=%g",
                 self.executed_loop.reader.describe(), loop.poll_interval_s, loop.max_slip_s,
                 loop.min_processed_fraction)

    # ------------------------------------------------------------ the jobs
    def _stopping(self) -> bool:
        return self.service.closing.is_set() or self.service.signals.stop.is_set()

    def poll_nights(self) -> None:
        """Without an executed source: re-plan each event's later night once it has begun (never raises)."""
        if self._stopping():
            return
        from astropy.time import Time

        from .planning.nights import record_night_replans

        service = self.service
        try:
            accepted = record_night_replans(service.pipeline, Time.now())
        except Exception:
            log.exception("event=night_replans_failed")
            return
        for a in accepted:
            if a.job is not None:
                service.metrics.notice(a, source="loop")
                service.start_jobs(a, time.time())

    def poll_executed(self) -> None:
        """One poll: read and store what was executed, start the re-plans it calls for (never raises)."""
        if self._stopping():
            return
        service = self.service
        try:
            self.executed_loop.pipeline = service.pipeline  # a SIGHUP builds a new pipeline on the same store
            poll = self.executed_loop.poll()
        except Exception:
            log.exception("event=executed_poll_failed")
            return
        if poll.error is None and poll.stored is not None:
            service.metrics.observations_read()
        for accepted in poll.jobs:
            service.metrics.notice(accepted, source="loop")
            service.start_jobs(accepted, time.time())

    def rewarm(self) -> None:
        """Compute the coming night's visibility before an alert needs it; try a failed warm-up plan again."""
        cache = self.service.sky_cache
        try:
            cache.warm(self.service.config.scheduler)
        except Exception:
            log.exception("event=warm_failed")
        if getattr(cache, "plan_failure", None) is not None:  # not ready until a plan succeeds
            self.warm_plan()

    def warm_plan_soon(self) -> None:
        """Run the warm-up plan once, now, on the timer thread (a reload: the main loop never waits for it)."""
        self.service.scheduler.add_job(self.warm_plan, misfire_grace_time=None)  # a job of its own each time:
        # one still running is not a reason to skip this one (the lock runs them one after the other)

    def warm_plan(self) -> None:
        """The warm-up's throw-away plan with the running configuration, its outcome recorded (never raises)."""
        from .planning.warm import warm_plan

        with self._warm_lock:
            try:
                warm_plan(self.service.sky_cache, self.service.config.scheduler)
            except Exception:  # warm_plan keeps its own failures; anything else is said and tried again later
                log.exception("event=warm_failed")
                return
            self.record_warm_plan()

    def record_warm_plan(self) -> None:
        """Keep the warm-up plan's outcome in the state file, for ``mushrooms status`` (no listener needed)."""
        from .ops.warm_record import WarmPlanRecord

        record = self._record("warm_record", WarmPlanRecord)
        if record is not None:
            record.update(getattr(self.service.sky_cache, "plan_failure", None))

    def _record(self, name: str, make: Any) -> Any:
        """The state-file record ``name`` of the pipeline's store (made again for a new store), or None."""
        store = getattr(getattr(self.service, "pipeline", None), "store", None)
        if store is None:
            return None
        record = getattr(self, name)
        if record is None or record.store is not store:
            record = make(store)
            setattr(self, name, record)
        return record

    def prune_raw(self) -> None:
        """Forget raw bytes no longer needed (rejected and planned notices, :meth:`Store.prune_raw`)."""
        self.last_prune = time.monotonic()
        daemon = self.service.config.daemon
        try:
            n = self.service.pipeline.store.prune_raw(daemon.rejected_raw_retention_s,
                                                      daemon.planned_raw_retention_s)
        except Exception as exc:
            log.warning("event=prune_failed error=%r", f"{type(exc).__name__}: {exc}")
            return
        if n:
            log.info("event=raw_pruned notices=%d rejected_retention_s=%.0f planned_retention_s=%.0f", n,
                     daemon.rejected_raw_retention_s, daemon.planned_raw_retention_s)

    def heartbeat(self) -> None:
        """One line of health in the log and in systemd's STATUS; prune and check the workers when due."""
        service = self.service
        up = time.monotonic() - service.started
        active = service.active()
        health = getattr(service.consumer, "health", None)
        service.broker_states()  # serves the sink's statistics callbacks between publishes
        counts = service.counts
        consuming = "" if getattr(service.consumer, "assigned", True) else "NOT consuming (no partitions), "
        failure = getattr(getattr(service, "sky_cache", None), "plan_failure", None)
        if failure is not None:  # not ready: said where systemctl status shows it, not only in the log
            consuming = f"NOT READY: warm-up plan failed ({failure[:120]}), " + consuming
        status = (f"{consuming}{health.status_text() + ', ' if health else ''}up {up / 3600:.1f} h, "
                  f"{counts['notices']} notices, {counts['jobs']} jobs done, "
                  f"active: {','.join(active) or 'none'}")
        service.notifier.status(status)
        log.info("event=heartbeat uptime_s=%.0f broker=%s notices=%d triggers=%d jobs_done=%d quarantined=%d "
                 "active=%s loop_age_s=%.1f", up, health.describe() if health else "-", counts["notices"],
                 counts["triggers"], counts["jobs"], counts["quarantined"],
                 ",".join(active) or "-", time.monotonic() - service.last_loop)
        self.record_brokers()
        if time.monotonic() - self.last_prune > PRUNE_EVERY_S:
            self.prune_raw()
        if hasattr(service, "jobs"):
            service.jobs.check_workers()

    def record_brokers(self) -> None:
        """Keep the brokers' state in the state file on a change, for ``mushrooms status`` (no listener needed)."""
        from .ops.broker_record import BrokerRecord

        record = self._record("brokers", BrokerRecord)
        if record is not None:
            sink = getattr(self.service.pipeline, "sink", None)
            record.update({"consumer": getattr(self.service.consumer, "health", None),
                           "sink": getattr(sink, "health", None)})

    def watchdog(self, interval_s: float) -> None:
        """Ping systemd's watchdog only while the main loop turns."""
        age = time.monotonic() - self.service.last_loop
        if age < max(2 * interval_s, 3 * self.service.config.kafka.poll_timeout_s):
            self.service.notifier.watchdog()
        else:
            log.error("event=watchdog_withheld loop_age_s=%.1f", age)
