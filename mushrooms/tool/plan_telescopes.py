"""``mushrooms plan --telescopes NAMES``: plan each described telescope alone (issue 53, phase 2).

``--telescopes`` (or ``[scheduler] telescopes``) names shipped telescopes
(``mushrooms telescopes`` lists them) or description files.  Phase 2 plans
each telescope alone, one document each: the first telescope's plan goes to
``-o FILE`` (``plan.json``), each other's beside it as ``plan.<name>.json``
(and its summaries, picture and queue the same way); two or more are now
planned together (:mod:`.plan_joint`, ``docs/design/telescopes.md``
section 5), each part written the same way.  Each telescope's configuration
starts from its description's defaults and every key the ``[scheduler]``
table (or ``--set``) sets wins (``PlanningConfig.for_telescope``).

What stays ZTF's in phase 2: the ToO queue (``--queue``: a telescope whose
``queue`` is not ``ztf_too`` is refused), the SkyPortal payload
(``--skyportal``), the executed record (``--executed``: ZTF's depot and
filters) and ``--deadline``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any, Callable

__all__ = ["wanted_telescopes", "telescope_configs", "telescope_path", "plan_each", "write_targets"]


def wanted_telescopes(args: argparse.Namespace, config: Any) -> tuple[str, ...] | None:
    """The telescopes to plan: ``--telescopes`` (comma-separated), else ``[scheduler] telescopes``.

    None when that is ZTF alone from the configuration: the plan is today's, by today's path.

    Raises
    ------
    InputError
        An unknown name (with the nearest known one), a missing file, a repeat.
    """
    from ..scheduler_core.config_checks import telescope_problems
    from ..scheduler_core.errors import InputError

    given = getattr(args, "telescopes", None)
    if given is None:
        names = tuple(config.scheduler.telescopes)
        return None if names == ("ztf",) else names
    names = tuple(n.strip() for n in str(given).split(",") if n.strip())
    problems = telescope_problems(argparse.Namespace(telescopes=names))
    if problems:
        raise InputError(f"--telescopes {given[:80]}: {'; '.join(problems)}")
    return names


def _scheduler_table(args: argparse.Namespace) -> dict[str, Any]:
    """The ``[scheduler]`` table as written (the config file, then ``--set``): the keys it sets win."""
    from .config import ConfigError, read_config_table

    table: dict[str, Any] = {} if not args.config else read_config_table(args.config)
    sets = getattr(args, "set", None) or ()
    if sets:
        from .settings_flag import apply_sets

        try:
            table = apply_sets(table, sets)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    section = table.get("scheduler", {})
    return dict(section) if isinstance(section, dict) else {}


def telescope_configs(args: argparse.Namespace, config: Any, names: tuple[str, ...]) -> list[tuple[Any, Any]]:
    """(description, whole configuration) per telescope, its ``[scheduler]`` made for it.

    Raises
    ------
    InputError
        A description that cannot be used (every problem, one line each), a
        key out of the telescope's range, an option the telescope lacks.
    """
    from ..scheduler_core.config import PlanningConfig
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.instruments import load_description

    table = _scheduler_table(args)
    out = []
    for name in names:
        telescope = load_description(name)  # DescriptionError: an InputError, one line per problem
        try:
            planning = PlanningConfig.for_telescope(telescope, table)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{telescope.name}: {exc}") from None
        _refuse_ztf_only_options(args, telescope)
        out.append((telescope, dataclasses.replace(config, scheduler=planning)))
    return out


def _refuse_ztf_only_options(args: argparse.Namespace, telescope: Any) -> None:
    """One line for an option phase 2 has for ZTF only, asked of another telescope."""
    from ..scheduler_core.errors import InputError

    if getattr(args, "queue", None) and telescope.queue != "ztf_too":
        raise InputError(f"--queue writes ZTF's ToO queue; {telescope.name}'s queue is {telescope.queue!r} "
                         f"(no ZTF queue export for it): drop --queue or plan ztf alone")
    if telescope.name == "ztf" and telescope.queue == "ztf_too":
        return
    for option in ("skyportal", "executed", "deadline"):
        if getattr(args, option, None) is not None:
            raise InputError(f"--{option} is ZTF's in this version; {telescope.name} is planned without it")


def telescope_path(path: str | None, first: bool, name: str) -> str | None:
    """The first telescope's file as given; another's beside it, ``plan.json`` -> ``plan.<name>.json``."""
    if path is None or first:
        return path
    p = Path(path)
    return str(p.with_name(f"{p.stem}.{name}{p.suffix}"))


def plan_each(args: argparse.Namespace, config: Any, names: tuple[str, ...],
              plan_one: Callable[[argparse.Namespace, Any], int]) -> int:
    """Plan every telescope alone, each with ``plan_one(args, config)`` on its own files; the worst status."""
    runs = telescope_configs(args, config, names)  # every description and option checked before any work
    status = 0
    for k, (telescope, each) in enumerate(runs):
        files = {key: telescope_path(getattr(args, key, None), k == 0, telescope.name)
                 for key in ("output", "queue", "skyportal", "plot", "targets")}
        status = max(status, plan_one(argparse.Namespace(**{**vars(args), **files}), each))
    return status


def write_targets(path: str | None, plan: Any) -> None:
    """``--targets FILE``: the target list as JSON into FILE, as CSV into FILE's ``.csv`` beside it."""
    if not path:
        return
    from pathlib import Path

    from ..outputs import write_bytes_atomic, write_json_atomic
    from ..scheduler_core.plan.target_list import target_list_csv, target_list_document

    write_json_atomic(path, target_list_document(plan, plan.config.get("telescopes", ["ztf"])[0]))
    write_bytes_atomic(str(Path(path).with_suffix(".csv")), target_list_csv(plan).encode())
