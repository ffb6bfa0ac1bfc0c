"""Pruning (lazy greedy max coverage) and weighted cells (merging keeps the optimum)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest_milp import random_problem, tiny_config, tiny_problem
from mushrooms.scheduler_core.schedulers.blocks.model import BlockParams, build_block_model
from mushrooms.scheduler_core.sky.cells import merge_cells, pixel_cells
from mushrooms.scheduler_core.schedulers.blocks.schedule import make_candidates, shortlist_footprints
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.windows import Windows
from mushrooms.scheduler_core.schedulers.blocks.prune import (SHORTLIST_MAX, SHORTLIST_MIN, default_shortlist_size,
                                            greedy_max_coverage, observable_time_s)
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp


def _naive_greedy(fp: Footprints, prob: np.ndarray, n: int) -> list[int]:
    uncovered = prob.copy()
    picked = []
    for _ in range(n):
        gains = [uncovered[fp.indices[fp.indptr[k]:fp.indptr[k + 1]]].sum() for k in range(len(fp.field_ids))]
        k = int(np.argmax(gains))
        if gains[k] <= 0:
            break
        picked.append(k)
        uncovered[fp.indices[fp.indptr[k]:fp.indptr[k + 1]]] = 0
    return picked


@pytest.mark.parametrize("seed", range(5))
def test_lazy_greedy_equals_the_plain_greedy(seed):
    problem = random_problem(seed, n_fields=30, nside=8)
    for n in (1, 5, 12, 30):
        lazy = greedy_max_coverage(problem.footprints, problem.prob, n)
        assert lazy.tolist() == _naive_greedy(problem.footprints, problem.prob, n)


def test_greedy_never_picks_useless_fields():
    problem = tiny_problem()
    prob = problem.prob.copy()
    prob[4] = 0.0  # field 4 now holds nothing
    picked = problem.field_ids[greedy_max_coverage(problem.footprints, prob, 5)]
    assert 4 not in picked
    assert picked[0] == 1  # fields 1 and 2 both hold 0.3: the tie goes to the lower row
    assert picked[1] == 5  # after field 1, field 2 only adds pixel 2 (0.1); field 5 adds 0.2


def test_observable_time_is_the_union_of_windows():
    w = Windows(np.array([1, 2, 3, 4]), np.array([-50.0, 100.0, 150.0, 900.0]), np.array([120.0, 200.0, 300.0, 2000.0]))
    assert observable_time_s(w, 1000.0) == pytest.approx(300.0 + 100.0)


def test_default_shortlist_size_from_the_horizon():
    problem = tiny_problem(tiny_config(n_fields=None))
    # 3600 s observable / (2 x 110 s) = 16.4 fields -> x 1.5 = 25, capped by the 5 candidates
    assert default_shortlist_size(problem) == 5
    big = random_problem(0, n_fields=200, nside=8, config=tiny_config(n_fields=None, horizon_h=24.0))
    assert SHORTLIST_MIN <= default_shortlist_size(big) == SHORTLIST_MAX
    assert default_shortlist_size(random_problem(0, config=tiny_config(n_fields=3))) == 3


@pytest.mark.parametrize("seed", range(4))
def test_cells_partition_the_covered_probability(seed):
    problem = random_problem(seed, n_fields=25, nside=8)
    fp = problem.footprints
    cells = merge_cells(fp, problem.prob)
    covered = np.unique(fp.indices)
    covered = covered[problem.prob[covered] > 0]
    assert cells.n_pixels == covered.size
    assert cells.n_cells < cells.n_pixels
    assert cells.weight.sum() == pytest.approx(problem.prob[covered].sum())
    # every pixel's field set is exactly the field set of one cell with that weight share
    member_sets = {}
    for k in range(len(fp.field_ids)):
        for p in fp.indices[fp.indptr[k]:fp.indptr[k + 1]]:
            member_sets.setdefault(int(p), set()).add(k)
    by_set = {}
    for p, s in member_sets.items():
        if problem.prob[p] > 0:
            by_set[frozenset(s)] = by_set.get(frozenset(s), 0.0) + problem.prob[p]
    got = {frozenset(cells.members(c).tolist()): w for c, w in enumerate(cells.weight)}
    assert got.keys() == by_set.keys()
    for key, w in by_set.items():
        assert got[key] == pytest.approx(w)


def test_cells_with_more_than_64_fields():
    problem = random_problem(1, n_fields=150, nside=16, config=tiny_config(n_fields=None, horizon_h=3.0))
    cells = merge_cells(problem.footprints, problem.prob)
    last = len(problem.field_ids) - 1
    assert any(last in cells.members(c) for c in range(cells.n_cells))
    assert cells.weight.sum() == pytest.approx(pixel_cells(problem.footprints, problem.prob).weight.sum())


@pytest.mark.parametrize("seed", range(3))
def test_cell_merging_keeps_the_optimum(seed):
    problem = random_problem(seed)
    params = BlockParams.from_config(problem.config)
    rows = np.arange(len(problem.field_ids))
    fp = shortlist_footprints(problem.footprints, rows)
    cand = make_candidates(problem, rows, params.least_duration_s(params.b_size))
    merged = merge_cells(fp, problem.prob)
    raw = pixel_cells(fp, problem.prob)
    assert merged.n_cells < raw.n_cells
    objectives = []
    for cells in (merged, raw):
        model = build_block_model(cand, cells, len(rows), params)
        res = solve_milp(model.milp, "highs", time_limit_s=60, mip_gap=0.0)
        assert res.status == "optimal"
        objectives.append(res.objective)
    # equal up to the solver feasibility tolerance (1e-6 per row)
    assert objectives[0] == pytest.approx(objectives[1], abs=1e-5)


def test_shortlist_footprints_slices_rows():
    problem = random_problem(2, n_fields=20)
    rows = np.array([7, 2, 19])
    sub = shortlist_footprints(problem.footprints, rows)
    assert sub.field_ids.tolist() == problem.field_ids[rows].tolist()
    for i, r in enumerate(rows):
        assert sub.pixels(int(sub.field_ids[i])).tolist() == problem.footprints.pixels(int(problem.field_ids[r])).tolist()
