"""Tables of a g-r-g plan (or re-plan) as planned, as queued and as ZTF's scheduler model runs it.

    python benchmarks/execution/filter_sequences.py plan PLAN.json MAP QUEUE.json EXECUTED_OUT.jsonl
    python benchmarks/execution/filter_sequences.py replan REPLAN.json MAP QUEUE.json EXECUTED.jsonl

``plan`` also writes EXECUTED_OUT.jsonl: the g and r visits of the plan's first block, as if the
telescope stopped before their third visit.  Used by ``benchmarks/execution/filter_sequences.sh``.
"""

from __future__ import annotations

import json
import sys

from mushrooms.scheduler_core import Plan, PlanningConfig, read_skymap
from mushrooms.scheduler_core.executed import ExecutedExposure, from_record, to_record
from mushrooms.scheduler_core.sequences import covered_fields
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues


def _hm(plan: Plan, seconds: float) -> str:
    return plan.absolute_time(seconds).utc.isot[11:16]


def _visits(plan: Plan) -> dict[int, list]:
    out: dict[int, list] = {}
    for o in plan.observations:
        out.setdefault(o.field_id, []).append(o)
    return out


def _queues(plan: Plan, queues: list[dict]) -> None:
    from astropy.time import Time

    print(f"queues: {len(queues)} (one per filter pass)")
    print("  queue                      window (UTC)   filter  targets")
    for q in queues:
        w = Time(q["validity_window_mjd"], format="mjd").utc.isot
        bands = "".join(sorted({ {1: "g", 2: "r", 3: "i"}[t["filter_id"]] for t in q["targets"]}))
        print(f"  {q['queue_name']:<26} {w[0][11:16]}-{w[1][11:16]}    {bands:^6}  {len(q['targets'])}")


def _executor(plan: Plan, queues: list[dict], prob, config: PlanningConfig) -> list[ExecutedExposure]:
    """Run the queues in the telescope model; credit on ``prob`` (a re-plan's: outside the done fields)."""
    fp = field_footprints(load_ztf_fields(), config.nside)
    done = execute_plan_queues(plan, queues)
    credited = covered_fields(done, config.filters, cadence_s=config.cadence_s)
    runs: dict[int, list[str]] = {}
    for e in done:
        runs.setdefault(e.field_id, []).append(f"{e.filter} {e.start.utc.isot[11:16]}")
    full = sum(1 for v in runs.values() if len(v) == len(config.filters))
    print(f"executor model (clear night, from the first observation): {len(done)} exposures, {len(runs)} fields, "
          f"{full} with the whole sequence, {len(credited)} credited (F1)")
    as_executed = cadence_coverage(done, fp, prob, tuple(config.filters), config.cadence_s)
    print(f"coverage planned {plan.metrics.coverage:.4f}, coverage_as_executed {plan.metrics.coverage_as_executed} "
          f"(recomputed from the run: {as_executed:.4f})")
    return list(done)


def plan_tables(path: str, map_path: str, queue_path: str, executed_out: str) -> None:
    doc = json.load(open(path))
    plan, config = Plan.from_document(doc), PlanningConfig.from_mapping(doc["config"])
    skymap = read_skymap(map_path, nside=config.nside)
    m = plan.metrics
    print(f"\n== g-r-g plan {plan.plan_id}: {m.n_fields} fields, {m.n_exposures} exposures of "
          f"{config.exposure_s:g} s, filters {'-'.join(config.filters)}, cadence {config.cadence_s:g} s, solver "
          f"{m.solver} ({m.status}); coverage {m.coverage:.4f}, upper bound {m.upper_bound}")
    print("  field  block  visits (filter UTC, minutes since the previous visit)")
    for fid, vs in _visits(plan).items():
        cells, prev = [], None
        for o in vs:
            gap = "" if prev is None else f" +{(o.start - prev) / 60:.1f}"
            cells.append(f"{o.filter} {_hm(plan, o.start)}{gap}")
            prev = o.start
        print(f"  {fid:>5}  {vs[0].block:>5}  " + ", ".join(cells))
    _queues(plan, json.load(open(queue_path)))
    _executor(plan, json.load(open(queue_path)), skymap.prob, config)
    first_r = min(o.start for o in plan.observations if o.block == 0 and o.filter == config.filters[1])
    half = [o for o in plan.observations if o.block == 0 and not (o.filter == config.filters[0] and o.start > first_r)]
    with open(executed_out, "w") as f:
        for o in half:
            e = ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s, 1.0, "processed")
            f.write(json.dumps(to_record(e)) + "\n")
    print(f"executed record for the re-plan: the g and r visits of block 0's {len({o.field_id for o in half})} "
          f"fields ({len(half)} exposures) -> {executed_out}")


def replan_tables(path: str, map_path: str, queue_path: str, executed_path: str) -> None:
    doc = json.load(open(path))
    plan, config = Plan.from_document(doc), PlanningConfig.from_mapping(doc["config"])
    skymap = read_skymap(map_path, nside=config.nside)
    executed = [from_record(json.loads(line)) for line in open(executed_path) if line.strip()]
    m = plan.metrics
    print(f"\n== re-plan {plan.plan_id} from {plan.start.utc.isot[:19]}Z: {m.n_fields} fields, {m.n_exposures} "
          f"exposures; adds {m.coverage:.4f} to the {m.coverage_executed:.4f} done")
    visits = _visits(plan)
    print("  half-done field  done (UTC)          re-planned (UTC, minutes after its r)")
    for fid in sorted({e.field_id for e in executed}):
        done = sorted((e for e in executed if e.field_id == fid), key=lambda e: e.start.unix)
        r = [e for e in done if e.filter == config.filters[1]][-1]
        mine = visits.get(fid, [])
        cells = ", ".join(f"{o.filter} {_hm(plan, o.start)} +{(plan.absolute_time(o.start) - r.start).to_value('s') / 60:.1f}"
                          for o in mine) or "nothing"
        print(f"  {fid:>15}  {', '.join(f'{e.filter} {e.start.utc.isot[11:16]}' for e in done):<18}  {cells}")
    others = set(visits) - {e.field_id for e in executed}
    print(f"  other fields: {len(others)}, each in {'-'.join(config.filters)}: "
          f"{all([o.filter for o in visits[f]] == list(config.filters) for f in others)}")
    _queues(plan, json.load(open(queue_path)))
    fp = field_footprints(load_ztf_fields(), config.nside)
    remaining = skymap.prob.copy()
    remaining[fp.union(sorted(covered_fields(executed, config.filters, cadence_s=config.cadence_s)))] = 0.0
    _executor(plan, json.load(open(queue_path)), remaining, config)


if __name__ == "__main__":
    mode, *rest = sys.argv[1:]
    {"plan": plan_tables, "replan": replan_tables}[mode](*rest)
