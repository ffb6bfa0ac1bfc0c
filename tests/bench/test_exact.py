"""The exact model of the full rules (evaluation/exact.py): hand-checked, enumerated, checked, above every plan."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.evaluation.exact import build_exact_model, exact_data, solve_exact, start_from_plan
from mushrooms.evaluation.reduced import reduced_problem
from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem, read_skymap
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.windows import Windows

MAP_220722V = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def small_config(**overrides) -> PlanningConfig:
    values = dict(nside=1, horizon_h=0.5, exposure_s=100.0, slew_estimate_s=10.0, filter_change_s=30.0,
                  cadence_s=250.0, milp_backend="highs", time_limit_s=5.0, mip_gap=0.0, min_gain=0.0,
                  objective="coverage", threads=1, slot_positions=(1, 2, 3), slot_margin_s=0.0)
    values.update(overrides)
    return PlanningConfig(**values)


def make_problem(config: PlanningConfig, prob, members, windows, ra) -> PlanningProblem:
    ids = np.arange(1, len(members) + 1)
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    fp = Footprints(config.nside, ids, indptr, np.concatenate([np.asarray(m, np.int64) for m in members]))
    w_ids = np.array([ids[f] for f, ws in enumerate(windows) for _ in ws])
    w_start = np.array([a for ws in windows for a, _ in ws], float)
    w_end = np.array([b for ws in windows for _, b in ws], float)
    return PlanningProblem(config, Time("2026-01-01T00:00:00", scale="utc"), np.asarray(prob, float), ids,
                           np.asarray(ra, float), np.zeros(len(members)), fp, Windows(w_ids, w_start, w_end))


def coverage(problem: PlanningProblem, observations) -> float:
    return problem.footprints.coverage({o.field_id for o in observations}, problem.prob)


def rule_problems(problem: PlanningProblem, observations) -> list[str]:
    """The checker's timing rules on a hand-made problem (no sky): windows, overheads, both filters, cadence."""
    from mushrooms.scheduler_core.telescope.slew import overhead_time

    cfg = problem.config
    obs = sorted(observations, key=lambda o: o.start)
    bad = [f"window {o}" for o in obs
           if not problem.windows.contains(o.field_id, o.start - 1e-6, o.start + o.exposure_s - 1e-6)
           and not problem.windows.contains(o.field_id, o.start + 1e-6, o.start + o.exposure_s - 1e-6)]
    for a, b in zip(obs[:-1], obs[1:]):
        need = float(overhead_time(a.ra, a.dec, b.ra, b.dec, cfg.slew,
                                   cfg.filter_change_s if a.filter != b.filter else 0.0))
        if b.start < a.start + a.exposure_s + need - 1e-6:
            bad.append(f"overhead {a} -> {b}")
    starts: dict[int, dict[str, float]] = {}
    for o in obs:
        starts.setdefault(o.field_id, {})[o.filter] = o.start
    for fid, s in starts.items():
        if set(s) != set(cfg.filters) or abs(s[cfg.filters[0]] - s[cfg.filters[1]]) < cfg.cadence_s - 1e-6:
            bad.append(f"cadence {fid}")
    return bad


