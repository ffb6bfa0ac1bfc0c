"""Bench arms: ``<row>@<arm>`` is the same row planned under the configuration with ``[bench.arms.<arm>]``'s keys
(fixed 300 s against the exposure menu, paired on the same map and injections)."""

from __future__ import annotations

import dataclasses
import shutil

import pytest

from mushrooms.cli import main as cli_main
from mushrooms.evaluation.bench import BenchConfig, BenchSettings, make_plots, read_csv, run_bench, summarize
from mushrooms.evaluation.bench.per_map import row_config
from mushrooms.evaluation.bench.settings import is_row_name, row_arm, row_solver
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.tables import TableError

#: Wall-clock cells (the detection stage's says how many grids it solved in its time).
TIMINGS = {"runtime_s", "prepare_s", "solve_s", "detection_stage"}
#: slots on a small map at nside 64 with a detection stage budget it does not use up (every grid solved, ~20 s), on
#: the work budget: two runs of one configuration publish the same plan (a clock-limited stage would not).
CFG = PlanningConfig(solver="slots", nside=64, threads=1, time_limit_s=64.0, detection_time_limit_s=60.0,
                     deterministic=True)
MENU = (30.0, 60.0, 120.0, 300.0, 600.0)
ARMS = BenchConfig(arms={"menu": {"exposure_menu_s": list(MENU)}, "one": {"exposure_menu_s": [300]}},
                   legacy_scoring=False)
CURVES = ("optimistic", "conservative", "nsbh")


def test_row_names_take_an_arm_on_our_rows_only() -> None:
    assert row_arm("hybrid-coverage@menu") == ("hybrid-coverage", "menu") and row_arm("hybrid") == ("hybrid", None)
    assert row_solver("hybrid-coverage@menu") == ("hybrid", "coverage")
    assert is_row_name("hybrid@menu") and is_row_name("greedy-detection@x")
    assert not is_row_name("gwemopt@menu") and not is_row_name("hybrid@") and not is_row_name("simplex@menu")


def test_an_arm_replaces_its_scheduler_keys_and_is_checked_when_read() -> None:
    settings = BenchSettings(config=CFG, bench=ARMS, solvers=("slots", "slots@menu"))
    base, cfg, objective = row_config(CFG, "slots@menu", settings)
    assert (base, objective) == ("slots", "detection") and cfg == dataclasses.replace(CFG, exposure_menu_s=MENU)
    assert row_config(CFG, "slots", settings)[1] == CFG
    assert row_config(CFG, "slots-detection@one", settings)[1].exposure_menu_s == (300.0,)
    with pytest.raises(ValueError, match="row slots-coverage@one: .*exposure_menu_s needs objective"):
        BenchSettings(config=CFG, bench=ARMS, solvers=("slots", "slots-coverage@one"))
    with pytest.raises(ValueError, match=r"row arm\(s\) deep not defined"):
        BenchSettings(config=CFG, bench=ARMS, solvers=("slots", "slots@deep"))
    with pytest.raises(TableError, match=r"unknown \[bench.arms.menu\] key\(s\): exposure_menu"):
        BenchConfig(arms={"menu": {"exposure_menu": [30]}})
    with pytest.raises(ValueError, match="exposure_menu_s needs objective"):
        BenchConfig(arms={"menu": {"exposure_menu_s": [30], "objective": "coverage"}})
    assert BenchConfig.from_mapping({"arms": {"menu": {"exposure_menu_s": [60, 300]}}}).arms["menu"] == \
        {"exposure_menu_s": [60, 300]}


