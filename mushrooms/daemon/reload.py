"""SIGHUP: read the configuration again and apply what can change while running.

The pipeline is rebuilt on the same store (policy, planning, ``[daemon]``),
the sink when ``[outbound]`` changed (the old one closed once it has flushed), the consumer when ``[kafka]`` changed,
the heartbeat's period, and the warm-up plan is run again (on the timer
thread); the state, trigger and pid paths, ``[loop]`` and
``[submit]`` change only at the next start (said in the log).  A file that
cannot be loaded leaves the running configuration in place.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

from .settings import resolve_paths
from .wiring import make_sink

__all__ = ["reload_service", "close_reloaded_sink"]

log = logging.getLogger("mushrooms.daemon")


def reload_service(service: Any) -> None:
    """Apply a re-read configuration to the running ``service`` (called by its main loop).

    Parameters
    ----------
    service : Service
        The running :class:`~mushrooms.daemon.service.Service`.
    """
    service.notifier.reloading()
    old_sink = service.pipeline.sink
    try:
        new = service.reload_config() if service.reload_config is not None else service.config
        if tuple(new.scheduler.telescopes) != tuple(service.config.scheduler.telescopes):  # (issue 53)
            raise ValueError(f"[scheduler] telescopes = {list(new.scheduler.telescopes)!r}: the telescopes "
                             f"change at a restart only (running: {list(service.config.scheduler.telescopes)!r})")
        sink = old_sink if new.outbound == service.config.outbound else _new_sink(service, new)
    except Exception as exc:  # a bad file, bad sink settings, a missing password: keep running as before
        log.error("event=reload_failed error=%r (keeping the running configuration)", str(exc))
        service.notifier.ready("reload failed; old configuration kept")
        return
    if resolve_paths(new.daemon) != service.paths:
        log.warning("event=reload_partial reason='state, trigger and pid paths change only at restart'")
        new = dataclasses.replace(new, daemon=dataclasses.replace(new.daemon, state_path=str(service.paths.state)))
    from .intake.pipeline import NoticePipeline

    parts = getattr(service.pipeline, "parts", None)  # the same telescopes (above): the same parts
    scheduler = dataclasses.replace(new.scheduler, telescopes=("ztf",)) if parts is not None else new.scheduler
    service.pipeline = NoticePipeline(new.policy, scheduler, service.pipeline.store, sink, daemon=new.daemon,
                                      sky_cache=service.sky_cache, on_outbox=service.queued,
                                      loop=getattr(new, "loop", None), parts=parts)
    if getattr(new, "loop", None) != getattr(service.config, "loop", None):
        log.warning("event=reload_partial reason='[loop] source and poll interval change at the next start'")
    if new.submit != service.config.submit:
        log.warning("event=reload_partial reason='[submit] changes apply at the next start'")
    if getattr(new, "notify", None) != getattr(service.config, "notify", None):
        log.warning("event=reload_partial reason='[notify] changes apply at the next start'")
    if getattr(new, "submit_parts", None) != getattr(service.config, "submit_parts", None):
        log.warning("event=reload_partial reason='[submit_parts] changes apply at the next start'")
    service.observe()
    if new.kafka != service.config.kafka:
        from .kafka.consumer import NoticeConsumer

        service.consumer.close()
        service.consumer = NoticeConsumer(new.kafka, on_offset_jump=service.offset_jump,
                                          instance_id=service.instance_id(new))
    if new.daemon.heartbeat_s != service.config.daemon.heartbeat_s:
        service.scheduler.reschedule_job("heartbeat", trigger="interval", seconds=new.daemon.heartbeat_s)
    service.config = new
    if sink is not old_sink:  # once it has flushed, off the main loop: no thread nor socket left behind
        service.sink_replaced = True
        service.scheduler.add_job(_close_replaced, args=[service, old_sink], misfire_grace_time=None)
    service.notifier.ready("configuration reloaded")
    log.info("event=config_reloaded source=%s", new.source)
    # the warm-up plan again, with the new configuration (or a repaired install): readiness follows at once,
    # not at the next re-warm; on the timer thread, so the main loop goes on consuming meanwhile
    service.timers.warm_plan_soon()


def _close_replaced(service: Any, sink: Any) -> None:
    """Close the sink a reload replaced, once no publish runs on it (the store's publish lock), keeping the webhook."""
    from .ops.announce import close_outbound

    publishing = getattr(service.pipeline.store, "publish_lock", None)
    took = publishing.acquire(timeout=service.config.outbound.delivery_timeout_s + 5.0) if publishing else False
    try:
        close_outbound(sink)
        log.info("event=sink_closed reason='replaced by a reload'")
    except Exception:
        log.exception("event=close_failed what=replaced_sink")
    finally:
        if took:
            publishing.release()


def close_reloaded_sink(service: Any) -> None:
    """At the stop: close the sink a reload made (the closer of the start closes only the start's), never raising."""
    if not getattr(service, "sink_replaced", False):
        return
    from .ops.announce import close_outbound

    try:
        close_outbound(service.pipeline.sink)
    except Exception:
        log.exception("event=close_failed what=sink")


def _new_sink(service: Any, new: Any) -> Any:
    """The sink of the new ``[outbound]``, telling the running webhook (``[notify]``) as the old one did."""
    from .ops.announce import NotifyingSink, webhook_of

    sink = make_sink(new.outbound, new, service.pipeline.store)
    hook = webhook_of(service.pipeline.sink)
    return NotifyingSink(sink, hook) if hook is not None else sink
