"""Split the distance to the bound into bound slack and optimiser loss, on reduced instances.

Usage::

    python benchmarks/quality/exact_split.py [--k 20] [--k-hard 30] [--exact-limit 30] [--plan-limit 10]
                                     [-o split.csv] [MAP ...]

For each reduced instance (the top ``k`` pairable fields of a shared sky map,
:func:`mushrooms.evaluation.reduced.reduced_problem`; the coverage objective,
``threads = 1``, ``min_gain = 0`` so every plan is scored on its raw coverage)
it runs greedy, the default ``hybrid`` (``time_limit_s = --plan-limit``), the
current certified bound (online U4 as published, and U0 solved), the
interval bound V (V1-V4, ``--interval-limit`` s), and the exact model (:mod:`mushrooms.evaluation.exact`, C0-C6) within
``--exact-limit`` s, started from the greedy and hybrid plans.  Every exact
plan goes through the independent checker.

Printed per instance: optimum (or incumbent and proven bound), hybrid,
greedy, bound, and the split ``bound slack = bound - optimum``,
``optimiser loss = optimum - hybrid``; then the exact plan, the hybrid and
greedy as ZTF's scheduler executes their queues (Q14), and the loss as
executed, ``exec loss = exact plan executed - hybrid executed`` (the exact
plan is optimal as planned, not as executed: it can be negative); then the means over the instances
proven optimal, and the instances not proven with their gap.  Default maps:
the four hardest maps of the block-stage run at ``k`` and ``--k-hard``, and every third map of
``shared/data/skymaps`` (public, simulated BNS, simulated NSBH) at ``k``.
Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SHARED_CANDIDATES = [ROOT.parent / "shared" / "data" / "skymaps", Path("/work/shared/data/skymaps")]
ISSUE_MAPS = ["simulated/bns_o3/2.fits", "simulated/nsbh_o3/allsky_400to799/1.fits",
              "simulated/nsbh_o3/allsky_400to799/8.fits", "simulated/bns_o3/14.fits"]


def shared_root() -> Path:
    """The shared sky-map folder (``../shared/data/skymaps`` beside the repository, else ``/work/shared``)."""
    for p in SHARED_CANDIDATES:
        if p.is_dir():
            return p
    raise SystemExit("no shared sky maps found in " + ", ".join(map(str, SHARED_CANDIDATES)))


def default_instances(k: int, k_hard: int) -> list[tuple[Path, int]]:
    """The issue's four maps at ``k`` and ``k_hard``, and every third shared map at ``k``."""
    from mushrooms.evaluation.bench import find_skymaps

    root = shared_root()
    issue = [root / m for m in ISSUE_MAPS]
    out = [(p, k) for p in issue] + [(p, k_hard) for p in issue]
    for sub in ("public", "simulated/bns_o3", "simulated/nsbh_o3"):
        maps = [p for p in find_skymaps(root / sub) if p not in issue]
        out += [(p, k) for p in maps[::3]]
    return out


