"""Block ordering: exact open-path TSP equals brute force; the approximation is sound."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mushrooms.scheduler_core.config import SlewModel
from mushrooms.scheduler_core.schedulers.blocks.ordering import approx_path, exact_path, order_fields, path_cost
from mushrooms.scheduler_core.telescope.slew import slew_matrix


def _brute_force(cost: np.ndarray) -> float:
    n = cost.shape[0]
    return min(path_cost(cost, p) for p in itertools.permutations(range(n)))


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 7, 8])
def test_exact_path_equals_brute_force_on_real_slews(n):
    rng = np.random.default_rng(n)
    for _ in range(3):
        ra, dec = rng.uniform(0, 80, n), rng.uniform(-30, 70, n)
        cost = slew_matrix(ra, dec, SlewModel())
        order = exact_path(cost)
        assert sorted(order.tolist()) == list(range(n))
        assert path_cost(cost, order) == pytest.approx(_brute_force(cost))


def test_exact_path_on_an_asymmetric_matrix():
    rng = np.random.default_rng(7)
    cost = rng.uniform(1, 50, (7, 7))
    np.fill_diagonal(cost, 0)
    assert path_cost(cost, exact_path(cost)) == pytest.approx(_brute_force(cost))


def test_approximation_finds_the_line():
    # fields along one declination strip: the best path sweeps it end to end
    ra = np.arange(20) * 7.0
    perm = np.random.default_rng(0).permutation(20)
    cost = slew_matrix(ra[perm], np.full(20, 10.0))
    order = approx_path(cost)
    assert sorted(order.tolist()) == list(range(20))
    swept = ra[perm][order]
    assert np.all(np.diff(swept) > 0) or np.all(np.diff(swept) < 0)


def test_approximation_is_close_to_exact_on_small_blocks():
    rng = np.random.default_rng(11)
    for _ in range(5):
        ra, dec = rng.uniform(0, 40, 9), rng.uniform(0, 40, 9)
        cost = slew_matrix(ra, dec)
        exact = path_cost(cost, exact_path(cost))
        approx = path_cost(cost, approx_path(cost))
        assert exact - 1e-9 <= approx <= 1.1 * exact


def test_order_fields_switches_to_the_approximation_for_large_blocks():
    rng = np.random.default_rng(5)
    ra, dec = rng.uniform(0, 60, 30), rng.uniform(-20, 50, 30)
    order = order_fields(ra, dec)
    assert sorted(order.tolist()) == list(range(30))
    cost = slew_matrix(ra, dec)
    assert path_cost(cost, order) < path_cost(cost, np.arange(30))
