"""A field whose windows cannot hold its whole g-r-g sequence is still planned in its first two visits (F10).

Issue 55 (grgfix, finding 1): on o4real-0000-3 (a 44 deg2 BNS seen only in the last 46-60 min of two
nights) the service under g-r-g at 180 s answered ``not_observable`` while the pair covers 0.59: a g-r-g
sequence needs two cadences and an exposure (63 min) inside a window, so the schedulers planned no field,
though F1 credits a field whole by its g and r. Here the same on the test map: 50 min of night left, two
hours of horizon (real map MS220722v, nside 64, real greedy and hybrid, the real checker).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, prepare_problem
from mushrooms.scheduler_core.plan.observability import not_observable
from mushrooms.scheduler_core.sky.skymap import read_skymap

#: The map's fields set (morning twilight) 13.9 h after its merger: start 50 min before.
SHORT_S = 13.9 * 3600.0 - 50 * 60.0
GRG = PlanningConfig(solver="greedy", filters=("g", "r", "g"), exposure_s=180.0, nside=64, horizon_h=2.0,
                     time_limit_s=3.0, detection_time_limit_s=1.0, threads=1)
PAIR = PlanningConfig(solver="greedy", filters=("g", "r"), exposure_s=180.0, nside=64, horizon_h=2.0, threads=1)


@pytest.fixture(scope="module")
def skymap(data_dir):
    return read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=GRG.nside)


@pytest.fixture(scope="module")
def short_start(skymap):
    return skymap.event_time + TimeDelta(SHORT_S, format="sec")


def _visits(plan):
    out: dict[int, list] = {}
    for o in plan.observations:
        out.setdefault(o.field_id, []).append(o)
    return {f: sorted(v, key=lambda o: o.start) for f, v in out.items()}


def test_greedy_plans_the_pairs_a_night_too_short_for_the_sequence_leaves(skymap, short_start):
    grg = make_plan(skymap, GRG, start=short_start)
    pair = make_plan(skymap, PAIR, start=short_start)
    assert pair.metrics.coverage > GRG.min_coverage
    assert grg.metrics.coverage == pytest.approx(pair.metrics.coverage, abs=1e-6)
    assert {tuple(o.filter for o in v) for v in _visits(grg).values()} == {("g", "r")}
    report = check_plan(grg, skymap, GRG)
    assert report.ok, report.problems[:3]


def test_the_service_answers_with_a_plan_not_not_observable(skymap, short_start):
    cfg = dataclasses.replace(GRG, solver="hybrid")
    plan = make_plan(skymap, cfg, start=short_start)
    assert not_observable(plan, skymap, cfg) is None
    assert plan.metrics.coverage > GRG.min_coverage
    assert check_plan(plan, skymap, cfg).ok


def test_a_sequence_is_cut_only_where_its_next_visit_has_no_window(skymap):
    """(F10) on a whole night: fields keep their three visits, and a field cut short could not take its next one
    anywhere from a cadence after its last visit to the pair separation after its first."""
    start = skymap.event_time + TimeDelta(6 * 3600.0, format="sec")
    cfg = dataclasses.replace(GRG, horizon_h=12.0)
    plan = make_plan(skymap, cfg, start=start)
    problem = prepare_problem(skymap, cfg, start)
    w = problem.windows
    visits = _visits(plan)
    lengths = [len(v) for v in visits.values()]
    assert lengths.count(3) > 0 and lengths.count(2) > 0 and min(lengths) >= 2  # the night's last batch is cut
    for fid, v in visits.items():
        assert tuple(o.filter for o in v) == cfg.filters[:len(v)]
        if len(v) == 3:
            continue
        lo, hi = v[-1].start + cfg.cadence_s, min(v[0].start + cfg.pair_separation_s, cfg.horizon_s - cfg.exposure_s)
        sel = w.field_ids == fid
        fits = (np.maximum(w.start[sel], lo) + cfg.exposure_s <= w.end[sel]) & (np.maximum(w.start[sel], lo) <= hi)
        assert not fits.any(), (fid, [o.start for o in v])
    assert check_plan(plan, skymap, cfg).ok
