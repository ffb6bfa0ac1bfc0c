"""The plan checker: one hand-built plan per rule that breaks exactly that rule.

The control plan is built by hand (not by a scheduler), so that it passes is
a real statement.  Every broken plan differs from a valid one in one respect
and must be refused for that reason alone.  The truth each test relies on
(Sun altitude, airmass, hour angle, Moon separation) is recomputed here with
astropy's full alt-az transformation at a site written out in this file, and
the boundary tests put the configured limit just on either side of it.
"""

from __future__ import annotations

import dataclasses

import healpy as hp
import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import TETE, AltAz, EarthLocation, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan
from mushrooms.scheduler_core.plan.check_geometry import conditions, mount_reachable, polygon_coverage, slew_seconds
from mushrooms.scheduler_core.plan.checker import MAX_LISTED
from mushrooms.scheduler_core.config import SlewModel
from mushrooms.scheduler_core.plan.document import Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.sky.skymap import SkyMap

# P48, ztf_sim constants.py P48_loc (GPS position used by ZTF's robotic software)
P48 = EarthLocation.from_geodetic(lon=-(116 + 51 / 60 + 35.5 / 3600) * u.deg,
                                  lat=(33 + 21 / 60 + 26.2 / 3600) * u.deg, height=1707 * u.m)
NEW_MOON = Time("2022-07-28T02:00:00", scale="utc")  # dark night: Sun below -12 deg from +1.9 h to +10 h
FULL_MOON = Time("2022-07-13T02:00:00", scale="utc")
T0 = 6 * 3600.0  # 08:00 UTC, the middle of the night
CFG = PlanningConfig()
# ZTF_Fields.txt: ID, RA, Dec
F687 = (687, 306.08789, 33.35)  # near the zenith at T0
F1685 = (1685, 307.14268, 29.75)


def obs(f, filt, start, exposure=300.0, block=0):
    return Observation(field_id=f[0], ra=f[1], dec=f[2], filter=filt, start=float(start),
                       exposure_s=exposure, block=block)


def plan_of(observations, start=NEW_MOON, hours=24.0, metrics=None):
    return Plan(plan_id="test", start=start, end=start + TimeDelta(hours * 3600, format="sec"),
                observations=tuple(observations), metrics=metrics)


def control_obs(later=0.0):
    """Two fields near the zenith, g then r, 1860 s apart; every gap >= its overhead."""
    t = T0 + later
    return [obs(F687, "g", t), obs(F1685, "g", t + 360), obs(F687, "r", t + 1860), obs(F1685, "r", t + 2220)]


def kinds(report):
    return {line.split(":")[0] for line in report.problems}


def truth(plan):
    """(sun alt, airmass, |HA| in h, Moon separation) at start, middle and end of each exposure (astropy)."""
    o = plan.observations
    t_rel = np.concatenate([[x.start for x in o], [x.start + x.exposure_s / 2 for x in o], [x.end for x in o]])
    times = plan.start + TimeDelta(t_rel, format="sec")
    c = SkyCoord(ra=np.tile([x.ra for x in o], 3) * u.deg, dec=np.tile([x.dec for x in o], 3) * u.deg)
    frame = AltAz(obstime=times, location=P48)
    alt = c.transform_to(frame).alt.deg
    sun = get_body("sun", times, P48).transform_to(frame).alt.deg
    moon = get_body("moon", times, P48).separation(c, origin_mismatch="ignore").deg
    return sun, 1 / np.sin(np.radians(alt)), np.abs(truth_ha(plan)) / 15, moon


def truth_ha(plan):
    """Signed apparent hour angle (deg) at start, middle and end of each exposure."""
    o = plan.observations
    t_rel = np.concatenate([[x.start for x in o], [x.start + x.exposure_s / 2 for x in o], [x.end for x in o]])
    times = plan.start + TimeDelta(t_rel, format="sec")
    c = SkyCoord(ra=np.tile([x.ra for x in o], 3) * u.deg, dec=np.tile([x.dec for x in o], 3) * u.deg)
    return (times.sidereal_time("apparent", longitude=P48.lon).deg - c.transform_to(TETE(obstime=times)).ra.deg
            + 180) % 360 - 180


