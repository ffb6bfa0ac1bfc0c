"""The service's Prometheus metrics: one registry per daemon, hooks the daemon calls.

:class:`ServiceMetrics` owns a :class:`prometheus_client.CollectorRegistry`
of its own (never the library's global ``REGISTRY``), so two daemons in one
process (tests) never share a counter.  Counters and histograms are updated
by the daemon where things happen (:mod:`.service` calls :meth:`notice`,
:meth:`job_finished`, ...; :class:`ObservedSink` counts what the outbox
published); gauges that describe *state* (jobs waiting, the outbox backlog,
broker connections, consumer lag, the state file) are read when Prometheus
scrapes, by :class:`_Live`, from callables the daemon hands in
(:meth:`ServiceMetrics.watch`).  ``scheduler_core`` and ``handlers`` know
nothing of this module.

Hooks for features that other parts add (documented in docs/operations.md):
:meth:`ServiceMetrics.submission` (one call per submission attempt with its
result) and :meth:`ServiceMetrics.observations_read` (each successful read
of the executed observations).  Until they are called the series stay at 0.

Names follow Prometheus' conventions: ``mushrooms_`` prefix, ``_total`` on
counters, base units (``_seconds``, ``_bytes``) in the name.
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from prometheus_client import CollectorRegistry, Counter, Histogram, Info
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily
from prometheus_client.registry import Collector

from ..state.views import connect_readonly, oldest_pending_submission, outbox_backlog

__all__ = ["ServiceMetrics", "ObservedSink", "rejection_class", "REJECTION_CLASSES", "SUBMISSION_RESULTS"]

#: First-plan latency buckets (s): the first plan is due within seconds; 60 s is the alert rule's limit.
FIRST_PLAN_BUCKETS = (0.5, 1.0, 2.0, 3.0, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 300.0, 600.0)
#: Final-plan latency buckets (s): the optimiser's budget and a burst's queue.
FINAL_PLAN_BUCKETS = (5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 300.0, 600.0, 1200.0, 3600.0)

#: Why a message was rejected, as a small label set (the full reason is in the store and the log).
REJECTION_CLASSES = ("too_large", "undecodable", "schema", "skymap", "policy_error", "other")
#: Submission results pre-initialised at 0 (the states of the submission lifecycle).
SUBMISSION_RESULTS = ("pending", "submitted", "replaced", "deleted", "rejected", "failed")


def rejection_class(reason: str) -> str:
    """The label of a rejection reason (one of :data:`REJECTION_CLASSES`).

    Parameters
    ----------
    reason : str
        The one-line reason the pipeline stored (``NoticeError`` text).
    """
    r = reason.lower()
    if r.startswith("policy evaluation failed"):
        return "policy_error"
    if "exceeds the" in r or "too large" in r:
        return "too_large"
    if "json" in r or "utf-8" in r or "avro" in r or r == "notice is empty" or "notice must be bytes" in r:
        return "undecodable"
    if "skymap" in r or "fits" in r or "base64" in r or "sky map" in r:
        return "skymap"
    if "must be" in r or "lacks key" in r or "unknown alert_type" in r or "is not" in r or "has no" in r:
        return "schema"
    return "other"


class ServiceMetrics:
    """Everything ``/metrics`` shows, in a registry owned by this object.

    Parameters
    ----------
    version : str
        The build version (``mushrooms_build_info``).
    state_path : Path, optional
        The SQLite state file: its size, and the outbox backlog read from it
        (read-only connection) at each scrape.
    """

    def __init__(self, version: str, state_path: Path | None = None) -> None:
        self.registry = CollectorRegistry(auto_describe=False)
        r = self.registry
        self.state_path = state_path
        self.notices = Counter("mushrooms_notices", "Messages taken in and decided, by source, alert type and "
                               "decision (plan, rerun, duplicate, withdraw, ignore, rejected)",
                               ["source", "alert_type", "decision"], registry=r)
        self.rejected = Counter("mushrooms_messages_rejected", "Messages rejected as bad input, by reason class",
                                ["reason"], registry=r)
        for c in REJECTION_CLASSES:
            self.rejected.labels(reason=c)
        self.quarantined = Counter("mushrooms_messages_quarantined", "Messages that could not be stored and "
                                   "were written to the quarantine directory", registry=r)
        self.first_plan = Histogram("mushrooms_first_plan_latency_seconds", "Notice consumed -> its first plan "
                                    "(revision 1, or the not_observable answer) acknowledged by the sink",
                                    buckets=FIRST_PLAN_BUCKETS, registry=r)
        self.final_plan = Histogram("mushrooms_final_plan_latency_seconds", "Notice consumed -> its final plan "
                                    "(the final revision, or plan_final) acknowledged by the sink",
                                    buckets=FINAL_PLAN_BUCKETS, registry=r)
        self.published = Counter("mushrooms_published_messages", "Outbox messages the sink acknowledged, by type "
                                 "(plan, not_observable, plan_final, withdrawal)", ["type"], registry=r)
        self.revisions = Counter("mushrooms_plan_revisions_published", "Plan documents published, by revision "
                                 "(1: the fast first plan, 2: the optimised replacement)", ["revision"], registry=r)
        for rev in ("1", "2"):
            self.revisions.labels(revision=rev)
        self.jobs_failed = Counter("mushrooms_jobs_failed", "Planning jobs that ended without a plan (bad sky map, "
                                   "checker refusal, internal error)", registry=r)
        self.jobs_finished = Counter("mushrooms_jobs_finished", "Planning jobs finished, by result (done, failed, "
                                     "stopped)", ["result"], registry=r)
        self.offset_jumps = Counter("mushrooms_consumer_offset_jumps", "Times the consumer found messages gone "
                                    "between its committed position and what it read (retention, reset)",
                                    ["topic"], registry=r)
        self.skipped = Counter("mushrooms_consumer_skipped_messages", "Messages skipped by offset jumps (never "
                               "seen by the service)", ["topic"], registry=r)
        self.submissions = Counter("mushrooms_submissions", "Plan submissions to the telescope queue, by result",
                                   ["result"], registry=r)
        for res in SUBMISSION_RESULTS:
            self.submissions.labels(result=res)
        self.build = Info("mushrooms_build", "Build of the running service", registry=r)
        self.build.info(_build_labels(version))
        self._last_observations_read = 0.0
        self._live = _Live(self)
        r.register(self._live)

    # -------------------------------------------------------------- hooks
    def notice(self, decision: Any, source: str = "kafka") -> None:
        """A message was decided (``Accepted`` of the pipeline, or None when it was quarantined)."""
        if decision is None:
            self.quarantined.inc()
            return
        action = str(getattr(decision, "action", None) or "unknown")
        alert_type = str(getattr(decision, "alert_type", None) or "none")
        self.notices.labels(source=source, alert_type=alert_type, decision=action).inc()
        if action == "rejected":
            self.rejected.labels(reason=rejection_class(str(getattr(decision, "reason", "")))).inc()

    def job_finished(self, outcome: Any, info: Mapping[str, Any]) -> None:
        """A planning job's last stage ended (the :class:`~mushrooms.daemon.planning.jobs.JobRunner`'s ``on_done``)."""
        decision = getattr(outcome, "decision", None)
        if "error" in info or decision in ("failed", "rejected"):
            self.jobs_failed.inc()
            result = "failed"
        elif info.get("stopped") or decision == "ignore" or outcome is None:
            result = "stopped"
        else:
            result = "done"
        self.jobs_finished.labels(result=result).inc()

    def offset_jump(self, topic: str, skipped: int) -> None:
        """The consumer skipped ``skipped`` messages of ``topic`` (see :class:`~mushrooms.daemon.kafka.consumer.NoticeConsumer`)."""
        self.offset_jumps.labels(topic=topic).inc()
        self.skipped.labels(topic=topic).inc(max(0, int(skipped)))

    def submission(self, result: str) -> None:
        """Hook: one plan submission ended with ``result`` (e.g. ``submitted``, ``rejected``, ``failed``)."""
        self.submissions.labels(result=str(result)).inc()

    def observations_read(self, when: float | None = None) -> None:
        """Hook: the executed observations were read successfully at ``when`` (Unix s; default now)."""
        self._last_observations_read = time.time() if when is None else float(when)

    def published_message(self, message: Mapping[str, Any], received_wall: float | None,
                          now: float | None = None) -> None:
        """The sink acknowledged ``message``; ``received_wall`` is its notice's receipt (Unix s), if known."""
        now = time.time() if now is None else now
        kind = str(message.get("type") or "unknown")
        self.published.labels(type=kind).inc()
        latency = None if received_wall is None else max(0.0, now - received_wall)
        if kind in ("plan", "not_observable"):
            revision = int(message.get("revision") or 1)
            self.revisions.labels(revision=str(revision)).inc()
            if latency is not None and revision == 1:
                self.first_plan.observe(latency)
            if latency is not None and message.get("final", True):
                self.final_plan.observe(latency)
        elif kind == "plan_final" and latency is not None:
            self.final_plan.observe(latency)

    def watch(self, **sources: Callable[[], Any]) -> None:
        """Hand in the callables the scrape reads (see :class:`_Live`); unknown names raise."""
        for name, fn in sources.items():
            if name not in _Live.SOURCES:
                raise ValueError(f"unknown metrics source {name!r}")
            self._live.sources[name] = fn

    def render(self) -> bytes:
        """The text exposition of the registry (what ``/metrics`` answers)."""
        from prometheus_client import generate_latest

        return generate_latest(self.registry)