def enumerated_optimum(problem: PlanningProblem) -> float:
    """Best coverage over every subset of fields and every order of their exposures (each as early as possible).

    For a fixed order the earliest start of each exposure (latest of the previous end plus the true
    overhead, the opening of the first window it fits, the first filter plus the cadence) is the best
    timing: every rule is a lower bound growing with the earlier starts, or a window end.
    """
    data = exact_data(problem)
    cfg = problem.config
    exp = cfg.exposure_s
    F = data.n_fields

    def fits(order) -> bool:
        prev, free, first = None, 0.0, {}
        for e in order:
            ready = free + (0.0 if prev is None else data.overhead[prev, e])
            if e // 2 in first:
                ready = max(ready, first[e // 2] + cfg.cadence_s)
            t = next((max(ready, a) for a, b in data.windows[e // 2] if max(ready, a) + exp <= b + 1e-9), None)
            if t is None:
                return False
            first.setdefault(e // 2, t)
            prev, free = e, t + exp
        return True

    best = 0.0
    for size in range(1, F + 1):
        for subset in itertools.combinations(range(F), size):
            value = problem.footprints.coverage(problem.field_ids[list(subset)], problem.prob)
            if value <= best:
                continue
            exposures = [2 * f + p for f in subset for p in (0, 1)]
            if any(fits(order) for order in itertools.permutations(exposures)):
                best = value
    return best


# Hand-checked instance.  Exposure 100 s, cadence 250 s, filter change 30 s, readout 8 s; fields on the
# equator at RA 0, 5, 10, 15 deg (true slews 8.1, 11.0, 13.2 s for 5, 10, 15 deg).  Fields 1, 2, 3 are
# visible in [0, 600] s only: three fields need six exposures, 600 s of exposure plus five overheads, so
# at most two fit (e.g. 1 g at 0, 2 g at 108.1, 1 r at 250, 2 r at 358.1, ending at 458.1 s).  Coverage
# (pixel probabilities): f1 = {0 (.2), 1 (.1)} = .3, f2 = {2 (.22)}, f3 = {1, 3 (.12)} = .22; the best
# pair is {1, 2} = .52 ({1, 3} and {2, 3} cover .44).  Field 4 = {4 (.1)} is visible in [1000, 1400] s,
# where its pair fits alone.  Optimum: .52 + .1 = .62 with fields {1, 2, 4}.
HAND_OPTIMUM = 0.62
HAND_FIELDS = {1, 2, 4}


def hand_problem() -> PlanningProblem:
    prob = [0.2, 0.1, 0.22, 0.12, 0.1, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7]
    return make_problem(small_config(), prob, [[0, 1], [2], [1, 3], [4]],
                        [[(0.0, 600.0)], [(0.0, 600.0)], [(0.0, 600.0)], [(1000.0, 1400.0)]], [0.0, 5.0, 10.0, 15.0])


def test_hand_checked_instance_has_the_optimum_worked_out_by_hand():
    problem = hand_problem()
    ex = solve_exact(problem, time_limit_s=60.0)
    assert ex.proven
    assert ex.optimum == pytest.approx(HAND_OPTIMUM, abs=1e-9)
    assert {o.field_id for o in ex.result.observations} == HAND_FIELDS
    assert coverage(problem, ex.result.observations) == pytest.approx(HAND_OPTIMUM, abs=1e-9)
    assert rule_problems(problem, ex.result.observations) == []
    assert enumerated_optimum(problem) == pytest.approx(HAND_OPTIMUM, abs=1e-9)


def test_a_third_field_in_the_short_window_does_not_fit():
    # widen the short window to 766.5 s: three fields fit (1 g, 2 g, 3 g, 1 r, 2 r, 3 r ends at 662.3 s),
    # and the optimum is every field, 0.74
    problem = hand_problem()
    w = problem.windows
    end = np.where(w.end == 600.0, 600.0 + 5 * 8.0 + 5 * 13.3 + 2 * 30.0, w.end)
    wide = make_problem(problem.config, problem.prob, [[0, 1], [2], [1, 3], [4]],
                        [[(0.0, e)] for e in end[:3]] + [[(1000.0, 1400.0)]], [0.0, 5.0, 10.0, 15.0])
    ex = solve_exact(wide, time_limit_s=20.0)
    assert ex.proven and ex.optimum == pytest.approx(0.74, abs=1e-9)
    assert rule_problems(wide, ex.result.observations) == []


def random_small_problem(seed: int, n_fields: int = 4) -> PlanningProblem:
    rng = np.random.default_rng(seed)
    cfg = small_config()
    prob = rng.random(12) ** 3
    prob /= prob.sum()
    members = [np.sort(rng.choice(12, size=rng.integers(1, 4), replace=False)) for _ in range(n_fields)]
    windows = []
    for _ in range(n_fields):
        a = float(rng.uniform(0, 900))
        ws = [(a, a + float(rng.uniform(360, 900)))]
        if rng.random() < 0.4:  # a second window, later
            b = ws[0][1] + float(rng.uniform(50, 300))
            ws.append((b, min(b + float(rng.uniform(150, 500)), cfg.horizon_s)))
        windows.append(ws)
    return make_problem(cfg, prob, members, windows, rng.uniform(0, 40, n_fields))


@pytest.mark.parametrize("seed", range(5))
def test_exact_optimum_equals_enumeration_on_small_random_instances(seed):
    problem = random_small_problem(seed)
    ex = solve_exact(problem, time_limit_s=60.0)
    assert ex.proven
    assert rule_problems(problem, ex.result.observations) == []
    assert coverage(problem, ex.result.observations) == pytest.approx(ex.optimum, abs=1e-9)
    assert ex.optimum == pytest.approx(enumerated_optimum(problem), abs=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_every_plan_is_a_point_of_the_model_and_the_optimum_is_above_it(seed):
    problem = random_small_problem(100 + seed, n_fields=7)
    model = build_exact_model(problem)
    ex = solve_exact(problem, time_limit_s=60.0)
    assert ex.proven
    for solver in ("greedy", "slots", "blocks"):
        obs = run_scheduler(problem, solver).observations
        assert rule_problems(problem, obs) == []
        v = start_from_plan(model, problem, obs)
        assert v is not None
        ax = model.milp.A @ v
        assert (ax >= model.milp.row_lo - 1e-6).all() and (ax <= model.milp.row_hi + 1e-6).all(), solver
        assert float(model.milp.c @ v) == pytest.approx(coverage(problem, obs), abs=1e-9)
        assert ex.optimum >= coverage(problem, obs) - 1e-9, solver
    assert coverage_upper_bound(problem).value >= ex.optimum - 1e-9
    assert interval_upper_bound(problem, time_limit_s=10.0).value >= ex.optimum - 1e-9


@pytest.mark.parametrize("seed", range(5))
def test_interval_bound_is_above_the_exact_optimum_and_below_the_online_bound(seed):
    problem = random_small_problem(200 + seed, n_fields=7)
    ex = solve_exact(problem, time_limit_s=60.0)
    assert ex.proven
    interval = interval_upper_bound(problem, time_limit_s=10.0).value
    assert ex.optimum - 1e-9 <= interval <= coverage_upper_bound(problem).value + 1e-9


@pytest.fixture(scope="module")
def reduced_220722v():
    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=3.0, milp_backend="highs", min_gain=0.0,
                         min_coverage=0.0)
    skymap = read_skymap(MAP_220722V, nside=cfg.nside)
    full = prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc"))
    return skymap, reduced_problem(full, 8)


def test_exact_plan_on_a_real_map_passes_the_checker_and_beats_every_scheduler(reduced_220722v):
    skymap, problem = reduced_220722v
    greedy = run_scheduler(problem, "greedy")
    slots = run_scheduler(problem, "slots")
    ex = solve_exact(problem, time_limit_s=60.0, starts=(greedy.observations,))
    assert ex.proven
    plan = build_plan(problem, ex.result, skymap, "hybrid")
    report = check_plan(plan, skymap, problem.config)
    assert report.ok, report.problems
    assert report.coverage == pytest.approx(ex.optimum, abs=2e-3)
    assert ex.optimum >= coverage(problem, greedy.observations) - 1e-9
    assert ex.optimum >= coverage(problem, slots.observations) - 1e-9
    assert slots.upper_bound.value >= ex.optimum - 1e-9
    assert coverage_upper_bound(problem, method="milp").value >= ex.optimum - 1e-9
    assert interval_upper_bound(problem, time_limit_s=10.0).value >= ex.optimum - 1e-9
