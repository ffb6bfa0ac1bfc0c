"""``mushrooms plan SKYMAP``: plan a ZTF night from a sky map, check it, write it.

Optionally also ZTF's ToO queue, SkyPortal's manual observation-plan payload
and a picture; ``--deadline`` writes the best plan found by then.
``--executed FILE`` re-plans what is left from ``--start`` given what the
telescope did (:func:`~mushrooms.scheduler_core.replan.plan_remaining`,
``docs/design/replan.md``).
"""

from __future__ import annotations

import argparse
import sys
import logging
import math
import time
from typing import Any, Sequence

from .settings_flag import add_set_option
from .common import SOLVER_CHOICES, SOLVER_HELP, SOLVER_METAVAR, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "parse_start", "warn_if_far_from_merger", "read_executed",
           "night_path"]

log = logging.getLogger("mushrooms.plan")

HELP = "plan a ZTF night from a sky map"

#: A start this far (days) from the merger is reported: the kilonova is then faint or not yet there.
FAR_FROM_MERGER_DAYS = 3.0


def parse_start(text: str) -> Any:
    """``--start``: ``now``, or :func:`~mushrooms.scheduler_core.times.parse_time` with MJD allowed.

    Raises
    ------
    InputError
        When it is not a time (an empty string included).
    """
    from ..scheduler_core.times import parse_time

    if text.strip().lower() == "now":
        from astropy.time import Time

        return Time.now()
    return parse_time(text, "--start", mjd=True)


