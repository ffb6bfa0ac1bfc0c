"""Expected detections (scheduler_core.source.detection) against the evaluation's injection recovery."""

from __future__ import annotations

import math

import pytest

from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.source.depth import ZTF_DEPTH
from mushrooms.scheduler_core.source.detection import expected_detections
from mushrooms.evaluation.efficiency import detection_efficiency, draw_injections
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.source.kilonova import load_kilonova
from mushrooms.scheduler_core.planner import make_plan
from mushrooms.scheduler_core.sky.skymap import read_skymap


def test_expected_detections_is_the_limit_of_the_monte_carlo_efficiency(data_dir) -> None:
    cfg = PlanningConfig(nside=64)
    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    plan = make_plan(sm, cfg, solver="greedy")
    fp = field_footprints(load_ztf_fields(), 64)
    n = 40_000
    inj = draw_injections(sm, n)
    for name in ("optimistic", "conservative", "nsbh"):
        kn = load_kilonova(name)
        e = expected_detections(plan, sm, fp, kn)
        mc = detection_efficiency(plan, sm, kn, ZTF_DEPTH, fp, inj)
        assert 0.0 < e < plan.metrics.coverage
        assert e == pytest.approx(mc, abs=4 * math.sqrt(mc * (1 - mc) / n) + 1e-3), name
