"""The daemon's warm state: per-night visibility of the whole grid, reused by every alert of the night."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.daemon.planning.warm import NIGHT_S, SkyCache
from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.sky.visibility import night_steps, observability_windows

CFG = PlanningConfig(nside=64, time_step_s=600.0)
MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


@pytest.fixture(scope="module")
def cache():
    return SkyCache()


def _inside(a: list[tuple[float, float]], b: list[tuple[float, float]], slack: float) -> bool:
    """Every window of ``a`` lies inside some window of ``b`` widened by ``slack`` (s)."""
    return all(any(s1 - slack <= s0 and e0 <= e1 + slack for s1, e1 in b) for s0, e0 in a)


def test_cached_windows_are_exactly_the_direct_ones(cache):
    """One anchored grid for both: the daemon's cache and a direct computation give the same windows."""
    start = Time("2022-07-23T02:13:20", scale="utc")
    w = cache.windows(start, CFG)
    g = cache.grid
    sel = slice(0, len(g), 11)
    direct = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], start, CFG)
    assert set(w.observable_fields()) & set(g.ids[sel]) == set(direct.observable_fields())
    for f in g.ids[sel]:
        assert w.for_field(int(f)) == direct.for_field(int(f)), f
    assert (w.start >= 0).all() and (w.end <= CFG.horizon_s).all()


def test_a_second_alert_of_the_night_reuses_the_cached_nights(cache):
    start = Time("2022-07-23T02:13:20", scale="utc")
    cache.windows(start, CFG)
    misses = cache.misses
    later = start + TimeDelta(3 * 3600, format="sec")
    w = cache.windows(later, CFG)
    assert cache.misses == misses  # nothing computed again
    other = dataclasses.replace(CFG, moon_sep_min_deg=40.0)  # another configuration is another key
    cache.windows(later, other)
    assert cache.misses > misses
    # the later horizon starts three hours later: its windows are the earlier ones shifted, where both see them
    early = cache.windows(start, CFG)
    f = int(w.field_ids[0])
    shifted = [(s + 3 * 3600, e + 3 * 3600) for s, e in w.for_field(f)]  # in the earlier horizon's seconds
    inner = [(s, e) for s, e in shifted if e < CFG.horizon_s]
    assert inner and _inside(inner, early.for_field(f), 0.0)


def test_prepare_with_cached_pieces_gives_the_same_candidates(cache):
    skymap = read_skymap(MAP, nside=CFG.nside)
    start = Time("2022-07-23T02:00:00", scale="utc")
    warm = cache.prepare(skymap, CFG, start)
    cold = prepare_problem(skymap, CFG, start)
    only_one = set(warm.field_ids) ^ set(cold.field_ids)
    # a field may differ only when its sole window is within one grid step of the exposure length
    for f in only_one:
        ws = (warm if f in warm.field_ids else cold).windows.for_field(int(f))
        assert max(e - s for s, e in ws) < CFG.exposure_s + CFG.time_step_s, f
    assert len(only_one) <= 0.02 * len(cold.field_ids)
    assert np.array_equal(warm.footprints.field_ids, warm.field_ids)
    assert set(np.unique(warm.windows.field_ids)) == set(warm.field_ids)


def test_night_grid_is_contiguous_across_nights():
    j0 = night_steps(120.0, 5)
    j1 = night_steps(120.0, 6)
    assert j1[0] == j0[-1] + 1 and len(j0) == NIGHT_S / 120.0
    k0, k1 = night_steps(7000.0, 0), night_steps(7000.0, 1)  # a step that does not divide a day
    assert k1[0] == k0[-1] + 1