def test_the_hand_built_control_breaks_no_rule(flat_map):
    plan = plan_of(control_obs())
    report = check_plan(plan, flat_map, CFG)
    assert report.ok and report.problems == () and report.counts == {}
    sun, airmass, ha_h, moon = truth(plan)  # and it is not a near miss
    assert sun.max() < -30 and airmass.max() < 1.1 and ha_h.max() < 1 and moon.min() > 90


# ----------------------------------------------------------------- observing conditions

def test_sun_up_is_refused(flat_map):
    """The control pattern in evening twilight (+1.6 h, Sun near -10 deg), fields on the meridian."""
    f683, f1681 = (683, 274.7095, 33.35), (1681, 276.5045, 29.75)
    t = 1.6 * 3600
    plan = plan_of([obs(f683, "g", t), obs(f1681, "g", t + 360), obs(f683, "r", t + 1860),
                    obs(f1681, "r", t + 2220)])
    sun, airmass, _, _ = truth(plan)
    assert sun[:2].min() > -11.5 and sun[[2, 3, 6, 7, 10, 11]].max() < -12.2  # only the g exposures
    report = check_plan(plan, flat_map, CFG)
    assert kinds(report) == {"window"} and report.counts == {"window": 2}
    assert all("Sun at" in line for line in report.problems)


def test_high_airmass_is_refused(flat_map):
    f1275 = (1275, 273.91893, -27.85)  # setting in the south-west, 2.35 h past the meridian
    plan = plan_of([obs(f1275, "g", T0), obs(f1275, "r", T0 + 1860)])
    _, airmass, ha_h, _ = truth(plan)
    assert airmass.min() > 2.8 and ha_h.max() < 5.0
    report = check_plan(plan, flat_map, CFG)
    assert report.counts == {"window": 2} and all("airmass" in line for line in report.problems)


def test_hour_angle_beyond_the_mount_limit_is_refused(flat_map):
    f874 = (874, 220.0, 83.75)  # circumpolar: airmass 1.8, but 6.4-6.9 h west of the meridian
    plan = plan_of([obs(f874, "g", T0 + 1800), obs(f874, "r", T0 + 3660)])
    _, airmass, ha_h, _ = truth(plan)
    assert ha_h.min() > 6.2 and airmass.max() < 2.2
    report = check_plan(plan, flat_map, CFG)
    assert report.counts == {"window": 2} and all("hour angle" in line for line in report.problems)


def test_rising_southern_field_in_the_ffi_keep_out_is_refused(flat_map):
    f290 = (290, 331.58811, -24.25)  # HA -22.5 deg, Dec < -22: ZTF rejects it (interference with the FFI)
    plan = plan_of([obs(f290, "g", T0), obs(f290, "r", T0 + 1860)])  # by the r visit HA > -17.6 deg
    _, airmass, ha_h, _ = truth(plan)
    assert airmass.max() < 2.2 and ha_h[[0, 2, 4]].min() * 15 > 20.5 and ha_h[[1, 3, 5]].max() * 15 < 16
    report = check_plan(plan, flat_map, CFG)
    assert report.counts == {"window": 1} and "hour angle -1.5" in report.problems[0]


def test_field_near_the_moon_is_refused(flat_map):
    f335 = (335, 290.80782, -17.05)
    plan = plan_of([obs(f335, "g", T0), obs(f335, "r", T0 + 1860)], start=FULL_MOON)
    sun, airmass, ha_h, moon = truth(plan)
    assert moon.max() < 14 and sun.max() < -30 and airmass.max() < 1.9
    report = check_plan(plan, flat_map, CFG)
    assert report.counts == {"window": 2} and all("Moon" in line for line in report.problems)


