"""``mushrooms check PLAN_JSON SKYMAP``: the independent plan checker on a plan document."""

from __future__ import annotations

import argparse
import sys
import logging
from typing import Sequence

from .common import add_common_options, execute, read_json_object, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

log = logging.getLogger("mushrooms.plan")

HELP = "check a plan document against a sky map"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms check`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("check", HELP)
    p.add_argument("plan", metavar="PLAN_JSON")
    p.add_argument("skymap", metavar="SKYMAP")
    p.add_argument("--executed", metavar="FILE",
                   help="a re-plan's executed record (as given to `mushrooms plan --executed`): its exposures "
                        "count towards the pairs, its done pairs must not be planned again")
    p.add_argument("--min-processed-fraction", metavar="F", type=float, default=0.5,
                   help="with --executed: least fraction of the quadrants reduced for an exposure to count (default 0.5)")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms check`` on its own."""
    return execute("check", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Check a plan document against a sky map; exit 1 when it fails.

    The plan's embedded ``config`` is used unless ``--config`` is given.
    """
    from .config import load_config
    from ..inputs import regular_file
    from ..offline import configure_astropy_offline

    configure_astropy_offline()
    config = load_config(args.config)
    doc = read_json_object(args.plan)
    map_path = regular_file(args.skymap, "sky map")  # checked before any work
    if doc.get("type") == "joint_plan":  # (issue 53 item 2) every telescope's part, then the joint metrics
        from .check_joint import check_joint

        return check_joint(args, doc, map_path, lambda part, label: _check_one(args, config, part, map_path, label))
    return _check_one(args, config, doc, map_path, args.plan)


def _check_one(args: argparse.Namespace, config, doc: dict, map_path, label: str) -> int:
    """Check one plan document (``label`` names it in the lines printed); 0 when it passes, else 1."""
    from ..scheduler_core import Plan, PlanningConfig, check_plan, read_skymap
    from ..scheduler_core.errors import InputError

    if doc.get("type") == "not_observable":
        print(f"{label}: a not_observable answer, no plan to check: {'; '.join(doc.get('reasons', []))}")
        return 0
    try:
        plan = Plan.from_document(doc)
    except ValueError as exc:
        raise InputError(f"{label}: {exc}") from None
    planning = config.scheduler
    if isinstance(doc.get("config"), dict) and not getattr(args, "config_explicit", False):
        try:
            planning = PlanningConfig.from_mapping(doc["config"])
        except (TypeError, ValueError) as exc:
            raise InputError(f"{label}: embedded config: {exc}") from None
        log.info("checking with the plan's embedded configuration (give --config to override)")
    elif isinstance(doc.get("config"), dict):
        log.info("checking with %s, not the plan's embedded configuration", args.config)
    skymap = read_skymap(map_path, nside=planning.nside)
    executed = ()
    if getattr(args, "executed", None):
        from .plan import read_executed

        from ..scheduler_core.instruments.active import description_of

        executed = read_executed(args.executed, plan.start, tuple(description_of(planning).filters))
    if plan.metrics.coverage_executed and not executed:
        log.warning("%s is a re-plan (metrics.coverage_executed is set): give its --executed record", label)
    report = check_plan(plan, skymap, planning, executed=executed,
                        min_processed_fraction=getattr(args, "min_processed_fraction", 0.5))
    recorded = plan.event.skymap_sha256
    other_map = [] if not recorded or recorded == skymap.sha256 else [
        f"the plan was made for another sky map: sha256 {recorded[:16]}... recorded, {args.skymap} is "
        f"{skymap.sha256[:16]}...; its coverage is not this map's"]
    if report.ok and not other_map:
        print(f"{label}: OK: {len(plan.observations)} exposures, coverage {report.coverage:.4f} "
              f"(reported {report.reported_coverage})")
        return 0
    problems = other_map + list(report.problems)
    print(f"{label}: FAILED with {len(other_map) + sum(report.counts.values())} problem(s):")
    for line in problems:
        print(f"  {line}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
