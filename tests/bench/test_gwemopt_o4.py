"""gwemopt as ZTF ran it (issue 55): the named configurations' command lines, SkyPortal's field selection, the
launcher, and a committed gwemopt-o4 schedule counted by the pair rule and submitted as SkyPortal submits it.

No test runs gwemopt: the schedule under ``tests/data/gwemopt/`` is gwemopt 0.4.2's own output for the test map
(``tests/data/gwemopt/SOURCES.md``)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig, read_skymap

DATA = Path(__file__).resolve().parents[1] / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
S200129M = DATA / "skymaps" / "S200129m_cWB_RING.fits.gz"
O4_SCHEDULE = DATA / "gwemopt" / "gwemopt-o4_MS220722v.dat"
START = Time("2022-07-22T21:57:12.384", scale="utc")  # MS220722v's event time


def _grid(args):
    """The options after ``--gpstime`` and ``--Tobs`` (which name the map's time)."""
    return args[args.index("--doTiles"):]


def test_each_named_configuration_passes_its_exact_command_line():
    from mushrooms.evaluation.gwemopt_options import GWEMOPT_CONFIGS, gwemopt_args

    cfg = PlanningConfig()
    o4 = gwemopt_args(MAP, START, cfg, "out", GWEMOPT_CONFIGS["gwemopt-o4"])
    assert o4[:8] == ["--telescopes", "ZTF", "-e", str(MAP), "-o", "out", "--gpstime", f"{START.gps:.3f}"]
    assert o4[8:10] == ["--Tobs", "0,1.000000"]
    assert _grid(o4) == [
        "--doTiles", "--tilesType", "moc", "--doSchedule", "--scheduleType", "greedy", "--timeallocationType",
        "powerlaw", "--filters", "g,r,g", "--exposuretimes", "180,180,180", "--doSingleExposure",
        "--doAlternatingFilters", "--doBalanceExposure", "--confidence_level", "0.9", "--mindiff", "30",
        "--max_nb_tiles", "15", "--doUsePrimary", "--nside", "256", "--airmass", "2.5"]
    sky = gwemopt_args(MAP, START, cfg, "out", GWEMOPT_CONFIGS["gwemopt-skyportal"], fields=[700, 3, 699, 3])
    assert _grid(sky) == [
        "--doTiles", "--tilesType", "moc", "--doSchedule", "--scheduleType", "greedy", "--timeallocationType",
        "powerlaw", "--filters", "g,r,g", "--exposuretimes", "300,300,300", "--doSingleExposure",
        "--doAlternatingFilters", "--doBalanceExposure", "--doUsePrimary", "--nside", "512", "--airmass", "2",
        "--mushrooms-fields", "3,699,700"]
    # the first release's row keeps its line, whatever the configuration's exposure and filters
    legacy = gwemopt_args(MAP, START, dataclasses.replace(cfg, exposure_s=120.0), "out", GWEMOPT_CONFIGS["gwemopt"])
    assert _grid(legacy) == [
        "--doTiles", "--tilesType", "moc", "--doSchedule", "--scheduleType", "greedy", "--timeallocationType",
        "powerlaw", "--doChipGaps", "--filters", "g,r", "--exposuretimes", "120,120", "--doSingleExposure",
        "--doAlternatingFilters", "--nside", "256", "--airmass", "2.5"]


def test_cache_keys_hold_every_option_and_the_first_release_keeps_its_keys():
    from mushrooms.evaluation.gwemopt_baseline import cache_key
    from mushrooms.evaluation.gwemopt_options import GWEMOPT_CONFIGS

    cfg = PlanningConfig()
    # the committed cache's entry for this map (benchmarks/results/science/gwemopt-cache, made 2026-12-01)
    start = Time(1264316116.410, format="gps", scale="utc")
    assert cache_key(S200129M, start, cfg) == "437c56c20125c54a202ff20652bb732059a3a9f6afc28160e18727ee797756ee"
    keys = {name: cache_key(S200129M, start, cfg, named) for name, named in GWEMOPT_CONFIGS.items()}
    assert len(set(keys.values())) == 3
    sky = GWEMOPT_CONFIGS["gwemopt-skyportal"]
    assert cache_key(S200129M, start, cfg, sky, [1, 2]) != cache_key(S200129M, start, cfg, sky, [1, 3])
    o4 = GWEMOPT_CONFIGS["gwemopt-o4"]
    assert cache_key(S200129M, start, cfg, o4) != cache_key(S200129M, start, cfg, dataclasses.replace(o4, max_nb_tiles=16))


def test_the_launcher_takes_our_fields_option_out_and_keeps_only_those_fields(tmp_path):
    """gwemopt's interpreter runs our launcher; a stand-in ``gwemopt`` package records what it is given."""
    from mushrooms.evaluation.gwemopt_baseline import _LAUNCHER

    pkg = tmp_path / "gwemopt"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "moc.py").write_text("def create_moc(params, map_struct=None):\n"
                                "    return {'ZTF': {1: 'a', 2: 'b', 700: 'c'}}\n")
    (pkg / "run.py").write_text("import json, gwemopt.moc\n"
                                "def run(argv):\n"
                                "    json.dump({'argv': argv, 'tiles': sorted(gwemopt.moc.create_moc({})['ZTF'])},\n"
                                "              open('seen.json', 'w'))\n")
    env = {"PYTHONPATH": str(tmp_path)}
    subprocess.run([sys.executable, "-c", _LAUNCHER, "--filters", "g,r,g", "--mushrooms-fields", "2,700",
                    "--nside", "512"], cwd=tmp_path, env=env, check=True, timeout=120)
    seen = json.loads((tmp_path / "seen.json").read_text())
    assert seen == {"argv": ["--filters", "g,r,g", "--nside", "512"], "tiles": [2, 700]}
    subprocess.run([sys.executable, "-c", _LAUNCHER, "--nside", "256"], cwd=tmp_path, env=env, check=True,
                   timeout=120)
    assert json.loads((tmp_path / "seen.json").read_text()) == {"argv": ["--nside", "256"], "tiles": [1, 2, 700]}


