"""``mushrooms bench`` end to end on small inputs, the summary, gwemopt's schedule reader."""

from __future__ import annotations

import csv
import shutil
import sys

import pytest
from astropy.time import Time

from mushrooms.evaluation.bench import COLUMNS, best_of, read_csv, summarize
from mushrooms.cli import main as cli_main
from mushrooms.evaluation.gwemopt_baseline import parse_schedule, run_gwemopt
from mushrooms.scheduler_core.config import PlanningConfig

REQUIRED = ["skymap", "solver", "coverage", "efficiency_optimistic", "efficiency_conservative",
            "n_exposures", "runtime_s", "status", "valid"]


def test_bench_csv_on_one_small_map_with_greedy(tmp_path, data_dir, monkeypatch, capsys) -> None:
    maps = tmp_path / "maps"
    (maps / "sub").mkdir(parents=True)
    shutil.copy(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", maps / "sub")
    shutil.copy(data_dir / "skymaps" / "S200129m_cWB_RING.fits.gz", maps)  # no distance layers
    (maps / "notes.txt").write_text("not a sky map")
    monkeypatch.delenv("MUSHROOMS_GWEMOPT_PYTHON", raising=False)
    monkeypatch.setitem(sys.modules, "gwemopt", None)  # no gwemopt here: its rows come from the (empty) cache
    monkeypatch.setenv("MUSHROOMS_PROGRESS", "0")
    config = tmp_path / "bench.toml"
    config.write_text(f'[bench]\ngwemopt_cache_dir = "{tmp_path / "gwemopt-cache"}"\n')
    out = tmp_path / "results.csv"
    rc = cli_main(["bench", str(maps), "--solvers", "greedy,gwemopt", "--injections", "2000",
                   "-o", str(out), "--plots", str(tmp_path / "plots"), "--config", str(config)])
    assert rc == 0
    with open(out, newline="") as fh:
        header = next(csv.reader(fh))
    assert header[:9] == REQUIRED
    assert set(COLUMNS) <= set(header)
    assert len(header) == len(set(header))  # each column once: a duplicated name would write its value twice
    rows = read_csv(out)
    assert [(r["skymap"].split("/")[-1], r["solver"]) for r in rows] == [
        ("S200129m_cWB_RING.fits.gz", "greedy"), ("S200129m_cWB_RING.fits.gz", "gwemopt"),
        ("MS220722v_bayestar.multiorder.fits", "greedy"), ("MS220722v_bayestar.multiorder.fits", "gwemopt"),
    ]
    by = {(r["skymap"].split("/")[-1].split("_")[0], r["solver"]): r for r in rows}
    g = by[("MS220722v", "greedy")]
    assert g["status"] == "greedy" and g["valid"] is True
    assert 0.0 < g["coverage"] <= 1.0 and g["runtime_s"] > 0
    assert g["n_exposures"] > 0 and g["n_exposures"] % 2 == 0  # every field in both filters
    # the checker's recomputation (great-circle CCD edges) against the scheduler's footprints
    assert abs(g["coverage"] - g["coverage_reported"]) < 2e-4
    assert 0.0 <= g["efficiency_optimistic"] <= 1.0 and 0.0 <= g["efficiency_conservative"] <= 1.0
    assert g["n_injections"] == 2000
    cwb = by[("S200129m", "greedy")]
    assert cwb["efficiency_optimistic"] is None and "no distance layers" in cwb["note"]
    assert by[("MS220722v", "gwemopt")]["status"] == "unavailable"
    text = capsys.readouterr().out
    assert "greedy" in text and "cov mean" in text and "gwemopt: 2 map(s) without a plan" in text


def test_bench_rejects_bad_input(tmp_path, capsys) -> None:
    assert cli_main(["bench", str(tmp_path / "nope"), "-o", str(tmp_path / "r.csv")]) == 2
    assert cli_main(["bench", str(tmp_path), "--solvers", "greedy,foo", "-o", str(tmp_path / "r.csv")]) == 2
    assert cli_main(["bench", str(tmp_path), "--solvers", "greedy", "-o", str(tmp_path / "r.csv")]) == 2
    err = capsys.readouterr().err
    assert "not a directory" in err and "unknown solver" in err and "no sky maps" in err


def _r(m: str, s: str, cov: float, eff: float) -> dict:
    return {"skymap": m, "solver": s, "coverage": cov, "efficiency_optimistic": eff,
            "efficiency_conservative": eff / 2, "runtime_s": 1.0, "valid": True, "n_exposures": 10}


def test_summary_counts_wins_and_builds_the_papers_hybrid() -> None:
    rows = [
        _r("a", "greedy", 0.5, 0.2), _r("a", "milp", 0.6, 0.1), _r("a", "gwemopt", 0.4, 0.3),
        _r("b", "greedy", 0.5, 0.2), _r("b", "milp", 0.3, 0.1), _r("b", "gwemopt", 0.7, 0.3),
        _r("c", "greedy", 0.5, 0.2), _r("c", "milp", 0.5, 0.2), _r("c", "gwemopt", 0.5, 0.2),
    ]
    hyb = {r["skymap"]: r for r in best_of(rows, "milp", "gwemopt")}
    assert hyb["a"]["coverage"] == 0.6 and hyb["a"]["efficiency_optimistic"] == 0.1
    assert hyb["b"]["coverage"] == 0.7 and hyb["b"]["efficiency_optimistic"] == 0.3
    text = summarize(rows)
    assert "milp vs greedy: coverage 1/1/1" in text
    assert "milp vs gwemopt: coverage 1/1/1, eff_opti 0/2/1" in text
    assert "best(milp,gwemopt)" in text


SCHEDULE = """489 295.13032 4.55000 56143.29626 21.65000 299 0.25760 1.15073 g
1535 293.39478 8.15000 56143.29985 21.65000 609 0.18784 1.12299 g
489 295.13032 4.55000 56143.31000 21.65000 300 0.25760 1.15073 r
"""


def test_gwemopt_schedule_is_read_into_observations() -> None:
    start = Time(56143.29626, format="mjd", scale="utc")
    obs = parse_schedule(SCHEDULE, start, exposure_s=300.0)
    assert [o.field_id for o in obs] == [489, 1535, 489]
    assert [o.filter for o in obs] == ["g", "g", "r"]
    assert [o.block for o in obs] == [0, 0, 1]
    assert obs[0].start == pytest.approx(0.0, abs=1e-3)
    assert obs[1].start == pytest.approx((56143.29985 - 56143.29626) * 86400, abs=1e-2)
    # %d-truncated exposure times are snapped back to whole slots (300, 2*310-10)
    assert [o.exposure_s for o in obs] == [300.0, 610.0, 300.0]
    assert parse_schedule("", start) == ()


def test_gwemopt_without_interpreter_is_unavailable(tmp_path, monkeypatch) -> None:
    """No interpreter configured and gwemopt not importable here, or one configured that does not exist."""
    monkeypatch.delenv("MUSHROOMS_GWEMOPT_PYTHON", raising=False)
    monkeypatch.setitem(sys.modules, "gwemopt", None)  # as if not installed, whatever this environment holds
    run = run_gwemopt(tmp_path / "x.fits", Time("2020-01-01T00:00:00"), PlanningConfig())
    assert run.status == "unavailable" and "MUSHROOMS_GWEMOPT_PYTHON" in run.message
    assert run.observations == () and not list(tmp_path.iterdir())  # nothing was run, nothing written
    monkeypatch.setenv("MUSHROOMS_GWEMOPT_PYTHON", str(tmp_path / "no-python"))
    assert run_gwemopt(tmp_path / "x.fits", Time("2020-01-01T00:00:00"), PlanningConfig()).status == "unavailable"
    monkeypatch.delenv("MUSHROOMS_GWEMOPT_PYTHON")
    missing = run_gwemopt(tmp_path / "x.fits", Time("2020-01-01T00:00:00"), PlanningConfig(),
                          python=str(tmp_path / "no-python"))  # the configured ([bench] gwemopt_python) one
    assert missing.status == "unavailable"


@pytest.mark.slow
def test_real_gwemopt_runs_offline_and_converts(data_dir) -> None:
    """Needs MUSHROOMS_GWEMOPT_PYTHON (a venv with ``pip install gwemopt``); ~1 min."""
    from mushrooms.scheduler_core import check_plan, read_skymap
    from mushrooms.evaluation.gwemopt_baseline import gwemopt_plan, gwemopt_python

    if gwemopt_python() is None:
        pytest.skip("MUSHROOMS_GWEMOPT_PYTHON not set")
    path = data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    sm = read_skymap(path)
    cfg = PlanningConfig()
    run = run_gwemopt(path, sm.event_time, cfg, timeout_s=900)
    assert run.status == "ok", run.message
    assert all(o.filter in ("g", "r") for o in run.observations)
    assert all(0 <= o.start <= cfg.horizon_s for o in run.observations)
    assert all(o.exposure_s % 310 == 300 for o in run.observations)
    plan = gwemopt_plan(run, sm.event_time, cfg, sm.sha256, 0.0)
    report = check_plan(plan, sm, cfg)
    assert report.coverage >= 0.0


def test_the_detection_stage_line_tells_decisions_from_an_exhausted_budget() -> None:
    """A detection stage that kept the coverage plan by decision (no distance layers, at the detection ceiling)
    is not a stage the budget starved; only one that tried grids and solved none is (paired_table's line)."""
    from mushrooms.evaluation.bench.summary import paired_table

    def row(m: str, s: str, stage: str) -> dict:
        paired = {"expected_optimistic_diff": 0.0, "efficiency_optimistic_diff": 0.0} if stage else {}
        return {**_r(m, s, 0.5, 0.1), "detection_stage": stage, "exposure_mix": "300:10",
                "expected_optimistic": 0.1, **paired}

    tail = "; budget 4.0 s, took 0.001 s; 0 grid(s) solved, 0 below the floor"
    rows = [row("a", "greedy", ""), row("a", "hybrid", "coverage (no distance layers)" + tail),
            row("b", "greedy", ""), row("b", "hybrid", "coverage (at the detection ceiling)" + tail),
            row("c", "greedy", ""), row("c", "hybrid", "coverage" + tail.replace("took 0.001", "took 4.2"))]
    line = next(x for x in paired_table(rows, ["greedy", "hybrid"], ("optimistic",)) if "detection stage" in x)
    assert "solved no grid: A 0, B 1 maps" in line
    assert "kept by decision: A 0, B 2 maps (at the detection ceiling 1, no distance layers 1)" in line
