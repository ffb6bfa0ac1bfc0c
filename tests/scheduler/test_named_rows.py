"""Every MILP row belongs to a block named after its equation, and a written-out LP file carries the names.

The models are the ones the planner itself builds on the packaged map (captured on their way to the real
HiGHS solve), plus the exact model (C0-C6) on a reduced instance of it.
"""

from __future__ import annotations

import re
from importlib.resources import files
from pathlib import Path

import highspy
import numpy as np
import pytest
from astropy.time import Time

from mushrooms.evaluation.reduced import reduced_problem
from mushrooms.scheduler_core import PlanningConfig, make_plan, prepare_problem, read_skymap
from mushrooms.scheduler_core.schedulers.blocks import schedule as block_schedule
from mushrooms.scheduler_core.schedulers.detection import stage as detection_slots
from mushrooms.scheduler_core.schedulers.slots import schedule as slot_schedule
from mushrooms.scheduler_core.schedulers.portfolio.continuous import build_exact_model
from mushrooms.scheduler_core.schedulers.milp.lp_file import write_lp
from mushrooms.scheduler_core.schedulers.milp.rows import lp_label, row_names
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp

MAP = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
NIGHT = Time("2019-05-01T03:00:00", scale="utc")  # the map's sky is up (at its merger time it is near the Sun)
#: a farther event, where expected detections and coverage differ (the detection model runs)
FAR_MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def equations(model) -> set[str]:
    """The equation numbers (``S2``, ``B11``) of a model's row blocks."""
    return {b.name.split()[0] for b in model.row_blocks}


@pytest.fixture(scope="module")
def skymap():
    return read_skymap(MAP, nside=64)


def planner_models(skymap, monkeypatch, module, solver: str, objective: str, start: Time = NIGHT) -> list:
    """The MILPs ``module`` hands to the real solver while ``make_plan`` runs."""
    seen = []

    def spy(model, *args, **kwargs):
        seen.append(model)
        return solve_milp(model, *args, **kwargs)

    monkeypatch.setattr(module, "solve_milp", spy)
    cfg = PlanningConfig(solver=solver, objective=objective, nside=64, time_limit_s=6, detection_time_limit_s=3,
                         bound_time_limit_s=0)
    make_plan(skymap, cfg, start=start)
    assert seen, f"{solver}/{objective} solved no MILP"
    return seen


def assert_rows_tiled_by_named_blocks(model) -> None:
    starts = [b.start for b in model.row_blocks]
    stops = [b.stop for b in model.row_blocks]
    assert starts[0] == 0 and stops[-1] == model.n_rows
    assert starts[1:] == stops[:-1], "blocks must follow one another without gaps"
    assert all(re.match(r"^[A-Z]\d+ \S", b.name) for b in model.row_blocks), [b.name for b in model.row_blocks]
    assert sum(f.size for f in model.col_families) == model.n_vars


def test_slot_model_rows_are_s1_to_s3(skymap, monkeypatch):
    for m in planner_models(skymap, monkeypatch, slot_schedule, "slots", "coverage"):
        assert_rows_tiled_by_named_blocks(m)
        assert equations(m) == {"S1", "S2", "S3"}
        assert [f.name for f in m.col_families] == ["x", "z", "y"]


def test_block_model_rows_are_b1_to_b11(skymap, monkeypatch):
    models = planner_models(skymap, monkeypatch, block_schedule, "blocks", "coverage")
    for m in models:
        assert_rows_tiled_by_named_blocks(m)
        assert equations(m) == {f"B{i}" for i in range(1, 12)}
        b2 = next(b for b in m.row_blocks if b.name.startswith("B2 "))
        assert b2.n_rows == next(f.size for f in m.col_families if f.name == "B")  # one row per B[i, k]


def test_detection_model_is_the_slot_rows_then_x3_x4_x6(monkeypatch):
    far = read_skymap(FAR_MAP, nside=64)
    models = planner_models(far, monkeypatch, detection_slots, "slots", "detection", start=far.event_time)
    for m in models:
        assert_rows_tiled_by_named_blocks(m)
        names = [b.name.split()[0] for b in m.row_blocks]
        assert names[:3] == ["S1", "S2", "S3"] and names[3:5] == ["X3", "X4"]
        assert set(names[5:]) <= {"X6"}


def test_exact_model_rows_are_c1_to_c6_and_c4_orders_every_pair(skymap):
    problem = reduced_problem(prepare_problem(skymap, PlanningConfig(solver="greedy", nside=64), NIGHT), 6)
    model = build_exact_model(problem)
    m = model.milp
    assert_rows_tiled_by_named_blocks(m)
    assert {"C3", "C4", "C5"} <= equations(m) <= {f"C{i}" for i in range(1, 7)}
    c3 = sum(b.n_rows for b in m.row_blocks if b.name.startswith("C3 "))
    assert c3 == 3 * int(model.data.pairable.sum())  # two orders and d_f <= x_f per pairable field


def test_an_lp_file_written_from_a_model_carries_the_block_names_and_is_the_same_model(skymap, tmp_path):
    problem = reduced_problem(prepare_problem(skymap, PlanningConfig(solver="greedy", nside=64), NIGHT), 6)
    m = build_exact_model(problem).milp
    path = tmp_path / "exact.lp"
    write_lp(m, path)
    text = path.read_text()
    for b in m.row_blocks:
        assert f"{lp_label(b.name)}.0" in text and f"{lp_label(b.name)}.{b.n_rows - 1}" in text
    assert "C3_cadence.0" in text and "C4_one_exposure_at_a_time.0" in text
    # HiGHS reads the file back as the same model: the same rows, by name, and the same optimum
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    assert h.readModel(str(path)) == highspy.HighsStatus.kOk
    lp = h.getLp()
    assert lp.num_row_ == m.n_rows and lp.num_col_ == m.n_vars
    assert list(lp.row_names_) == row_names(m.row_blocks)
    h.setOptionValue("mip_rel_gap", 0.0)
    h.run()
    direct = solve_milp(m, "highs", 60.0, mip_gap=0.0, threads=0)
    assert direct.status == "optimal"
    assert h.getInfo().objective_function_value == pytest.approx(direct.objective, abs=1e-9)


def test_a_model_without_names_is_written_with_default_names(tmp_path):
    import scipy.sparse as sp

    from mushrooms.scheduler_core.schedulers.milp.solvers import MilpModel

    A = sp.csr_matrix(np.array([[1.0, 1.0]]))
    m = MilpModel(np.array([1.0, 2.0]), A, np.array([-np.inf]), np.array([1.0]), np.zeros(2), np.ones(2),
                  np.array([True, True]))
    write_lp(m, tmp_path / "plain.lp")
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    assert h.readModel(str(tmp_path / "plain.lp")) == highspy.HighsStatus.kOk
    h.run()
    assert h.getInfo().objective_function_value == pytest.approx(2.0)