def measure(path: Path, k: int, exact_limit: float, plan_limit: float, interval_limit: float,
            refined: bool = False) -> dict:
    """One reduced instance: greedy, hybrid, bounds, the exact optimum and its check."""
    from astropy.time import Time

    from mushrooms.evaluation.exact import solve_exact
    from mushrooms.evaluation.reduced import reduced_problem
    from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import build_plan, run_scheduler
    from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
    from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound
    from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed

    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=plan_limit, milp_backend="highs",
                         min_gain=0.0, min_coverage=0.0)
    sm = read_skymap(path, nside=cfg.nside)
    full = prepare_problem(sm, cfg, Time(sm.event_time, scale="utc"))
    problem = reduced_problem(full, k)

    def cov(result) -> float:
        return problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob)

    greedy = run_scheduler(problem, "greedy")
    hybrid = run_scheduler(problem, "hybrid")
    online = coverage_upper_bound(problem)  # U4: the bound plans published before min(U4, V)
    published = hybrid.upper_bound  # what the hybrid publishes now: min(U4, V) (V5)
    u0 = coverage_upper_bound(problem, method="milp", time_limit_s=30.0)
    interval = interval_upper_bound(problem, time_limit_s=interval_limit)
    t = time.perf_counter()
    ex = solve_exact(problem, time_limit_s=exact_limit, threads=1,
                     starts=(greedy.observations, hybrid.observations))
    exact_s = time.perf_counter() - t
    plan = build_plan(problem, ex.result, sm, "hybrid")
    report = check_plan(plan, sm, cfg)
    opt = cov(ex.result)
    executed = {name: keyed_coverage_as_executed(problem, r)[1]
                for name, r in (("greedy", greedy), ("hybrid", hybrid), ("optimum", ex.result))}
    proven_bound = ex.bound if ex.bound is not None else opt
    extra = {}
    if refined:  # the exact optimum on windows with refined ends (evaluation/true_windows.py)
        from mushrooms.evaluation.true_windows import refined_problem

        for mode in ("inner", "outer"):
            q = refined_problem(problem, mode)
            exq = solve_exact(q, time_limit_s=exact_limit, threads=1, starts=(ex.result.observations,))
            v = q.footprints.coverage({o.field_id for o in exq.result.observations}, q.prob)
            extra[f"optimum_{mode}"] = v
            extra[f"status_{mode}"] = exq.result.status
            extra[f"bound_{mode}"] = exq.bound if exq.bound is not None else v
    return extra | {
        "map": str(path.relative_to(shared_root())), "k": len(problem.field_ids),
        "status": ex.result.status, "optimum": opt, "exact_bound": proven_bound, "exact_gap": ex.gap,
        "hybrid": cov(hybrid), "hybrid_choice": hybrid.portfolio_choice, "greedy": cov(greedy),
        "bound": online.value, "bound_status": online.status, "bound_u0": u0.value,
        "published_bound": published.value, "published_method": published.method,
        "bound_interval": interval.value, "bound_interval_status": interval.status,
        "bound_interval_s": round(interval.runtime_s, 2),
        "bound_slack": online.value - opt, "bound_slack_min": online.value - proven_bound,
        "interval_slack": interval.value - opt,
        "optimiser_loss": opt - cov(hybrid), "optimiser_loss_max": proven_bound - cov(hybrid),
        "greedy_loss": opt - cov(greedy),
        "greedy_executed": executed["greedy"], "hybrid_executed": executed["hybrid"],
        "optimum_executed": executed["optimum"],
        "optimiser_loss_executed": executed["optimum"] - executed["hybrid"],
        "exact_fields": len({o.field_id for o in ex.result.observations}),
        "hybrid_fields": len({o.field_id for o in hybrid.observations}),
        "exact_valid": report.ok, "first_problem": report.problems[0] if report.problems else "",
        "exact_s": round(exact_s, 2), "vars": ex.size.get("vars"), "cuts": ex.size.get("cuts"),
    }


HEADER = (f"{'map':42s} {'k':>3s} {'status':>10s} {'optimum':>8s} {'hybrid':>8s} {'greedy':>8s} {'bound':>8s} "
          f"{'slack':>8s} {'loss':>8s} {'gap':>7s} {'V':>8s} {'V slack':>8s} {'exec opt':>8s} {'exec hyb':>8s} "
          f"{'exec gre':>8s} {'exec loss':>9s} ok")


def line(r: dict) -> str:
    gap = "" if r["exact_gap"] is None else f"{r['exact_gap']:.4f}"
    check = "ok" if r["exact_valid"] else "INVALID: " + r["first_problem"]
    return (f"{r['map'][-42:]:42s} {r['k']:3d} {r['status'][:10]:>10s} {r['optimum']:8.4f} {r['hybrid']:8.4f} "
            f"{r['greedy']:8.4f} {r['bound']:8.4f} {r['bound_slack']:8.4f} {r['optimiser_loss']:8.4f} {gap:>7s} "
            f"{r['bound_interval']:8.4f} {r['interval_slack']:8.4f} {r['optimum_executed']:8.4f} "
            f"{r['hybrid_executed']:8.4f} "
            f"{r['greedy_executed']:8.4f} {r['optimiser_loss_executed']:9.4f} {check}")


MEANS = ("optimum", "hybrid", "greedy", "bound", "bound_u0", "bound_interval", "bound_slack", "interval_slack",
         "optimiser_loss", "greedy_loss", "optimum_executed", "hybrid_executed", "greedy_executed",
         "optimiser_loss_executed")