@pytest.fixture(scope="module")
def scene():
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

    cfg = PlanningConfig(nside=64)
    return cfg, read_skymap(MAP, nside=cfg.nside), field_footprints(load_ztf_fields(), cfg.nside)


def test_skyportal_hands_gwemopt_the_fields_touching_the_credible_region(scene):
    from mushrooms.evaluation.gwemopt_options import credible_fields

    _, skymap, fp = scene
    prob = skymap.prob
    order = np.argsort(prob)[::-1]
    inside = order[np.cumsum(prob[order]) <= 0.9]
    touching = {int(f) for f, p in zip(fp.field_ids, fp.field_probability(np.isin(np.arange(prob.size), inside)))
                if p > 0}
    assert set(credible_fields(fp, prob, 0.9)) == touching
    fifty = set(credible_fields(fp, prob, 0.5))
    assert fifty < touching and int(fp.field_ids[np.argmax(fp.field_probability(prob))]) in fifty
    with pytest.raises(ValueError):
        credible_fields(fp, prob, 1.5)


def _o4_plan(cfg, skymap):
    """The committed gwemopt-o4 schedule as the bench wraps it."""
    from mushrooms.evaluation.gwemopt_baseline import GwemoptRun, gwemopt_plan, parse_schedule
    from mushrooms.evaluation.gwemopt_options import GWEMOPT_CONFIGS, row_planning_config

    rcfg = row_planning_config(cfg, GWEMOPT_CONFIGS["gwemopt-o4"])
    obs = parse_schedule(O4_SCHEDULE.read_text(), START, rcfg.exposure_s)
    return rcfg, gwemopt_plan(GwemoptRun("ok", obs, 30.0), START, rcfg, skymap.sha256, 0.0, name="gwemopt-o4")