@pytest.mark.parametrize("rule", ["sun", "airmass", "ha_east", "ha_west", "moon"])
def test_each_limit_holds_to_its_tolerance_and_no_further(flat_map, rule):
    """The configured limit is put just inside, then just beyond, the control plan's worst value."""
    # at 08:00 UTC both fields are still east of the meridian; 2.5 h later both are west of it
    plan = plan_of(control_obs(later=9000.0 if rule == "ha_west" else 0.0), start=FULL_MOON)
    sun, airmass, ha_h, moon = truth(plan)
    signed_ha = ha_h * np.sign(truth_ha(plan))
    assert rule != "ha_east" or signed_ha.max() < 0
    assert rule != "ha_west" or signed_ha.min() > 0
    worst = {"sun": sun.max(), "airmass": airmass.max(), "ha_east": ha_h.max(), "ha_west": ha_h.max(),
             "moon": moon.min()}[rule]
    key, inside, beyond = {
        "sun": ("sun_alt_max_deg", worst - 0.03, worst - 0.08),  # tolerance 0.05 deg
        "airmass": ("airmass_max", worst - 0.008, worst - 0.015),  # tolerance 0.01
        "ha_east": ("ha_max_h", worst - 0.004, worst - 0.007),  # tolerance 0.005 h
        "ha_west": ("ha_max_h", worst - 0.004, worst - 0.007),
        "moon": ("moon_sep_min_deg", worst + 0.08, worst + 0.13),  # tolerance 0.1 deg
    }[rule]
    assert check_plan(plan, flat_map, dataclasses.replace(CFG, **{key: inside})).ok
    report = check_plan(plan, flat_map, dataclasses.replace(CFG, **{key: beyond}))
    assert kinds(report) == {"window"} and report.counts["window"] >= 1


def test_interpolated_conditions_match_astropy_at_the_exposure_times():
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 86400, 120))
    ra, dec = rng.uniform(0, 360, t.size), rng.uniform(-30, 85, t.size)
    c = conditions(NEW_MOON, t, ra, dec)
    times = NEW_MOON + TimeDelta(t, format="sec")
    sky = SkyCoord(ra * u.deg, dec * u.deg)
    frame = AltAz(obstime=times, location=P48)
    alt = sky.transform_to(frame).alt.deg
    up = alt > 20
    assert np.abs(c.sun_alt - get_body("sun", times, P48).transform_to(frame).alt.deg).max() < 2e-3
    assert np.abs(c.airmass[up] - 1 / np.sin(np.radians(alt[up]))).max() < 1e-3
    assert np.all(np.isinf(c.airmass[alt < 0]))
    ha = times.sidereal_time("apparent", longitude=P48.lon).deg - sky.transform_to(TETE(obstime=times)).ra.deg
    assert np.abs((c.ha - ha + 180) % 360 - 180).max() < 0.01
    moon = get_body("moon", times, P48).separation(sky, origin_mismatch="ignore").deg
    assert np.abs(c.moon_sep - moon).max() < 0.02


def test_mount_keep_outs_follow_ztf_sims_queue_rules():
    """ztf_sim QueueManager: |HA| < 5.95 h; HA < -17.6 & Dec < -22; HA > -17.6 & Dec < -45; |HA| > 3 & Dec < -46; Dec > 87.5."""
    ha = np.array([-17.7, -17.5, -17.7, 10.0, 10.0, 2.9, 3.1, -2.9, 89.0, 89.5, 0.0, 0.0])
    dec = np.array([-22.1, -22.1, -21.9, -45.1, -44.9, -46.1, -46.1, -46.1, 10.0, 10.0, 87.4, 87.6])
    expected = [False, True, True, False, True, False, False, False, True, False, True, False]
    assert mount_reachable(ha, dec, 5.95).tolist() == expected
    assert mount_reachable(np.array([-95.0, 95.0]), np.array([0.0, 0.0]), 6.5).tolist() == [True, True]


# ----------------------------------------------------------------- timing rules

def test_overlapping_exposures_are_refused(flat_map):
    o = control_obs()
    o[1] = dataclasses.replace(o[1], start=o[0].start + 299.0)
    report = check_plan(plan_of(o), flat_map, CFG)
    assert report.counts == {"overlap": 1}
    assert report.problems == ("overlap: field 1685 g starts 1.0 s before field 687 g ends",)
    for gap in (0.0, 0.5):  # back to back is no overlap, but leaves no time to read out and slew
        o[1] = dataclasses.replace(o[1], start=o[0].end + gap)
        assert check_plan(plan_of(o), flat_map, CFG).counts == {"slew": 1}


