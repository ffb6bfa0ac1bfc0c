"""The daemon's wiring: state store, outbound sink and notice pipeline, from plain values.

Used by ``mushrooms run`` (:mod:`.service`) and ``mushrooms trigger``
without a daemon (:mod:`~mushrooms.daemon.intake.trigger`), so both open the same store and sink the
same way.  The configuration comes in already loaded, command-line
overrides included (the tool layer's ``mushrooms.tool.overrides.effective_config``).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import Any, Callable

from .sections import ServiceConfig
from .settings import OutboundConfig, RuntimePaths

__all__ = ["private_dir", "make_sink", "open_store", "open_pipeline", "open_state", "StateOpened", "EXIT_STATE"]

log = logging.getLogger("mushrooms.daemon")

#: Exit status when the state file is unusable (empty, damaged, newer schema):
#: sysexits' EX_DATAERR; the unit's RestartPreventExitStatus= lists it, since a
#: restart cannot repair the file and would only loop.
EXIT_STATE = 65


def private_dir(path: Path, group_readable: bool = False) -> Path:
    """Create a directory (and parents) 0700, or 0750 when group readable; an existing one is left as is."""
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        path.chmod(0o750 if group_readable else 0o700)
    return path


def make_sink(out: OutboundConfig, config: ServiceConfig | None = None, store: Any = None,
              why_not_submitted: str | None = None) -> Any:
    """The outbound sink of the ``[outbound]`` section.

    A directory sink writes each plan's summaries beside it; with ``config``
    they name the plan's ZTF queues (``[submit]``, ``[export]``; or why they
    are not submitted: ``why_not_submitted``), with ``store`` the page draws the
    plan on its sky map.
    """
    if out.sink == "kafka":
        from .kafka.sink import KafkaSink, sink_security

        security, described = sink_security(out)
        log.info("event=outbound_kafka broker=%s topic=%s security=%r", out.bootstrap, out.topic, described)
        return KafkaSink(out.bootstrap, out.topic, out.max_message_bytes, out.delivery_timeout_s, extra=security)
    from ..report.files import SummarisingSink
    from .sinks import DirectorySink

    queues = skymap_for = None
    if config is not None:
        from .submission.names import publish_queues

        queues = publish_queues(config.submit, config.export, why_not_submitted)
        if store is not None:
            from .planning.skymaps import plan_skymap_reader

            skymap_for = plan_skymap_reader(store, config.policy.max_skymap_bytes)
    # each plan's .txt and .html beside its JSON
    return SummarisingSink(DirectorySink(Path(out.directory)), queues=queues, skymap_for=skymap_for)


def open_store(path: Path, group_readable: bool = False) -> Any:
    """Open (create, 0600 in a 0700 directory) the SQLite state store."""
    from .state.store import Store

    private_dir(path.parent, group_readable)
    return Store(path, group_readable=group_readable)


def service_telescopes_problem(config: ServiceConfig) -> str:
    """Why the service cannot plan ``[scheduler] telescopes`` (one line), or ``""``.

    ZTF comes first (its plan is every revision, its queue Kowalski's, as for a
    ZTF-only service); every other telescope must load (its part:
    :mod:`~mushrooms.daemon.planning.parts`).
    """
    names = list(config.scheduler.telescopes)
    if not names or names[0] != "ztf":
        return (f"[scheduler] telescopes = {names!r}: the service plans ZTF first (its revisions and queue), then "
                f"every other telescope's part: write [\"ztf\", ...] (`mushrooms plan --telescopes` plans any alone)")
    if len(names) > 1:
        from .planning.parts import TelescopeParts

        try:
            TelescopeParts.from_config(config)
        except Exception as exc:  # DescriptionError, a key out of the telescope's range
            return f"[scheduler] telescopes = {names!r}: {str(exc)[:400]}"
    return ""


def _parts_note(store: Any) -> tuple[Callable[[Any], list[dict[str, Any]]], Callable[[list[dict[str, Any]]], list[str]]]:
    """(plan_id -> its revision's other telescopes' parts, parts -> lines of words) on ``store``."""
    from .planning.parts import parts_lines, plan_parts

    return (lambda plan_id: plan_parts(store, plan_id)), parts_lines


def open_pipeline(config: ServiceConfig, paths: RuntimePaths, sink: Any = None, **pipeline_kw: Any
                  ) -> tuple[Any, Callable[[], None]]:
    """Store + sink + pipeline; returns the pipeline and a closer.

    ``config`` is the assembled configuration (its sections); ``paths`` the
    resolved runtime paths (:func:`~.settings.resolve_paths`).

    ``pipeline_kw`` go to :class:`~mushrooms.daemon.intake.pipeline.NoticePipeline` (the daemon's
    ``sky_cache`` and ``on_outbox``).
    """
    from .intake.pipeline import NoticePipeline

    scheduler = config.scheduler
    if "parts" not in pipeline_kw and tuple(scheduler.telescopes)[1:]:  # ztf first, then the others' parts
        from .planning.parts import TelescopeParts

        pipeline_kw["parts"] = TelescopeParts.from_config(config)
        scheduler = dataclasses.replace(scheduler, telescopes=("ztf",))  # ZTF's revisions: a ZTF-only plan
    store = open_store(paths.state, config.daemon.group_readable)
    own_sink = sink is None
    sink = make_sink(config.outbound, config, store) if own_sink else sink
    from .ops.announce import NotifyingSink, open_webhook

    note = _parts_note(store) if pipeline_kw.get("parts") is not None else None
    if note is not None and hasattr(sink, "parts_note"):  # the summary and page name every telescope's part
        sink.parts_note = lambda doc: note[1](note[0](doc.get("plan_id")))
    hook = open_webhook(getattr(config, "notify", None))  # [notify]: off by default
    if hook is not None:
        sink = NotifyingSink(sink, hook, note[0] if note is not None else None)
    pipeline_kw.setdefault("loop", getattr(config, "loop", None))
    pipeline = NoticePipeline(config.policy, scheduler, store, sink, daemon=config.daemon, **pipeline_kw)

    def close() -> None:
        for obj in ((sink,) if own_sink else (hook,) if hook is not None else ()) + (store,):
            fn = getattr(obj, "close", None)
            if fn is not None:
                try:
                    fn()
                except Exception:
                    log.exception("event=close_failed what=%s", type(obj).__name__)

    return pipeline, close


@dataclasses.dataclass
class StateOpened:
    """What the service opened on the state file (:func:`open_state`), for its stop to close."""

    close: Callable[[], None] = lambda: None
    state_lock: Any = None


def open_state(config: ServiceConfig, paths: RuntimePaths, opened: StateOpened, **pipeline_kw: Any
               ) -> tuple[Any, int | None]:
    """``mushrooms run``'s start on the state file: the pipeline opened on it, and the file locked.

    Returns
    -------
    (pipeline or None, int or None)
        The pipeline (None when the store refused to open) and the exit
        status of a refused start (:data:`EXIT_STATE` for an unusable file,
        1 for a file another daemon holds), else None.  ``opened`` gets the
        pipeline's close and the state lock.
    """
    from .state.store import StateInUse, StoreError, lock_state

    try:
        pipeline, opened.close = open_pipeline(config, paths, **pipeline_kw)
    except StoreError as exc:  # empty, damaged, newer: one line, and a status Restart= does not loop on
        log.error("event=start_refused reason=%r", str(exc))
        return None, EXIT_STATE
    try:  # one daemon per state file, whatever its pid file says
        opened.state_lock = lock_state(paths.state)
    except StateInUse as exc:
        log.error("event=start_refused reason=%r", str(exc))
        return pipeline, 1
    return pipeline, None