def test_a_gwemopt_o4_schedule_is_judged_under_g_r_g_at_180_s(scene):
    cfg, skymap, _ = scene
    rcfg, plan = _o4_plan(cfg, skymap)
    assert rcfg.filters == ("g", "r", "g") and rcfg.exposure_s == 180.0 and rcfg.airmass_max == cfg.airmass_max
    assert plan.metrics.solver == "gwemopt-o4"
    # gwemopt writes 179 (``%d`` of 179.99...): snapped back to the 180 s the command line asked for
    assert {o.exposure_s for o in plan.observations} == {180.0}
    assert [o.filter for o in plan.observations][:1] == ["g"] and {o.filter for o in plan.observations} == {"g", "r"}


def _shift(plan, pick, by_s):
    obs = tuple(dataclasses.replace(o, start=o.start + by_s) if pick(o) else o for o in plan.observations)
    return plan.with_(observations=tuple(sorted(obs, key=lambda o: o.start)))


def test_the_pair_rule_counts_fields_with_both_filters_the_cadence_apart_inside_their_windows(scene):
    from mushrooms.evaluation.pair_coverage import open_shutter_s, planned_pair_coverage
    from mushrooms.scheduler_core.plan.checker import exposures_in_windows

    cfg, skymap, fp = scene
    rcfg, plan = _o4_plan(cfg, skymap)
    inside = exposures_in_windows(plan, rcfg)
    by = {}
    for o, ok in zip(plan.observations, inside):
        by.setdefault(o.field_id, []).append((o.filter, o.start, bool(ok)))
    paired = {f for f, v in by.items()
              if any(a == "g" and b == "r" and ka and kb and abs(ta - tb) >= rcfg.cadence_s
                     for a, ta, ka in v for b, tb, kb in v)}
    assert paired
    full = planned_pair_coverage(plan, fp, skymap.prob, rcfg)
    assert full == pytest.approx(fp.coverage(paired, skymap.prob), abs=1e-12)
    assert open_shutter_s(plan) == pytest.approx(180.0 * len(plan.observations))
    one = sorted(paired)[0]
    rest = [o for o in plan.observations if o.field_id != one]
    g = min((o for o in plan.observations if o.field_id == one and o.filter == "g"), key=lambda o: o.start)
    r = next(o for o in plan.observations if o.field_id == one and o.filter == "r")

    def with_r_after_g(gap_s):
        obs = rest + [g, dataclasses.replace(r, start=g.start + gap_s)]
        return plan.with_(observations=tuple(sorted(obs, key=lambda o: o.start)))

    without = paired - {one}
    # without its r exposure a field no longer counts
    no_r = plan.with_(observations=tuple(rest + [g]))
    assert planned_pair_coverage(no_r, fp, skymap.prob, rcfg) == pytest.approx(fp.coverage(without, skymap.prob))
    # one g and one r: 10 min apart it does not count, the cadence apart it does
    assert planned_pair_coverage(with_r_after_g(600.0), fp, skymap.prob, rcfg) == pytest.approx(
        fp.coverage(without, skymap.prob), abs=1e-12)
    assert planned_pair_coverage(with_r_after_g(rcfg.cadence_s), fp, skymap.prob, rcfg) == pytest.approx(
        full, abs=1e-12)
    # every exposure moved 12 h on, into the day: nothing is inside a window
    day = _shift(plan, lambda o: True, 12 * 3600.0)
    assert not exposures_in_windows(day, rcfg).any()
    assert planned_pair_coverage(day, fp, skymap.prob, rcfg) == 0.0