def test_slew_readout_and_filter_change_set_the_least_gap(flat_map):
    o = control_obs()  # 687 -> 1685: Dec axis 3.6 deg: 2 sqrt(3.6 / 0.5) + 1 s settle = 6.37 s < 8 s readout
    for gap, ok in ((8.0, True), (7.99, False)):
        o[1] = dataclasses.replace(o[1], start=o[0].end + gap)
        report = check_plan(plan_of(o), flat_map, CFG)
        assert report.ok == ok and (ok or report.counts == {"slew": 1})
    o = control_obs()  # a far field: the slew, not the readout, sets the gap
    far = (1729, 313.5795, 36.95)  # from 1685: HA 6.43682 deg, Dec 7.2 deg, both short of top speed
    need = max(2 * np.sqrt(6.43682 / 0.4), 2 * np.sqrt(7.2 / 0.5)) + 1.0  # 9.02 s, the HA axis
    for gap, ok in ((need + 0.01, True), (need - 0.01, False)):
        seq = [o[0], o[1], obs(far, "g", o[1].end + gap), obs(F687, "r", T0 + 1860),
               obs(F1685, "r", T0 + 2220), obs(far, "r", T0 + 2580)]
        report = check_plan(plan_of(seq), flat_map, CFG)
        assert report.ok == ok and (ok or report.counts == {"slew": 1}), (gap, report.problems)
    for gap, ok in ((120.0, True), (119.0, False)):  # a filter change (120 s) outlasts the slew
        seq = [obs(F687, "g", T0), obs(F1685, "r", T0 + 300 + gap), obs(F687, "r", T0 + 1860),
               obs(F1685, "g", T0 + 2160 + gap)]
        report = check_plan(plan_of(seq), flat_map, CFG)
        assert report.ok == ok and (ok or report.counts == {"slew": 2})
    assert report.problems[0] == "slew: only 119.0 s from field 687 g to field 1685 r, needs 120.0 s"


def test_checker_slew_arithmetic_is_the_published_trapezoid():
    m = SlewModel()  # ztf_sim P48_slew_pars: HA 0.4 deg/s2, 2.5 deg/s; Dec 0.5 deg/s2, 3.0 deg/s; settle 1 s
    t = slew_seconds(np.array([0.0, 359.0, 10.0, 5.0]), np.array([0.0, 0.0, 0.0, 5.0]),
                     np.array([20.0, 1.0, 10.0, 5.0]), np.array([0.0, 0.0, -30.0, 5.0]), m)
    assert t == pytest.approx([20 / 2.5 + 2.5 / 0.4 + 1, 2 * np.sqrt(2 / 0.4) + 1, 30 / 3 + 3 / 0.5 + 1, 0.0])
    # a 0.05 deg move takes 0.71 s and still settles
    assert slew_seconds(10.0, 0.0, 10.05, 0.0, m) == pytest.approx(2 * np.sqrt(0.05 / 0.4) + 1.0)
    slow = dataclasses.replace(m, dec_vmax_deg_s=1.0, settle_s=2.0)
    assert slew_seconds(0.0, 0.0, 0.0, 5.0, slow) == pytest.approx(5 / 1.0 + 1.0 / 0.5 + 2.0)


def test_cadence_too_short_or_one_filter_only_is_refused(flat_map):
    o = control_obs()
    o[2] = dataclasses.replace(o[2], start=T0 + 1799.0)
    report = check_plan(plan_of(o), flat_map, CFG)
    assert report.counts == {"cadence": 1} and "687: g and r only 1799 s apart" in report.problems[0]
    o[2] = dataclasses.replace(o[2], start=T0 + 1800.0)
    assert check_plan(plan_of(o), flat_map, CFG).ok
    report = check_plan(plan_of(control_obs()[:2] + control_obs()[3:]), flat_map, CFG)
    assert report.problems == ("cadence: field 687 is not observed in both g and r",)


def test_exposure_outside_the_horizon_is_refused(flat_map):
    end = T0 + 2220 + 300  # the control's last exposure ends here
    assert check_plan(plan_of(control_obs(), hours=end / 3600), flat_map, CFG).ok
    report = check_plan(plan_of(control_obs(), hours=(end - 1) / 3600), flat_map, CFG)
    assert report.counts == {"horizon": 1}
    for before, ok in ((1.0, False), (0.001, True), (0.0, True)):  # the first exposure starts at -before
        early = plan_of(control_obs(), start=NEW_MOON + TimeDelta(T0 + before, format="sec"))
        shifted = [dataclasses.replace(x, start=x.start - T0 - before) for x in control_obs()]
        report = check_plan(early.with_(observations=tuple(shifted)), flat_map, CFG)
        assert report.ok == ok and (ok or report.counts == {"horizon": 1})
    assert report.problems == () and shifted[0].start == 0.0
    early = plan_of(control_obs(), start=NEW_MOON + TimeDelta(T0 + 1, format="sec"))
    shifted = [dataclasses.replace(x, start=x.start - T0 - 1) for x in control_obs()]
    report = check_plan(early.with_(observations=tuple(shifted)), flat_map, CFG)
    assert report.problems == ("horizon: field 687 g at -1-299 s is outside the horizon 0-86400 s",)


