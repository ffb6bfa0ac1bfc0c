"""The benchmark as a library: ``[bench]`` as a typed section (BenchConfig), ``run_bench`` from Python.

``mushrooms bench`` is a shell over :func:`~mushrooms.evaluation.bench.run_bench`: the same rows
come out of Python and out of the command's CSV.
"""

from __future__ import annotations

import shutil

import pytest

from mushrooms.cli import main as cli_main
from mushrooms.evaluation.bench import BenchConfig, BenchSettings, read_csv, run_bench, summarize, write_csv
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.tables import TableError
from mushrooms.tool.config import Config, ConfigError

#: Wall-clock columns: the only ones allowed to differ between two runs of the same plan.
TIMINGS = {"runtime_s", "prepare_s", "solve_s"}
FAST = PlanningConfig(solver="greedy", nside=64, threads=1)


# ------------------------------------------------------------------------------------------- [bench]
@pytest.mark.parametrize("table, key, value, says", [
    ({"gwemopt_timout_s": 10.0}, "gwemopt_timout_s", None, "unknown [bench] key(s): gwemopt_timout_s"),
    ({"gwemopt_timeout_s": "600"}, "gwemopt_timeout_s", "600", "expected a number, got string"),
    ({"gwemopt_timeout_s": 0.5}, "gwemopt_timeout_s", 0.5, "[1, 86400] s"),
    ({"fixed_distance_mpc": 30000}, "fixed_distance_mpc", 30000, "[1, 20000] Mpc"),
    ({"detection_extra_s": -1.0}, "detection_extra_s", -1.0, "[0, 3600] s"),
    ({"legacy_scoring": "yes"}, "legacy_scoring", "yes", "expected a boolean, got string"),
    ({"gwemopt_cache_only": 1}, "gwemopt_cache_only", 1, "expected a boolean, got integer"),
    ({"maglim": {"g": 35.0}}, "maglim.g", 35.0, "[10, 30] mag"),
    ({"maglim": {"r": "21"}}, "maglim.r", "21", "expected a number"),
    ({"maglim": 21.7}, "maglim", 21.7, "expected a table"),
    ({"lightcurves": {"optimistic": 3}}, "lightcurves.optimistic", 3, "expected a string"),
])
def test_bench_config_names_the_refused_key_value_and_type(table, key, value, says) -> None:
    with pytest.raises(TableError) as err:
        BenchConfig.from_mapping(table)
    assert err.value.section == "bench" and err.value.key == key and err.value.value == value
    assert says in str(err.value) and "[bench]" in str(err.value)


def test_bench_config_reads_a_table_and_is_frozen() -> None:
    cfg = BenchConfig.from_mapping({"gwemopt_timeout_s": 600, "maglim": {"g": 21.0, "r": 20.5},
                                    "lightcurves": {"bright": "optimistic"}, "legacy_scoring": False})
    assert cfg.gwemopt_timeout_s == 600 and cfg.maglim == {"g": 21.0, "r": 20.5} and cfg.legacy_scoring is False
    assert cfg.lightcurves == {"bright": "optimistic"}
    assert BenchConfig.from_mapping({}) == BenchConfig()
    with pytest.raises(AttributeError):
        cfg.legacy_scoring = True  # type: ignore[misc]


def test_bench_is_a_section_of_the_config_read_once(tmp_path) -> None:
    assert Config().bench == BenchConfig()
    loaded = Config.from_mapping({"bench": {"fixed_distance_mpc": 40.0}, "scheduler": {"nside": 64}}, source="c.toml")
    assert loaded.bench.fixed_distance_mpc == 40.0 and loaded.scheduler.nside == 64
    with pytest.raises(ConfigError, match=r"^c.toml: unknown \[bench\] key\(s\): nope$"):
        Config.from_mapping({"bench": {"nope": 1}}, source="c.toml")


def test_bench_settings_refuse_unknown_rows_and_no_injections() -> None:
    assert BenchSettings(config=FAST, solvers=("greedy", "hybrid-coverage", "gwemopt")).reference == "greedy"
    with pytest.raises(ValueError, match="unknown solver"):
        BenchSettings(config=FAST, solvers=("greedy", "simplex"))
    with pytest.raises(ValueError, match="unknown solver"):
        BenchSettings(config=FAST, solvers=())
    with pytest.raises(ValueError, match="n_injections"):
        BenchSettings(config=FAST, solvers=("greedy",), n_injections=0)
    assert BenchSettings(config=FAST, solvers=("greedy", "slots"),
                         bench=BenchConfig(reference_solver="slots")).reference == "slots"