def test_as_submitted_today_is_one_list_queue_over_the_plans_horizon_as_skyportal_builds_it(scene):
    """SkyPortal's ZTF API (skyportal 8bd346c, facility_apis/ztf.py:252-312, 891-897): one ``list`` queue valid
    from the request's start_date to end_date - the times gwemopt planned over (utils/observation_plan.py:386-391)
    - its planned observations in order; the bench's single queue is that queue, and executes the same."""
    from mushrooms.evaluation.queue_sim import execution_cells
    from mushrooms.evaluation.skyportal_queue import skyportal_queue
    from mushrooms.scheduler_core.plan.exports import to_trigger_queue
    from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues

    cfg, skymap, fp = scene
    rcfg, plan = _o4_plan(cfg, skymap)
    plan = plan.with_(config={"filters": list(rcfg.filters), "cadence_s": rcfg.cadence_s})
    body = {"payload": {"queue_name": "x", "start_date": plan.start.iso, "end_date": plan.end.iso},
            "observation_plans": [{"planned_observations": [
                {"field_id": o.field_id, "filt": f"ztf{o.filter}", "exposure_time": o.exposure_s}
                for o in plan.observations]}]}
    theirs, ours = skyportal_queue(body), to_trigger_queue(plan)
    assert ours["queue_type"] == theirs["queue_type"] == "list"
    assert ours["validity_window_mjd"] == pytest.approx(theirs["validity_window_mjd"], abs=1e-8)
    assert ours["validity_window_mjd"] == pytest.approx([START.mjd, START.mjd + rcfg.horizon_h / 24], abs=1e-8)
    assert [(t["field_id"], t["filter_id"], t["exposure_time"]) for t in ours["targets"]] == [
        (t["field_id"], t["filter_id"], t["exposure_time"]) for t in theirs["targets"]]
    done = execute_plan_queues(plan, [theirs], 0.0)
    today = cadence_coverage(done, fp, skymap.prob, ("g", "r"), rcfg.cadence_s)
    cells = execution_cells(plan, fp, skymap.prob)
    assert cells["coverage_single_queue"] == pytest.approx(today, abs=1e-6)
    assert cells["open_shutter_single_queue_s"] <= 180.0 * len(plan.observations) + 1e-6


def test_service_grg_is_the_service_under_g_r_g_at_180_s():
    from mushrooms.evaluation.bench.per_map import row_config
    from mushrooms.evaluation.bench.settings import SOLVERS, BenchSettings, check_rows

    check_rows(["service", "service-grg", "greedy", "gwemopt-o4", "gwemopt-skyportal", "gwemopt-repaired"])
    assert "service-grg" in SOLVERS
    settings = BenchSettings(config=PlanningConfig(), solvers=("service-grg",))
    base, rcfg, objective = row_config(settings.config, "service-grg", settings)
    assert (base, rcfg.filters, rcfg.exposure_s) == ("service", ("g", "r", "g"), 180.0)
    assert objective == PlanningConfig().objective
    assert row_config(settings.config, "service", settings)[1] == settings.config


def test_bench_rows_carry_the_pair_rule_the_open_shutter_and_the_commit(monkeypatch):
    """Our own plan pairs every field inside its window: the pair rule gives back the checker's coverage."""
    from mushrooms.evaluation.bench.per_map import bench_map
    from mushrooms.evaluation.bench.settings import BenchSettings
    from mushrooms.evaluation.commit import code_commit

    monkeypatch.setenv("MUSHROOMS_CODE_COMMIT", "cafe123")
    code_commit.cache_clear()
    try:
        settings = BenchSettings(config=PlanningConfig(solver="greedy", nside=64), solvers=("greedy",),
                                 n_injections=200)
        row = bench_map(MAP, settings)[0]
    finally:
        code_commit.cache_clear()
    assert row["commit"] == "cafe123" and row["valid"] is True
    assert row["coverage_pairs"] == pytest.approx(row["coverage"], abs=2e-3) and row["coverage_pairs"] > 0.1
    assert row["open_shutter_s"] == pytest.approx(300.0 * row["n_exposures"])
    assert 0 < row["open_shutter_executed_s"] <= row["open_shutter_s"]
    assert 0 < row["open_shutter_single_queue_s"] <= row["open_shutter_s"]


def test_the_code_commit_is_the_trees_head_unless_a_snapshot_names_it(monkeypatch):
    from mushrooms.evaluation.commit import code_commit

    root = Path(__file__).resolve().parents[2]
    monkeypatch.delenv("MUSHROOMS_CODE_COMMIT", raising=False)
    code_commit.cache_clear()
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
        assert code_commit().removesuffix("-dirty") == head
    finally:
        code_commit.cache_clear()