@pytest.mark.slow  # a bench run: three slot plans and 400 injections on a real map, about 27 s
def test_fixed_and_menu_arms_on_a_real_map_are_paired(tmp_path, data_dir) -> None:
    skymap = data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    settings = BenchSettings(config=CFG, bench=ARMS, solvers=("slots", "slots@one", "slots@menu"), n_injections=400)
    fixed, one, menu = run_bench(settings, [skymap])
    assert [r["solver"] for r in (fixed, one, menu)] == ["slots", "slots@one", "slots@menu"]
    assert (fixed["arm"], one["arm"], menu["arm"]) == ("", "one", "menu")
    assert all(r["valid"] is True and r["objective"] == "detection" for r in (fixed, one, menu))
    # a menu of the configured exposure alone is the fixed plan: every cell the same, every difference zero
    # (but the bound: a menu row's is the one its plan publishes, planner._menu_upper_bound: U4 of the shortest
    # exposure, without the interval bound V the fixed plan's min(U4, V) has)
    skip = TIMINGS | {k for k in one if k.endswith(("_diff", "_differr"))} | {"solver", "arm", "bound",
                                                                               "coverage_over_bound"}
    assert {k: v for k, v in one.items() if k not in skip} == {k: v for k, v in fixed.items() if k not in skip}
    assert one["bound"] >= fixed["bound"] >= fixed["coverage"] and menu["bound"] >= menu["coverage"]
    assert fixed["exposure_mix"] == f"300:{fixed['n_exposures']}" and fixed["exposure_mean_s"] == 300.0
    for k in CURVES:
        assert one[f"efficiency_{k}_diff"] == 0.0 and one[f"efficiency_{k}_differr"] == 0.0
        assert one[f"expected_{k}_diff"] == 0.0
        # the menu row's paired columns are its own numbers against the fixed row's
        assert 0.0 <= menu[f"expected_{k}"] <= 1.0 and fixed[f"expected_{k}"] > 0.0
        assert menu[f"expected_{k}_diff"] == pytest.approx(menu[f"expected_{k}"] - fixed[f"expected_{k}"], abs=2e-6)
        assert menu[f"efficiency_{k}_diff"] == pytest.approx(menu[f"efficiency_{k}"] - fixed[f"efficiency_{k}"],
                                                             abs=2e-6)
        assert menu[f"efficiency_{k}_differr"] >= 0.0
    assert menu["coverage_diff"] == pytest.approx(menu["coverage"] - fixed["coverage"], abs=2e-6)
    lengths = [float(p.split(":")[0]) for p in menu["exposure_mix"].split()]
    assert set(lengths) <= set(MENU) and sum(int(p.split(":")[1]) for p in menu["exposure_mix"].split()) \
        == menu["n_exposures"]
    assert min(lengths) <= menu["exposure_mean_s"] <= max(lengths)
    text = summarize([fixed, one, menu])
    assert "paired against slots" in text and "slots@menu vs slots: 1 maps, plans valid 1/1" in text
    assert "slots@one vs slots" in text and "E A" in text and "coverage      A" in text
    written = make_plots([fixed, one, menu], tmp_path / "plots")
    assert {p.name for p in written} >= {"paired_slots_at_menu.png", "exposure_vs_distance_slots_at_menu.png"}
    assert all(p.stat().st_size > 0 for p in written)


def test_the_command_defines_arms_and_documents_them(tmp_path, data_dir, monkeypatch, capsys) -> None:
    maps = tmp_path / "maps"
    maps.mkdir()
    shutil.copy(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", maps)
    config = tmp_path / "c.toml"
    config.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\nthreads = 1\n[bench]\nlegacy_scoring = false\n')
    monkeypatch.setenv("MUSHROOMS_PROGRESS", "0")
    out = tmp_path / "r.csv"
    assert cli_main(["bench", str(maps), "--solvers", "greedy,greedy@m", "--arm", "m:exposure_menu_s=[60, 300]",
                     "--injections", "200", "--config", str(config), "-o", str(out)]) == 0
    rows = read_csv(out)
    assert [(r["solver"], r["arm"]) for r in rows] == [("greedy", ""), ("greedy@m", "m")]
    assert "expected_optimistic_diff" in rows[1] and rows[1]["expected_optimistic_diff"] == 0.0  # greedy: no menu
    capsys.readouterr()
    for bad, says in ((["--arm", "m:exposure_menu_s"], "expected ARM:KEY=VALUE"),
                      (["--arm", "m:exposure_menu_s=[60,"], "VALUE is not TOML"),
                      (["--arm", "m:exposure_menu_s=[5000]"], "[bench.arms.m] exposure_menu_s"),
                      (["--solvers", "greedy@nope"], "row arm(s) nope not defined")):
        args = ["bench", str(maps), "--solvers", "greedy,greedy@m", *bad, "--config", str(config), "-o",
                str(tmp_path / "x.csv")]
        assert cli_main(args) == 2
        assert says in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli_main(["bench", "--help"])
    helptext = " ".join(capsys.readouterr().out.split())
    assert "--arm ARM:KEY=VALUE" in helptext and "exposure_menu_s=[30,60,120,300,600]" in helptext
    assert "ROW@ARM" in helptext
