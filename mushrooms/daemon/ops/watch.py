"""What the running service shows an operator: the metrics it watches, the health listener, the brokers' state.

:func:`observe` is called at start and after a reload (the sink may be new);
the listener opens once.  See ``docs/operations.md`` for the names.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from .systemd import watchdog_interval_s

__all__ = ["observe", "broker_states"]

log = logging.getLogger("mushrooms.daemon")


def broker_states(consumer: Any, sink: Any) -> dict[str, Any]:
    """Whether the consumer's and a Kafka sink's brokers are up (serving the sink's statistics callbacks)."""
    out: dict[str, Any] = {}
    if consumer is not None:
        out["consumer"] = consumer.health.up
    if getattr(sink, "health", None) is not None:
        serve = getattr(sink, "serve_callbacks", None)
        if serve is not None:
            serve()
        out["sink"] = sink.health.up
    return out


def _notify_counts(sink: Any) -> dict[str, int] | None:
    """The webhook's counts (``[notify]``), or None when it is off."""
    from .announce import webhook_of

    hook = webhook_of(sink)
    return hook.counts() if hook is not None else None


def observe(service: Any) -> None:
    """Count what the service's sink publishes, and open the metrics/health listener when configured.

    Parameters
    ----------
    service : Service
        Its ``metrics``, ``pipeline``, ``consumer``, ``jobs``, ``phase`` and
        ``last_loop`` are read at scrape time; ``listener`` is set once open.
    """
    from .metrics import ObservedSink

    pipeline = service.pipeline
    if not isinstance(pipeline.sink, ObservedSink):
        pipeline.sink = ObservedSink(pipeline.sink, service.metrics, pipeline.store.received_wall)
    service.metrics.watch(
        jobs=lambda: service.jobs.counts() if hasattr(service, "jobs") else {},
        brokers=service.broker_states,
        lag=lambda: dict(service.consumer.health.lag) if service.consumer is not None else {},
        loop_age=lambda: time.monotonic() - service.last_loop,
        assigned=lambda: len(service.consumer.assigned) if service.consumer is not None else 0,
        notify=lambda: _notify_counts(getattr(service.pipeline, "sink", None)),
    )
    address = service.config.daemon.metrics_address
    if not address or service.listener is not None:
        return
    from ..settings import parse_address
    from .health import LIVENESS_DEFAULT_S, HealthServer, liveness, service_checks

    host, port = parse_address(address)
    limit = watchdog_interval_s()
    limit = max(2 * limit, 3 * service.config.kafka.poll_timeout_s) if limit else LIVENESS_DEFAULT_S
    try:
        service.listener = HealthServer(host, port, service.metrics,
                                        liveness(lambda: service.phase, lambda: time.monotonic() - service.last_loop,
                                                 limit), service_checks(service)).start()
    except OSError as exc:  # the plans matter more than the metrics: run on, say so loudly
        log.error("event=metrics_unavailable address=%s error=%r", address, str(exc))
        return
    log.info("event=metrics_listening address=%s:%d paths=/metrics,/healthz,/readyz", *service.listener.address)
