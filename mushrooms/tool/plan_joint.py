"""``mushrooms plan MAP --telescopes ztf,ls4``: several telescopes planned together (issue 53 item 2).

The telescopes named (``--telescopes`` or ``[scheduler] telescopes``, two or
more) are planned together on the map (``docs/design/telescopes.md``,
section 5: J1-J8, :func:`~..scheduler_core.joint_plans.make_joint_plans`):
each telescope's part is its own plan document, written where a telescope
planned alone goes (the first into ``-o FILE``, each other beside it as
``FILE.<name>.json``, with its summaries, picture and target list), and the
whole is the ``joint_plan`` document ``FILE.joint.json``
(``docs/design/plan-format.md``): the observations of every telescope, each
naming its telescope, the union, each telescope's share and the certified
bound.  ``mushrooms check FILE.joint.json MAP`` checks every part and the
joint metrics.

What a joint plan does not take in this version: ``--executed`` (a re-plan),
``--deadline``, ``[scheduler] nights`` above 1.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Callable

__all__ = ["plan_joint", "joint_path"]


def joint_path(output: str) -> str:
    """``plan.json`` -> ``plan.joint.json``: where the joint document goes."""
    p = Path(output)
    return str(p.with_name(f"{p.stem}.joint{p.suffix or '.json'}"))


def _refuse(args: argparse.Namespace, configs: list[Any]) -> None:
    """One line for what a joint plan does not take, before any work."""
    from ..scheduler_core.errors import InputError

    for option in ("executed", "deadline"):
        if getattr(args, option, None) is not None:
            raise InputError(f"--{option} is not taken by a joint plan of several telescopes in this version")
    if any(c.scheduler.nights > 1 for c in configs):
        raise InputError("a joint plan of several telescopes plans one night: [scheduler] nights must be 1")
    if len({c.scheduler.nside for c in configs}) > 1:
        raise InputError("the telescopes of a joint plan share one working resolution: set [scheduler] nside")


def plan_joint(args: argparse.Namespace, config: Any, names: tuple[str, ...], start: Any,
               write_part: Callable[[argparse.Namespace, Any, Any], int]) -> int:
    """Plan ``names`` together, write each part with ``write_part(args, config, plan)`` and the joint document.

    ``start``: the horizon start (``--start``, parsed), None for the sky map's event time.

    Returns the worst status of the parts' writes.
    """
    from ..inputs import regular_file
    from ..outputs import write_json_atomic
    from ..scheduler_core import read_skymap
    from ..scheduler_core.clock import on_merger_clock
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.joint_plans import joint_document, make_joint_plans
    from ..scheduler_core.prepare import prepare_problem
    from .plan_telescopes import telescope_configs, telescope_path

    runs = telescope_configs(args, config, names)  # every description and option checked before any work
    _refuse(args, [each for _, each in runs])
    first = runs[0][1].scheduler
    skymap, _ = on_merger_clock(read_skymap(regular_file(args.skymap, "sky map"), nside=first.nside), None)
    start = start if start is not None else skymap.event_time
    if start is None:
        raise InputError("the sky map has no event time (DATE-OBS); give --start")
    problems = [prepare_problem(skymap, each.scheduler, start, telescope=telescope) for telescope, each in runs]
    greedy = (args.solver or first.solver) == "greedy"
    plans, result = make_joint_plans(skymap, problems, [t.name for t, _ in runs], greedy=greedy)
    status = 0
    for k, ((telescope, each), plan) in enumerate(zip(runs, plans)):
        files = {key: telescope_path(getattr(args, key, None), k == 0, telescope.name)
                 for key in ("output", "queue", "skyportal", "plot", "targets")}
        status = max(status, write_part(argparse.Namespace(**{**vars(args), **files, "start": start.isot + "Z"}),
                                        each, plan))
    path = joint_path(args.output)
    write_json_atomic(path, joint_document(plans, result))
    m, b = result.metrics, result.bound
    shares = ", ".join(f"{n} {s:.4f}" for n, s in zip(result.names, m.share))
    print(f"{path}: joint plan of {', '.join(result.names)} ({result.method}): union {m.union:.4f} "
          f"(shares {shares}; covered twice or more {m.more_than_once:.4f}), certified bound {b.value:.4f}")
    return status