def summary(rows: list[dict]) -> list[str]:
    """Means over the proven instances and over all, then the unproven ones with their gap."""
    out = []
    proven = [r for r in rows if r["status"] == "optimal"]
    for name, sel in (("proven optimal", proven), ("all (incumbent for unproven)", rows)):
        if not sel:
            continue
        m = {key: statistics.mean(r[key] for r in sel) for key in MEANS}
        ratio_opt = statistics.mean(r["optimum"] / r["bound"] for r in sel if r["bound"] > 0)
        ratio_int = statistics.mean(r["optimum"] / r["bound_interval"] for r in sel if r["bound_interval"] > 0)
        ratio_hyb = statistics.mean(r["hybrid"] / r["optimum"] for r in sel if r["optimum"] > 0)
        out.append(f"MEAN over {len(sel)} {name}: " + ", ".join(f"{key} {m[key]:.4f}" for key in MEANS)
                   + f"; optimum/bound {ratio_opt:.3f}, optimum/V {ratio_int:.3f}, hybrid/optimum {ratio_hyb:.3f}")
    out.append(f"exact plans passing the checker: {sum(r['exact_valid'] for r in rows)}/{len(rows)}; "
               f"hybrid = optimum (1e-6) on {sum(r['optimiser_loss'] <= 1e-6 for r in rows)}/{len(rows)}; "
               f"as executed, hybrid >= the exact plan on {sum(r['optimiser_loss_executed'] <= 1e-6 for r in rows)}"
               f"/{len(rows)} and >= greedy on {sum(r['hybrid_executed'] >= r['greedy_executed'] - 1e-6 for r in rows)}"
               f"/{len(rows)}; "
               f"V >= optimum on {sum(r['bound_interval'] >= r['optimum'] - 1e-9 for r in rows)}/{len(rows)}; "
               f"V <= bound on {sum(r['bound_interval'] <= r['bound'] + 1e-9 for r in rows)}/{len(rows)}; "
               f"median V time {statistics.median(r['bound_interval_s'] for r in rows):.2f} s")
    unproven = [r for r in rows if r["status"] != "optimal"]
    out.append(f"not proven optimal: {len(unproven)}")
    for r in unproven:
        gap = float("nan") if r["exact_gap"] is None else r["exact_gap"]
        out.append(f"  {r['map']} k={r['k']}: incumbent {r['optimum']:.4f}, proven bound {r['exact_bound']:.4f}, "
                   f"gap {gap:.4f}; bound slack in [{r['bound_slack_min']:.4f}, {r['bound_slack']:.4f}], "
                   f"optimiser loss in [{r['optimiser_loss']:.4f}, {r['optimiser_loss_max']:.4f}]")
    return out


def refined_summary(rows: list[dict]) -> list[str]:
    """Split V's slack on the instances whose grid, inner and outer exact models are all proven optimal."""
    sel = [r for r in rows if r["status"] == r["status_inner"] == r["status_outer"] == "optimal"]
    if not sel:
        return ["refined: no instance proven optimal on all three window sets"]
    m = {key: statistics.mean(r[key] for r in sel) for key in
         ("optimum", "optimum_inner", "optimum_outer", "bound_interval", "hybrid")}
    return [f"REFINED over {len(sel)} instances proven optimal on grid, inner and outer windows: "
            f"optimum grid {m['optimum']:.4f}, inner {m['optimum_inner']:.4f}, outer {m['optimum_outer']:.4f}, "
            f"V {m['bound_interval']:.4f}, hybrid {m['hybrid']:.4f}",
            f"  V - optimum(grid) {m['bound_interval'] - m['optimum']:.4f} = grid conservatism (outer - grid) "
            f"{m['optimum_outer'] - m['optimum']:.4f} + V's own slack (V - outer) {m['bound_interval'] - m['optimum_outer']:.4f}; "
            f"plannable by refining the ends (inner - grid) {m['optimum_inner'] - m['optimum']:.4f}",
            f"  V >= outer on {sum(r['bound_interval'] >= r['optimum_outer'] - 1e-9 for r in rows)}/{len(rows)}; "
            f"outer >= inner >= grid on {sum(r['optimum_outer'] >= r['optimum_inner'] - 1e-6 >= r['optimum'] - 2e-6 for r in rows)}/{len(rows)}"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--k", type=int, default=20, help="fields per reduced instance")
    ap.add_argument("--k-hard", type=int, default=30, help="fields for the issue's four maps, second instance")
    ap.add_argument("--exact-limit", type=float, default=30.0, help="time limit (s) of each exact solve")
    ap.add_argument("--plan-limit", type=float, default=10.0, help="hybrid's time_limit_s (s)")
    ap.add_argument("--interval-limit", type=float, default=2.0, help="time limit (s) of the interval bound V")
    ap.add_argument("--refined", action="store_true",
                    help="also solve the exact model on the windows with refined ends (inner: plannable; "
                         "outer: contains every checker-accepted exposure), evaluation/true_windows.py")
    ap.add_argument("-o", "--output", type=Path)
    args = ap.parse_args(argv)
    instances = [(p, args.k) for p in args.maps] if args.maps else default_instances(args.k, args.k_hard)
    rows: list[dict] = []
    print(HEADER, flush=True)
    t0 = time.perf_counter()
    for path, k in instances:
        try:
            r = measure(path, k, args.exact_limit, args.plan_limit, args.interval_limit, args.refined)
        except Exception as exc:  # a benchmark reports, it does not stop
            print(f"{str(path)[-42:]:42s} ERROR {type(exc).__name__}: {exc}", flush=True)
            continue
        rows.append(r)
        print(line(r) + (f"  inner {r['optimum_inner']:.4f} ({r['status_inner'][:4]}) outer {r['optimum_outer']:.4f} "
                         f"({r['status_outer'][:4]}, bound {r['bound_outer']:.4f})" if args.refined else ""), flush=True)
        if args.output:
            write_rows(args.output, rows)
    for text in summary(rows):
        print(text)
    if args.refined:
        for text in refined_summary(rows):
            print(text)
    print(f"wall {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