def test_out_of_order_exposures_are_refused(flat_map):
    o = control_obs()
    report = check_plan(plan_of([o[1], o[0]] + o[2:]), flat_map, CFG)
    assert "order" in kinds(report)
    assert "order: exposure 1 (field 687) starts before exposure 0" in report.problems


# ----------------------------------------------------------------- fields, filters, coverage

def test_unknown_field_or_wrong_position_is_refused(flat_map):
    o = [dataclasses.replace(x, field_id=99999) if x.field_id == 687 else x for x in control_obs()]
    report = check_plan(plan_of(o), flat_map, CFG)
    assert report.counts == {"field": 2} and report.problems[0] == "field: unknown field 99999"
    for shift, ok in ((0.0009, True), (0.0011, False)):
        o = control_obs()
        o[0] = dataclasses.replace(o[0], dec=o[0].dec + shift)
        o[2] = dataclasses.replace(o[2], ra=(o[2].ra + shift) % 360)
        report = check_plan(plan_of(o), flat_map, CFG)
        assert report.ok == ok and (ok or report.counts == {"field": 2})
    o = [dataclasses.replace(x, ra=359.9995, dec=-89.05) if x.field_id == 687 else x for x in control_obs()]
    o = [dataclasses.replace(x, field_id=1) if x.field_id == 687 else x for x in o]  # field 1 is at RA 0
    assert "field" not in kinds(check_plan(plan_of(o), flat_map, CFG))


def test_wrong_filter_or_exposure_is_refused(flat_map):
    o = control_obs()
    o[3] = dataclasses.replace(o[3], filter="i")
    report = check_plan(plan_of(o), flat_map, CFG)
    # and, the filter having changed, the 60 s after the previous exposure is short of the filter change
    assert report.counts == {"filter": 1, "cadence": 1, "slew": 1}
    o = control_obs()
    o[1] = dataclasses.replace(o[1], exposure_s=0.0)
    assert check_plan(plan_of(o), flat_map, CFG).counts == {"exposure": 1}
    o[1] = dataclasses.replace(o[1], exposure_s=0.5)  # short, but an exposure
    assert check_plan(plan_of(o), flat_map, CFG).ok


def _unit_pixel(nside, ra0, dec0, x, y):
    """Pixel at orthographic offsets (x: West, y: North; deg) from (ra0, dec0), by plain spherical trig."""
    x, y = np.radians(x), np.radians(y)
    z = np.sqrt(1 - x * x - y * y)
    a, d = np.radians(ra0), np.radians(dec0)
    v = (z * np.array([np.cos(d) * np.cos(a), np.cos(d) * np.sin(a), np.sin(d)])
         + x * np.array([np.sin(a), -np.cos(a), 0.0])
         + y * np.array([-np.sin(d) * np.cos(a), -np.sin(d) * np.sin(a), np.cos(d)]))
    return hp.vec2pix(nside, *v, nest=True)


def test_coverage_is_the_probability_on_the_ccds_exactly():
    """Probability on a CCD, in the central chip gap, and just outside the camera: a known answer."""
    nside = 512
    ra0, dec0 = F687[1], F687[2]
    on = _unit_pixel(nside, ra0, dec0, 1.0, 1.0)  # inside CCD 11's outline
    gap = _unit_pixel(nside, ra0, dec0, 0.0, 0.0)  # the boresight lies in the cross-shaped gap
    beyond = _unit_pixel(nside, ra0, dec0, 3.75, 0.0)  # the layout ends at EW 3.6474 deg
    west_edge = _unit_pixel(nside, ra0, dec0, 3.55, 1.0)  # inside CCD 09 near its outer edge
    prob = np.zeros(hp.nside2npix(nside))
    prob[[on, gap, beyond, west_edge]] = [0.25, 0.4, 0.3, 0.05]
    assert polygon_coverage([687], prob) == pytest.approx(0.30)
    assert polygon_coverage([687, 99999], prob) == pytest.approx(0.30)
    assert polygon_coverage([], prob) == 0.0


