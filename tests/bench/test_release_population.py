"""The frozen release's run across sessions (issue 55 item 6): the ``o4-real`` provenance, resuming from the
committed result records, and the release tables of a partial run.

Real files throughout: the committed ``o4-real`` population (``benchmarks/results/science/population_o4/``), the
small test sky maps, a real Dask LocalCluster, the scripts as ``population_o4.sh`` runs them.
"""

from __future__ import annotations

import gzip
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from mushrooms.evaluation import bench, study  # noqa: E402
from mushrooms.evaluation.bench.settings import BenchConfig  # noqa: E402
from mushrooms.evaluation.study.population_rows import write_population_csv  # noqa: E402
from mushrooms.scheduler_core.config import PlanningConfig  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
RELEASE = REPO / "benchmarks" / "results" / "science" / "population_o4"
SCRIPTS = REPO / "benchmarks" / "science"
SIX = ("service", "service-grg", "greedy", "gwemopt-o4", "gwemopt-skyportal", "gwemopt-repaired")


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        with distributed.Client(cl) as c:
            yield c


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, cwd=REPO, timeout=300)


def test_the_o4_real_provenance_names_its_sources_ranges_epochs_threshold_and_what_each_chunk_kept():
    from mushrooms.evaluation.study.population import coinc_ids
    from mushrooms.evaluation.study.population_rows import population_events
    from mushrooms.evaluation.study.recipes import O4_REAL_SOURCES, recipe_population

    results = _script("population_o4_results")
    chunks = sorted((RELEASE / "population" / "chunks").glob("events-*.xml.gz"))
    assert chunks, "the release's committed population has no chunk"
    pop, _ = recipe_population("o4-real", 15000, seed=2)
    assert (RELEASE / "population" / "population.key").read_text().strip() == pop.key()
    events = population_events(chunks, prefix="o4real")
    text = results.provenance("o4-real", RELEASE / "population", chunks, events, [], {}, 15000, 2,
                              ["Code: `abc` 6."])
    assert text.startswith("# O4 population (recipe `o4-real`): provenance")
    for source in O4_REAL_SOURCES:
        assert f"- {source}" in text
    assert "{'H1': 155.0, 'L1': 160.0, 'V1': 55.0}" in text
    assert "| O4a | 237 | 0.312 | H1 0.675, L1 0.690 |" in text and "| O4b | 293 |" in text and "| O4c | 230 |" in text
    assert "network SNR 8.50 for a coincidence, 10.00 for one detector" in text
    assert "apply_o4_real(\"events-k.xml.gz\", 2+1+k)" in text and "--duty-cycle 1.0" in text
    for k, f in enumerate(chunks):
        assert f"\n| {k} | {len(coinc_ids(f))} | " in text
    assert f"| all {len(chunks)} | {sum(len(coinc_ids(f)) for f in chunks)} | |" in text
    assert "Virgo at 78" not in text and "Code: `abc` 6." in text


def _settings(**bench_keys) -> bench.BenchSettings:
    return bench.BenchSettings(config=PlanningConfig(nside=64), solvers=("greedy",), n_injections=300,
                               bench=BenchConfig(legacy_scoring=False, **bench_keys))


def _study(client, maps: Path, out: Path, settings: bench.BenchSettings) -> study.StudyOutcome:
    return study.run_study(study.StudySettings(bench=settings, out=out, cache=out.parent / "cache",
                                               scheduler=client.scheduler.address, figures=False),
                           study.StudyInputs(maps=str(maps)))


def test_seeding_the_committed_records_makes_a_second_study_plan_nothing(tmp_path, data_dir, client):
    """A tiny study (one small map, the greedy row), its records committed and seeded into a new ROOT: the
    second study plans nothing there and appends nothing; under another configuration it plans again."""
    maps = tmp_path / "maps"
    maps.mkdir()
    shutil.copy(data_dir / "skymaps" / "S200129m_cWB_RING.fits.gz", maps)
    settings = _settings(gwemopt_cache_dir=str(tmp_path / "first" / "gwemopt-cache"))
    first = _study(client, maps, tmp_path / "first" / "study", settings)
    assert len(first.run.executed) == 1
    # what population_o4_results.py commits, and population_o4.sh seeds a new ROOT from (population_o4_seed.py)
    committed = tmp_path / "committed"
    (tmp_path / "first" / "config.toml").write_text("[bench]\ngwemopt_cache_dir = 'x'\n")
    _script("population_o4_results").commit_study(tmp_path / "first", committed / "study")
    copy = [json.loads(x) for x in gzip.open(committed / "study" / "results.jsonl.gz", "rt")]
    assert len(copy) == 1 and all("config" not in r and r["ok"] for r in copy)
    root = tmp_path / "second"
    seeded = _run("benchmarks/science/population_o4_seed.py", "--population", "o4-real", "--from",
                  str(committed / "population"), "--root", str(root), "--config", str(root / "config.toml"))
    assert seeded.returncode == 0, seeded.stderr
    assert "1 result record(s) seeded" in seeded.stderr
    assert (root / "config.toml").read_bytes() == (tmp_path / "first" / "config.toml").read_bytes()
    lines = (root / "study" / "results.jsonl").read_text().splitlines()
    again = _study(client, maps, root / "study", settings)  # another directory, the same configuration
    assert again.run.executed == [] and again.run.failed == []
    assert (root / "study" / "results.jsonl").read_text().splitlines() == lines  # nothing planned, nothing appended
    assert [r["coverage"] for r in again.run.rows] == [r["coverage"] for r in first.run.rows]
    assert _run("benchmarks/science/population_o4_seed.py", "--population", "o4-real", "--from",
                str(committed / "population"), "--root", str(root), "--config",
                str(root / "config.toml")).stderr.count("0 result record(s) seeded") == 1  # idempotent
    # a configuration naming another gwemopt cache (a new ROOT's default) is another configuration: all again
    moved = _study(client, maps, root / "study", _settings(gwemopt_cache_dir=str(root / "gwemopt-cache")))
    assert len(moved.run.executed) == 1


