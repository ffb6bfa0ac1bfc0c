"""The study's simulation stage: chunked realisation with ligo.skymap's tools.

The chunk bookkeeping is checked on its own; the injection splitter and one
chunk's realisation run on the real LIGO-LW files and the real
``bayestar-realize-coincs`` (three injections of the packaged O3 BNS
population, ~10 s).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from mushrooms.evaluation import study


def test_chunks_partition_the_injections_and_do_not_change_the_population_key():
    pop = study.Population(n_injections=105, chunk=20)
    chunks = pop.chunks()
    assert chunks[0] == (0, 20) and chunks[-1] == (100, 105) and len(chunks) == 6
    assert all(b == c for (_, b), (c, _) in zip(chunks, chunks[1:]))
    assert pop.key() == study.Population(n_injections=105, chunk=7).key()
    assert pop.key() != study.Population(n_injections=106, chunk=20).key()
    with pytest.raises(ValueError):
        study.Population(chunk=0).chunks()


def test_chunks_needed_is_the_shortest_realised_prefix_whatever_the_finishing_order():
    counts = {0: 1, 1: 0, 2: 3, 3: 2}
    assert study.chunks_needed(counts, 10, 4) == 3
    assert study.chunks_needed(dict(reversed(list(counts.items()))), 10, 4) == 3
    assert study.chunks_needed({0: 1, 2: 9}, 10, 4) is None  # chunk 1 could still hold them
    assert study.chunks_needed({0: 1, 1: 1}, 2, 4) == 2  # all realised, short of the target
    assert study.chunks_needed({0: 1, 1: 1}, 2, None) == 2
    assert study.chunks_needed({0: 1}, 2, None) is None


def _sim_ids(path):
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    doc = ligolw_utils.load_filename(str(path), contenthandler=ContentHandler)
    return [int(r.simulation_id) for r in lsctables.SimInspiralTable.get_table(doc)]


def _sim_rows(path):
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    doc = ligolw_utils.load_filename(str(path), contenthandler=ContentHandler)
    return [(r.mass1, r.mass2, r.distance) for r in lsctables.SimInspiralTable.get_table(doc)]


def test_split_injections_keeps_each_injection_once_in_order(tmp_path):
    source = study.DEFAULT_EVENTS
    ids = _sim_ids(source)
    parts = []
    for k, (a, b) in enumerate(study.Population(n_injections=len(ids), chunk=8).chunks()):
        target = tmp_path / f"part{k}.xml"
        assert study.split_injections(source, a, b, target) == b - a
        parts.append(_sim_ids(target))
    assert [len(p) for p in parts] == [8, 8, len(ids) - 16]
    assert sum(parts, []) == ids


@pytest.mark.skipif(shutil.which("bayestar-realize-coincs") is None, reason="needs ligo.skymap's tools")
def test_realize_chunk_runs_the_real_tool_and_caches_its_events(tmp_path):
    pop_dir = tmp_path / "pop"
    pop_dir.mkdir()
    subprocess.run(["bayestar-sample-model-psd", "-o", "psds.xml",
                    *sum(([f"--{d}", m, f"--{d}-scale", str(s)] for d, m, s in study.Population().psd_scales), [])],
                   cwd=pop_dir, check=True, capture_output=True)
    injections = pop_dir / "injections.xml"
    study.split_injections(study.DEFAULT_EVENTS, 0, 6, injections)
    pop = study.Population(n_injections=6, chunk=3, seed=5)
    first = study.realize_chunk(pop, str(injections), 1)
    assert first["chunk"] == 1 and first["injections"] == 3 and not first["cached"]
    assert Path(first["events"]).name == "events-0001.xml.gz" and first["cpu_s"] > 0
    assert first["coincidences"] == len(study.coinc_ids(first["events"]))
    # these three injections were loud enough once: with fresh noise most still are
    assert 1 <= first["coincidences"] <= 3
    # the tool renumbers its injections: compare them by their (exact) masses and distances
    chunk_rows = _sim_rows(injections)[3:6]
    assert set(_sim_rows(first["events"])) <= set(chunk_rows)
    assert not set(_sim_rows(first["events"])) & set(_sim_rows(injections)[:3])
    again = study.realize_chunk(pop, str(injections), 1)
    assert again["cached"] and again["events"] == first["events"]
    assert again["coincidences"] == first["coincidences"]


@pytest.mark.parametrize("args, says", [
    (["--detections", "5"], "--detections goes with --simulate"),
    (["--only-simulate"], "--only-simulate goes with --simulate"),
    (["--simulate", "100", "--chunk", "0"], "--chunk must be >= 1"),
    (["--simulate", "100", "--detections", "0"], "--detections must be >= 1"),
])
def test_bad_simulation_options_are_one_line_and_exit_2(tmp_path, capsys, args, says):
    from mushrooms.cli import main as cli_main

    assert cli_main(["study", *args, "--workers", "1", "--out", str(tmp_path / "out"),
                     "--cache", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not (tmp_path / "cache").exists()  # refused before any cluster or tool ran


def test_a_failing_tool_stops_the_simulation_with_one_line(tmp_path, monkeypatch, capsys):
    """No simulation tools on PATH: the injection task fails, the study says so and exits 1."""
    from mushrooms.cli import main as cli_main

    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setenv("MUSHROOMS_PROGRESS", "0")
    rc = cli_main(["study", "--simulate", "100", "--workers", "1", "--out", str(tmp_path / "out"),
                   "--cache", str(tmp_path / "cache")])
    err = capsys.readouterr().err
    assert rc == 1
    assert "simulation failed: injecting" in err and "bayestar-sample-model-psd not found" in err
    assert not list((tmp_path / "cache").rglob("injections.xml"))


def _seed_chunks(tmp_path, pop, chunks):
    """The cache of ``pop`` under ``tmp_path`` holding realised chunks (the packaged events file as each)."""
    d = tmp_path / pop.key() / f"realized-{pop.chunk}"
    d.mkdir(parents=True)
    for k in chunks:
        shutil.copy(study.DEFAULT_EVENTS, d / f"events-{k:04d}.xml.gz")
    return d


def test_a_cache_of_realised_chunks_is_taken_without_injecting_again(tmp_path):
    pop = study.Population(n_injections=600, chunk=300, seed=11)
    _seed_chunks(tmp_path, pop, [0, 1])
    n = len(study.coinc_ids(study.DEFAULT_EVENTS))
    files, records = study.simulate_population(pop, tmp_path, client=None, detections=n + 1)
    assert [Path(f).name for f in files] == ["events-0000.xml.gz", "events-0001.xml.gz"]
    assert [(r["chunk"], r["cached"], r["coincidences"], r["cpu_s"]) for r in records] == [
        (0, True, n, 0.0), (1, True, n, 0.0)]
    assert not (tmp_path / pop.key() / "injections.xml").exists()  # bayestar-inject never ran
    assert study.cached_chunk(pop, tmp_path, 2) is None


def test_on_a_cluster_the_cached_chunks_are_taken_without_a_task(tmp_path):
    from distributed import Client, LocalCluster

    pop = study.Population(n_injections=900, chunk=300, seed=11)
    _seed_chunks(tmp_path, pop, [0, 1, 2])
    n = len(study.coinc_ids(study.DEFAULT_EVENTS))
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        files, records = study.simulate_population(pop, tmp_path, client=client, detections=2 * n)
    assert [Path(f).name for f in files] == ["events-0000.xml.gz", "events-0001.xml.gz"]
    assert all(r["cached"] for r in records) and len(records) == 2  # chunk 2 was not needed
    assert not (tmp_path / pop.key() / "injections.xml").exists()  # no injections: a realisation task would have failed
