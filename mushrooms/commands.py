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


def check_output_path(path: str | Path, what: str) -> Path:
    """Refuse, before any work, an output file that could not be written.

    The directory must exist (it is not created silently) and accept a new
    file; the path must not be a directory.

    Raises
    ------
    InputError
        One line naming the option and the reason.
    """
    from .scheduler_core.errors import InputError

    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if p.is_dir():
        raise InputError(f"{what} {path}: is a directory")
    if not parent.is_dir():
        raise InputError(f"{what} {path}: directory {parent} does not exist")
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{p.name}.", suffix=".probe")
    except OSError as exc:
        raise InputError(f"{what} {path}: cannot write in {parent}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)
    return p


#: A start this far (days) from the merger is reported: the kilonova is then faint or not yet there.
FAR_FROM_MERGER_DAYS = 3.0


def parse_start(text: str) -> Any:
    """``--start``: ISO-8601 (``Z``, ``+hh:mm`` offsets; no offset means UTC) or an MJD number.

    Raises
    ------
    InputError
        When it is neither.
    """
    from datetime import datetime, timezone

    from astropy.time import Time

    from .scheduler_core.errors import InputError

    value = text.strip()
    try:
        mjd = float(value)
    except ValueError:
        pass
    else:
        if not 0.0 < mjd < 200000.0:
            raise InputError(f"--start {text}: an MJD must be a positive day number (e.g. 60000.5)")
        return Time(mjd, format="mjd", scale="utc")
    try:
        t = datetime.fromisoformat(value[:-1] + "+00:00" if value[-1:] in "Zz" else value)
    except ValueError:
        raise InputError(f"--start {text!r}: not an ISO-8601 time (2026-05-01T03:00:00Z, "
                         "2026-05-01T05:00:00+02:00) nor an MJD (61161.125)") from None
    t = t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)
    return Time(t.replace(tzinfo=None), scale="utc")


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


def plan_main(args: argparse.Namespace) -> int:
    """Plan a sky map, check the plan, write it (and optionally a queue, a SkyPortal payload and a picture).

    When the plan covers less than ``min_coverage`` the document written is
    a ``not_observable`` answer; no queue nor SkyPortal file is written.
    """
    from .scheduler_core import make_plan, not_observable, read_skymap, to_skyportal, to_trigger_queue

    configure_astropy_offline()
    t0 = time.perf_counter()
    config = load_config(args.config)
    cfg = config.scheduler
    outputs = {"-o/--output": args.output, "--queue": args.queue, "--skyportal": getattr(args, "skyportal", None),
               "--plot": args.plot}
    for what, path in outputs.items():  # before any work
        if path:
            check_output_path(path, what)
    if getattr(args, "skyportal", None) and config.export.skyportal_allocation_id is None:
        from .scheduler_core.errors import InputError

        raise InputError("--skyportal needs [export] skyportal_allocation_id in the config "
                         "(the SkyPortal allocation of ZTF)")
    start = parse_start(args.start) if args.start else None
    source = args.skymap or demo_skymap_path()
    if not args.skymap:
        log.info("no sky map given: planning the bundled demo map (mock BNS MS181101ab)")
    skymap = read_skymap(source, nside=cfg.nside)
    log.info("read %s: nside %d, 90%% area %.0f deg2, event time %s", source, skymap.nside,
             skymap.credible_area(0.9), skymap.event_time.isot if skymap.event_time else "unknown")
    if start is not None:
        warn_if_far_from_merger(start, skymap.event_time)
    deadline = getattr(args, "deadline", None)
    if deadline is None:
        from .scheduler_core.anytime import revision_document

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
            from .plotting import plot_plan

            plot_plan(plan, skymap, args.plot, answer=answer)
        return 0
    write_json_atomic(args.output, doc)
    if args.queue:
        write_json_atomic(args.queue, to_trigger_queue(plan, config.export))
    if getattr(args, "skyportal", None):
        write_json_atomic(args.skyportal, to_skyportal(plan, config.export))
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
    from .scheduler_core.anytime import anytime_plans, is_better, revision_document
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
        if best is None or is_better(plan, best, 0.0, cfg.objective, cfg.detection_max_coverage_loss):
            best, revision = plan, revision + 1
            log.info("--deadline: %s plan covers %.4f at %.1f s", plan.metrics.solver, plan.metrics.coverage,
                     time.perf_counter() - t0)
    assert best is not None
    return best, revision_document(best, revision, True)


def check_main(args: argparse.Namespace) -> int:
    """Check a plan document against a sky map; exit 1 when it fails.

    The plan's embedded ``config`` is used unless ``--config`` is given.
    """
    from .scheduler_core import Plan, PlanningConfig, check_plan, read_skymap
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
    if doc.get("type") == "not_observable":
        print(f"{args.plan}: a not_observable answer, no plan to check: {'; '.join(doc.get('reasons', []))}")
        return 0
    try:
        plan = Plan.from_document(doc)
    except ValueError as exc:
        raise InputError(f"{args.plan}: {exc}") from None
    planning = config.scheduler
    if isinstance(doc.get("config"), dict) and not getattr(args, "config_explicit", False):
        try:
            planning = PlanningConfig.from_mapping(doc["config"])
        except (TypeError, ValueError) as exc:
            raise InputError(f"{args.plan}: embedded config: {exc}") from None
        log.info("checking with the plan's embedded configuration (give --config to override)")
    elif isinstance(doc.get("config"), dict):
        log.info("checking with %s, not the plan's embedded configuration", args.config)
    skymap = read_skymap(args.skymap, nside=planning.nside)
    report = check_plan(plan, skymap, planning)
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
    replay_args = argparse.Namespace(
        notices=[str(notice)], allow_mock=True, solver=args.solver, out=str(out / "outbox"),
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
