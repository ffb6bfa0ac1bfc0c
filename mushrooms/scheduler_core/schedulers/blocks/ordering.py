"""Ordering the fields of a block: a shortest open path over real slew times.

A block visits its fields in the first filter, changes filter, and visits
them again in the same order.  The return from the last field to the first
one runs during the filter change, and so does the move to the next block,
so what matters is the open path through the block's fields: a travelling
salesperson *path* with free ends over the true exposure-to-exposure
overheads (:func:`~...telescope.slew.slew_matrix`: per-axis trapezoid, settle, readout).

Small blocks are solved exactly (Held–Karp dynamic programming over subsets,
vectorised over the last field); larger ones with networkx's simulated
annealing on a greedy start, as a cycle through a zero-cost dummy node which
is then cut out.
"""

from __future__ import annotations

import numpy as np

from ...config import SlewModel
from ...telescope.slew import slew_matrix

__all__ = ["path_cost", "exact_path", "approx_path", "order_fields", "EXACT_MAX"]

#: Blocks up to this many fields are ordered exactly (2^n n^2 work).
EXACT_MAX = 11


def path_cost(cost: np.ndarray, order: np.ndarray | list[int]) -> float:
    """Total cost (s) of visiting ``order`` with the cost matrix ``cost``."""
    o = np.asarray(order, dtype=int)
    return float(cost[o[:-1], o[1:]].sum()) if o.size > 1 else 0.0


def exact_path(cost: np.ndarray) -> np.ndarray:
    """Shortest open path through all nodes (Held–Karp, any start and end).

    Parameters
    ----------
    cost : numpy.ndarray
        (n, n) cost matrix (s).

    Returns
    -------
    numpy.ndarray
        Node order; ties go to the lexicographically first path found.
    """
    n = cost.shape[0]
    if n <= 2:
        return np.arange(n)
    full = 1 << n
    best = np.full((full, n), np.inf)
    parent = np.full((full, n), -1, dtype=np.int64)
    for j in range(n):
        best[1 << j, j] = 0.0
    masks = np.arange(full)
    popcount = np.array([bin(m).count("1") for m in range(full)])
    bit = 1 << np.arange(n)
    for size in range(2, n + 1):
        for mask in masks[popcount == size]:
            members = np.flatnonzero(mask & bit)
            for j in members:
                prev_mask = mask ^ (1 << j)
                cand = best[prev_mask] + cost[:, j]     # end at i, then go to j
                i = int(np.argmin(cand))
                best[mask, j] = cand[i]
                parent[mask, j] = i
    mask = full - 1
    j = int(np.argmin(best[mask]))
    order = [j]
    while True:
        i = int(parent[mask, j])
        if i < 0:
            break
        mask ^= 1 << j
        j = i
        order.append(j)
    return np.asarray(order[::-1])


def approx_path(cost: np.ndarray, seed: int = 0) -> np.ndarray:
    """A short open path (networkx simulated annealing from a greedy tour).

    Parameters
    ----------
    cost : numpy.ndarray
        (n, n) symmetric cost matrix (s).
    seed : int
        Seed of the annealing (results are reproducible).

    Returns
    -------
    numpy.ndarray
        Node order.
    """
    import networkx as nx
    from networkx.algorithms import approximation as approx

    n = cost.shape[0]
    if n <= 2:
        return np.arange(n)
    dummy = n
    g = nx.Graph()
    iu, ju = np.triu_indices(n, 1)
    g.add_weighted_edges_from(zip(iu.tolist(), ju.tolist(), cost[iu, ju].tolist()))
    g.add_weighted_edges_from((dummy, k, 0.0) for k in range(n))
    start = approx.greedy_tsp(g, source=dummy)
    tour = approx.simulated_annealing_tsp(g, start, source=dummy, seed=seed, max_iterations=20,
                                          N_inner=200)
    path = [v for v in tour[:-1] if v != dummy]  # the tour starts and ends at the dummy
    order = np.asarray(path)
    return _two_opt(cost, order)


def _two_opt(cost: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Polish an open path with 2-opt reversals until no move helps."""
    o = order.copy()
    n = o.size
    improved = True
    while improved:
        improved = False
        for a in range(n - 1):
            # reversing o[a+1 .. b] changes edges (a, a+1) and (b, b+1)
            b = np.arange(a + 1, n)
            before = cost[o[a], o[a + 1]] + np.where(b < n - 1, cost[o[b], o[np.minimum(b + 1, n - 1)]], 0.0)
            after = cost[o[a], o[b]] + np.where(b < n - 1, cost[o[a + 1], o[np.minimum(b + 1, n - 1)]], 0.0)
            delta = after - before
            k = int(np.argmin(delta))
            if delta[k] < -1e-9:
                bb = int(b[k])
                o[a + 1:bb + 1] = o[a + 1:bb + 1][::-1]
                improved = True
        # reversing a prefix changes only edge (a, a+1) with the new start free
        for a in range(1, n - 1):
            if cost[o[0], o[a + 1]] < cost[o[a], o[a + 1]] - 1e-9:
                o[:a + 1] = o[:a + 1][::-1]
                improved = True
    return o


def order_fields(ra_deg: np.ndarray, dec_deg: np.ndarray, model: SlewModel = SlewModel(),
                 exact_max: int = EXACT_MAX) -> np.ndarray:
    """Observing order of a block's fields minimising the real overheads.

    Parameters
    ----------
    ra_deg, dec_deg : numpy.ndarray
        Field centres (deg).
    model : SlewModel
        Slew model (true overheads from :func:`~...telescope.slew.slew_matrix`).
    exact_max : int
        Blocks up to this size are solved exactly.

    Returns
    -------
    numpy.ndarray
        Permutation of ``range(len(ra_deg))``.
    """
    cost = slew_matrix(ra_deg, dec_deg, model)
    if len(ra_deg) <= exact_max:
        return exact_path(cost)
    return approx_path(cost)
