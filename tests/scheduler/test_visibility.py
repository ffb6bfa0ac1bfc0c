"""Observability windows agree with astropy's own alt-az."""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import TETE, AltAz, EarthLocation, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.sky.constraints import mount_limits_ok
from mushrooms.scheduler_core.sky.visibility import observability_windows

START = Time("2022-07-22T21:57:12", scale="utc")
# the P48 as ztf_sim's constants.py gives it (P48_loc), written out here rather than taken from the code
P48 = EarthLocation.from_geodetic(lon=-(116 + 51 / 60 + 35.5 / 3600) * u.deg,
                                  lat=(33 + 21 / 60 + 26.2 / 3600) * u.deg, height=1707 * u.m)


def _ztf_sim_mount_ok(ha, dec, ha_max_h):
    """ztf_sim QueueManager's pointing limits (HA, Dec in deg)."""
    return ((np.abs(ha) <= ha_max_h * 15) & ~((ha < -17.6) & (dec < -22)) & ~((ha > -17.6) & (dec < -45))
            & ~((np.abs(ha) > 3) & (dec < -46)) & (dec <= 87.5))
FIELDS = [400, 700, 1500, 862, 1650, 300]


def _astropy_ok(ra, dec, t, cfg):
    """Every constraint evaluated with astropy's full alt-az, for many times at once."""
    loc = P48
    frame = AltAz(obstime=t, location=loc)
    c = SkyCoord(np.full(t.size, ra) * u.deg, np.full(t.size, dec) * u.deg)
    alt = c.transform_to(frame).alt.deg
    sun = get_body("sun", t, loc).transform_to(frame).alt.deg
    moon = get_body("moon", t, loc).separation(c, origin_mismatch="ignore").deg
    ha = ((t.sidereal_time("apparent", longitude=loc.lon).deg - c.transform_to(TETE(obstime=t)).ra.deg + 180) % 360) - 180
    with np.errstate(divide="ignore"):
        airmass = np.where(alt > 0, 1 / np.sin(np.radians(np.maximum(alt, 1e-9))), np.inf)
    return ((sun <= cfg.sun_alt_max_deg) & (airmass <= cfg.airmass_max) & (moon >= cfg.moon_sep_min_deg)
            & _ztf_sim_mount_ok(ha, np.full(t.size, dec), cfg.ha_max_h))


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
    # each of ztf_sim's limits, a little inside and a little beyond
    ha = np.array([-17.7, -17.5, -17.7, 10.0, 10.0, 2.9, 3.1, -3.1, 89.0, 89.5, 0.0, 0.0])
    dec = np.array([-22.1, -22.1, -21.9, -45.1, -44.9, -46.1, -46.1, -46.1, 10.0, 10.0, 87.4, 87.6])
    assert mount_limits_ok(ha, dec, 5.95).tolist() == _ztf_sim_mount_ok(ha, dec, 5.95).tolist() == [
        False, True, True, False, True, False, False, False, True, False, True, False]


# ---------------------------------------------------------------- astroplan at the window edges

def test_window_edges_agree_with_astroplan_exactly_and_one_step_beyond():
    """At every window edge all constraints hold (astroplan); one grid step outside, one of them fails.

    The site is ztf_sim's P48 position written out here, and the Sun, airmass and Moon come from
    astroplan's own constraint classes; the hour angle is astroplan's, tested against ztf_sim's
    queue limits (|HA| < 5.95 h; keep-outs HA < -17.6 deg & Dec < -22, HA > -17.6 & Dec < -45,
    |HA| > 3 deg & Dec < -46).  Widening or narrowing any window by one step fails this test.
    """
    from astroplan import (AirmassConstraint, AtNightConstraint, FixedTarget, MoonSeparationConstraint,
                           Observer)
    cfg = PlanningConfig()
    p48 = Observer(location=P48)
    # astropy's Moon separation moves the field into the Moon's GCRS frame (annual aberration, up to
    # 20 arcsec); the planner compares catalogue positions.  Inside an edge the Moon limit is therefore
    # relaxed by 0.005 deg, one step beyond it tightened by as much (the Moon moves ~0.02 deg per step).
    moon_slack = {True: -0.005, False: 0.005}
    constraints = {inside: [AtNightConstraint(max_solar_altitude=cfg.sun_alt_max_deg * u.deg),
                            AirmassConstraint(max=cfg.airmass_max),
                            MoonSeparationConstraint(min=(cfg.moon_sep_min_deg + moon_slack[inside]) * u.deg)]
                   for inside in (True, False)}
    ids = [400, 700, 1500, 862, 300, 874, 290, 1283, 335]  # equatorial, northern, circumpolar, south
    g = load_ztf_fields()
    sel = np.isin(g.ids, ids)
    w = observability_windows(g.ids[sel], g.ra[sel], g.dec[sel], START, cfg)
    last = np.floor(cfg.horizon_s / cfg.time_step_s) * cfg.time_step_s
    probes, expected, targets, decs = [], [], [], []
    for fid, ra, dec in zip(g.ids[sel], g.ra[sel], g.dec[sel]):
        for s, e in np.array(w.for_field(int(fid))).reshape(-1, 2):
            for t, inside in ((s, True), (s - cfg.time_step_s, False), (e, True), (e + cfg.time_step_s, False)):
                if 0 <= t <= last:  # an edge at the horizon's end has no step beyond it
                    probes.append(t)
                    expected.append(inside)
                    targets.append((ra, dec))
                    decs.append(dec)
    assert len(probes) >= 30 and sum(expected) >= 15
    times = START + TimeDelta(np.array(probes), format="sec")
    ok = np.ones(len(probes), bool)
    for k, ((ra, dec), t) in enumerate(zip(targets, times)):
        target = FixedTarget(SkyCoord(ra * u.deg, dec * u.deg))
        ok[k] = all(c(p48, target, times=t) for c in constraints[expected[k]])
        # hour angle of the apparent place (astroplan's target_hour_angle subtracts the J2000 RA)
        ra_date = target.coord.transform_to(TETE(obstime=t)).ra.deg
        ha = (p48.local_sidereal_time(t, kind="apparent").deg - ra_date + 180) % 360 - 180
        ok[k] &= (abs(ha) <= cfg.ha_max_h * 15) and not (ha < -17.6 and dec < -22) \
            and not (ha > -17.6 and dec < -45) and not (abs(ha) > 3 and dec < -46)
    bad = np.flatnonzero(ok != np.array(expected))
    assert bad.size == 0, [(targets[i], probes[i], expected[i]) for i in bad]
