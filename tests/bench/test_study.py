"""``mushrooms study`` on a real Dask LocalCluster: same numbers as the serial bench, resumable, failures recorded."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

import mushrooms  # noqa: E402
from mushrooms.evaluation import bench, study  # noqa: E402
from mushrooms.evaluation.bench.compare import scored  # noqa: E402
from mushrooms.evaluation.bench.rows import make_row  # noqa: E402
from mushrooms.evaluation.bench.settings import BenchConfig  # noqa: E402
from mushrooms.evaluation.study.provenance import digest  # noqa: E402
from mushrooms.scheduler_core.config import PlanningConfig  # noqa: E402

DEMO_MAP = Path(mushrooms.__file__).parent / "scheduler_core" / "data" / "MS181101ab_bayestar.multiorder.fits"
#: The study scores with the fixed source model only.
NO_V1 = BenchConfig(legacy_scoring=False)
#: Wall-clock columns: the only ones allowed to differ between two runs of the same plan.
TIMINGS = {"runtime_s", "prepare_s", "solve_s"}


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        with distributed.Client(cl) as c:
            yield c


def _plan_tasks(ts) -> int:
    return sum(1 for t in ts.data if str(t["key"]).startswith("plan-"))


def test_cluster_matches_serial_bench_and_rerun_skips_finished_work(tmp_path, data_dir, client) -> None:
    maps_dir = tmp_path / "maps"
    maps_dir.mkdir()
    for p in (data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits",
              data_dir / "skymaps" / "S200129m_cWB_RING.fits.gz", DEMO_MAP):
        shutil.copy(p, maps_dir)
    (maps_dir / "broken.fits").write_bytes(b"SIMPLE  =                    T" + b"\0" * 100)  # deliberately broken
    settings = bench.BenchSettings(config=PlanningConfig(nside=64, threads=1), solvers=("greedy",),
                                   n_injections=500, bench=NO_V1)
    maps = study.maps_from_directory(maps_dir)
    assert len(maps) == 4

    serial = bench.run_bench(settings, [m.path for m in maps], jobs=1, progress=False)
    out = tmp_path / "study"
    with distributed.get_task_stream(client) as ts:
        run = study.run_graph(client, maps, settings, out, progress=False)
    assert _plan_tasks(ts) == 4 and len(run.executed) == 4

    by_serial = {(r["skymap"], r["solver"]): r for r in serial}
    good = [r for r in run.rows if not r["skymap"].endswith("broken.fits")]
    assert len(good) == 3
    for row in good:
        ref = by_serial[(row["skymap"], row["solver"])]
        assert scored(row)
        assert {k: v for k, v in row.items() if k not in TIMINGS} == {k: v for k, v in ref.items() if k not in TIMINGS}
    assert any(r["efficiency_optimistic"] not in ("", None) for r in good)  # real efficiencies were compared

    records = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 4
    for rec in records:
        assert rec["versions"]["mushrooms"] != "-" and rec["versions"]["dask"] != "-"
        assert rec["config"]["n_injections"] == 500 and rec["config"]["config"]["nside"] == 64
    bad = [r for r in records if r["skymap"].endswith("broken.fits")]
    assert len(bad) == 1 and bad[0]["ok"] is False
    assert bad[0]["error"] and "read_skymap" in bad[0]["traceback"]
    assert run.failed == [bad[0]["key"]]
    assert by_serial[(bad[0]["skymap"], "greedy")]["status"].startswith("skymap_error")  # the bench agrees

    # the rerun plans only the failed map again; finished results are not recomputed
    with distributed.get_task_stream(client) as ts:
        again = study.run_graph(client, maps, settings, out, progress=False)
    assert _plan_tasks(ts) == 1 and again.executed == [bad[0]["key"]]
    assert len((out / "results.jsonl").read_text().splitlines()) == 5
    assert [r for r in again.rows if r in good] == good

    # another configuration is another result: nothing is reused across configurations
    other = study.study_config(bench.BenchSettings(config=PlanningConfig(nside=64, threads=1), n_injections=501))
    assert digest(other) != records[0]["config_hash"]

    text = study.paper_tables(again.rows)
    assert "| greedy | coverage | 3 |" in text and "Similar-length" not in text  # one solver: no pair to compare
    figs = study.make_figures(again.rows, tmp_path / "figs")
    assert [p.name for p in figs] == ["solve_time_hist.png"]  # nothing to compare with one solver


def test_run_study_from_python_writes_results_tables_and_figures(tmp_path, data_dir, client) -> None:
    """The study as a library: plain settings and inputs in, the outcome out; nothing printed."""
    maps_dir = tmp_path / "maps"
    maps_dir.mkdir()
    for name in ("MS220722v_bayestar.multiorder.fits", "S200129m_cWB_RING.fits.gz"):
        shutil.copy(data_dir / "skymaps" / name, maps_dir)
    # threads = 0 and the default legacy scoring: the study makes them one thread and the fixed source model
    settings = study.StudySettings(
        bench=bench.BenchSettings(config=PlanningConfig(nside=64, threads=0), solvers=("greedy", "greedy-coverage"),
                                  n_injections=300),
        out=tmp_path / "out", cache=tmp_path / "cache", scheduler=client.scheduler.address)
    told: list[str] = []
    outcome = study.run_study(settings, study.StudyInputs(maps=str(maps_dir), limit=1), notify=told.append)
    assert told == [f"1 map(s) x 2 solver(s) on {client.scheduler.address}"]
    assert outcome.n_maps == 1 and outcome.run is not None and len(outcome.run.executed) == 2
    assert [r["solver"] for r in outcome.run.rows] == ["greedy", "greedy-coverage"]
    assert all(scored(r) and not any(k.endswith("_v1") for k in r) for r in outcome.run.rows)
    records = [json.loads(x) for x in (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    assert {r["config"]["config"]["threads"] for r in records} == {1}
    assert {r["config"]["legacy_scoring"] for r in records} == {False}
    assert (tmp_path / "out" / "tables.md").read_text() == outcome.tables + "\n\n" + outcome.footer + "\n"
    assert "| greedy | coverage | 1 |" in outcome.tables and outcome.footer.startswith("1 map(s), solvers greedy,")
    assert [p.name for p in outcome.figures] == ["solve_time_hist.png"] and outcome.figures[0].exists()
    assert len(bench.read_csv(tmp_path / "out" / "results.csv")) == 2
    assert client.status == "running"  # a scheduler it was given is left running
    with pytest.raises(ValueError, match="one source"):
        study.StudyInputs(maps=str(maps_dir), events="e.xml.gz")


def test_failed_localisation_is_recorded_and_its_plans_fail_alone(tmp_path, data_dir, client) -> None:
    good = study.MapTask(key="good", name=str(DEMO_MAP), path=str(DEMO_MAP))
    lost = study.MapTask(key="lost", name=str(tmp_path / "cache" / "7.fits"), path=str(tmp_path / "cache" / "7.fits"),
                         events=str(tmp_path / "no-such-events.xml.gz"), coinc_id=7)
    settings = bench.BenchSettings(config=PlanningConfig(nside=64, threads=1), solvers=("greedy",),
                                   n_injections=200, bench=NO_V1)
    remote = study.open_client(scheduler=client.scheduler.address)  # --scheduler ADDRESS: a running cluster
    try:
        run = study.run_graph(remote, [lost, good], settings, tmp_path / "out", progress=False)
    finally:
        remote.close()
    assert len(run.executed) == 2 and len(run.failed) == 1
    records = {r["map"]: r for r in map(json.loads, (tmp_path / "out" / "results.jsonl").read_text().splitlines())}
    assert records["good"]["ok"] is True
    assert records["lost"]["ok"] is False and "RuntimeError" in records["lost"]["error"]
    assert "localise" in records["lost"]["traceback"]
    loc = [json.loads(x) for x in (tmp_path / "out" / "localisations.jsonl").read_text().splitlines()]
    assert len(loc) == 1 and loc[0]["ok"] is False and loc[0]["coinc_id"] == 7


def test_paper_tables_and_figures_on_two_solvers(tmp_path) -> None:
    def row(m: str, s: str, cov: float, eff: float, n: int, area: float, solve: float) -> dict:
        return make_row(m, s, coverage=cov, efficiency_optimistic=eff, efficiency_conservative=eff / 2,
                          n_exposures=n, area90_deg2=area, solve_s=solve, valid=True, bound=0.9,
                          coverage_over_bound=cov / 0.9)

    rows = [row("a", "greedy", 0.40, 0.20, 50, 100.0, 1.0), row("a", "hybrid", 0.50, 0.30, 52, 100.0, 8.0),
            row("b", "greedy", 0.30, 0.10, 40, 2000.0, 1.2), row("b", "hybrid", 0.20, 0.05, 60, 2000.0, 9.0),
            row("c", "greedy", 0.60, 0.30, 30, 500.0, 0.9), row("c", "hybrid", 0.60, 0.30, 34, 500.0, 7.5)]
    assert study.similar_length_maps(rows, "hybrid", "greedy") == {"a", "c"}
    text = study.paper_tables(rows, ("optimistic", "conservative"))
    lines = text.splitlines()
    hybrid_all = next(x for x in lines if x.startswith("| hybrid |"))
    # the rows have no coverage_as_executed: its column is "-"
    assert "| hybrid | - | 3 | 0.4333 | - | 0.2167 | 0.1083 |" in hybrid_all and "| 1/1/1 |" in hybrid_all
    executed = [dict(r, coverage_as_executed=0.5 * r["coverage"]) for r in rows]
    assert "| hybrid | - | 3 | 0.4333 | 0.2167 | 0.2167 | 0.1083 |" in study.paper_tables(executed, ("optimistic",
                                                                                              "conservative"))
    best = [x for x in lines if x.startswith("| best(hybrid,greedy) |")]
    assert best[0].startswith("| best(hybrid,greedy) | - | 3 | 0.4667 |")  # per map the plan with more coverage
    assert "Similar-length subset (2 of 3 maps" in text
    assert best[1].startswith("| best(hybrid,greedy) | - | 2 | 0.5500 |")
    figs = study.make_figures(rows, tmp_path)
    names = sorted(p.relative_to(tmp_path).as_posix() for p in figs)
    assert names == ["area_hist_similar_length.png", "coverage_scatter.png", "efficiency_vs_area.png",
                     "similar_length/coverage_scatter.png", "similar_length/efficiency_vs_area.png",
                     "solve_time_hist.png"]
    assert all(p.stat().st_size > 5000 for p in figs)


def test_localised_map_cache_key_and_bad_cli_input(tmp_path, capsys) -> None:
    a = study.localised_path(tmp_path, "ab" * 32, 3, study.Localisation())
    assert a == study.localised_path(tmp_path, "ab" * 32, 3, study.Localisation())
    assert a != study.localised_path(tmp_path, "ab" * 32, 4, study.Localisation())
    assert a != study.localised_path(tmp_path, "cd" * 32, 3, study.Localisation())
    assert a != study.localised_path(tmp_path, "ab" * 32, 3, study.Localisation(f_low=30.0))
    assert study.coinc_ids(study.DEFAULT_EVENTS) == list(range(21))  # the packaged O3 BNS population

    from mushrooms.cli import main as cli_main

    assert cli_main(["study", "--maps", str(tmp_path / "nowhere"), "--workers", "1", "--out", str(tmp_path)]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert cli_main(["study", "--solvers", "nope", "--out", str(tmp_path)]) == 2
    assert "unknown solver" in capsys.readouterr().err


@pytest.mark.slow
def test_localise_one_packaged_coincidence_with_bayestar(tmp_path) -> None:
    """The real tool (lalsuite; ~1 min of one core): one map, cached, readable by the planner."""
    if shutil.which("bayestar-localize-coincs") is None:
        pytest.skip("bayestar-localize-coincs (ligo.skymap with lalsuite) not on PATH")
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    (task,) = study.maps_from_events(study.DEFAULT_EVENTS, tmp_path, study.Localisation(), ids=[0])
    first = study.localise(task.events, task.coinc_id, study.Localisation(), task.path)
    assert first["cached"] is False and first["cpu_s"] > 1.0 and Path(first["path"]).exists()
    again = study.localise(task.events, task.coinc_id, study.Localisation(), task.path)
    assert again["cached"] is True and again["path"] == first["path"]
    skymap = read_skymap(first["path"], nside=64)
    assert skymap.event_time is not None and skymap.distmean is not None



def test_gwemopt_repaired_waits_for_the_raw_row_of_its_map_on_the_cluster(tmp_path, data_dir, client) -> None:
    from mushrooms.evaluation.study.provenance import digest

    maps = study.maps_from_directory(data_dir / "skymaps")[:1]
    settings = bench.BenchSettings(config=PlanningConfig(nside=64, threads=1), solvers=("gwemopt", "gwemopt-repaired"),
                                   n_injections=100, bench=BenchConfig(legacy_scoring=False, gwemopt_cache_only=True,
                                                                       gwemopt_cache_dir=str(tmp_path / "gw")))
    with distributed.get_task_stream(client) as ts:
        run = study.run_graph(client, maps, settings, tmp_path / "study", progress=False)
    assert [r["status"] for r in run.rows] == ["not_cached", "not_cached"]  # (no cached schedule: quick rows)
    config_hash = digest(study.study_config(settings))
    spans = {}
    for t in ts.data:
        compute = [s for s in t["startstops"] if s["action"] == "compute"]
        spans[str(t["key"])] = (compute[0]["start"], compute[-1]["stop"])
    raw, repaired = (spans[f"plan-{digest([study.result_key(maps[0].key, s, config_hash)], 16)}"]
                     for s in ("gwemopt", "gwemopt-repaired"))
    # one gwemopt run per map, never two side by side; the worker stamps a task's stop after its result is
    # handed on, so under load the next task can start ~ms before it (seen: 1.6 ms); a run overlaps by seconds
    assert repaired[0] >= raw[1] - 0.05
