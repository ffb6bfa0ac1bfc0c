"""The exposure menu on the slot grid: each field's visits take one exposure of ``exposure_menu_s``.

A longer exposure reaches deeper (at most +1.25 log10(t2/t1) mag: D1, less in
the difference image, D2) but holds the
telescope longer, so it covers less area: which is better depends on the
distance the kilonova must be seen to (X1).  The detection stage
(:mod:`..detection.stage`) lets the solver choose, on a *menu grid*:

- the grid's pitch is the shortest menu exposure plus the slew estimate,
  ``s0 = e_1 + t_slew``, and its blocks have ``n' = n ceil((t_exp + t_slew) / s0)``
  positions, so a block holds ``n`` visits of the configured
  ``exposure_s`` as the fixed grid's does (the same grid, finer);
- exposure ``e_m`` holds ``n_m = ceil((e_m + t_slew) / s0)`` consecutive
  positions in both passes (X7) and may start only at positions that are a
  multiple of ``n_m`` (aligned starts: fewer pairs, and a shorter exposure
  can start wherever a longer one can);
- both visits of a pair have the same exposure and the second starts
  ``D_n'`` after the first, as on every grid, so the cadence rule and the
  filter change hold unchanged; the real timing then packs the exposures
  with the true overheads (:func:`.schedule.time_slot_plan`).

A pair ``(f, q, m)`` is only offered when its exposure reaches a higher
distance level than every shorter exposure of the same field starting in
the same slot (:func:`dominated_pairs`): a longer exposure that sees no
farther only costs time.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp

from ...config import PlanningConfig
from ...problem import PlanningProblem
from ...sky.cells import Cells
from .model import SlotGrid, SlotInstance, eligible_pairs, make_slot_grid, observable_segments

__all__ = ["menu_pitch_s", "menu_spans", "menu_positions", "menu_portfolio", "menu_instance", "dominated_pairs",
           "map_start_menu", "greedy_menu_pairs", "menu_start_pairs"]


def menu_pitch_s(config: PlanningConfig) -> float:
    """s0 (s): the menu grid's position pitch, shortest menu exposure plus the slew estimate (X8)."""
    return float(min(config.exposure_menu_s)) + config.slew_estimate_s


def menu_spans(config: PlanningConfig) -> np.ndarray:
    """(M,) positions n_m each menu exposure holds: ceil((e_m + t_slew) / s0) (X8)."""
    s0 = menu_pitch_s(config)
    return np.array([max(1, math.ceil((float(e) + config.slew_estimate_s) / s0 - 1e-9))
                     for e in config.exposure_menu_s], np.int64)


def menu_positions(n: int, config: PlanningConfig) -> int:
    """n' positions of a menu block holding ``n`` visits of ``exposure_s`` (at least the longest span).

    ``n' = n * ceil((t_exp + t_slew) / s0)``: the block holds exactly ``n``
    aligned visits of the configured exposure, as the fixed grid's block
    does, or any mix of the menu's exposures in the same time.
    """
    s0 = menu_pitch_s(config)
    per_visit = max(1, math.ceil((config.exposure_s + config.slew_estimate_s) / s0 - 1e-9))
    return max(int(n) * per_visit, int(menu_spans(config).max()))


def _grid_config(config: PlanningConfig) -> PlanningConfig:
    """The configuration the menu grid is cut with: exposure_s the shortest menu exposure."""
    return dataclasses.replace(config, exposure_s=float(min(config.exposure_menu_s)), exposure_menu_s=())


def menu_portfolio(problem: PlanningProblem, rows: np.ndarray) -> list[SlotGrid]:
    """The menu grids: ``config.slot_positions`` (as menu blocks of n' positions) × phases ``start``, ``end``.

    Each grid keeps the name of the ``n`` it stands for (``n6/start`` ...),
    with ``n_positions`` = n'.
    """
    cfg = problem.config
    gcfg = _grid_config(cfg)
    segments = observable_segments(problem, rows)
    grids = []
    for n in cfg.slot_positions:
        for phase in ("start", "end"):
            g = make_slot_grid(segments, gcfg, menu_positions(int(n), cfg), phase)
            if g.n_slots:
                grids.append(g)
    return grids


