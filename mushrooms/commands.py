"""``mushrooms plan`` and ``mushrooms check``."""

from __future__ import annotations

import argparse
import json
import logging
import os
import tempfile
import time
from importlib import resources
from pathlib import Path
from typing import Any

from .config import load_config

log = logging.getLogger("mushrooms.plan")

#: The bundled demo sky map (mock BNS MS181101ab, LVK user guide example).
DEMO_SKYMAP = "data/MS181101ab_bayestar.multiorder.fits"


def configure_astropy_offline() -> None:
    """Never let astropy try to download Earth-orientation tables (no network)."""
    from astropy.utils import iers

    iers.conf.auto_download = False
    iers.conf.auto_max_age = None


def write_json_atomic(path: str | Path, obj: Any) -> None:
    """Write JSON so that readers see the old file or the whole new one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(obj, fh, indent=1)
            fh.write("\n")
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def demo_skymap_path() -> str:
    """Path of the bundled demo sky map."""
    return str(resources.files("mushrooms.scheduler_core").joinpath(DEMO_SKYMAP))


def plan_main(args: argparse.Namespace) -> int:
    """Plan a sky map, check the plan, write it (and optionally a queue and a picture)."""
    from .scheduler_core import make_plan, read_skymap, to_trigger_queue
    from .scheduler_core.errors import InputError
    from .scheduler_core.plan import parse_time

    configure_astropy_offline()
    t0 = time.perf_counter()
    config = load_config(args.config)
    cfg = config.scheduler
    start = None
    if args.start:
        try:
            start = parse_time(args.start)
        except ValueError as exc:
            raise InputError(f"--start: {exc}") from None
    source = args.skymap or demo_skymap_path()
    if not args.skymap:
        log.info("no sky map given: planning the bundled demo map (mock BNS MS181101ab)")
    skymap = read_skymap(source, nside=cfg.nside)
    log.info("read %s: nside %d, 90%% area %.0f deg2, event time %s", source, skymap.nside,
             skymap.credible_area(0.9), skymap.event_time.isot if skymap.event_time else "unknown")
    deadline = getattr(args, "deadline", None)
    if deadline is None:
        from .scheduler_core.anytime import revision_document

        plan = make_plan(skymap, cfg, start=start, solver=args.solver)
        doc = revision_document(plan, 1, True)
    else:
        plan, doc = _plan_by_deadline(skymap, cfg, start, args.solver or cfg.solver, float(deadline), t0)
    write_json_atomic(args.output, doc)
    if args.queue:
        write_json_atomic(args.queue, to_trigger_queue(plan))
    if args.plot:
        from .plotting import plot_plan

        plot_plan(plan, skymap, args.plot)
    m = plan.metrics
    gap = "" if m.mip_gap is None else f", gap {m.mip_gap:.2%}"
    print(f"{args.output}: {m.n_fields} fields, {m.n_exposures} exposures, coverage {m.coverage:.4f}, "
          f"{m.solver} ({m.status}{gap}), checked, {time.perf_counter() - t0:.1f} s")
    return 0


def _plan_by_deadline(skymap: Any, cfg: Any, start: Any, solver: str, deadline_s: float,
                      t0: float) -> tuple[Any, dict[str, Any]]:
    """The best checked plan found ``deadline_s`` after ``t0`` (anytime: greedy first, then ``solver``)."""
    from .scheduler_core.anytime import anytime_plans, revision_document
    from .scheduler_core.errors import InputError
    from .scheduler_core.prepare import prepare_problem

    if deadline_s <= 0:
        raise InputError(f"--deadline must be > 0 seconds, got {deadline_s:g}")
    if start is None:
        if skymap.event_time is None:
            raise InputError("the sky map has no event time (DATE-OBS); give --start")
        start = skymap.event_time
    problem = prepare_problem(skymap, cfg, start)
    best, revision = None, 0
    for plan in anytime_plans(problem, skymap, solver, should_stop=lambda: time.perf_counter() - t0 > deadline_s):
        if best is None or plan.metrics.coverage > best.metrics.coverage:
            best, revision = plan, revision + 1
            log.info("--deadline: %s plan covers %.4f at %.1f s", plan.metrics.solver, plan.metrics.coverage,
                     time.perf_counter() - t0)
    assert best is not None
    return best, revision_document(best, revision, True)


def check_main(args: argparse.Namespace) -> int:
    """Check a plan document against a sky map; exit 1 when it fails."""
    from .scheduler_core import Plan, check_plan, read_skymap
    from .scheduler_core.errors import InputError

    configure_astropy_offline()
    config = load_config(args.config)
    try:
        doc = json.loads(Path(args.plan).read_text())
    except FileNotFoundError:
        raise InputError(f"plan not found: {args.plan}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read plan {args.plan}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{args.plan} is not JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise InputError(f"{args.plan} is not a plan document (not a JSON object)")
    try:
        plan = Plan.from_document(doc)
    except ValueError as exc:
        raise InputError(f"{args.plan}: {exc}") from None
    skymap = read_skymap(args.skymap, nside=config.scheduler.nside)
    report = check_plan(plan, skymap, config.scheduler)
    if report.ok:
        print(f"{args.plan}: OK: {len(plan.observations)} exposures, coverage {report.coverage:.4f} "
              f"(reported {report.reported_coverage})")
        return 0
    print(f"{args.plan}: FAILED with {sum(report.counts.values())} problem(s):")
    for line in report.problems:
        print(f"  {line}")
    return 1


#: The bundled demo notice (mock BNS MS260605l, PRELIMINARY, H1/L1/V1, ~8 deg2).
DEMO_NOTICE = "data/demo/MS260605l-preliminary.json"


def demo_main(args: argparse.Namespace) -> int:
    """Replay the bundled mock notice through the daemon's own path, then draw the plan.

    Writes the plan document, a picture of it and the SQLite state into
    ``--out``; needs no credentials and no network.
    """
    import base64
    import dataclasses

    from .daemon.replay import main as replay_main
    from .scheduler_core import Plan, read_skymap

    configure_astropy_offline()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    notice = resources.files("mushrooms").joinpath(DEMO_NOTICE)
    load_config(args.config)  # a bad config fails here, in one line
    config_path = args.config
    if args.solver:  # a one-off copy of the config with the chosen solver
        override = out / "demo-config.toml"
        base = Path(args.config).read_text() if args.config else ""
        override.write_text(_with_solver(base, args.solver))
        config_path = str(override)
    replay_args = argparse.Namespace(
        notices=[str(notice)], allow_mock=True, out=str(out / "outbox"),
        state=str(out / "state.sqlite"), config=config_path,
        command="replay", debug=False, log_level="INFO",
    )
    code = replay_main(replay_args)
    plans = sorted((out / "outbox").glob("*.json"))
    docs = [json.loads(p.read_text()) for p in plans]
    docs = [d for d in docs if d.get("type") == "plan"]
    if not docs:
        print(f"demo: no plan was produced (replay exit status {code}); see the log above")
        return 1
    doc = max(docs, key=lambda d: d.get("revision", 1))  # the optimised revision when one was published
    plan = Plan.from_document(doc)
    payload = json.loads(Path(str(notice)).read_text())["event"]["skymap"]
    skymap = read_skymap(base64.b64decode(payload), nside=load_config(config_path).scheduler.nside)
    from .plotting import plot_plan

    picture = out / "plan.png"
    plot_plan(dataclasses.replace(plan), skymap, picture)
    m = plan.metrics
    print(f"demo: plan {plan.plan_id} for {plan.event.superevent_id}: {m.n_fields} fields, "
          f"{m.n_exposures} exposures, coverage {m.coverage:.3f} ({m.solver}, {m.status}); "
          f"plan in {out / 'outbox'}, picture {picture}")
    return 0


def _with_solver(toml_text: str, solver: str) -> str:
    """TOML text with ``[scheduler] solver`` set (added or replaced)."""
    import re

    if re.search(r"(?m)^\[scheduler\]", toml_text):
        if re.search(r"(?ms)^\[scheduler\][^\[]*^solver\s*=", toml_text):
            return re.sub(r'(?ms)(^\[scheduler\][^\[]*?^)solver\s*=\s*"[^"]*"', rf'\1solver = "{solver}"', toml_text)
        return re.sub(r"(?m)^\[scheduler\]\s*$", f'[scheduler]\nsolver = "{solver}"', toml_text, count=1)
    return toml_text + f'\n[scheduler]\nsolver = "{solver}"\n'