class _Live(Collector):
    """Gauges computed at scrape time from the daemon's state.

    Sources (each optional; a failing one is skipped and counted in
    ``mushrooms_scrape_errors``): ``jobs() -> {"queued": n, "running": n}``,
    ``brokers() -> {client: True | False | None}``,
    ``lag() -> {topic: messages}``, ``loop_age() -> s``,
    ``assigned() -> number of partitions``,
    ``notify() -> {"sent": n, "failed": n, "dropped": n, "pending": n}`` (the webhook's counts).
    """

    SOURCES = ("jobs", "brokers", "lag", "loop_age", "assigned", "notify")

    def __init__(self, metrics: ServiceMetrics) -> None:
        self.metrics = metrics
        self.sources: dict[str, Callable[[], Any]] = {}
        self.errors = 0
        self._lock = threading.Lock()

    def _call(self, name: str) -> Any:
        fn = self.sources.get(name)
        if fn is None:
            return None
        try:
            return fn()
        except Exception:
            self.errors += 1
            return None

    def collect(self) -> Iterable[Any]:
        m = self.metrics
        jobs = GaugeMetricFamily("mushrooms_jobs", "Planning work in this process, by state (queued: waiting for "
                                 "a worker, a first plan or an optimisation; running)", labels=["state"])
        counts = self._call("jobs") or {}
        for state in ("queued", "running"):
            jobs.add_metric([state], float(counts.get(state, 0)))
        yield jobs
        up = GaugeMetricFamily("mushrooms_broker_up", "1 while the Kafka client has a broker connection up "
                               "(consumer: the input cluster; sink: the outbound one), 0 when down or not yet known",
                               labels=["client"])
        for client, state in sorted((self._call("brokers") or {}).items()):
            up.add_metric([client], 1.0 if state else 0.0)
        yield up
        lag = GaugeMetricFamily("mushrooms_consumer_lag_messages", "Messages on the input topic not yet consumed "
                                "(librdkafka statistics, every 5 s)", labels=["topic"])
        for topic, n in sorted((self._call("lag") or {}).items()):
            lag.add_metric([topic], float(n))
        yield lag
        assigned = self._call("assigned")
        if assigned is not None:
            yield GaugeMetricFamily("mushrooms_consumer_assigned_partitions", "Input partitions assigned to the "
                                    "consumer (0: not consuming, e.g. waiting for the group)", value=float(assigned))
        age = self._call("loop_age")
        if age is not None:
            yield GaugeMetricFamily("mushrooms_main_loop_age_seconds", "Time since the consume loop last turned",
                                    value=float(age))
        yield GaugeMetricFamily("mushrooms_executed_observations_last_read_timestamp_seconds",
                                "When the executed observations were last read (Unix s; 0: never)",
                                value=m._last_observations_read)
        yield from self._notify()
        yield from self._state()
        yield GaugeMetricFamily("mushrooms_scrape_errors", "Metric sources that failed during scrapes "
                                "(since start)", value=float(self.errors))

    def _notify(self) -> Iterable[Any]:
        """The webhook's messages by outcome, and those waiting (zeros when ``[notify]`` is off)."""
        counts = self._call("notify") or {}
        total = CounterMetricFamily("mushrooms_notify_messages", "Webhook messages by outcome (sent: 2xx; failed: "
                                    "no answer within [notify] timeout_s, a redirect or an error status; dropped: "
                                    "the queue was full or the service stopped)", labels=["outcome"])
        for outcome in ("sent", "failed", "dropped"):
            total.add_metric([outcome], float(counts.get(outcome, 0)))
        yield total
        yield GaugeMetricFamily("mushrooms_notify_pending_messages", "Webhook messages waiting to be posted",
                                value=float(counts.get("pending", 0)))

    def _state(self) -> Iterable[Any]:
        path = self.metrics.state_path
        if path is None:
            return
        size = GaugeMetricFamily("mushrooms_state_file_bytes", "Size of the SQLite state file and its WAL",
                                 labels=["file"])
        for name, p in (("db", path), ("wal", Path(f"{path}-wal"))):
            try:
                size.add_metric([name], float(os.stat(p).st_size))
            except OSError:
                size.add_metric([name], 0.0)
        yield size
        with self._lock:  # one scrape at a time reads the state file
            try:
                conn = connect_readonly(path, timeout_s=2.0)
                try:
                    pending, oldest_age, _ = outbox_backlog(conn)
                    waiting = oldest_pending_submission(conn)
                finally:
                    conn.close()
            except (sqlite3.Error, OSError):
                self.errors += 1
                return
        yield GaugeMetricFamily("mushrooms_outbox_pending_messages", "Outbox messages not yet acknowledged by "
                                "the sink", value=float(pending))
        yield GaugeMetricFamily("mushrooms_outbox_oldest_pending_age_seconds", "Age of the oldest message waiting "
                                "in the outbox (0 when it is empty)", value=float(oldest_age or 0.0))
        yield GaugeMetricFamily("mushrooms_submission_oldest_pending_age_seconds", "Age of the oldest plan "
                                "submission not yet accepted by the telescope queue (0 when none waits)",
                                value=float(waiting["age_s"]) if waiting else 0.0)


class ObservedSink:
    """A sink that tells :class:`ServiceMetrics` what it published (latency from the notice's receipt).

    Parameters
    ----------
    sink : Sink
        The real sink; everything else is delegated to it.
    metrics : ServiceMetrics
    received_wall : callable
        ``received_wall(plan_id) -> float | None``: when the plan's notice
        was received (the store's ``jobs.received_wall``).
    """

    def __init__(self, sink: Any, metrics: ServiceMetrics, received_wall: Callable[[str], float | None]) -> None:
        self.inner = sink
        self._metrics = metrics
        self._received_wall = received_wall

    def publish(self, message: Mapping[str, Any]) -> None:
        self.inner.publish(message)  # a failure raises: nothing counted, the outbox retries
        wall = None
        plan_id = message.get("plan_id")
        if plan_id and message.get("type") in ("plan", "not_observable", "plan_final"):
            try:
                wall = self._received_wall(str(plan_id))
            except Exception:
                wall = None
        self._metrics.published_message(message, wall)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _build_labels(version: str) -> dict[str, str]:
    import platform

    labels = {"version": version, "python": platform.python_version()}
    try:
        import confluent_kafka

        labels["librdkafka"] = confluent_kafka.libversion()[0]
    except ImportError:
        pass
    return labels
