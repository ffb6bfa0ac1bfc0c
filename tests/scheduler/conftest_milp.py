"""Hand-made planning problems for the MILP tests (imported explicitly, not a conftest).

The tiny instance (:func:`tiny_problem`) has an optimum known by hand:

* config: exposure 100 s, slew estimate 10 s, filter change 30 s, cadence
  250 s, so ``b_size = ceil((250 - 30) / 110) = 2``; horizon 1 h; at most
  two blocks; penalty p = 0.06 per field.
* fields 1..5 at RA 0, 5, 10, 15, 20 deg on the equator (true overheads
  are below the 10 s estimate);
* pixels (nside 1): field 1 = {0, 1}, 2 = {1, 2}, 3 = {3}, 4 = {4},
  5 = {5, 6}; probabilities 0.1, 0.2, 0.1, 0.15, 0.05, 0.1, 0.1 and 0.2
  spread over pixels nobody covers;
* windows: fields 1, 2 in [0, 1000] s, fields 3, 4 in [0, 3600] s,
  field 5 in [3000, 3600] s.

Field 4 adds 0.05 < p, so it is left out; every other field adds more than
p.  Field 5 can only be observed in a block starting at or after 3000 s, and
a block needs two fields: its partner must be visible then, i.e. field 3.
Fields 1 and 2 form the first block (470 s fits their 1000 s window).
Optimum: 0.1 + 0.2 + 0.1 + 0.15 + 0.1 + 0.1 - 4 p = 0.51, blocks
{1, 2} then {3, 5}.
"""

from __future__ import annotations

import numpy as np
from astropy.time import Time

from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.sky.windows import Windows

TINY_OPTIMUM = 0.51
TINY_BLOCKS = ({1, 2}, {3, 5})


def tiny_config(**overrides) -> PlanningConfig:
    values = dict(nside=1, horizon_h=1.0, exposure_s=100.0, slew_estimate_s=10.0, filter_change_s=30.0,
                  cadence_s=250.0, n_blocks_max=2, penalty=0.06, milp_backend="highs", time_limit_s=20.0,
                  mip_gap=0.0, n_fields=5)
    values.update(overrides)
    return PlanningConfig(**values)


def tiny_problem(config: PlanningConfig | None = None, window_5: tuple[float, float] = (3000.0, 3600.0)
                 ) -> PlanningProblem:
    config = config or tiny_config()
    prob = np.array([0.1, 0.2, 0.1, 0.15, 0.05, 0.1, 0.1, 0.04, 0.04, 0.04, 0.04, 0.04])
    ids = np.arange(1, 6)
    members = [[0, 1], [1, 2], [3], [4], [5, 6]]
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    footprints = Footprints(1, ids, indptr, np.concatenate(members))
    windows = Windows(ids, np.array([0.0, 0.0, 0.0, 0.0, window_5[0]]),
                      np.array([1000.0, 1000.0, 3600.0, 3600.0, window_5[1]]))
    return PlanningProblem(config, Time("2026-01-01T00:00:00", scale="utc"), prob, ids,
                           np.array([0.0, 5.0, 10.0, 15.0, 20.0]), np.zeros(5), footprints, windows)


def crowded_problem(window_end_s: float, **overrides) -> PlanningProblem:
    """Three fields visible in [0, ``window_end_s``] s only, one in [1000, 1400] s: fields competing for minutes.

    :func:`tiny_config` with nside 1, a 0.5 h horizon, a 60 s time step, no penalty, no field cap and no
    least gain (``overrides`` on top).  Coverage: f1 = {0, 1} = .3, f2 = {2} = .22, f3 = {1, 3} = .22,
    f4 = {4} = .1; the best two of fields 1-3 are {1, 2} = .52 (with f4: .62), all four .74.
    """
    cfg = tiny_config(**{**dict(nside=1, horizon_h=0.5, time_step_s=60.0, penalty=0.0, n_fields=None,
                                min_gain=0.0), **overrides})
    prob = np.array([0.2, 0.1, 0.22, 0.12, 0.1] + [0.26 / 7] * 7)
    ids = np.arange(1, 5)
    members = [[0, 1], [2], [1, 3], [4]]
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    fp = Footprints(1, ids, indptr, np.concatenate(members))
    end = float(window_end_s)
    windows = Windows(ids, np.array([0.0, 0.0, 0.0, 1000.0]), np.array([end, end, end, 1400.0]))
    return PlanningProblem(cfg, Time("2026-01-01T00:00:00", scale="utc"), prob, ids,
                           np.array([0.0, 5.0, 10.0, 15.0]), np.zeros(4), fp, windows)


