"""The certified bound's margin (``milp.md`` B1-B3): what HiGHS's gap and tolerances allow, checked against plans."""

from __future__ import annotations

import healpy as hp
import numpy as np
import pytest

from test_interval_bound import _crowded_problem
from test_checker import CFG, control_obs, kinds, plan_of
from mushrooms.scheduler_core import check_plan
from mushrooms.scheduler_core.plan.checker import polygon_coverage
from mushrooms.scheduler_core.plan.document import PlanMetrics
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.sky.skymap import SkyMap

#: HiGHS's relative MIP gap and its primal feasibility tolerance (the solves' settings).
GAP, PRIMAL_TOL = 1e-6, 1e-7
#: The crowded problem's V3 optimum (fields 1, 2 and 4: .3 + .22 + .1).
OPTIMUM = 0.62


def test_the_interval_bound_carries_the_solvers_gap_above_its_optimum():
    got = certified_upper_bound(_crowded_problem())
    assert got.method == "interval"
    # a solve stopped at the gap may stand up to GAP * v below the optimum: the margin covers that
    assert got.value >= OPTIMUM * (1.0 + GAP)
    assert got.value <= OPTIMUM * (1.0 + GAP) + PRIMAL_TOL + 1e-8  # and no more than the tolerances say


@pytest.fixture(scope="module")
def peaked_map():
    nside = 64
    prob = np.full(hp.nside2npix(nside), 1e-12)
    prob[hp.ang2pix(nside, 306.6, 31.5, lonlat=True)] = 1.0
    prob /= prob.sum()
    return SkyMap(prob=prob, nside=nside, event_time=None, object_id=None, distmu=None, distsigma=None,
                  distnorm=None, distmean=None, sha256="0" * 64, source="<peaked>")


def _metrics(coverage: float, bound: float) -> PlanMetrics:
    return PlanMetrics(coverage=coverage, solver="hand", status="feasible", mip_gap=None, runtime_s=0.0, n_fields=2,
                       n_exposures=4, upper_bound=bound, upper_bound_method="interval")


def test_the_checker_refuses_a_coverage_above_the_published_bound(peaked_map):
    obs = control_obs()
    coverage = polygon_coverage({o.field_id for o in obs}, peaked_map.prob)
    ok = check_plan(plan_of(obs, metrics=_metrics(coverage, coverage + 1e-6)), peaked_map, CFG)
    assert ok.ok, ok.problems
    bad = check_plan(plan_of(obs, metrics=_metrics(coverage, coverage - 1e-4)), peaked_map, CFG)
    assert not bad.ok and kinds(bad) == {"bound"}, bad.problems