def menu_instance(problem: PlanningProblem, rows: np.ndarray, grid: SlotGrid, cells: Cells) -> SlotInstance:
    """Eligible (field, slot, exposure) pairs of a menu grid.

    A pair of exposure ``e_m`` starts at a position ``q`` with ``q mod n_m = 0``
    and ``q + n_m`` within its block, and both its exposures (of ``e_m``)
    lie in windows of the field.
    """
    cfg = problem.config
    spans = menu_spans(cfg)
    size = grid.block_size[grid.slot_block]
    parts = []
    for e, n_m in zip(cfg.exposure_menu_s, spans):
        f, slot, w1, w2 = eligible_pairs(problem, rows, grid, float(e))
        q = grid.slot_position[slot]
        ok = (q % n_m == 0) & (q + n_m <= size[slot])
        parts.append((f[ok], slot[ok], w1[ok], w2[ok], np.full(int(ok.sum()), float(e)), np.full(int(ok.sum()), n_m)))
    cols = [np.concatenate([p[i] for p in parts]) for i in range(6)]
    return SlotInstance(np.asarray(rows, np.int64), grid, cells, cols[0].astype(np.int64), cols[1].astype(np.int64),
                        cols[2].astype(np.int64), cols[3].astype(np.int64), cols[4], cols[5].astype(np.int64),
                        open_shutter_cap_s=cfg.max_open_shutter_s, exposure_s=cfg.exposure_s)


def dominated_pairs(inst: SlotInstance, level: np.ndarray) -> np.ndarray:
    """(K,) mask of the pairs a shorter exposure of the same field and start slot reaches as far as.

    Parameters
    ----------
    inst : SlotInstance
        A menu instance (``pair_exposure`` set).
    level : numpy.ndarray
        (K,) distance level each pair reaches (``lev(k)``).
    """
    exp = inst.exposures(0.0)
    order = np.lexsort((exp, inst.pair_slot, inst.pair_field))
    f, s, lv = inst.pair_field[order], inst.pair_slot[order], np.asarray(level, np.int64)[order]
    new_group = np.ones(order.size, bool)
    new_group[1:] = (f[1:] != f[:-1]) | (s[1:] != s[:-1])
    # the best level of the shorter exposures before each pair in its group: a running max offset per group
    group = np.cumsum(new_group) - 1
    big = int(lv.max(initial=0)) + 2
    running = np.maximum.accumulate(group * big + lv)
    before = np.concatenate([[-1], running[:-1]]) - group * big
    dominated = ~new_group & (lv <= before)
    out = np.zeros(order.size, bool)
    out[order] = dominated
    return out


def map_start_menu(inst: SlotInstance, start: dict[int, float], exposure: dict[int, float]) -> np.ndarray:
    """Pairs placing a start plan's fields on a menu grid, each with its own exposure (or the menu's nearest).

    Parameters
    ----------
    inst : SlotInstance
        A menu instance.
    start : dict
        Model field index -> first exposure start (s) in the start plan.
    exposure : dict
        Model field index -> that field's exposure (s) in the start plan.

    Returns
    -------
    numpy.ndarray
        Pair indices satisfying (S2) and (X7): fields in the start plan's
        time order, each on the free eligible start nearest in time whose
        whole span is free, with the menu exposure nearest its own; fields
        that fit nowhere are left out.
    """
    exp = inst.exposures(0.0)
    span = np.ones(inst.n_pairs, np.int64) if inst.pair_span is None else inst.pair_span
    menu = np.unique(exp)
    taken = np.zeros(inst.grid.n_slots, bool)
    t1 = inst.grid.t1
    chosen = []
    for f, t in sorted(start.items(), key=lambda kv: kv[1]):
        if menu.size == 0:
            break
        want = menu[np.argmin(np.abs(menu - exposure.get(f, menu[-1])))]
        k = np.flatnonzero((inst.pair_field == f) & (exp == want))
        free = np.array([not taken[inst.pair_slot[j]:inst.pair_slot[j] + span[j]].any() for j in k], bool)
        k = k[free] if k.size else k
        if k.size == 0:
            continue
        best = k[np.argmin(np.abs(t1[inst.pair_slot[k]] - t))]
        taken[inst.pair_slot[best]:inst.pair_slot[best] + span[best]] = True
        chosen.append(int(best))
    return np.asarray(chosen, np.int64)


def _menu_value(inst: SlotInstance, level: np.ndarray, W: np.ndarray, coverage_weight: float, penalty: float,
                pairs: np.ndarray) -> float:
    """The detection model's objective (X5) of a set of pairs: Σ_cl W_cl v_cl + λ Σ w_c y_c - p Σ z_f."""
    C, L = W.shape
    cumW = np.concatenate([np.zeros((C, 1)), np.cumsum(W, axis=1)], axis=1)
    best = np.full(inst.n_fields, -1, np.int64)
    p = np.asarray(pairs, np.int64)
    np.maximum.at(best, inst.pair_field[p], np.asarray(level, np.int64)[p])
    cell_of = np.repeat(np.arange(C), np.diff(inst.cells.indptr))
    cl = np.full(C, -1, np.int64)
    np.maximum.at(cl, cell_of, best[inst.cells.fields])
    cov = cl >= 0
    return float(cumW[np.flatnonzero(cov), cl[cov]].sum() + coverage_weight * inst.cells.weight[cov].sum()
                 - penalty * p.size)


