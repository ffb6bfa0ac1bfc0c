"""Issue 53, phase 2: a ``PlanningProblem`` for any described telescope (``prepare_problem(..., telescope=)``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.prepare import prepare_problem

SOUTH = Path("/work/shared/data/skymaps/public/obs-scenarios_sim6_HKL.multiorder.fits")


def test_the_default_configuration_records_no_telescope():
    cfg = PlanningConfig()
    assert cfg.telescopes == ("ztf",) and "telescopes" not in cfg.record()
    assert list(PlanningConfig(telescopes=("ls4",), filters=("i",)).record()["telescopes"]) == ["ls4"]


def test_a_telescopes_defaults_and_a_set_key_wins():
    ls4 = load_description("ls4")
    cfg = PlanningConfig.for_telescope(ls4, {"nside": 64, "moon_sep_min_deg": 30.0})
    assert cfg.telescopes == ("ls4",) and cfg.exposure_s == 45.0 and cfg.filters == ("i",)
    assert cfg.dec_min_deg == -90.0 and cfg.dec_max_deg == 30.0 and cfg.ha_max_h == 5.0
    assert cfg.moon_sep_min_deg == 30.0 and cfg.nside == 64  # set in [scheduler]: it wins
    assert cfg.slew.readout_s == 10.0 and cfg.slew.ha_vmax_deg_s == 1.0
    ztf = PlanningConfig.for_telescope(load_description("ztf"), {})
    assert ztf == PlanningConfig() and ztf.record() == PlanningConfig().record()


def test_filters_are_checked_against_the_telescopes():
    with pytest.raises(ValueError, match="filters must be ls4 filters"):
        PlanningConfig(telescopes=("ls4",), filters=("r",))
    with pytest.raises(ValueError, match="filters must be ZTF filters"):
        PlanningConfig(filters=("J",))
    assert PlanningConfig(telescopes=("winter",), filters=("J",)).filters == ("J",)


def test_an_unknown_telescope_is_refused_with_a_guess():
    with pytest.raises(ValueError, match="did you mean 'decam'"):
        PlanningConfig(telescopes=("decan",))


def test_prepare_problem_for_ls4_uses_its_grid_and_carries_its_name():
    if not SOUTH.is_file():
        pytest.skip("the shared sky maps are not here")
    ls4 = load_description("ls4")
    cfg = PlanningConfig.for_telescope(ls4, {"nside": 64, "solver": "greedy"})
    skymap = read_skymap(SOUTH, nside=64)
    problem = prepare_problem(skymap, cfg, skymap.event_time, telescope=ls4)
    assert problem.telescope == "ls4" and problem.field_ids.size > 0
    assert np.isin(problem.field_ids, ls4.grid.ids).all()
    with pytest.raises(ValueError, match="telescope"):
        prepare_problem(skymap, PlanningConfig(nside=64), problem.start, telescope=ls4)
    ztf = prepare_problem(skymap, PlanningConfig(nside=64, solver="greedy"), problem.start)
    assert ztf.telescope == "ztf"