def test_a_bad_bench_table_is_one_line_and_exit_2(tmp_path, data_dir, capsys) -> None:
    config = tmp_path / "c.toml"
    config.write_text('[bench]\nmaglim = { g = 40.0 }\n')
    rc = cli_main(["bench", str(data_dir / "skymaps"), "--solvers", "greedy", "--config", str(config),
                   "-o", str(tmp_path / "r.csv")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 2 and err == f"mushrooms bench: error: {config}: [bench] maglim.g = 40: outside its range [10, 30] mag"
    assert not (tmp_path / "r.csv").exists()


# ------------------------------------------------------------------------------------------- run_bench
def test_run_bench_from_python_plans_and_scores_a_small_map(tmp_path, data_dir) -> None:
    skymap = data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    settings = BenchSettings(config=FAST, solvers=("greedy", "greedy-coverage"), n_injections=500)
    rows = run_bench(settings, [skymap])
    assert [(r["skymap"], r["solver"]) for r in rows] == [(str(skymap), "greedy"), (str(skymap), "greedy-coverage")]
    g, gc = rows
    assert g["status"] == "greedy" and g["valid"] is True and g["n_problems"] == 0
    assert 0.0 < g["coverage"] <= 1.0 and g["n_exposures"] > 0
    assert 0.0 < g["coverage_over_bound"] <= 1.0 and g["bound"] >= g["coverage"]  # the certified upper bound
    assert g["n_injections"] == 500 and 0.0 <= g["efficiency_optimistic"] <= 1.0
    assert "efficiency_optimistic_v1" in g  # [bench] legacy_scoring, on by default
    # greedy is a coverage heuristic under either objective: the same plan, paired difference exactly zero
    assert {k: v for k, v in gc.items() if k not in TIMINGS | {"solver"} and not k.endswith(("_diff", "_differr"))} \
        == {k: v for k, v in g.items() if k not in TIMINGS | {"solver", "coverage_diff"}}
    assert gc["efficiency_optimistic_diff"] == 0.0 and gc["efficiency_optimistic_differr"] == 0.0
    assert "greedy-coverage" in summarize(rows)


def test_run_bench_without_legacy_scoring_and_a_broken_map(tmp_path, data_dir) -> None:
    broken = tmp_path / "broken.fits"
    broken.write_bytes(b"SIMPLE  =                    T" + b"\0" * 100)
    settings = BenchSettings(config=FAST, solvers=("greedy",), n_injections=200,
                             bench=BenchConfig(legacy_scoring=False))
    (bad, good) = run_bench(settings, [broken, data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"])
    assert bad["status"].startswith("skymap_error") and bad["valid"] is False and bad["coverage"] == ""
    assert good["valid"] is True and not any(k.endswith("_v1") for k in good)


def test_the_command_writes_the_rows_run_bench_returns(tmp_path, data_dir, monkeypatch) -> None:
    maps = tmp_path / "maps"
    maps.mkdir()
    shutil.copy(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", maps)
    config = tmp_path / "c.toml"
    config.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\nthreads = 1\n[bench]\nlegacy_scoring = false\n')
    monkeypatch.setenv("MUSHROOMS_PROGRESS", "0")
    out = tmp_path / "cli.csv"
    assert cli_main(["bench", str(maps), "--solvers", "greedy", "--injections", "300", "--config", str(config),
                     "-o", str(out)]) == 0
    settings = BenchSettings(config=Config.from_mapping({"scheduler": {"solver": "greedy", "nside": 64,
                                                                       "threads": 1}}).scheduler,
                             bench=BenchConfig(legacy_scoring=False), solvers=("greedy",), n_injections=300)
    write_csv(run_bench(settings, sorted(maps.iterdir())), tmp_path / "py.csv")
    cli, py = read_csv(out), read_csv(tmp_path / "py.csv")
    assert len(cli) == 1 and cli[0]["coverage"] > 0
    assert [{k: v for k, v in r.items() if k not in TIMINGS} for r in cli] == \
        [{k: v for k, v in r.items() if k not in TIMINGS} for r in py]
