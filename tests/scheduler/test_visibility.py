"""Observability windows agree with astropy's own alt-az."""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.fields import load_ztf_fields
from mushrooms.scheduler_core.visibility import mount_limits_ok, observability_windows, site

START = Time("2022-07-22T21:57:12", scale="utc")
FIELDS = [400, 700, 1500, 862, 1650, 300]


def _astropy_ok(ra, dec, t, cfg):
    """Every constraint evaluated with astropy's full alt-az, for many times at once."""
    loc = site()
    frame = AltAz(obstime=t, location=loc)
    c = SkyCoord(np.full(t.size, ra) * u.deg, np.full(t.size, dec) * u.deg)
    alt = c.transform_to(frame).alt.deg
    sun = get_body("sun", t, loc).transform_to(frame).alt.deg
    moon = get_body("moon", t, loc).separation(c, origin_mismatch="ignore").deg
    ha = ((t.sidereal_time("apparent", longitude=loc.lon).deg - ra + 180) % 360) - 180
    with np.errstate(divide="ignore"):
        airmass = np.where(alt > 0, 1 / np.sin(np.radians(np.maximum(alt, 1e-9))), np.inf)
    return ((sun <= cfg.sun_alt_max_deg) & (airmass <= cfg.airmass_max) & (moon >= cfg.moon_sep_min_deg)
            & mount_limits_ok(ha, np.full(t.size, dec), cfg.ha_max_h))


def test_windows_match_astropy_inside_and_well_outside():
    cfg = PlanningConfig()
    g = load_ztf_fields()
    sel = np.isin(g.ids, FIELDS)
    w = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], START, cfg)
    rng = np.random.default_rng(1)
    checked_in = checked_out = 0
    for fid, ra, dec in zip(g.ids[sel], g.ra[sel], g.dec[sel]):
        wins = np.array(w.for_field(int(fid))).reshape(-1, 2)
        t_rel = rng.uniform(0, cfg.horizon_s, 200)
        inside = np.any((wins[:, 0][None] <= t_rel[:, None]) & (t_rel[:, None] <= wins[:, 1][None]), axis=1)
        edges = wins.ravel()
        far = np.all(np.abs(t_rel[:, None] - edges[None]) >= cfg.time_step_s, axis=1) if edges.size else np.ones(t_rel.size, bool)
        ok = _astropy_ok(ra, dec, START + TimeDelta(t_rel[far], format="sec"), cfg)
        assert np.array_equal(ok, inside[far]), (fid, t_rel[far][ok != inside[far]], wins)
        checked_in += int(inside[far].sum())
        checked_out += int((~inside[far]).sum())
    assert checked_in > 50 and checked_out > 50


def test_several_windows_per_field_over_a_long_horizon():
    cfg = PlanningConfig(horizon_h=72)
    g = load_ztf_fields()
    sel = np.isin(g.ids, [700])
    w = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], START, cfg)
    assert len(w.for_field(700)) == 3  # one per night


def test_stricter_airmass_shrinks_windows():
    g = load_ztf_fields()
    sel = np.isin(g.ids, FIELDS)
    loose = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], START, PlanningConfig())
    tight = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], START, PlanningConfig(airmass_max=1.3))
    assert (tight.end - tight.start).sum() < (loose.end - loose.start).sum()


def test_mount_keeps_out_of_the_south_east():
    ha = np.array([-30.0, 10.0, -30.0, 100.0])
    dec = np.array([-25.0, -25.0, -20.0, 10.0])
    assert mount_limits_ok(ha, dec, 5.95).tolist() == [False, True, True, False]
