"""``mushrooms replay NOTICE_OR_DIR...``: archived notices through the daemon's own path.

Each notice goes through :meth:`NoticePipeline.handle` (handlers ->
scheduler_core -> plan checker -> store -> directory sink), in the order of
the notices' own ``time_created`` (ties: alert-type order, then file order;
notices that cannot be parsed keep their place in file order).  The policy
clock of each notice is its ``time_created`` (as if received when issued), so
age cuts pass and plan ids are reproducible.  The library logs and returns a
:class:`ReplayReport`; the tool (:mod:`mushrooms.tool.replay`) prints one line
per notice (:func:`format_line`) as each is done, and the report's summary::

    MS181101ab-earlywarning.json MS181101ab EARLYWARNING plan plan_id=mushrooms-7bb99e8043271d99 \
        coverage=0.7312 latency_s=3.21 reason='58 fields, 116 exposures'

(one line in the output; wrapped here).

A bad file never stops the replay: it is a ``rejected`` line.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Callable, Sequence

from ...handlers.alert import ALERT_TYPES, parse_notice
from ...handlers.alert import NoticeError
from ...inputs import read_regular_file
from ...scheduler_core.errors import InputError
from .pipeline import NoticePipeline, Outcome
from ..sections import ServiceConfig
from ..sinks import DirectorySink
from ...report.files import SummarisingSink
from ..state.store import Store

__all__ = ["replay_notices", "ReplayReport", "collect_notices", "order_notices", "replay", "format_line"]

log = logging.getLogger("mushrooms.daemon.replay")

NOTICE_SUFFIXES = (".json", ".avro", ".xml")
_RANK = {t: i for i, t in enumerate(ALERT_TYPES)}


def collect_notices(paths: Sequence[str | Path]) -> list[Path]:
    """Files named on the command line; a directory gives its notice files, sorted by name.

    Directories are not descended into recursively; hidden files are skipped.
    A named path that does not exist is kept (it becomes a rejected line).
    """
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            out.extend(sorted(q for q in p.iterdir()
                              if q.is_file() and not q.name.startswith(".") and q.suffix.lower() in NOTICE_SUFFIXES))
        else:
            out.append(p)
    return out


def order_notices(items: Sequence[tuple[Path, bytes | None]], max_bytes: int | None = None
                  ) -> list[tuple[Path, bytes | None, datetime | None]]:
    """Sort by ``time_created`` (then alert type, then file order).

    Notices whose time cannot be read stay in their original slots; the
    readable ones are sorted into the remaining slots.
    """
    info: list[tuple[Path, bytes | None, datetime | None, int]] = []
    for p, data in items:
        t, rank = None, 99
        if data is not None:
            try:
                a = parse_notice(data, max_bytes)
                t, rank = a.time_created, _RANK.get(a.alert_type, 99)
            except NoticeError:
                pass
        info.append((p, data, t, rank))
    slots = [i for i, x in enumerate(info) if x[2] is not None]
    timed = sorted((info[i] for i in slots), key=lambda x: (x[2], x[3]))  # stable: file order on ties
    result = list(info)
    for i, x in zip(slots, timed):
        result[i] = x
    return [(p, d, t) for p, d, t, _ in result]


def format_line(name: str, outcome: Outcome) -> str:
    """One replay line: file, superevent, alert type, decision, plan_id, coverage, latency, reason."""
    cov = f"{outcome.coverage:.4f}" if outcome.coverage is not None else "-"
    lat = f"{outcome.latency_s:.2f}" if outcome.latency_s is not None else "-"
    extra = f" withdrawn={','.join(outcome.plan_ids) or '-'}" if outcome.decision == "withdraw" else ""
    sup = f" supersedes={outcome.supersedes}" if outcome.supersedes else ""
    sup += f" revision={outcome.revision}" if outcome.revision else ""
    return (f"{name} {outcome.superevent_id or '-'} {outcome.alert_type or '-'} {outcome.decision} "
            f"plan_id={outcome.plan_id or '-'} coverage={cov} latency_s={lat}{sup}{extra} "
            f"reason={outcome.reason!r}")


#: Called with each notice's file and outcome as soon as it is handled.
OnOutcome = Callable[[Path, Outcome], None]


@dataclass(frozen=True)
class ReplayReport:
    """What a replay did: every notice's outcome and what went wrong on the way.

    Attributes
    ----------
    results : tuple of (Path, Outcome)
        One per notice, in the order handled.
    out_dir : Path
        The directory sink (plans, withdrawals).
    state : Path
        The SQLite state file.
    errors : tuple of str
        Inputs that are missing, unreadable, not a usable notice (``rejected``:
        malformed, a sky map that does not decode) or directories with no
        notice (one line each).
    status : int
        The exit status: 0 every notice processed (ignored ones included),
        1 some failed on our side (plan checker, internal error), 2 bad input:
        an input missing, unreadable or rejected, or a directory with no
        notice (the README's rule; the other notices are replayed all the same).
    """

    results: tuple[tuple[Path, Outcome], ...]
    out_dir: Path
    state: Path
    errors: tuple[str, ...]
    status: int

    def counts(self) -> dict[str, int]:
        """Number of notices per decision (``plan``, ``ignore``, ``rejected``, ...)."""
        out: dict[str, int] = {}
        for _, oc in self.results:
            out[oc.decision] = out.get(oc.decision, 0) + 1
        return out


def replay(pipeline: NoticePipeline, paths: Sequence[str | Path], on_outcome: OnOutcome | None = None
           ) -> list[tuple[Path, Outcome]]:
    """Run every notice under ``paths`` through ``pipeline.handle``, in the notices' order.

    Parameters
    ----------
    pipeline : NoticePipeline
    paths : sequence of path
        Notice files, or directories of them (:func:`collect_notices`).
    on_outcome : callable, optional
        Called with each notice's file and :class:`~mushrooms.daemon.intake.pipeline.Outcome` as soon as it is handled.

    Returns
    -------
    list of (path, Outcome)
    """
    items: list[tuple[Path, bytes | None]] = []
    read_errors: dict[Path, str] = {}
    for p in collect_notices(paths):
        try:
            items.append((p, read_regular_file(p)))  # a FIFO or device is refused, never waited on
        except InputError as exc:
            read_errors[p] = str(exc)
            items.append((p, None))
    results: list[tuple[Path, Outcome]] = []
    for p, data, t in order_notices(items, pipeline.policy.max_notice_bytes):
        if data is None:
            oc = Outcome("rejected", None, read_errors.get(p, "unreadable"))
            log.warning("notice origin=file:%s superevent_id=- decision=rejected reason=%r", p, oc.reason)
        else:
            try:
                oc = pipeline.handle(data, origin=f"file:{p}", received_at=t)
            except Exception as exc:  # the state could not be written: report and go on
                log.exception("notice origin=file:%s: not processed", p)
                oc = Outcome("failed", None, f"internal error: {type(exc).__name__}: {exc}")
        if on_outcome is not None:
            on_outcome(p, oc)
        results.append((p, oc))
    return results


def replay_notices(notices: Sequence[str | Path], out_dir: str | Path, config: ServiceConfig,
                   state: str | Path | None = None, on_outcome: OnOutcome | None = None) -> ReplayReport:
    """``mushrooms replay`` as a library call: archived notices through the daemon's path into a directory.

    Parameters
    ----------
    notices : sequence of path
        Notice files, or directories of them (see :func:`collect_notices`).
    out_dir : path
        Directory sink for plans and withdrawals (created).
    config : ServiceConfig
        The assembled configuration's sections, command-line overrides
        included (the tool layer's ``mushrooms.tool.overrides.override_config``);
        handed to the :class:`~mushrooms.daemon.intake.pipeline.NoticePipeline` as it is.
    state : path, optional
        SQLite state file; default a fresh ``.replay-state.sqlite`` in ``out_dir``.
    on_outcome : callable, optional
        Called with each notice's file and outcome as soon as it is handled
        (the tool prints :func:`format_line`).

    Returns
    -------
    ReplayReport
        Its ``status`` is 2 when an input is missing, unreadable or rejected,
        or a directory holds no notice (the others are still replayed), else 1
        when some notice failed on our side, else 0.
    """
    missing = [p for p in map(Path, notices) if not p.exists()]
    empty = [p for p in map(Path, notices) if p.is_dir() and not collect_notices([p])]
    unreadable = [p for p in collect_notices(notices) if p.exists() and not os.access(p, os.R_OK)]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if state:
        state = Path(state)
        state.parent.mkdir(parents=True, exist_ok=True)
    else:
        state = out_dir / ".replay-state.sqlite"
        for suffix in ("", "-wal", "-shm"):  # a fresh state for every replay
            Path(str(state) + suffix).unlink(missing_ok=True)
    store = Store(state)
    from ..planning.skymaps import plan_skymap_reader
    from ..submission.names import publish_queues

    # each plan's .txt and .html beside its JSON, naming the queues the service would submit
    sink = SummarisingSink(DirectorySink(out_dir), skymap_for=plan_skymap_reader(store, config.policy.max_skymap_bytes),
                           queues=publish_queues(config.submit, config.export, "a replay submits nothing"))
    try:
        pipeline = NoticePipeline(config.policy, config.scheduler, store, sink, daemon=config.daemon)
        results = replay(pipeline, notices, on_outcome)
    finally:
        sink.close()
        store.close()
    errors = [f"{p}: no such file or directory" for p in missing] + \
             [f"{p}: no notice files (*.json, *.avro, *.xml) in this directory" for p in empty] + \
             [f"{p}: unreadable" for p in unreadable] + \
             [f"{p}: {oc.reason}" for p, oc in results if oc.decision == "rejected" and p not in missing]
    errors = list(dict.fromkeys(errors))
    failed = any(oc.decision == "failed" for _, oc in results)
    report = ReplayReport(tuple(results), out_dir, Path(state), tuple(errors), 2 if errors else 1 if failed else 0)
    log.info("replay done: %d notice(s): %s; output in %s; state %s", len(results),
             ", ".join(f"{k}={v}" for k, v in sorted(report.counts().items())) or "none", out_dir, state)
    return report