def warn_if_far_from_merger(start: Any, event_time: Any) -> None:
    """One warning line when the horizon starts far from the merger (or outside Earth-orientation tables)."""
    if event_time is not None:
        days = float((start - event_time).to_value("day"))
        if abs(days) > FAR_FROM_MERGER_DAYS:
            span = f"{abs(days) / 365.25:.1f} years" if abs(days) > 365.25 else f"{abs(days):.1f} days"
            log.warning("--start %s is %s %s the merger (%s): planning anyway", start.isot[:19], span,
                        "after" if days > 0 else "before", event_time.isot[:19])
    from astropy.utils import iers

    table = iers.earth_orientation_table.get()
    if not table["MJD"][0].value <= start.mjd <= table["MJD"][-1].value + 366:
        log.warning("--start %s is outside the Earth-orientation tables: pointing is approximate",
                    start.isot[:19])


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms plan`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("plan", HELP)
    p.add_argument("skymap", nargs="?", metavar="SKYMAP",
                   help="sky map FITS (multi-order or flat HEALPix); `mushrooms demo` plans the bundled demo map")
    p.add_argument("--start", metavar="TIME",
                   help="horizon start: now, ISO-8601 (Z or +hh:mm offset; no offset means UTC) or MJD "
                        "(default: the sky map's event time)")
    p.add_argument("--solver", choices=SOLVER_CHOICES, metavar=SOLVER_METAVAR, help=SOLVER_HELP)
    p.add_argument("--telescopes", metavar="NAMES",
                   help="telescopes to plan, comma-separated: shipped names (`mushrooms telescopes`) or description "
                        "files (default [scheduler] telescopes, ztf); two or more are planned together: each "
                        "one's part as if alone, the first into -o FILE, each other into FILE.<name>.json, and the "
                        "joint plan (union, shares, certified bound) into FILE.joint.json")
    p.add_argument("-o", "--output", metavar="FILE", default="plan.json",
                   help="plan document to write (default plan.json); its summary goes beside it as FILE.txt and "
                        "FILE.html (the page; the picture in it with --plot)")
    p.add_argument("--brief", action="store_true", help="print the one-line answer only, not the text summary")
    p.add_argument("--deadline", metavar="SECONDS", type=float,
                   help="write the best plan found by then: the greedy plan at once, the optimised one if it is "
                        "ready and covers more (default: wait for the solver)")
    p.add_argument("--queue", metavar="FILE",
                   help="also write ZTF's ToO queues as the daemon submits them (revision 1; program fields from "
                        "[export]): one queue object, or a JSON list of them in submission order")
    p.add_argument("--skyportal", metavar="FILE",
                   help="also write the SkyPortal observation plans as the daemon POSTs them to "
                        "/api/observation_plan/manual (revision 1; [export] skyportal_plans): one plan object, or a "
                        "JSON list of them in submission order")
    p.add_argument("--targets", metavar="FILE",
                   help="also write the plan as a target list (field id, RA, Dec, filter, exposure, start): JSON "
                        "into FILE and CSV beside it (FILE.csv), for a telescope without a queue API")
    p.add_argument("--plot", metavar="FILE", help="also draw the plan on the sky map (PNG)")
    p.add_argument("--executed", metavar="FILE",
                   help="what the telescope did: a JSON-lines file of executed exposures (field_id, filter, start, "
                        "exposure_s, processed_fraction, status), or file:PATH, or depot:DIR (a local copy of ZTF's "
                        "depot); plans what is left from --start: fields done in both filters count as covered, "
                        "half-done fields get their other filter (default --start: the end of the last exposure)")
    p.add_argument("--min-processed-fraction", metavar="F", type=float, default=None,
                   help="with --executed: least fraction of the 64 quadrants reduced for an exposure to count "
                        "(default 0.5)")
    add_set_option(p)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms plan`` on its own."""
    return execute("plan", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Plan a sky map, check the plan, write it (and optionally a queue, a SkyPortal payload and a picture).

    When the plan covers less than ``min_coverage`` the document written is
    a ``not_observable`` answer; no queue nor SkyPortal file is written.
    """
    t_imports = time.perf_counter()
    from .config import load_config
    from ..offline import configure_astropy_offline
    from ..scheduler_core import make_plan  # noqa: F401  (the scheduler's modules, timed as imports)

    configure_astropy_offline()
    t0 = time.perf_counter()
    t_imports = t0 - t_imports  # the scheduler's modules (numpy, astropy, healpy, scipy, the checker)
    config = load_config(args.config, getattr(args, "set", None) or ())
    from .plan_telescopes import plan_each, wanted_telescopes

    names = wanted_telescopes(args, config)
    if names is not None and len(names) > 1:  # (issue 53 item 2) planned together: each one's document and the joint
        from .plan_joint import plan_joint

        start = parse_start(args.start) if args.start is not None else None
        return plan_joint(args, config, names, start, lambda a, c, made: _plan(a, c, t0, t_imports, made))
    if names is not None:  # (issue 53, phase 2) one telescope, by name or description
        return plan_each(args, config, names, lambda a, c: _plan(a, c, t0, t_imports))
    return _plan(args, config, t0, t_imports)


def _plan(args: argparse.Namespace, config: Any, t0: float, t_imports: float, made: Any = None) -> int:
    """Plan with ``config`` (one telescope's), check, write; :func:`run` after the configuration.

    ``made``: the telescope's part of a joint plan, already made and checked (written, not planned).
    """
    from ..handlers.text import storable
    from ..inputs import regular_file
    from ..outputs import write_json_atomic
    from ..scheduler_core import make_plan, not_observable, read_skymap

    cfg = config.scheduler
    outputs, start = _checked_arguments(args, config)
    deadline = getattr(args, "deadline", None)
    executed_spec = getattr(args, "executed", None)
    fraction = getattr(args, "min_processed_fraction", None)
    from .progress import Progress

    progress = Progress("plan")
    progress.stage("reading the sky map")
    source = regular_file(args.skymap, "sky map")  # never a FIFO nor a device
    skymap = read_skymap(source, nside=cfg.nside)
    progress.stage(f"planning ({args.solver or cfg.solver})", deadline or _budget_s(cfg, args.solver))
    t_load = time.perf_counter() - t0  # config, imports and the sky map
    log.info("read %s: nside %d, 90%% area %.0f deg2, event time %s", storable(source), skymap.nside,
             skymap.credible_area(0.9), skymap.event_time.isot if skymap.event_time else "unknown")
    if executed_spec is not None or cfg.nights > 1:
        with progress:
            return _replan(args, config, skymap, start, executed_spec, 0.5 if fraction is None else fraction, t0,
                           progress)
    if start is not None:
        warn_if_far_from_merger(start, skymap.event_time)
    if deadline is None:
        from ..scheduler_core.plan.messages import revision_document

        plan = made if made is not None else make_plan(skymap, cfg, start=start, solver=args.solver,
                                                       times_before={"imports": t_imports, "load": t_load})
        doc = revision_document(plan, 1, True)
    else:
        plan, doc = _plan_by_deadline(skymap, cfg, start, args.solver or cfg.solver, float(deadline), t0)
    progress.stage("checking what is observable and writing")
    answer = not_observable(plan, skymap, cfg)
    if answer is not None:
        progress.done()
        _write_not_observable(args, answer, plan, skymap, cfg, outputs, t0)
        return 0
    write_json_atomic(args.output, doc)
    from .plan_telescopes import write_targets

    write_targets(getattr(args, "targets", None), plan)
    queues = _write_submissions(args.queue, getattr(args, "skyportal", None), plan, config, doc)
    picture = _write_summary(args, doc, plan, skymap, queues=queues)
    progress.done()
    if args.plot:
        from ..outputs import write_bytes_atomic

        write_bytes_atomic(args.plot, picture)
    _print_answer(args, args.output, doc, time.perf_counter() - t0, queues=queues)
    return 0


def _checked_arguments(args: argparse.Namespace, config: Any) -> tuple[dict[str, Any], Any]:
    """Refuse a bad combination of arguments before any work (one line each); the outputs named, the start."""
    from ..outputs import check_outputs
    from ..scheduler_core.errors import InputError

    cfg = config.scheduler
    if not args.skymap:
        raise InputError("no sky map given: name a FITS sky map (`mushrooms demo` plans the bundled demo map)")
    outputs = {"-o/--output": args.output, "--queue": args.queue, "--skyportal": getattr(args, "skyportal", None),
               "--plot": args.plot, "--targets": getattr(args, "targets", None)}
    if outputs["--targets"]:
        from pathlib import Path

        outputs["--targets (CSV)"] = str(Path(outputs["--targets"]).with_suffix(".csv"))
    check_outputs(outputs, inputs=[args.skymap, args.config])  # before any work; never onto an input
    if getattr(args, "skyportal", None) and config.export.skyportal_allocation_id is None:
        raise InputError("--skyportal needs [export] skyportal_allocation_id in the config "
                         "(the SkyPortal allocation of ZTF)")
    start = parse_start(args.start) if args.start is not None else None
    deadline = getattr(args, "deadline", None)
    if deadline is not None and not (math.isfinite(deadline) and deadline > 0):
        raise InputError(f"--deadline {deadline:g}: must be a finite number of seconds > 0")
    executed_spec = getattr(args, "executed", None)
    fraction = getattr(args, "min_processed_fraction", None)
    if executed_spec is None and fraction is not None:
        raise InputError("--min-processed-fraction needs --executed")
    if cfg.max_open_shutter_s is not None and args.solver in ("blocks", "milp"):
        raise InputError(f"--solver {args.solver}: the block MILP holds no open-shutter cap (S4); "
                         "[scheduler] max_open_shutter_s needs greedy, slots or hybrid")
    if deadline is not None and cfg.nights > 1:
        raise InputError(f"--deadline plans one night; [scheduler] nights is {cfg.nights}")
    if executed_spec is not None:
        if deadline is not None:
            raise InputError("--deadline and --executed do not go together: a re-plan waits for the solver")
        if fraction is not None and not 0.0 <= fraction <= 1.0:
            raise InputError(f"--min-processed-fraction {fraction:g}: must be in [0, 1]")
    return outputs, start


def _write_not_observable(args: argparse.Namespace, answer: Any, plan: Any, skymap: Any, cfg: Any,
                          outputs: dict[str, Any], t0: float) -> None:
    """Write the ``not_observable`` answer and say why; no queue nor SkyPortal file."""
    from ..outputs import write_json_atomic

    write_json_atomic(args.output, answer.to_document())
    _write_summary(args, answer.to_document(), plan, skymap, answer=answer, show=False)
    print(f"{args.output}: NOT OBSERVABLE: best coverage {plan.metrics.coverage:.4f} < min_coverage "
          f"{cfg.min_coverage:g}, {time.perf_counter() - t0:.1f} s")
    for line in answer.sentences:
        print(f"  {line}")
    for what in ("--queue", "--skyportal"):
        if outputs[what]:
            print(f"{outputs[what]}: not written ({what}): nothing to observe")


def _budget_s(cfg: Any, solver: str | None) -> float | None:
    """The planning's time budget to show (s): the MILP's time limit, none for greedy nor a work budget (its
    seconds are work, not wall seconds: a loaded machine takes longer)."""
    return None if (solver or cfg.solver) == "greedy" or cfg.deterministic else float(cfg.time_limit_s)


def _write_summary(args: argparse.Namespace, doc: dict[str, Any], plan: Any, skymap: Any, answer: Any = None,
                   show: bool = True, queues: tuple[tuple[str, ...], str] = ((), "")) -> bytes | None:
    """Write ``P.txt`` and ``P.html`` beside ``-o P.json``; the picture's PNG, or None.

    The page embeds the picture when one is drawn (``--plot``): a plan without it does not load matplotlib
    (about a second of a greedy ``mushrooms plan``), and its page has the tables without the picture.
    """
    from ..report.files import write_summaries

    picture = None
    if args.plot:
        from ..plotting import plan_picture_png

        picture = plan_picture_png(plan, skymap, dpi=120, answer=answer,
                                   executed=getattr(args, "executed_exposures", ()))
    write_summaries(doc, args.output, picture, queues=queues[0], queue_note=queues[1])
    if answer is not None and args.plot:
        from ..outputs import write_bytes_atomic

        write_bytes_atomic(args.plot, picture)
    return picture


def _print_answer(args: argparse.Namespace, output: str, doc: dict[str, Any], seconds: float,
                  what: str = "", queues: tuple[tuple[str, ...], str] = ((), "")) -> None:
    """The text summary (unless ``--brief``), then the one-line answer in words (``what``: the night, the window)."""
    from ..report.files import summary_paths
    from ..report.summary import answer_line, summary_text

    if not getattr(args, "brief", False):
        print(summary_text(doc, rows=False, queues=queues[0], queue_note=queues[1]))
    txt, page = summary_paths(output)
    print(f"{output}: {what + ': ' if what else ''}{answer_line(doc)}; checked, {seconds:.1f} s "
          f"(summary {txt}, page {page})")


def _plan_by_deadline(skymap: Any, cfg: Any, start: Any, solver: str, deadline_s: float,
                      t0: float) -> tuple[Any, dict[str, Any]]:
    """The best checked plan found ``deadline_s`` after ``t0`` (anytime: greedy first, then ``solver``)."""
    from ..scheduler_core.anytime import anytime_plans, is_better
    from ..scheduler_core.plan.messages import revision_document
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.prepare import prepare_problem

    if deadline_s <= 0:
        raise InputError(f"--deadline must be > 0 seconds, got {deadline_s:g}")
    if start is None:
        if skymap.event_time is None:
            raise InputError("the sky map has no event time (DATE-OBS); give --start")
        start = skymap.event_time
    problem = prepare_problem(skymap, cfg, start)
    best, revision = None, 0
    for plan in anytime_plans(problem, skymap, solver, should_stop=lambda: time.perf_counter() - t0 > deadline_s):
        if best is None or is_better(plan, best, 0.0, cfg.objective, cfg.detection_max_coverage_loss):
            best, revision = plan, revision + 1
            log.info("--deadline: %s plan covers %.4f at %.1f s", plan.metrics.solver, plan.metrics.coverage,
                     time.perf_counter() - t0)
    assert best is not None
    return best, revision_document(best, revision, True)


def read_executed(spec: str, around: Any | None, filters: Sequence[str] | None = None) -> tuple[Any, ...]:
    """The exposures ``--executed`` names: a JSON-lines file, ``file:PATH`` or ``depot:DIR``.

    ``filters``: the telescope's (default ZTF's); ``depot:`` is ZTF's processing record only.

    ``depot:DIR`` reads the depot files (``<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json``)
    of the two days before ``around`` (the start, or the merger) that exist.

    Raises
    ------
    InputError
        A missing file, a SkyPortal URL (the plan tool reads no network), a
        file of the wrong shape.
    """
    from astropy.time import Time, TimeDelta

    from ..handlers.executed import depot_paths, parse_executed_source, read_depot, read_jsonl
    from ..inputs import regular_file
    from ..scheduler_core.errors import InputError

    kind, location = "file", spec
    if spec.split(":", 1)[0] in ("none", "file", "depot", "skyportal"):
        try:
            source = parse_executed_source(spec)
        except ValueError as exc:
            raise InputError(f"--executed {spec}: {exc}") from None
        kind, location = source.kind, source.location
    if kind == "none":
        return ()
    if kind == "skyportal" or (kind == "depot" and "://" in str(location)):
        raise InputError(f"--executed {spec}: the plan tool reads files only; the service polls "
                         f"{kind} ([loop] executed_source)")
    if kind == "file":
        return read_jsonl(regular_file(location, "executed file"), **({} if filters is None else {"filters": filters}))
    if filters is not None and tuple(filters) != ("g", "r", "i"):
        raise InputError(f"--executed {spec}: depot: is ZTF's processing record; give another telescope's "
                         "exposures as a JSON-lines file")
    from pathlib import Path

    folder = Path(location)
    if not folder.is_dir():
        raise InputError(f"--executed {spec}: {folder} is not a directory")
    end = around if around is not None else Time.now()
    exposures: list[Any] = []
    names = depot_paths(end - TimeDelta(2.0, format="jd"), end + TimeDelta(1.0, format="jd"))
    for name in names:
        if (folder / name).is_file():
            exposures.extend(read_depot(folder / name))
    if not exposures:
        log.warning("--executed %s: no depot file of %s", spec, ", ".join(names))
    return tuple(exposures)


#: What ``mushrooms plan`` says of the queue names in its summaries.
PLAN_QUEUE_WORDS = "not sent by mushrooms plan, named as mushrooms submit and the service send them"


def _write_submissions(queue_path: str | None, skyportal_path: str | None, plan: Any, config: Any,
                       doc: dict[str, Any]) -> tuple[tuple[str, ...], str]:
    """``--queue`` and ``--skyportal`` files, both from one timing of the plan's queue set; the plan's queue
    names (as the service would submit it to ``[submit] target``) and what becomes of them, for its summaries."""
    from ..daemon.submission.names import queue_names
    from ..outputs import write_json_atomic
    from ..scheduler_core.plan.exports import timed_passes

    export = config.export
    try:
        passes = timed_passes(plan, export, _submission_base(plan, export))
    except ValueError:
        if queue_path:
            raise
        return (), ""
    if queue_path:
        write_json_atomic(queue_path, passes.queues[0] if len(passes.queues) == 1 else passes.queues)
    if skyportal_path:
        write_json_atomic(skyportal_path, submitted_skyportal(plan, export, passes))
    return queue_names(doc, export, config.submit.target, passes), PLAN_QUEUE_WORDS


def _submission_base(plan: Any, export: Any) -> str:
    """The name base of the plan's queues (:func:`~..scheduler_core.plan.exports.queue_name_base`)."""
    from ..scheduler_core.plan.exports import queue_name_base

    return queue_name_base(export.subprogram_name, plan.plan_id, plan.event.superevent_id)


def submitted_skyportal(plan: Any, export: Any, passes: Any = None) -> Any:
    """What the daemon POSTs to SkyPortal for ``plan`` as revision 1: one plan, or a list in submission order.

    ``passes``: revision 1's timed queue set (:func:`~..scheduler_core.plan.exports.timed_passes`), if known.
    """
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.plan.exports import to_skyportal_plans

    base = _submission_base(plan, export).removeprefix("ToO_")
    try:
        plans = to_skyportal_plans(plan, export, name_base=base, passes=passes)
    except ValueError as exc:  # no event time, or no pass opens before the plan's end: one line
        raise InputError(f"--skyportal: {exc}") from None
    return plans[0] if len(plans) == 1 else plans


def night_path(path: str, night: int) -> str:
    """The file of night ``night``'s document: ``plan.json`` for night 1, ``plan.night2.json`` for night 2, ..."""
    if night == 1:
        return path
    from pathlib import Path

    p = Path(path)
    return str(p.with_name(f"{p.stem}.night{night}{p.suffix}"))


def _write_night(args: argparse.Namespace, config: Any, skymap: Any, plan: Any, n: int, what: str,
                 t0: float) -> None:
    """One night's files of a re-plan (the plan, its summaries, queue, payload and picture), then its summary."""
    from ..outputs import write_bytes_atomic, write_json_atomic
    from ..scheduler_core.plan.messages import revision_document

    output = night_path(args.output, n)
    doc = revision_document(plan, 1, True)
    write_json_atomic(output, doc)
    skyportal = getattr(args, "skyportal", None)
    queues = _write_submissions(args.queue and night_path(args.queue, n), skyportal and night_path(skyportal, n),
                                plan, config, doc)
    picture = _write_summary(argparse.Namespace(**{**vars(args), "output": output}), doc, plan, skymap,
                             queues=queues)
    if args.plot and picture is not None:
        write_bytes_atomic(night_path(args.plot, n), picture)
    _print_answer(argparse.Namespace(**{**vars(args), "output": output}), output, doc,
                  time.perf_counter() - t0, what, queues=queues)


def _replan(args: argparse.Namespace, config: Any, skymap: Any, start: Any, spec: str | None, fraction: float,
            t0: float, progress: Any = None) -> int:
    """``--executed`` and/or ``[scheduler] nights > 1``: plan what is left, night by night; write each night's files."""
    from ..scheduler_core.sequences import done_covering
    from ..scheduler_core.nights import plan_nights
    from ..scheduler_core.replan import plan_remaining
    from ..scheduler_core.errors import InputError

    cfg = config.scheduler
    executed: tuple[Any, ...] = ()
    if spec is not None:
        executed = read_executed(spec, start if start is not None else skymap.event_time)
        if start is None:
            if not executed:
                raise InputError("--executed holds no exposure: give --start")
            start = max((e.end for e in executed), key=lambda t: t.unix)
            log.info("--start: the end of the last executed exposure, %s", start.isot[:19])
    if start is not None:
        warn_if_far_from_merger(start, skymap.event_time)
    pairs = done_covering(executed, tuple(cfg.filters), fraction, cfg.cadence_s)
    if spec is not None:
        log.info("--executed: %d exposure(s); %d field(s) covered (done in the first two filters), %d with other "
                 "done visits", len(executed), len(pairs.both), len(pairs.one))
    if cfg.nights > 1:
        plans = plan_nights(skymap, cfg, start, executed, min_processed_fraction=fraction, solver=args.solver)
    else:
        plans = (plan_remaining(skymap, cfg, start, executed, min_processed_fraction=fraction, solver=args.solver),)
    args.executed_exposures = executed  # drawn apart in the picture
    if progress is not None:
        progress.done()  # the summaries are printed after the stage lines
    for n, plan in enumerate(plans, 1):
        night = f"night {n} of {len(plans)}, " if len(plans) > 1 else ""
        # a pair's half-done fields are those done in one filter; a sequence's, the covered ones (F3)
        half_done = set(pairs.one) if len(cfg.filters) == 2 else set(pairs.both)
        completed = len({o.field_id for o in plan.observations} & half_done)
        half = f", {completed} of {len(half_done)} half-done fields completed" if n == 1 and spec is not None else ""
        _write_night(args, config, skymap, plan, n, f"{night}{plan.start.isot[:16]}Z to {plan.end.isot[:16]}Z{half}",
                     t0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
