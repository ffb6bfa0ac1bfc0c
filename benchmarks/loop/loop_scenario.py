#!/usr/bin/env python
"""The loop's scenario through the real pipeline, with its documents printed and saved.

    notice -> plan (revisions 1, 2) -> executed file with the plan's first 10 exposures -> the [loop] poll
    (on time: nothing re-planned) -> `trigger SUPEREVENT --closed-until` 2 h after the 10th exposure
    -> the re-plan job -> a new revision from the reopening

MS181101ab's PRELIMINARY notice (tests/data/notices/json), re-dated as if sent
live at 2023-04-15T02:55Z (a good night for its map), planned by
:class:`~mushrooms.daemon.intake.pipeline.NoticePipeline` on a real SQLite state with
the configuration given (default: the built-in one, the daemon's: hybrid at
nside 256; ``--fast``: the tests' greedy at nside 64).  The poll and the
closure use the night's clock (the 10th exposure's end + 60 s), so the run
is the same every time.  Documents go to ``--out`` (default
``benchmarks/results/loop/loop_scenario``); the report to stdout
(``benchmarks/results/loop/loop_scenario.txt`` is the ``--fast`` run,
``loop_scenario_default.txt`` the default one).

    PYTHONPATH=. python benchmarks/loop/loop_scenario.py [--fast] [--config config.toml] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTICE = ROOT / "tests" / "data" / "notices" / "json" / "MS181101ab-preliminary.json"
SENT = "2023-04-15T02:55:00Z"
RECEIVED = datetime(2023, 4, 15, 2, 55, 30, tzinfo=timezone.utc)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", help="config.toml (default: the built-in configuration)")
    ap.add_argument("--fast", action="store_true", help="greedy at nside 64, 600 s steps (the tests' configuration)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "loop" / "loop_scenario"))
    ap.add_argument("--closure-h", type=float, default=2.0, help="hours closed after the 10th exposure")
    args = ap.parse_args(argv)

    from astropy.time import Time, TimeDelta

    from mushrooms.daemon.loop.poll import ExecutedLoop
    from mushrooms.daemon.intake.pipeline import NoticePipeline
    from mushrooms.daemon.sinks import MemorySink
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.intake.trigger import closure_payload
    from mushrooms.handlers.executed import write_jsonl
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs
    from mushrooms.scheduler_core.plan.schema import validate_document
    from mushrooms.tool.config import load_config

    configure_astropy_offline()
    import logging

    said: list[str] = []  # what the re-planner logged (e.g. a half-done field with no window left)

    class _Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.append(record.getMessage())

    replan_log = logging.getLogger("mushrooms.scheduler_core.replan")
    replan_log.setLevel(logging.INFO)
    replan_log.addHandler(_Keep())
    config = load_config(args.config)
    sched = config.scheduler
    if args.fast:
        sched = dataclasses.replace(sched, solver="greedy", nside=64, time_step_s=600.0)
    policy = dataclasses.replace(config.policy, allow_mock=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    import tempfile

    state = Path(tempfile.mkdtemp(prefix="loop-scenario-")) / "state.sqlite"  # the documents are what is kept
    executed = out / "executed.jsonl"
    loop = dataclasses.replace(config.loop, executed_source=f"file:{executed}")

    def t(iso: str) -> Time:
        return Time(iso.rstrip("Z"), scale="utc")

    def save(name: str, doc: object) -> Path:
        path = out / name
        path.write_text(json.dumps(doc, indent=1) + "\n")
        return path

    def table(doc: dict, limit: int | None = None) -> str:
        rows = [f"    {o['start']}  field {o['field_id']:>4}  {o['filter']}  block {o['block']}"
                for o in doc["observations"][:limit]]
        more = len(doc["observations"]) - len(rows)
        return "\n".join(rows + ([f"    ... {more} more"] if more > 0 else []))

    notice = json.loads(NOTICE.read_bytes())
    notice["time_created"] = notice["event"]["time"] = SENT
    p = NoticePipeline(policy, sched, Store(state), MemorySink(), daemon=config.daemon, loop=loop)
    try:
        t0 = time.perf_counter()
        outcome = p.handle(json.dumps(notice).encode(), "benchmark:notice", RECEIVED)
        plan_s = time.perf_counter() - t0
        plans = p.store.plans("MS181101ab")
        current = plans[-1]["document"]
        for r in plans:
            save(f"plan_r{r['revision']}.json", r["document"])
        print(f"# the loop through the real pipeline (config {config.source}{', --fast' if args.fast else ''};"
              f" [scheduler] solver {sched.solver}, nside {sched.nside}, cadence {sched.cadence_s:g} s)\n")
        print(f"notice: {NOTICE.relative_to(ROOT)} re-dated to {SENT}, received {RECEIVED.isoformat()}")
        print(f"  -> {outcome.decision}: {len(plans)} revision(s) stored in {plan_s:.1f} s; the current plan:")
        print(f"  plan_id {current['plan_id']} revision {current['revision']} final {current['final']} "
              f"window {current['start']} .. {current['end']}")
        print(f"  coverage {current['metrics']['coverage']:.4f}, {current['metrics']['n_fields']} fields, "
              f"{current['metrics']['n_exposures']} exposures; its first 12:")
        print(table(current, 12))

        obs = current["observations"]
        ten = [ExecutedExposure(int(o["field_id"]), o["filter"], t(o["start"]), float(o["exposure_s"]), 1.0,
                                "processed") for o in obs[:10]]
        write_jsonl(ten, executed)
        print(f"\nexecuted file {executed.name} (the first 10 exposures, as ZTF would report them):")
        print("".join(f"    {line}\n" for line in executed.read_text().splitlines()), end="")
        now = t(obs[9]["end"]) + TimeDelta(60.0, format="sec")
        poll = ExecutedLoop(loop, p).poll(now)
        print(f"\n[loop] poll at {now.isot}Z: read {poll.read}, stored {poll.stored}, re-plans {len(poll.jobs)}")
        again = ExecutedLoop(loop, p).poll(now)
        print(f"the same file again: stored {again.stored}")

        reopening = t(obs[9]["end"]) + TimeDelta(args.closure_h * 3600.0, format="sec")
        payload = json.loads(closure_payload("MS181101ab", reopening.isot + "Z"))
        save("closure_trigger.json", payload)
        print(f"\nmushrooms trigger MS181101ab --closed-until {reopening.isot}Z  (trigger file kind 'closure': "
              f"{json.dumps(payload)})")
        acc = p.replan_closure("MS181101ab", payload["closed_until"], "benchmark:closure", now=now.to_datetime())
        print(f"  -> {acc.action}: {acc.reason} (job {acc.job_id})")
        t0 = time.perf_counter()
        done = p.run_job(acc.job)
        replan_s = time.perf_counter() - t0
        new = p.store.plans("MS181101ab")[-1]["document"]
        save(f"plan_r{new['revision']}.json", new)
        save("decisions.json", [{k: d[k] for k in ("decision", "reason", "origin", "job_id")}
                                for d in p.store.decisions()])
        print(f"  -> {done.decision}: plan_id {done.plan_id} revision {new['revision']} supersedes {new['supersedes']}"
              f" in {replan_s:.1f} s")
        print(f"  window {new['start']} .. {new['end']}; adds coverage {new['metrics']['coverage']:.4f} "
              f"(executed pairs hold {new['metrics'].get('coverage_executed', 0):.4f}); "
              f"{new['metrics']['n_fields']} fields, {new['metrics']['n_exposures']} exposures; its first 12:")
        print(table(new, 12))
        for line in said:
            print(f"  plan_remaining: {line}")

        validate_document(new)
        pairs = done_pairs(ten, tuple(sched.filters), cadence_s=sched.cadence_s)
        first_start = min(t(o["start"]).unix for o in new["observations"])
        repeats = [o for o in new["observations"] if o["field_id"] in pairs.both]
        print("\nchecks:")
        print(f"  starts after the closure: first exposure {new['observations'][0]['start']} >= reopening "
              f"{reopening.isot}Z: {first_start >= reopening.unix - 1e-3}")
        print(f"  fields done in both filters (E3, cadence {sched.cadence_s:g} s): {sorted(pairs.both)}; exposures "
              f"of them in the new revision: {len(repeats)}")
        ok = first_start >= reopening.unix - 1e-3 and not repeats
        for field_id, visits in sorted(pairs.one.items()):
            done_filter = visits.filters[0]
            other = [o for o in new["observations"] if o["field_id"] == field_id and o["filter"] != done_filter]
            again_done = [o for o in new["observations"] if o["field_id"] == field_id and o["filter"] == done_filter]
            gap = (min(t(o["start"]).unix for o in other) - visits.earliest.unix) if other else None
            windows = _windows_left(field_id, reopening, t(new["end"]), sched)
            # the other filter is due when it fits a window after the reopening (P2-P3: inside its window)
            ok = ok and not again_done and (gap >= sched.cadence_s if other else not windows)
            print(f"  half-done field {field_id}: {done_filter} at {visits.earliest.isot}Z; its other filter at "
                  f"{other[0]['start'] if other else '-'} ({'-' if gap is None else f'{gap / 60:.1f} min'} later, "
                  f">= {sched.cadence_s / 60:g} min: {gap is not None and gap >= sched.cadence_s}); "
                  f"{done_filter} repeated: {bool(again_done)}")
            if not other:
                print(f"    its observability windows from the reopening to the plan's end: "
                      f"{', '.join(f'{a} .. {b}' for a, b in windows) or 'none'}")
        print(f"  the document validates against the plan schema: True\n  all: {bool(ok)}")
        print(f"\ndocuments: {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}/"
              f"{{plan_r*.json, executed.jsonl, closure_trigger.json, decisions.json}}")
        return 0 if ok else 1
    finally:
        p.store.close()


def _windows_left(field_id: int, start, end, sched) -> list[tuple[str, str]]:
    """A field's observability windows between two times (ISO UTC), with the plan's constraints."""
    import dataclasses as dc

    import numpy as np
    from astropy.time import TimeDelta

    from mushrooms.scheduler_core.sky.fields import load_ztf_fields
    from mushrooms.scheduler_core.sky.visibility import observability_windows

    grid = load_ztf_fields()
    sel = grid.ids == field_id
    hours = max(1.0, float((end - start).to_value("s")) / 3600.0)
    w = observability_windows(grid.ids[sel], grid.ra[sel], grid.dec[sel], start, dc.replace(sched, horizon_h=hours))
    return [((start + TimeDelta(a, format="sec")).isot[:19] + "Z", (start + TimeDelta(b, format="sec")).isot[:19] + "Z")
            for a, b in w.for_field(field_id)]


if __name__ == "__main__":
    sys.exit(main())
