"""Observing constraints as composable masks (sky/constraints.py): ``&`` is the logical and, shapes broadcast."""

from __future__ import annotations

import numpy as np
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.sky.constraints import (AirmassBelow, AllOf, MoonSeparation, MountLimits,
                                                      ObservingGeometry, SunBelow, observing_geometry)
from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.sky.visibility import observing_conditions, site, ztf_constraints


def _geometry() -> ObservingGeometry:
    # 3 fields x 4 times, chosen by hand so each constraint cuts something different
    return ObservingGeometry(
        sun_alt_deg=np.array([-30.0, -18.0, -12.0, 5.0]),
        ha_deg=np.array([[0.0, 10.0, 50.0, 100.0], [-20.0, -10.0, 0.0, 10.0], [0.0, 0.0, 0.0, 0.0]]),
        dec_deg=np.array([20.0, -30.0, 88.0]),
        airmass=np.array([[1.1, 1.5, 2.4, np.inf], [3.0, 2.0, 1.9, 1.8], [1.3, 1.3, 1.3, 1.3]]),
        moon_sep_deg=np.array([[90.0, 90.0, 10.0, 90.0], [30.0, 30.0, 30.0, 30.0], [5.0, 50.0, 50.0, 50.0]]),
    )


def test_each_constraint_reads_its_own_quantity():
    g = _geometry()
    assert SunBelow(-18.0)(g).tolist() == [[True, True, False, False]]
    assert AirmassBelow(2.0)(g).tolist() == [[True, True, False, False], [False, True, True, True],
                                             [True, True, True, True]]
    assert MoonSeparation(20.0)(g).tolist() == [[True, True, False, True], [True] * 4,
                                                [False, True, True, True]]
    # field 1 (Dec -30) rising at HA -20 deg is in the keep-out zone; field 2 is past Dec 87.5
    assert MountLimits(5.95)(g).tolist() == [[True, True, True, False], [False, True, True, True], [False] * 4]


def test_and_is_the_elementwise_and_and_flattens():
    g = _geometry()
    a, b, c = SunBelow(-18.0), AirmassBelow(2.0), MoonSeparation(20.0)
    both = a & b & c
    assert isinstance(both, AllOf) and both.parts == (a, b, c)
    assert (a & (b & c)).parts == (a, b, c)
    assert both(g).shape == (3, 4)
    assert np.array_equal(both(g), a(g) & b(g) & c(g))
    assert both(g).tolist() == [[True, True, False, False], [False, True, False, False], [False, True, False, False]]


def test_ztf_constraints_are_the_schedulers_mask():
    cfg = PlanningConfig()
    grid = load_ztf_fields()
    ra, dec = grid.ra[::40], grid.dec[::40]
    times = Time("2026-05-01T03:00:00", scale="utc") + TimeDelta(np.arange(0, 36000, 1200.0), format="sec")
    night, reachable, moon_clear = ztf_constraints(cfg)
    composed = (night & reachable & moon_clear)(observing_geometry(ra, dec, times, site()))
    expected = observing_conditions(ra, dec, times, cfg)
    assert composed.dtype == bool and np.array_equal(composed, expected)
    assert 0 < composed.sum() < composed.size  # a real night: some fields up, some not