def greedy_menu_pairs(inst: SlotInstance, level: np.ndarray, W: np.ndarray, coverage_weight: float, penalty: float,
                      fixed: np.ndarray | None = None) -> np.ndarray:
    """Pairs added greedily by marginal objective per position held (X9), after the pairs ``fixed``.

    Each step adds the free pair of an unplanned field with the largest
    ``g_k / n_k``: ``g_k`` the gain of (X5) (detection probability of its
    cells' sources newly reached, plus λ w_c of the cells newly covered,
    less p), ``n_k`` the positions it holds (X7, its exposure plus the slew
    estimate in pitches of ``s0``, X8), so a field's exposure is chosen by
    expected detections per second of telescope time.  Stops when no free
    pair gains.  The result satisfies (X7), (S2) and, with ``fixed`` above
    the floor, (X6) (adding a field never lowers coverage).

    Returns
    -------
    numpy.ndarray
        ``fixed`` then the added pair indices.
    """
    C, L = W.shape
    F = inst.n_fields
    lev = np.asarray(level, np.int64)
    span = np.ones(inst.n_pairs, np.int64) if inst.pair_span is None else np.asarray(inst.pair_span, np.int64)
    cumW = np.concatenate([np.zeros((C, 1)), np.cumsum(W, axis=1)], axis=1)  # (C, L+1)
    cell_of = np.repeat(np.arange(C), np.diff(inst.cells.indptr))
    M = sp.csr_matrix((np.ones(cell_of.size), (inst.cells.fields, cell_of)), shape=(F, C))
    w = np.asarray(inst.cells.weight, float)
    cl = np.zeros(C, np.int64)  # levels reached per cell
    cov = np.zeros(C, bool)
    used = np.zeros(F, bool)
    taken = np.zeros(inst.grid.n_slots + int(span.max(initial=1)) + 1, bool)
    chosen = [] if fixed is None else [int(k) for k in np.asarray(fixed, np.int64)]

    def take(k: int) -> None:
        f = int(inst.pair_field[k])
        used[f] = True
        taken[inst.pair_slot[k]:inst.pair_slot[k] + span[k]] = True
        cells = M.indices[M.indptr[f]:M.indptr[f + 1]]
        cl[cells] = np.maximum(cl[cells], lev[k])
        cov[cells] = True

    for k in chosen:
        take(k)
    rows = np.arange(C)
    while True:
        gain_c = np.maximum(cumW - cumW[rows, cl][:, None], 0.0) + (coverage_weight * w * ~cov)[:, None]
        G = np.asarray(M @ gain_c)  # (F, L+1) gain of each field observed at each level
        pre = np.concatenate([[0], np.cumsum(taken)])
        free = (pre[inst.pair_slot + span] - pre[inst.pair_slot] == 0) & ~used[inst.pair_field]
        g = G[inst.pair_field, lev] - penalty
        rate = np.where(free & (g > 1e-12), g / span, -np.inf)
        k = int(np.argmax(rate)) if rate.size else -1
        if k < 0 or not np.isfinite(rate[k]):
            break
        chosen.append(k)
        take(k)
    return np.asarray(chosen, np.int64)


def menu_start_pairs(inst: SlotInstance, level: np.ndarray, W: np.ndarray, coverage_weight: float, penalty: float,
                     seed: np.ndarray, floor: float | None) -> np.ndarray:
    """The menu MILP's start (X9): the best by (X5) of the seed, the seed filled greedily, and a greedy plan.

    ``seed`` is the best plan so far mapped on the menu grid
    (:func:`map_start_menu`); the greedy plan built from nothing is only
    taken when it keeps the floor (X6).  The seed is a candidate, so the
    start is never worse by (X5) than the seed.
    """
    cands = [np.asarray(seed, np.int64), greedy_menu_pairs(inst, level, W, coverage_weight, penalty, seed),
             greedy_menu_pairs(inst, level, W, coverage_weight, penalty)]
    best, best_v = cands[0], _menu_value(inst, level, W, coverage_weight, penalty, cands[0])
    cell_of = np.repeat(np.arange(inst.cells.n_cells), np.diff(inst.cells.indptr))
    for c in cands[1:]:
        z = np.zeros(inst.n_fields, bool)
        z[inst.pair_field[c]] = True
        hit = np.zeros(inst.cells.n_cells, bool)
        np.logical_or.at(hit, cell_of, z[inst.cells.fields])
        if floor is not None and inst.cells.weight[hit].sum() < floor - 1e-12:
            continue
        v = _menu_value(inst, level, W, coverage_weight, penalty, c)
        if v > best_v + 1e-12:
            best, best_v = c, v
    return best
