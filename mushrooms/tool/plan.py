"""``mushrooms plan SKYMAP``: plan a ZTF night from a sky map, check it, write it.

Optionally also ZTF's ToO queue, SkyPortal's manual observation-plan payload
and a picture; ``--deadline`` writes the best plan found by then.
"""

from __future__ import annotations

import argparse
import sys
import logging
import math
import time
from typing import Any, Sequence

from .common import SOLVER_CHOICES, SOLVER_HELP, SOLVER_METAVAR, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "parse_start", "warn_if_far_from_merger"]

log = logging.getLogger("mushrooms.plan")

HELP = "plan a ZTF night from a sky map"

#: A start this far (days) from the merger is reported: the kilonova is then faint or not yet there.
FAR_FROM_MERGER_DAYS = 3.0


def parse_start(text: str) -> Any:
    """``--start``: :func:`~mushrooms.scheduler_core.times.parse_time` with MJD allowed.

    Raises
    ------
    InputError
        When it is not a time (an empty string included).
    """
    from ..scheduler_core.times import parse_time

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
                   help="horizon start: ISO-8601 (Z or +hh:mm offset; no offset means UTC) or MJD "
                        "(default: the sky map's event time)")
    p.add_argument("--solver", choices=SOLVER_CHOICES, metavar=SOLVER_METAVAR, help=SOLVER_HELP)
    p.add_argument("-o", "--output", metavar="FILE", default="plan.json", help="plan document to write (default plan.json)")
    p.add_argument("--deadline", metavar="SECONDS", type=float,
                   help="write the best plan found by then: the greedy plan at once, the optimised one if it is "
                        "ready and covers more (default: wait for the solver)")
    p.add_argument("--queue", metavar="FILE", help="also write ZTF's ToO trigger queue (program fields from [export])")
    p.add_argument("--skyportal", metavar="FILE",
                   help="also write the body of SkyPortal's POST /api/observation_plan/manual")
    p.add_argument("--plot", metavar="FILE", help="also draw the plan on the sky map (PNG)")
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
    from .config import load_config
    from ..inputs import regular_file
    from ..offline import configure_astropy_offline
    from ..outputs import check_outputs, write_json_atomic
    from ..scheduler_core.errors import InputError
    from ..scheduler_core import make_plan, not_observable, read_skymap, to_skyportal, to_trigger_queue

    configure_astropy_offline()
    t0 = time.perf_counter()
    config = load_config(args.config)
    cfg = config.scheduler
    if not args.skymap:
        raise InputError("no sky map given: name a FITS sky map (`mushrooms demo` plans the bundled demo map)")
    outputs = {"-o/--output": args.output, "--queue": args.queue, "--skyportal": getattr(args, "skyportal", None),
               "--plot": args.plot}
    check_outputs(outputs, inputs=[args.skymap, args.config])  # before any work; never onto an input
    if getattr(args, "skyportal", None) and config.export.skyportal_allocation_id is None:
        raise InputError("--skyportal needs [export] skyportal_allocation_id in the config "
                         "(the SkyPortal allocation of ZTF)")
    start = parse_start(args.start) if args.start is not None else None
    deadline = getattr(args, "deadline", None)
    if deadline is not None and not (math.isfinite(deadline) and deadline > 0):
        raise InputError(f"--deadline {deadline:g}: must be a finite number of seconds > 0")
    source = regular_file(args.skymap, "sky map")  # never a FIFO nor a device
    skymap = read_skymap(source, nside=cfg.nside)
    log.info("read %s: nside %d, 90%% area %.0f deg2, event time %s", source, skymap.nside,
             skymap.credible_area(0.9), skymap.event_time.isot if skymap.event_time else "unknown")
    if start is not None:
        warn_if_far_from_merger(start, skymap.event_time)
    if deadline is None:
        from ..scheduler_core.plan.messages import revision_document

        plan = make_plan(skymap, cfg, start=start, solver=args.solver)
        doc = revision_document(plan, 1, True)
    else:
        plan, doc = _plan_by_deadline(skymap, cfg, start, args.solver or cfg.solver, float(deadline), t0)
    answer = not_observable(plan, skymap, cfg)
    if answer is not None:
        write_json_atomic(args.output, answer.to_document())
        print(f"{args.output}: NOT OBSERVABLE: best coverage {plan.metrics.coverage:.4f} < min_coverage "
              f"{cfg.min_coverage:g}, {time.perf_counter() - t0:.1f} s")
        for line in answer.sentences:
            print(f"  {line}")
        for what in ("--queue", "--skyportal"):
            if outputs[what]:
                print(f"{outputs[what]}: not written ({what}): nothing to observe")
        if args.plot:
            from ..plotting import plot_plan

            plot_plan(plan, skymap, args.plot, answer=answer)
        return 0
    write_json_atomic(args.output, doc)
    if args.queue:
        write_json_atomic(args.queue, to_trigger_queue(plan, config.export))
    if getattr(args, "skyportal", None):
        write_json_atomic(args.skyportal, to_skyportal(plan, config.export))
    if args.plot:
        from ..plotting import plot_plan

        plot_plan(plan, skymap, args.plot)
    m = plan.metrics
    gap = "" if m.mip_gap is None else f", gap {m.mip_gap:.2%}"
    print(f"{args.output}: {m.n_fields} fields, {m.n_exposures} exposures, coverage {m.coverage:.4f}, "
          f"{m.solver} ({m.status}{gap}), checked, {time.perf_counter() - t0:.1f} s")
    return 0


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




if __name__ == "__main__":
    sys.exit(main())
