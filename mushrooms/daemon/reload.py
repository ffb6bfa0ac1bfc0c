"""SIGHUP: read the configuration again and apply what can change while running.

The pipeline is rebuilt on the same store (policy, planning, ``[daemon]``),
the sink when ``[outbound]`` changed, the consumer when ``[kafka]`` changed,
the heartbeat's period; the state, trigger and pid paths, ``[loop]`` and
``[submit]`` change only at the next start (said in the log).  A file that
cannot be loaded leaves the running configuration in place.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

from .settings import resolve_paths
from .wiring import make_sink

__all__ = ["reload_service"]

log = logging.getLogger("mushrooms.daemon")


def reload_service(service: Any) -> None:
    """Apply a re-read configuration to the running ``service`` (called by its main loop).

    Parameters
    ----------
    service : Service
        The running :class:`~mushrooms.daemon.service.Service`.
    """
    service.notifier.reloading()
    try:
        new = service.reload_config() if service.reload_config is not None else service.config
        sink = service.pipeline.sink if new.outbound == service.config.outbound else make_sink(new.outbound, new, service.pipeline.store)
    except Exception as exc:  # a bad file, bad sink settings, a missing password: keep running as before
        log.error("event=reload_failed error=%r (keeping the running configuration)", str(exc))
        service.notifier.ready("reload failed; old configuration kept")
        return
    if resolve_paths(new.daemon) != service.paths:
        log.warning("event=reload_partial reason='state, trigger and pid paths change only at restart'")
        new = dataclasses.replace(new, daemon=dataclasses.replace(new.daemon, state_path=str(service.paths.state)))
    from .intake.pipeline import NoticePipeline

    service.pipeline = NoticePipeline(new.policy, new.scheduler, service.pipeline.store, sink, daemon=new.daemon,
                                      sky_cache=service.sky_cache, on_outbox=service.queued,
                                      loop=getattr(new, "loop", None))
    if getattr(new, "loop", None) != getattr(service.config, "loop", None):
        log.warning("event=reload_partial reason='[loop] source and poll interval change at the next start'")
    if new.submit != service.config.submit:
        log.warning("event=reload_partial reason='[submit] changes apply at the next start'")
    service.observe()
    if new.kafka != service.config.kafka:
        from .kafka.consumer import NoticeConsumer

        service.consumer.close()
        service.consumer = NoticeConsumer(new.kafka, on_offset_jump=service.offset_jump,
                                          instance_id=service.instance_id(new))
    if new.daemon.heartbeat_s != service.config.daemon.heartbeat_s:
        service.scheduler.reschedule_job("heartbeat", trigger="interval", seconds=new.daemon.heartbeat_s)
    service.config = new
    service.notifier.ready("configuration reloaded")
    log.info("event=config_reloaded source=%s", new.source)
