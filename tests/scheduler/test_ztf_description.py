"""``ztf.toml`` holds exactly the ZTF numbers the code uses today (issue 53, item 1, first phase).

Each test imports today's constants from where the planner, the checker,
the executor model, the depth model and the exports define them, and
compares them with the shipped description: the description is a second
statement of the same telescope, so a change to either shows here.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.scheduler_core.config import PlanningConfig, SlewModel
from mushrooms.scheduler_core.instruments import load_description, pointing_allowed
from mushrooms.scheduler_core.instruments.description import local_mean_noon
from mushrooms.scheduler_core.instruments.footprint import project as description_plane
from mushrooms.scheduler_core.plan import check_geometry
from mushrooms.scheduler_core.plan.document import FILTER_IDS as DOCUMENT_FILTER_IDS
from mushrooms.scheduler_core.plan.exports import FILTER_IDS, PROGRAM_IDS, SKYPORTAL_FILTERS
from mushrooms.scheduler_core.sky.constraints import mount_limits_ok
from mushrooms.scheduler_core.sky.ephemeris import GRID_ANCHOR
from mushrooms.scheduler_core.sky.fields import FOOTPRINT_RADIUS_DEG, ccd_corners, load_ztf_fields, project
from mushrooms.scheduler_core.sky.visibility import PALOMAR, site
from mushrooms.scheduler_core.source import depth as depth_module
from mushrooms.scheduler_core.source.depth import ZTF_DEPTH, ZTF_MEDIAN_DEPTH_30S
from mushrooms.scheduler_core.telescope.executor import FILTER_NAMES
from mushrooms.scheduler_core.telescope.timing import PALOMAR_LAT_DEG, TelescopeTiming


@pytest.fixture(scope="module")
def ztf():
    return load_description("ztf")


def test_the_field_grid_is_ztf_fields_txt(ztf):
    today = load_ztf_fields()
    assert np.array_equal(ztf.grid.ids, today.ids)
    assert np.array_equal(ztf.grid.ra, today.ra) and np.array_equal(ztf.grid.dec, today.dec)
    checker = check_geometry.field_positions()  # the checker's own reading of the same file
    assert {int(i): (float(r), float(d)) for i, r, d in zip(ztf.grid.ids, ztf.grid.ra, ztf.grid.dec)} == checker


def test_the_footprint_is_the_ccd_layout(ztf):
    assert np.array_equal(ztf.footprint.corners(), ccd_corners())
    assert ztf.footprint.radius_deg == FOOTPRINT_RADIUS_DEG
    # the plane of the description's polygons is the planner's
    ra, dec = np.random.default_rng(3).uniform(0, 360, 50), np.random.default_rng(4).uniform(-80, 80, 50)
    x, y, _ = description_plane(ra, dec, 120.0, 30.0)
    x0, y0 = project(ra, dec, 120.0, 30.0)
    assert np.array_equal(x, x0) and np.array_equal(y, y0)


def test_the_site_and_the_night_anchor(ztf):
    s = ztf.site
    assert (s.latitude_deg, s.longitude_deg, s.height_m) == PALOMAR
    assert s.latitude_deg == PALOMAR_LAT_DEG
    assert s.location == site()
    # the checker's independent position is the same one to 0.01 arcsec
    assert np.allclose((s.latitude_deg, s.longitude_deg, s.height_m), check_geometry.P48_SITE, atol=3e-6)
    assert Time(s.night_anchor_utc, scale="utc") == GRID_ANCHOR
    assert local_mean_noon(-116.86) == s.night_anchor_utc  # the anchor as its docstring derives it


def test_the_overheads_and_slew_axes(ztf):
    o, slew, timing = ztf.overheads, SlewModel(), TelescopeTiming()
    assert (o.readout_s, o.settle_s) == (slew.readout_s, slew.settle_s) == (timing.slew.readout_s,
                                                                           timing.slew.settle_s)
    assert o.filter_change_s == timing.filter_change_s
    assert o.filter_change_with_slew is False  # Q7: change + max(readout, slews)
    assert [a.coordinate for a in o.axes] == ["ha", "dec", "dome_azimuth"]
    assert (o.axis("ha").accel_deg_s2, o.axis("ha").vmax_deg_s) == (slew.ha_accel_deg_s2, slew.ha_vmax_deg_s)
    assert (o.axis("dec").accel_deg_s2, o.axis("dec").vmax_deg_s) == (slew.dec_accel_deg_s2, slew.dec_vmax_deg_s)
    assert ((o.axis("dome_azimuth").accel_deg_s2, o.axis("dome_azimuth").vmax_deg_s)
            == (timing.dome_accel_deg_s2, timing.dome_vmax_deg_s))


def test_the_pointing_limits(ztf):
    lim, cfg, timing = ztf.limits, PlanningConfig(), TelescopeTiming()
    assert ((lim.airmass_max, lim.ha_max_h, lim.dec_min_deg, lim.dec_max_deg, lim.sun_alt_max_deg,
             lim.moon_sep_min_deg)
            == (cfg.airmass_max, cfg.ha_max_h, cfg.dec_min_deg, cfg.dec_max_deg, cfg.sun_alt_max_deg,
                cfg.moon_sep_min_deg))
    assert (lim.airmass_max, lim.ha_max_h, lim.sun_alt_max_deg) == (timing.max_airmass, timing.ha_max_h,
                                                                    timing.sun_alt_max_deg)


def test_the_keep_out_boxes_are_the_mounts_rules(ztf):
    # a dense grid of (HA, Dec) with every rule's edges on it, and both sides of each edge
    edges_ha = np.array([-180.0, -89.25, -17.6, -3.0, 0.0, 3.0, 89.25, 179.99])
    edges_dec = np.array([-90.0, -46.0, -45.0, -22.0, 0.0, 87.5, 90.0])
    ha = np.concatenate([np.arange(-180.0, 180.0, 0.05), edges_ha, np.nextafter(edges_ha, 200),
                         np.nextafter(edges_ha, -200)])[:, None]
    dec = np.concatenate([np.arange(-90.0, 90.0001, 0.25), edges_dec, np.nextafter(edges_dec, 100),
                          np.nextafter(edges_dec, -100)])[None, :]
    ha, dec = np.broadcast_arrays(ha, dec)  # today's functions take arrays of one shape
    mine = pointing_allowed(ztf.limits, ha, dec)
    assert np.array_equal(mine, mount_limits_ok(ha, dec, PlanningConfig().ha_max_h))
    assert np.array_equal(mine, check_geometry.mount_reachable(ha, dec, PlanningConfig().ha_max_h))
    assert 0.2 < mine.mean() < 0.8  # both answers occur


def test_the_filters_and_the_depth_model(ztf):
    assert list(ztf.filters) == ["g", "r", "i"]
    for band, f in ztf.filters.items():
        assert f.zenith_depth == ZTF_DEPTH.dark_zenith_depth_30s[band]
        assert f.sky_zenith == ZTF_DEPTH.dark_sky_zenith[band]
        assert f.extinction == ZTF_DEPTH.extinction[band]
        assert f.zenith_fwhm_arcsec == ZTF_DEPTH.zenith_fwhm_arcsec[band]
        assert f.reference_depth == ZTF_DEPTH.reference_depth[band]
        assert f.reference_fwhm_arcsec == ZTF_DEPTH.reference_fwhm_arcsec[band]
        assert f.median_depth == ZTF_MEDIAN_DEPTH_30S[band]
        assert f.sun_minus_v == depth_module._SUN_MINUS_V[band]  # the moonlight's colour (a module constant)
        assert f.queue_id == FILTER_IDS[band] == DOCUMENT_FILTER_IDS[band] and FILTER_NAMES[f.queue_id] == band
        assert f.skyportal_name == SKYPORTAL_FILTERS[band]
        assert f.detectors == ()  # every CCD sees every filter
    d = ztf.depth
    assert d.reference_exposure_s == 30.0  # (D1)'s 1.25 log10(t / 30 s)
    assert d.seeing_airmass_exponent == ZTF_DEPTH.seeing_airmass_exponent
    assert d.twilight_slope_mag_per_deg == ZTF_DEPTH.twilight_slope_mag_per_deg
    assert {f.name for f in dataclasses.fields(ZTF_DEPTH)} == {  # a new term would need a key
        "dark_zenith_depth_30s", "dark_sky_zenith", "extinction", "seeing_airmass_exponent",
        "twilight_slope_mag_per_deg", "zenith_fwhm_arcsec", "reference_depth", "reference_fwhm_arcsec",
        "sun_minus_v", "location"}  # (phase 2) the Sun's colour per filter and the site: keys of the description
    assert dict(ZTF_DEPTH.sun_minus_v) == {b: f.sun_minus_v for b, f in ztf.filters.items()}
    assert ZTF_DEPTH.location is None  # the P48's: site(), compared with [site] above


def test_the_planning_defaults_and_the_queue(ztf):
    p, cfg, timing = ztf.planning, PlanningConfig(), TelescopeTiming()
    assert ((p.exposure_s, p.filters, p.cadence_s, p.filter_change_s, p.slew_estimate_s)
            == (cfg.exposure_s, cfg.filters, cfg.cadence_s, cfg.filter_change_s, cfg.slew_estimate_s))
    e = ztf.execution
    assert e.queue == "ztf_too"
    assert (e.survey_step_s, e.lost_pointing_slew_s, e.default_max_airmass) == (
        timing.survey_step_s, timing.lost_pointing_slew_s, timing.max_airmass)
    assert dict(e.program_ids) == PROGRAM_IDS