def test_reported_coverage_is_held_to_the_recomputed_value(flat_map):
    true = polygon_coverage([687, 1685], flat_map.prob)
    area = true * 41252.96  # deg2 of a flat map: two overlapping 47 deg2 footprints
    assert 60 < area < 94
    for claim, ok in ((true + 0.0019, True), (true - 0.0019, True), (true + 0.0021, False), (true - 0.0021, False)):
        m = PlanMetrics(coverage=claim, solver="hand", status="hand", mip_gap=None, runtime_s=0.0, n_fields=2,
                        n_exposures=4)
        report = check_plan(plan_of(control_obs(), metrics=m), flat_map, CFG)
        assert report.ok == ok and report.coverage == true and report.reported_coverage == claim
        assert ok or report.counts == {"coverage": 1}


def test_footprints_built_from_shrunken_ccds_are_caught(monkeypatch):
    """The checker has its own CCD outlines: coverage from CCDs shrunk by 1.5 % in fields.py is refused."""
    import mushrooms.scheduler_core.sky.fields as fields

    nside = 256
    centres = hp.ang2vec([F687[1], F1685[1]], [F687[2], F1685[2]], lonlat=True)
    prob = np.zeros(hp.nside2npix(nside))
    for v in centres:  # the probability sits on the two control fields
        prob[hp.query_disc(nside, v, np.radians(4.0), nest=True)] = 1.0
    prob /= prob.sum()
    sky = SkyMap(prob=prob, nside=nside, event_time=None, object_id=None, distmu=None, distsigma=None,
                 distnorm=None, distmean=None, sha256="0" * 64, source="<two discs>")
    grid = fields.load_ztf_fields()
    sub = grid.select(np.isin(grid.ids, [687, 1685]))
    metrics = dict(solver="hand", status="hand", mip_gap=None, runtime_s=0.0, n_fields=2, n_exposures=4)
    right = fields.field_footprints(sub, nside).coverage({687, 1685}, prob)
    plan = plan_of(control_obs(), metrics=PlanMetrics(coverage=right, **metrics))
    assert check_plan(plan, sky, CFG).ok
    shrunk = fields.ccd_corners() * 0.985
    monkeypatch.setattr(fields, "ccd_corners", lambda: shrunk)
    monkeypatch.setattr(fields, "_memory_cache", {})
    wrong = fields.field_footprints(sub, nside).coverage({687, 1685}, prob)
    assert wrong < right - 0.01
    report = check_plan(plan.with_(metrics=PlanMetrics(coverage=wrong, **metrics)), sky, CFG)
    assert report.counts == {"coverage": 1} and report.coverage == pytest.approx(right, abs=1e-3)


def test_many_problems_are_counted_but_listed_only_up_to_the_limit(flat_map):
    o = [obs(F687, "g" if k % 2 == 0 else "r", T0 + k * 10.0) for k in range(MAX_LISTED + 6)]  # 10 s apart
    report = check_plan(plan_of(o), flat_map, CFG)
    assert report.counts["overlap"] == MAX_LISTED + 5
    assert sum(line.startswith("overlap:") for line in report.problems) == MAX_LISTED


def test_an_empty_plan_is_valid_unless_it_claims_coverage(flat_map):
    m = PlanMetrics(coverage=0.0, solver="hand", status="hand", mip_gap=None, runtime_s=0.0, n_fields=0,
                    n_exposures=0)
    report = check_plan(plan_of([], metrics=m), flat_map, CFG)
    assert report.ok is True and report.problems == () and report.counts == {}
    assert report.coverage == 0.0 and report.reported_coverage == 0.0
    report = check_plan(plan_of([], metrics=dataclasses.replace(m, coverage=0.1)), flat_map, CFG)
    assert report.ok is False and report.counts == {"coverage": 1}
    assert report.coverage == 0.0 and report.reported_coverage == 0.1