def test_an_event_whose_rows_are_all_done_is_not_localised_again(tmp_path, client):
    from mushrooms.evaluation.study.graph import run_graph
    from mushrooms.evaluation.study.provenance import digest
    from mushrooms.evaluation.study.recipes import RECIPES
    from mushrooms.evaluation.study.run import study_bench_settings
    from mushrooms.evaluation.study.store import ResultStore, result_key, study_config

    chunk = next(f for f in sorted((RELEASE / "population" / "chunks").glob("events-*.xml.gz"))
                 if study.coinc_ids(f))
    loc = RECIPES["o4-real"].localisation
    maps = study.maps_from_events(chunk, tmp_path / "cache", loc)
    settings = study_bench_settings(_settings())
    config_hash = digest(study_config(settings))
    store = ResultStore(tmp_path / "study" / "results.jsonl")
    for m in maps:  # finished on another machine: the rows are there, the maps are not
        store.append(dict(kind="result", key=result_key(m.key, "greedy", config_hash), map=m.key, skymap=m.name,
                          solver="greedy", ok=True, row=dict(solver="greedy", coverage=0.5)))
    run = run_graph(client, maps, settings, tmp_path / "study", loc)
    assert run.executed == [] and run.localisations == []
    assert not any(Path(m.path).exists() for m in maps)
    assert not (tmp_path / "study" / "localisations.jsonl").exists()
    assert [r["coverage"] for r in run.rows] == [0.5] * len(maps)


def _partial_rows(second_commit: str) -> list[dict]:
    rows = []
    for k in range(6):
        have = SIX if k < 4 else (SIX[:4] if k == 4 else SIX[:1])
        for j, solver in enumerate(have):
            v = 0.1 * (k + 1) - 0.01 * j
            rows.append(dict(event=f"e{k}", solver=solver, coverage=v, coverage_executed=v, coverage_pairs=v,
                             coverage_executed_single_queue=0.0 if solver == "gwemopt-o4" else v / 2,
                             efficiency_two_detections=v / 10, efficiency_optimistic=v / 5,
                             open_shutter_s=3600.0, valid=True, event_class="BNS" if k % 2 else "NSBH",
                             distance_mpc=100.0 * (k + 1), area90_deg2=50.0 * (k + 1), status="ok",
                             commit=second_commit if (k, solver) == (3, "greedy") else "af0ff7d"))
    for j, solver in enumerate(SIX):  # all six ran, one failed (no plan scored): not comparable either
        failed = solver == "gwemopt-o4"
        rows.append(dict(event="e6", solver=solver, coverage=None if failed else 0.3, coverage_executed=None
                         if failed else 0.3, status="error: RuntimeError: gwemopt died" if failed else "ok",
                         event_class="BNS", distance_mpc=300.0, area90_deg2=90.0, commit="af0ff7d"))
    return rows


@pytest.mark.parametrize("second_commit", ["af0ff7d", "0123abc"])
def test_release_tables_of_a_partial_run_list_the_unfinished_events_and_warn_of_mixed_commits(tmp_path,
                                                                                             second_commit):
    csv = tmp_path / "results.csv"
    write_population_csv(_partial_rows(second_commit), csv)
    done = _run("benchmarks/science/release_tables.py", str(csv), "-o", str(tmp_path / "t.md"), "--draws", "200")
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "t.md").read_text()
    mixed = second_commit != "af0ff7d"
    assert text.startswith("**WARNING: NOT ONE FROZEN RELEASE. These rows come from 2 commit(s) `0123abc`, "
                           "`af0ff7d`") == mixed
    assert "4 events with a row of every row name (of 7); 24 (event, row) rows" in text
    assert ("3 event(s) of 7 lack a row (of service, service-grg, greedy, gwemopt-o4, gwemopt-skyportal, "
            "gwemopt-repaired) and are left out of every table below, paired differences included") in text
    assert ("e4 (no gwemopt-skyportal, gwemopt-repaired); e5 (no service-grg, greedy, gwemopt-o4, "
            "gwemopt-skyportal, gwemopt-repaired); e6 (no gwemopt-o4 (failed))") in text
    lines = text.splitlines()
    paired = lines[lines.index(next(ln for ln in lines if ln.startswith("## Per-event paired"))) + 4:][:5]
    assert [ln.split(" | ")[0] for ln in paired] == ["| " + s for s in SIX[1:]]
    assert all("(0/4/0 of 4)" in ln for ln in paired)  # each row 0.01 x j below the service on all 4 events
    assert "| gwemopt-o4 | 4 | 0 | 0 | 4 | 4 |" in lines  # zero executions as submitted today, per row
    row = next(ln for ln in lines if ln.startswith("| service | 4 | "))
    assert "0.250 [" in row and " / 0.250 [" in row  # mean [95 %] / median [95 %] over the four complete events
