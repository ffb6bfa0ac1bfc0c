"""Independent plan checker: is a plan something ZTF can really execute?

It shares no code path with the schedulers' window or footprint computation:
each exposure is tested at its start, middle and end with astropy's full
alt-az transformation (Sun altitude, airmass, Moon separation) and the
apparent hour angle; coverage is recomputed from the CCD outlines with
``healpy.query_polygon`` instead of the schedulers' projected-plane test.
Only the slew model and the mount limits, which *are* the specification,
are shared.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import healpy as hp
import numpy as np
from astropy import units as u
from astropy.coordinates import TETE, AltAz, SkyCoord, get_body
from astropy.time import TimeDelta

from .config import PlanningConfig
from .fields import ccd_corners, deproject, load_ztf_fields
from .plan import Plan
from .skymap import SkyMap
from .slew import overhead_time
from .visibility import mount_limits_ok, site

__all__ = ["CheckReport", "check_plan", "polygon_coverage"]

#: Slack allowed against each constraint (numerical noise only).
TOL_TIME_S = 1e-3
TOL_AIRMASS = 0.01
TOL_SUN_DEG = 0.05
TOL_MOON_DEG = 0.1
TOL_HA_H = 0.005
#: Reported and recomputed coverage may differ by this much (absolute):
#: the two footprint methods differ only at pixel centres on CCD edges.
TOL_COVERAGE = 2e-3
MAX_LISTED = 20


@dataclass(frozen=True)
class CheckReport:
    """Verdict of the plan checker.

    Attributes
    ----------
    ok : bool
        True when no problem was found.
    problems : tuple of str
        One line per problem (the first MAX_LISTED of each kind).
    coverage : float
        Probability recomputed from the planned fields' CCD outlines.
    reported_coverage : float or None
        The plan's own ``metrics.coverage``.
    """

    ok: bool
    problems: tuple[str, ...]
    coverage: float
    reported_coverage: float | None = None
    counts: dict[str, int] = field(default_factory=dict)


def polygon_coverage(field_ids: Iterable[int], prob: np.ndarray) -> float:
    """Probability inside the union of fields' CCD outlines (query_polygon).

    Parameters
    ----------
    field_ids : iterable of int
        ZTF field IDs.
    prob : numpy.ndarray
        NESTED probability map.

    Returns
    -------
    float
    """
    nside = hp.npix2nside(prob.size)
    grid = load_ztf_fields()
    corners = ccd_corners()
    ids = np.unique(np.asarray(list(field_ids), dtype=int))
    rows = grid.index_of(ids)
    pixels = []
    for k in rows[rows >= 0]:
        ra, dec = deproject(corners[..., 0], corners[..., 1], grid.ra[k], grid.dec[k])
        verts = hp.ang2vec(ra.ravel(), dec.ravel(), lonlat=True).reshape(ra.shape + (3,))  # (16, 4, 3)
        turn = np.einsum("ij,ij->i", np.cross(verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 1]), verts[:, 0])
        verts = np.where((turn < 0)[:, None, None], verts[:, ::-1], verts)  # healpy wants counter-clockwise
        for ccd in verts:
            pixels.append(hp.query_polygon(nside, ccd, inclusive=False, nest=True))
    if not pixels:
        return 0.0
    return float(prob[np.unique(np.concatenate(pixels))].sum())


class _Problems:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.counts: dict[str, int] = {}

    def add(self, kind: str, text: str) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if self.counts[kind] <= MAX_LISTED:
            self.lines.append(f"{kind}: {text}")


def check_plan(plan: Plan, skymap: SkyMap, config: PlanningConfig = PlanningConfig(),
               coverage_tolerance: float = TOL_COVERAGE) -> CheckReport:
    """Verify a plan against the telescope, the sky and the cadence rule.

    Checks: known fields with the grid's coordinates; allowed filters;
    exposures in time order, not overlapping, separated by at least the
    slew/readout/filter-change overhead; inside the horizon; every
    exposure (start, middle, end) with the Sun low enough, airmass,
    hour angle and mount limits, Moon separation; every field observed in
    both filters at least the cadence apart; reported coverage equal to the
    recomputed one.

    Parameters
    ----------
    plan : Plan
        The plan.
    skymap : SkyMap
        The sky map it was made for (for coverage).
    config : PlanningConfig
        Constraints to check against.
    coverage_tolerance : float
        Largest allowed |reported - recomputed| coverage.

    Returns
    -------
    CheckReport
    """
    p = _Problems()
    obs = plan.observations
    horizon = float((plan.end - plan.start).to_value(u.s))
    coverage = polygon_coverage((o.field_id for o in obs), skymap.prob)
    reported = plan.metrics.coverage if plan.metrics is not None else None
    if reported is not None and abs(float(reported) - coverage) > coverage_tolerance:
        p.add("coverage", f"reported {reported:.5f} but the footprints hold {coverage:.5f}")
    if not obs:
        return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)

    grid = load_ztf_fields()
    ids = np.array([o.field_id for o in obs])
    ra = np.array([o.ra for o in obs], float)
    dec = np.array([o.dec for o in obs], float)
    flt = np.array([o.filter for o in obs])
    start = np.array([o.start for o in obs], float)
    exp = np.array([o.exposure_s for o in obs], float)
    end = start + exp

    rows = grid.index_of(ids)
    for i in np.flatnonzero(rows < 0):
        p.add("field", f"unknown field {ids[i]}")
    known = rows >= 0
    off = np.zeros(len(obs), bool)
    off[known] = (np.abs(((grid.ra[rows[known]] - ra[known]) + 180) % 360 - 180) > 1e-3) | (
        np.abs(grid.dec[rows[known]] - dec[known]) > 1e-3)
    for i in np.flatnonzero(off):
        p.add("field", f"field {ids[i]} at ({ra[i]:.4f}, {dec[i]:.4f}) is not where the grid puts it")
    for i in np.flatnonzero(~np.isin(flt, config.filters)):
        p.add("filter", f"field {ids[i]} in filter {flt[i]!r}, not one of {config.filters}")
    for i in np.flatnonzero(exp <= 0):
        p.add("exposure", f"field {ids[i]} has exposure {exp[i]} s")

    # order, overlaps and overheads
    for i in np.flatnonzero(np.diff(start) < 0):
        p.add("order", f"exposure {i + 1} (field {ids[i + 1]}) starts before exposure {i}")
    gap = start[1:] - end[:-1]
    need = overhead_time(ra[:-1], dec[:-1], ra[1:], dec[1:], config.slew,
                         np.where(flt[:-1] != flt[1:], config.filter_change_s, 0.0))
    for i in np.flatnonzero(gap < 0):
        p.add("overlap", f"field {ids[i + 1]} {flt[i + 1]} starts {-gap[i]:.1f} s before field {ids[i]} {flt[i]} ends")
    for i in np.flatnonzero((gap >= 0) & (gap < need - TOL_TIME_S)):
        p.add("slew", f"only {gap[i]:.1f} s from field {ids[i]} {flt[i]} to field {ids[i + 1]} {flt[i + 1]}, needs {need[i]:.1f} s")

    # horizon
    for i in np.flatnonzero((start < -TOL_TIME_S) | (end > horizon + TOL_TIME_S)):
        p.add("horizon", f"field {ids[i]} {flt[i]} at {start[i]:.0f}-{end[i]:.0f} s is outside the horizon 0-{horizon:.0f} s")

    # observing conditions at start, middle and end of each exposure
    n = len(obs)
    t_rel = np.concatenate([start, start + exp / 2, end])
    times = plan.start + TimeDelta(t_rel, format="sec")
    coords = SkyCoord(ra=np.tile(ra, 3) * u.deg, dec=np.tile(dec, 3) * u.deg, frame="icrs")
    loc = site()
    frame = AltAz(obstime=times, location=loc)
    altaz = coords.transform_to(frame)
    alt = altaz.alt.deg
    with np.errstate(divide="ignore"):
        airmass = np.where(alt > 0, 1.0 / np.sin(np.radians(np.maximum(alt, 1e-9))), np.inf)
    sun_alt = get_body("sun", times, loc).transform_to(frame).alt.deg
    moon_sep = get_body("moon", times, loc).separation(coords, origin_mismatch="ignore").deg
    lst = times.sidereal_time("apparent", longitude=loc.lon).deg
    ra_app = coords.transform_to(TETE(obstime=times)).ra.deg
    ha = (lst - ra_app + 180.0) % 360.0 - 180.0
    mount_ok = mount_limits_ok(ha, np.tile(dec, 3), config.ha_max_h + TOL_HA_H)

    def per_exposure(bad: np.ndarray) -> np.ndarray:
        return bad.reshape(3, n).any(axis=0)

    for i in np.flatnonzero(per_exposure(sun_alt > config.sun_alt_max_deg + TOL_SUN_DEG)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Sun at {sun_alt[[i, n + i, 2 * n + i]].max():.1f} deg")
    for i in np.flatnonzero(per_exposure(airmass > config.airmass_max + TOL_AIRMASS)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: airmass {airmass[[i, n + i, 2 * n + i]].max():.2f}")
    for i in np.flatnonzero(per_exposure(~mount_ok)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: hour angle {ha[i] / 15:.2f} h beyond the mount limits")
    for i in np.flatnonzero(per_exposure(moon_sep < config.moon_sep_min_deg - TOL_MOON_DEG)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Moon {moon_sep[[i, n + i, 2 * n + i]].min():.1f} deg away")

    # both filters per field, the cadence apart
    f1, f2 = config.filters
    for fid in np.unique(ids):
        sel = ids == fid
        t1 = start[sel & (flt == f1)]
        t2 = start[sel & (flt == f2)]
        if t1.size == 0 or t2.size == 0:
            p.add("cadence", f"field {fid} is not observed in both {f1} and {f2}")
            continue
        sep = np.abs(t1[:, None] - t2[None, :]).min()
        if sep < config.cadence_s - TOL_TIME_S:
            p.add("cadence", f"field {fid}: {f1} and {f2} only {sep:.0f} s apart (cadence {config.cadence_s:.0f} s)")

    return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)
