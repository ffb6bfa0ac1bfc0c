"""(M1) An alt-azimuth mount (WINTER) has its slews timed on azimuth and altitude at the slew's time.

Before, every slew was timed by the RA and Dec differences with the azimuth
and altitude axes' speeds: through the zenith a 1.2 deg step in declination
is a half turn in azimuth, which took 4 s instead of a minute.  ZTF, LS4 and
DECam (hour-angle and declination axes) are timed as before.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import TETE, AltAz, EarthLocation, SkyCoord
from astropy.time import Time, TimeDelta

from tests_paths import MAP_220722V
from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.plan.checker import check_plan

START = Time("2022-07-23T04:00:00", scale="utc")


def _site(telescope) -> EarthLocation:
    s = telescope.site
    return EarthLocation.from_geodetic(s.longitude_deg * u.deg, s.latitude_deg * u.deg, s.height_m * u.m)


def _through_the_zenith(telescope, when: Time) -> tuple[tuple[float, float], tuple[float, float]]:
    """ICRS places of the points 0.6 deg north and south of the zenith on the meridian at ``when`` (astropy)."""
    lst = when.sidereal_time("apparent", longitude=telescope.site.longitude_deg * u.deg).deg
    lat = telescope.site.latitude_deg
    of_date = SkyCoord([lst, lst] * u.deg, [lat + 0.6, lat - 0.6] * u.deg, frame=TETE(obstime=when))
    icrs = of_date.transform_to("icrs")
    return (float(icrs.ra.deg[0]), float(icrs.dec.deg[0])), (float(icrs.ra.deg[1]), float(icrs.dec.deg[1]))


def test_only_winter_is_an_altaz_mount():
    from mushrooms.scheduler_core.telescope.mount import altaz_mount

    assert altaz_mount(PlanningConfig(), START) is None  # ZTF: no description read
    for name in ("ls4", "decam", "ztf"):
        assert altaz_mount(PlanningConfig.for_telescope(load_description(name), {}), START) is None, name
    mount = altaz_mount(PlanningConfig.for_telescope(load_description("winter"), {}), START)
    assert mount is not None and mount.latitude_deg == pytest.approx(33.3571)


def test_a_slew_through_the_zenith_is_a_half_turn_in_azimuth():
    from mushrooms.scheduler_core.telescope.mount import altaz_mount
    from mushrooms.scheduler_core.telescope.slew import slew_time

    winter = load_description("winter")
    cfg = PlanningConfig.for_telescope(winter, {})
    t = 3600.0
    when = START + TimeDelta(t, format="sec")
    (ra1, dec1), (ra2, dec2) = _through_the_zenith(winter, when)
    frame = AltAz(obstime=when, location=_site(winter))
    hor = SkyCoord([ra1, ra2] * u.deg, [dec1, dec2] * u.deg).transform_to(frame)  # astropy's (aberration: 20")
    d_az = abs((hor.az.deg[1] - hor.az.deg[0] + 180.0) % 360.0 - 180.0)
    assert d_az > 170.0 and abs(hor.alt.deg[1] - hor.alt.deg[0]) < 1.0
    v, a = cfg.slew.ha_vmax_deg_s, cfg.slew.ha_accel_deg_s2  # the azimuth axis (3.3 deg/s, 1 deg/s2)
    want = d_az / v + v / a + cfg.slew.settle_s  # trapezoid, at top speed
    got = float(slew_time(ra1, dec1, ra2, dec2, cfg.slew, altaz_mount(cfg, START), t))
    # the model and astropy's places differ by 0.006 deg (aberration): ~0.6 deg of azimuth 0.6 deg from the zenith
    assert got == pytest.approx(want, abs=0.5)
    equatorial = float(slew_time(ra1, dec1, ra2, dec2, cfg.slew))
    assert equatorial < 5.0 < 50.0 < got  # 1.2 deg in declination: what it was timed as before


def test_the_checker_wants_the_altaz_slew(tmp_path):
    winter = load_description("winter")
    cfg = PlanningConfig.for_telescope(winter, {"nside": 64, "solver": "greedy",  # I5's, set: a plan on main too
                                                "min_gain": 2e-5, "min_coverage": 2e-4})
    skymap = read_skymap(MAP_220722V, nside=64)
    plan = make_plan(skymap, cfg, start=START)
    assert plan.observations and check_plan(plan, skymap, cfg).ok  # the planner's timing passes the checker
    first = plan.observations[0]
    (ra1, dec1), (ra2, dec2) = _through_the_zenith(winter, START + TimeDelta(first.end, format="sec"))
    grid = winter.grid
    near = [int(np.argmin((grid.ra - r) ** 2 + (grid.dec - d) ** 2)) for r, d in ((ra1, dec1), (ra2, dec2))]
    a, b = (dataclasses.replace(first, field_id=int(grid.ids[k]), ra=float(grid.ra[k]), dec=float(grid.dec[k]))
            for k in near)

    def slew_problems(gap_s: float) -> list[str]:
        two = (a, dataclasses.replace(b, start=a.end + gap_s))
        report = check_plan(dataclasses.replace(plan, observations=two), skymap, cfg)
        return [line for line in report.problems if line.startswith("slew:")]

    assert slew_problems(6.0)  # enough for RA/Dec travel (4 s), not for half a turn in azimuth
    assert not slew_problems(70.0)


def test_winter_plans_keep_their_altaz_slews():
    """Every consecutive pair of a WINTER plan is at least the alt-azimuth slew apart (the planner times them so)."""
    from mushrooms.scheduler_core.telescope.mount import altaz_mount
    from mushrooms.scheduler_core.telescope.slew import overhead_time

    cfg = PlanningConfig.for_telescope(load_description("winter"), {"nside": 64, "solver": "greedy"})
    plan = make_plan(read_skymap(MAP_220722V, nside=64), cfg, start=START)
    obs = plan.observations
    assert len(obs) >= 5
    ra, dec = np.array([o.ra for o in obs]), np.array([o.dec for o in obs])
    end, start = np.array([o.end for o in obs]), np.array([o.start for o in obs])
    need = overhead_time(ra[:-1], dec[:-1], ra[1:], dec[1:], cfg.slew, 0.0, altaz_mount(cfg, START), end[:-1])
    assert np.all(start[1:] - end[:-1] >= need - 1e-3)
