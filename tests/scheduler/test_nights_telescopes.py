"""Several nights of a described telescope (docs/design/replan.md N1-N3, telescopes.md section 4).

The nights after the first are planned by ``plan_remaining`` on the telescope's own grid and
detectors, and a night is its site's night: split at the site's local noon, not Palomar's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from astropy import units as u
from astropy.coordinates import AltAz, EarthLocation, get_sun
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, read_skymap
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.nights import as_planned, plan_nights
from mushrooms.scheduler_core.sky.twilight import NIGHT_GRID_S, night_windows

MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
LS4 = Path(__file__).resolve().parents[2] / "mushrooms" / "scheduler_core" / "data" / "telescopes" / "ls4.toml"
#: Xinglong Station (China), a site far east of Palomar: 19:47 UTC is 03:37 local mean time there.
EAST_SITE = (40.3956, 117.5750, 960.0)


def east_description(tmp_path: Path) -> Path:
    """LS4's description moved to a site in the far east (a test-only telescope)."""
    text = LS4.read_text()
    head, rest = text.split("[site]", 1)
    rest = rest.split("[grid]", 1)[1]
    lat, lon, height = EAST_SITE
    site = (f'[site]\nlatitude_deg = {lat}\nlongitude_deg = {lon}\nheight_m = {height}\n'
            f'source = "test only: Xinglong Station"\n\n[grid]')
    path = tmp_path / "east.toml"
    path.write_text(head.replace('name = "ls4"', 'name = "east"') + site + rest)
    return path


def sun_alt(times: Time, site: tuple[float, float, float]) -> np.ndarray:
    lat, lon, height = site
    here = EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)
    return get_sun(times).transform_to(AltAz(obstime=times, location=here)).alt.deg


def checked(plans, skymap) -> bool:
    """Every night through the checker, on the nights before taken as done (N2)."""
    done, ok = [], True
    for plan in plans:
        ok &= check_plan(plan, skymap, PlanningConfig.from_mapping(plan.config), executed=tuple(done)).ok
        done += as_planned(plan)
    return bool(ok)


def test_two_nights_of_ls4_are_planned_on_its_grid_and_pass_the_checker():
    ls4 = load_description("ls4")
    cfg = PlanningConfig.for_telescope(ls4, {"nside": 64, "solver": "greedy", "nights": 2})
    skymap = read_skymap(MAP, nside=64)
    plans = plan_nights(skymap, cfg)  # each night checked (PlanCheckError otherwise): it took ZTF's grid
    assert len(plans) == 2 and plans[0].observations
    for plan in plans:
        assert set(plan.field_ids) <= set(ls4.grid.ids.tolist())
        assert {o.filter for o in plan.observations} <= {"i"}
    assert checked(plans, skymap)
    assert not set(plans[0].field_ids) & set(plans[1].field_ids)  # night 2 on what night 1 covered (N2)


def test_a_far_east_sites_nights_are_whole(tmp_path):
    east = east_description(tmp_path)
    cfg = PlanningConfig.for_telescope(load_description(east), {"nside": 64, "nights": 3})
    windows = night_windows(Time("2026-01-10T06:00:00", scale="utc"), cfg, 3)
    step = TimeDelta(2 * NIGHT_GRID_S, format="sec")
    for evening, morning in windows:
        assert 11.0 < (morning - evening).to_value("h") < 15.0  # a January night at 40 deg N
        inside = evening + TimeDelta(np.linspace(0, (morning - evening).to_value("s"), 40), format="sec")
        assert (sun_alt(inside, EAST_SITE) <= cfg.sun_alt_max_deg + 0.01).all()
        # whole: the Sun is up (above the limit) just before the evening and just after the morning
        assert (sun_alt(Time([evening - step, morning + step]), EAST_SITE) > cfg.sun_alt_max_deg).all()


def test_two_nights_at_a_far_east_site_pass_the_checker(tmp_path):
    east = east_description(tmp_path)
    cfg = PlanningConfig.for_telescope(load_description(east), {"nside": 64, "solver": "greedy", "nights": 2,
                                                                 "dec_max_deg": 90.0})
    skymap = read_skymap(MAP, nside=64)
    plans = plan_nights(skymap, cfg)
    assert len(plans) == 2
    assert checked(plans, skymap) and plans[0].observations
    for plan in plans:
        times = Time([plan.absolute_time(o.start).isot for o in plan.observations] or [plan.start.isot])
        assert (sun_alt(times, EAST_SITE) <= cfg.sun_alt_max_deg + 0.01).all()