def slot_hand_problem(window_end: tuple[float, ...], **overrides) -> PlanningProblem:
    """The slot model's hand instance: fields 1-5 as :func:`tiny_problem`'s, windows ``[0, window_end]``.

    Pixels (nside 1): f1 = {0 (.12), 1 (.2)}, f2 = {1, 2 (.1)}, f3 = {3 (.15)},
    f4 = {4 (.05)}, f5 = {5 (.1), 6 (.12)}; horizon 1000 s, no margin, one
    grid of 2 positions, no penalty unless ``overrides`` say otherwise.
    """
    values = dict(horizon_h=1000.0 / 3600.0, slot_margin_s=0.0, slot_positions=(2,), penalty=0.0, n_fields=None)
    cfg = tiny_config(**{**values, **overrides})
    prob = np.array([0.12, 0.2, 0.1, 0.15, 0.05, 0.1, 0.12, 0.04, 0.04, 0.04, 0.02, 0.02])
    ids = np.arange(1, 6)
    members = [[0, 1], [1, 2], [3], [4], [5, 6]]
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    footprints = Footprints(1, ids, indptr, np.concatenate(members))
    windows = Windows(ids, np.zeros(5), np.asarray(window_end, float))
    return PlanningProblem(cfg, Time("2026-01-01T00:00:00", scale="utc"), prob, ids,
                           np.array([0.0, 5.0, 10.0, 15.0, 20.0]), np.zeros(5), footprints, windows)


def random_problem(seed: int, n_fields: int = 14, nside: int = 4, config: PlanningConfig | None = None
                   ) -> PlanningProblem:
    """Fields with overlapping random footprints and one or two windows each."""
    rng = np.random.default_rng(seed)
    config = config or tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=2.0)
    npix = 12 * nside * nside
    prob = rng.random(npix) ** 4
    prob /= prob.sum()
    ids = np.arange(100, 100 + n_fields)
    members = [np.sort(rng.choice(npix, size=rng.integers(3, 12), replace=False)) for _ in ids]
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    footprints = Footprints(nside, ids, indptr, np.concatenate(members))
    horizon = config.horizon_s
    w_ids, w_start, w_end = [], [], []
    for f in ids:
        a = rng.uniform(0, horizon * 0.6)
        w_ids.append(f), w_start.append(a), w_end.append(min(horizon, a + rng.uniform(900, horizon)))
        if rng.random() < 0.3:
            w_ids.append(f), w_start.append(0.0), w_end.append(min(a, 600.0))
    windows = Windows(np.array(w_ids), np.array(w_start), np.array(w_end))
    ra = rng.uniform(0, 30, n_fields)
    dec = rng.uniform(-10, 20, n_fields)
    return PlanningProblem(config, Time("2026-01-01T00:00:00", scale="utc"), prob, ids, ra, dec,
                           footprints, windows)


def check_observations(problem: PlanningProblem, observations) -> list[str]:
    """The checker's scheduling rules on a hand-made problem (no sky needed)."""
    from mushrooms.scheduler_core.telescope.slew import overhead_time

    cfg = problem.config
    f1, f2 = cfg.filters
    obs = sorted(observations, key=lambda o: o.start)
    bad = []
    for o in obs:
        if o.start < -1e-6 or o.start + o.exposure_s > cfg.horizon_s + 1e-6:
            bad.append(f"horizon {o}")
        if not problem.windows.contains(o.field_id, o.start + 1e-6, o.start + o.exposure_s - 1e-6):
            bad.append(f"window {o}")
    for a, b in zip(obs[:-1], obs[1:]):
        need = float(overhead_time(a.ra, a.dec, b.ra, b.dec, cfg.slew,
                                   cfg.filter_change_s if a.filter != b.filter else 0.0))
        if b.start < a.start + a.exposure_s + need - 1e-6:
            bad.append(f"overhead {a} -> {b}")
    by_field: dict[int, dict[str, float]] = {}
    for o in obs:
        if o.filter in by_field.setdefault(o.field_id, {}):
            bad.append(f"twice {o}")
        by_field[o.field_id][o.filter] = o.start
    for fid, v in by_field.items():
        if set(v) != {f1, f2}:
            bad.append(f"filters {fid}")
        elif v[f2] - v[f1] < cfg.cadence_s - 1e-6:
            bad.append(f"cadence {fid}")
    blocks: dict[int, dict[str, list[int]]] = {}
    for o in obs:
        blocks.setdefault(o.block, {f1: [], f2: []})[o.filter].append(o.field_id)
    for b, v in blocks.items():
        if v[f1] != v[f2]:
            bad.append(f"block {b} order differs between filters")
    return bad
