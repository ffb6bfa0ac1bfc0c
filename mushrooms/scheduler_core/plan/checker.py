"""Independent plan checker: is a plan something ZTF can really execute?

The checker shares no code with the schedulers' geometry (``fields``,
``visibility``, ``slew``), so a bug there cannot hide behind the same bug
here.  It has its own reading of the package data files, its own site, mount
and slew arithmetic from published constants, and its own footprint test:

* **Field grid and CCD layout**: parsed here from ``data/ZTF_Fields.txt``
  and ``data/ztf_ccd_layout.tbl`` (the files ``fields.py`` reads too; see
  ``data/SOURCES.md``).
* **Footprints**: each CCD is a spherical quadrilateral whose corners are
  the layout's plane offsets lifted onto the sphere around the field centre
  (a rotation matrix, not ``fields.deproject``); a pixel centre is covered
  when it lies on the inner side of all four great-circle edges of some CCD
  (the schedulers test straight edges in the projected plane; the two differ
  by about 1 arcsec, far below a pixel).
* **Site**: :data:`P48_SITE`, ztf_sim's GPS position of the P48.
* **Sun, Moon, field altitude and hour angle**: astropy (full ICRS to AltAz
  and true-equator-of-date transforms, Moon topocentric) evaluated on a
  coarse time grid (:data:`GRID_STEP_S`) spanning the plan, then interpolated
  to the start, middle and end of every exposure by cubic Lagrange
  polynomials through the four grid times around each (a few lines of
  numpy: no interpolation library to import).  The interpolated quantities
  (sin altitude, Moon direction, unwrapped hour angle) are smooth with
  periods of a day or more, so the error, about ``(h ω)⁴ / 40`` of their
  amplitude (h the step, ω the Earth's rotation rate), is below 1e-3 deg,
  far inside the tolerances below; the grid keeps the checker cheaper than
  the greedy scheduler it checks.
* **Mount limits**: :func:`mount_reachable`, ztf_sim's queue rules.
* **Slews**: :func:`slew_seconds`, the per-axis trapezoid written out from
  its kinematics, with the drive parameters of the plan's
  :class:`~.config.SlewModel` (the specification being checked against).
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass, field
from importlib import resources
from typing import Iterable, Sequence

import numpy as np
from astropy import units as u
from astropy.coordinates import AltAz, EarthLocation, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from ..config import PlanningConfig, SlewModel
from ..executed import MIN_PROCESSED_FRACTION, ExecutedExposure, done_pairs, is_done
from .document import Plan
from .sequence_check import check_sequences, covered_by_record
from ..sky.healpix import hp
from ..sky.skymap import SkyMap

__all__ = ["CheckReport", "check_plan", "polygon_coverage", "mount_reachable", "slew_seconds",
           "P48_SITE"]

#: P48 at Palomar: geodetic latitude, longitude (deg) and height (m), the GPS
#: position used by ZTF's robotic observing software as given in ztf_sim's
#: ``ztf_sim/constants.py`` (``P48_loc``: 33d21m26.2s, -116d51m35.5s, 1707 m;
#: commit 2208be2 "Change P48 position to GPS coordinates used by ROS").
P48_SITE = (33.0 + 21.0 / 60 + 26.2 / 3600, -(116.0 + 51.0 / 60 + 35.5 / 3600), 1707.0)

#: Slack allowed against each constraint (numerical noise only).
TOL_TIME_S = 1e-3
TOL_AIRMASS = 0.01
TOL_SUN_DEG = 0.05
TOL_MOON_DEG = 0.1
TOL_HA_H = 0.005
#: Reported and recomputed coverage may differ by this much (absolute):
#: the two footprint methods differ only at pixel centres on CCD edges.
TOL_COVERAGE = 2e-3
#: Field centres in the plan may differ from the grid's by this much (deg).
TOL_POSITION_DEG = 1e-3
MAX_LISTED = 20
#: Spacing (s) of the time grid on which astropy is evaluated before the
#: cubic interpolation to the exposures' times.
GRID_STEP_S = 1800.0

_DATA = "data"


@dataclass(frozen=True)
class CheckReport:
    """Verdict of the plan checker.

    Attributes
    ----------
    ok : bool
        True when no problem was found.
    problems : tuple of str
        One line per problem (the first MAX_LISTED of each kind), each
        starting with its kind (``window:``, ``slew:``, ...).
    coverage : float
        Probability recomputed from the planned fields' CCD outlines.
    reported_coverage : float or None
        The plan's own ``metrics.coverage``.
    counts : dict of str to int
        Number of problems of each kind (all of them, not only those listed).
    """

    ok: bool
    problems: tuple[str, ...]
    coverage: float
    reported_coverage: float | None = None
    counts: dict[str, int] = field(default_factory=dict)


# --------------------------------------------------------------------------- data files

def _data_text(name: str) -> str:
    return resources.files("mushrooms.scheduler_core").joinpath(_DATA, name).read_text()


@functools.lru_cache(maxsize=1)
def _grid() -> dict[int, tuple[float, float]]:
    """Field ID -> (RA, Dec) in deg, read from ``ZTF_Fields.txt``."""
    grid = {}
    for line in _data_text("ZTF_Fields.txt").splitlines():
        words = line.split()
        if words and not words[0].startswith("%"):
            grid[int(words[0])] = (float(words[1]), float(words[2]))
    return grid


@functools.lru_cache(maxsize=1)
def _ccd_offsets() -> np.ndarray:
    """(16, 4, 2) corner offsets (EW, NS; deg) of each CCD, from ``ztf_ccd_layout.tbl``."""
    corners: dict[int, list[tuple[float, float]]] = {}
    rows = csv.reader(_data_text("ztf_ccd_layout.tbl").splitlines()[1:])
    for ew, ns, ccd in rows:
        corners.setdefault(int(ccd), []).append((float(ew), float(ns)))
    return np.array([corners[k] for k in sorted(corners)], float)


def _unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)


def _ccd_vertices(ra0_deg: float, dec0_deg: float) -> np.ndarray:
    """(16, 4, 3) unit vectors of the CCD corners of a field centred at (ra0, dec0).

    The layout's offsets (x, y) are orthographic plane coordinates: x grows
    to the West (``x = -cos(dec) sin(ra - ra0)``), y to the North, so a
    corner is ``x * west + y * north + sqrt(1 - x^2 - y^2) * centre``.
    """
    ra0, dec0 = np.radians(ra0_deg), np.radians(dec0_deg)
    centre = _unit(ra0_deg, dec0_deg)
    west = np.array([np.sin(ra0), -np.cos(ra0), 0.0])
    north = np.cross(centre, -west)
    basis = np.stack([west, north, centre])  # rows: the local axes
    xy = np.radians(_ccd_offsets())
    local = np.concatenate([xy, np.sqrt(1.0 - (xy ** 2).sum(-1, keepdims=True))], axis=-1)
    return local @ basis


def _covered_pixels(ra0_deg: float, dec0_deg: float, nside: int) -> np.ndarray:
    """NESTED pixels whose centres lie inside one of the field's 16 CCDs."""
    verts = _ccd_vertices(ra0_deg, dec0_deg)
    centre = _unit(ra0_deg, dec0_deg)
    reach = float(np.arccos(np.clip(verts @ centre, -1, 1)).max()) + 1e-9
    cand = hp.query_disc(nside, centre, reach, inclusive=False, nest=True)
    pix = np.stack(hp.pix2vec(nside, cand, nest=True), axis=-1)  # (m, 3)
    normals = np.cross(verts, np.roll(verts, -1, axis=1))  # (16, 4, 3) edge planes
    inward = np.sign(np.einsum("ckj,cj->ck", normals, verts.mean(axis=1)))
    inner = (pix @ (normals * inward[..., None]).reshape(-1, 3).T) >= 0  # (m, 64): 16 CCDs x 4 edges
    # inside a CCD = its four edge bytes all 1: read each CCD's four bools as one uint32
    on_ccd = inner.reshape(-1, 16, 4).view(np.uint32)[..., 0] == 0x01010101
    return cand[on_ccd.any(axis=1)]


def polygon_coverage(field_ids: Iterable[int], prob: np.ndarray, without: Iterable[int] = ()) -> float:
    """Probability whose pixel centres fall inside the fields' CCD outlines.

    Parameters
    ----------
    field_ids : iterable of int
        ZTF field IDs (unknown ones are ignored).
    prob : numpy.ndarray
        NESTED probability map.
    without : iterable of int
        Fields whose pixels do not count (a re-plan's executed pairs, P8).

    Returns
    -------
    float
    """
    nside = hp.npix2nside(prob.size)
    hit = _polygon_mask(field_ids, nside) & ~_polygon_mask(without, nside)
    return float(prob[hit].sum())


def _polygon_mask(field_ids: Iterable[int], nside: int) -> np.ndarray:
    """(npix,) True on the pixels whose centres lie inside one of the fields' CCDs."""
    grid = _grid()
    hit = np.zeros(hp.nside2npix(nside), bool)
    for fid in {int(f) for f in field_ids} & grid.keys():
        hit[_covered_pixels(*grid[fid], nside)] = True
    return hit


# --------------------------------------------------------------------------- telescope

def mount_reachable(ha_deg: np.ndarray, dec_deg: np.ndarray, ha_max_h: float) -> np.ndarray:
    """Can the P48 point there?  ZTF's queue rules as coded in ztf_sim.

    From ``ztf_sim/QueueManager.py`` (commit c5ab409, lines 1235-1253):
    |HA| below 5.95 h ("Reed limits"); HA < -17.6 deg with Dec < -22 deg is
    rejected (interference with the FFI); west of HA -17.6 deg, Dec < -45 deg
    is rejected (service platform); |HA| > 3 deg with Dec < -46 deg is
    rejected (shutter "ears"); Dec > 87.5 deg is rejected.

    Parameters
    ----------
    ha_deg, dec_deg : numpy.ndarray
        Hour angle (deg, in [-180, 180)) and declination (deg); broadcast.
    ha_max_h : float
        Largest |hour angle| (h).

    Returns
    -------
    numpy.ndarray of bool
    """
    ha = np.asarray(ha_deg, float)
    dec = np.asarray(dec_deg, float)
    rejected = (np.abs(ha) / 15.0 > ha_max_h) | (dec > 87.5)
    rejected |= (ha < -17.6) & (dec < -22.0)
    rejected |= (ha > -17.6) & (dec < -45.0)
    rejected |= (np.abs(ha) > 3.0) & (dec < -46.0)
    return ~rejected


def slew_seconds(ra1_deg: np.ndarray, dec1_deg: np.ndarray, ra2_deg: np.ndarray, dec2_deg: np.ndarray,
                 model: SlewModel) -> np.ndarray:
    """P48 slew time (s), settle included, from one field centre to the next.

    Each equatorial axis ramps up at its acceleration ``a`` to its top speed
    ``v``, cruises and ramps down again at the same rate; the two ramps take
    ``2 v / a`` seconds and cover ``v^2 / a`` degrees.  A shorter move never reaches
    ``v`` and takes ``2 sqrt(d / a)``.  The HA travel is the wrapped RA
    difference.  Both axes move at once: the slew lasts as long as the slower
    one, plus the settle time when anything moved (ztf_sim's
    ``constants.slew_time``).

    Parameters
    ----------
    ra1_deg, dec1_deg, ra2_deg, dec2_deg : numpy.ndarray
        Field centres (deg).
    model : SlewModel
        Drive parameters.

    Returns
    -------
    numpy.ndarray
    """
    def axis(d: np.ndarray, a: float, v: float) -> np.ndarray:
        ramp_s, ramp_deg = 2.0 * v / a, v * v / a
        return np.where(d > ramp_deg, ramp_s + (d - ramp_deg) / v, 2.0 * np.sqrt(d / a))

    d_ha = np.abs((np.asarray(ra2_deg, float) - ra1_deg + 540.0) % 360.0 - 180.0)
    d_dec = np.abs(np.asarray(dec2_deg, float) - dec1_deg)
    t = np.maximum(axis(d_ha, model.ha_accel_deg_s2, model.ha_vmax_deg_s),
                   axis(d_dec, model.dec_accel_deg_s2, model.dec_vmax_deg_s))
    return np.where(t > 0, t + model.settle_s, 0.0)


@functools.lru_cache(maxsize=1)
def _site() -> EarthLocation:
    lat, lon, height = P48_SITE
    return EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)


@dataclass(frozen=True)
class _Conditions:
    """Observing conditions at given times: each array has the times' shape."""

    sun_alt: np.ndarray  # deg
    airmass: np.ndarray  # sec z, inf below the horizon
    ha: np.ndarray  # apparent hour angle, deg in [-180, 180)
    moon_sep: np.ndarray  # deg


def _conditions(start: Time, t_rel: np.ndarray, ra_deg: np.ndarray, dec_deg: np.ndarray) -> _Conditions:
    """Sun altitude, airmass, hour angle and Moon separation of fields at times.

    Parameters
    ----------
    start : astropy.time.Time
        Reference time.
    t_rel : numpy.ndarray
        (n,) times (s since ``start``).
    ra_deg, dec_deg : numpy.ndarray
        (n,) ICRS position looked at, at each time.

    Returns
    -------
    _Conditions
    """
    loc = _site()
    lo, hi = float(t_rel.min()), float(t_rel.max())
    n_grid = max(5, int(np.ceil((hi - lo) / GRID_STEP_S)) + 1)
    grid_s = np.linspace(lo, hi + 1.0, n_grid)  # +1 s: never a zero-length grid
    times = start + TimeDelta(grid_s, format="sec")
    frame = AltAz(obstime=times, location=loc)

    # cubic Lagrange interpolation on the four grid times around each time (numpy only)
    x = (t_rel - lo) / (grid_s[1] - grid_s[0])
    b = np.clip(np.floor(x).astype(np.int64) - 1, 0, n_grid - 4)
    s = x - b
    weights = [np.prod([(s - m) / (k - m) for m in range(4) if m != k], axis=0) for k in range(4)]

    def cubic(values: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``values`` (..., grid) at t_rel; with ``rows``, row ``rows[i]`` of a (fields, grid) array at t_rel[i]."""
        at = (lambda k: values[..., b + k]) if rows is None else (lambda k: values[rows, b + k])
        return sum(w * at(k) for k, w in enumerate(weights))

    sun = get_body("sun", times, loc).transform_to(frame)
    sin_sun = cubic(np.sin(sun.alt.rad))
    moon = get_body("moon", times, loc).cartesian.xyz.value  # (3, grid) topocentric, GCRS axes
    moon_dir = cubic(moon / np.linalg.norm(moon, axis=0, keepdims=True)).T

    fields, which = np.unique(np.stack([ra_deg, dec_deg], axis=1), axis=0, return_inverse=True)
    which = which.ravel()
    coords = SkyCoord(ra=fields[:, 0] * u.deg, dec=fields[:, 1] * u.deg)[:, None]
    altaz = coords.transform_to(frame)  # (fields, grid)
    alt, az, lat = altaz.alt.rad, altaz.az.rad, np.radians(P48_SITE[0])
    sin_alt_grid = np.sin(alt)
    # hour angle from the same alt-az (azimuth from North through East):
    # cos(dec) sin(HA) = -cos(alt) sin(az), cos(dec) cos(HA) = cos(lat) sin(alt) - sin(lat) cos(alt) cos(az)
    ha_grid = np.degrees(np.unwrap(np.arctan2(-np.cos(alt) * np.sin(az),
                                              np.cos(lat) * np.sin(alt) - np.sin(lat) * np.cos(alt) * np.cos(az)),
                                   axis=1))
    sin_alt = cubic(sin_alt_grid, which)
    ha = cubic(ha_grid, which)

    moon_dir /= np.linalg.norm(moon_dir, axis=1, keepdims=True)
    cos_moon = np.einsum("ij,ij->i", moon_dir, _unit(ra_deg, dec_deg))
    with np.errstate(divide="ignore"):
        airmass = np.where(sin_alt > 0, 1.0 / np.where(sin_alt > 0, sin_alt, 1.0), np.inf)
    return _Conditions(
        sun_alt=np.degrees(np.arcsin(np.clip(sin_sun, -1, 1))),
        airmass=airmass,
        ha=(ha + 180.0) % 360.0 - 180.0,
        moon_sep=np.degrees(np.arccos(np.clip(cos_moon, -1, 1))),
    )


# --------------------------------------------------------------------------- the check

class _Problems:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.counts: dict[str, int] = {}

    def add(self, kind: str, text: str) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if self.counts[kind] <= MAX_LISTED:
            self.lines.append(f"{kind}: {text}")


def check_plan(plan: Plan, skymap: SkyMap, config: PlanningConfig = PlanningConfig(),
               coverage_tolerance: float = TOL_COVERAGE, *, executed: Sequence[ExecutedExposure] = (),
               min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> CheckReport:
    """Verify a plan against the telescope, the sky and the cadence rule.

    Checks: known fields with the grid's coordinates; allowed filters;
    exposures in time order, not overlapping, separated by at least the
    slew/readout/filter-change overhead; inside the horizon; every
    exposure (start, middle, end) with the Sun low enough, airmass,
    hour angle and mount limits, Moon separation; every field observed in
    both filters at least the cadence apart; reported coverage equal to the
    recomputed one.

    With an executed record (a re-plan, ``docs/design/replan.md``): no
    exposure of a field done in both filters (E3); a field's done exposures
    (E1) count towards its pair, which then needs its two filters the
    cadence apart at their widest (E3), so a half-done field may get its
    other filter only; the coverage is recomputed outside the executed
    pairs (P8) and ``metrics.coverage_executed`` compared with theirs.

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
    executed : sequence of ExecutedExposure
        What the telescope did before the plan (default none).
    min_processed_fraction : float
        The done rule (E1) for ``executed``.

    Returns
    -------
    CheckReport

    Examples
    --------
    >>> from importlib.resources import files
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> night = Time("2019-05-01T03:00:00", scale="utc")
    >>> from mushrooms.scheduler_core import make_plan
    >>> plan = make_plan(skymap, config, start=night)  # checked on the way out too
    >>> report = check_plan(plan, skymap, config)
    >>> report.ok, report.problems
    (True, ())
    >>> abs(report.coverage - plan.metrics.coverage) < 1e-4
    True

    A plan that breaks the cadence rule (its second pass moved onto the
    first) is refused, with one line per problem:

    >>> import dataclasses
    >>> early = tuple(dataclasses.replace(o, start=o.start - config.cadence_s) if o.filter == "r" else o
    ...               for o in plan.observations)
    >>> bad = check_plan(dataclasses.replace(plan, observations=early), skymap, config)
    >>> bad.ok, len(bad.problems) > 0
    (False, True)
    """
    p = _Problems()
    obs = plan.observations
    horizon = float((plan.end - plan.start).to_value(u.s))
    if config.revisit and executed:  # (N4, N5) revisit: only the plan's own night's exposures count as done
        from ..executed import counted_for_night
        from ..sky.twilight import night_evening

        executed = counted_for_night(executed, night_evening(plan.start, config), True)
    done = _done_times(executed, plan.start, min_processed_fraction)
    covered = _covered(executed, done, config, min_processed_fraction)
    coverage = polygon_coverage((o.field_id for o in obs), skymap.prob, without=covered)
    reported = plan.metrics.coverage if plan.metrics is not None else None
    if reported is not None and abs(float(reported) - coverage) > coverage_tolerance:
        p.add("coverage", f"reported {reported:.5f} but the footprints hold {coverage:.5f}")
    bound = None if plan.metrics is None else plan.metrics.upper_bound
    if reported is not None and bound is not None and float(reported) > float(bound):
        # (B3) the certified bound (its margin included, milp.md B1, B2) is above every plan's coverage
        p.add("bound", f"reported coverage {reported:.7f} above the certified upper bound {bound:.7f}")
    reported_executed = None if plan.metrics is None else plan.metrics.coverage_executed
    if reported_executed is not None:
        held = polygon_coverage(covered, skymap.prob)
        if abs(float(reported_executed) - held) > coverage_tolerance:
            p.add("coverage", f"reported {reported_executed:.5f} executed but the executed pairs hold {held:.5f}")
    # (P9) with an executed record: no exposure of a field done in both filters (a sequence: F7, F8)
    for fid in sorted({o.field_id for o in obs} & set(covered) if len(config.filters) == 2 else ()):
        p.add("repeat", f"field {fid} is done in both {config.filters[0]} and {config.filters[1]} "
                        f"(executed) and planned again")
    if not obs:
        return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)

    x = _Exposures.of(obs)
    _check_fields(p, x, config)
    _check_sequence(p, x, horizon, config)
    _check_conditions(p, x, plan.start, config)
    if len(config.filters) == 2:
        _check_cadence(p, x, config, done)
    else:  # (F6-F8) a sequence of another length: its own rules, sequence_check.py
        check_sequences(p.add, x.ids, x.flt, x.start, tuple(config.filters), config.cadence_s,
                        config.pair_separation_s, done)

    return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)


@dataclass(frozen=True)
class _Exposures:
    """A plan's exposures as arrays, in plan order."""

    ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    flt: np.ndarray
    start: np.ndarray
    exp: np.ndarray

    @property
    def end(self) -> np.ndarray:
        return self.start + self.exp

    @classmethod
    def of(cls, obs) -> "_Exposures":
        return cls(np.array([o.field_id for o in obs]), np.array([o.ra for o in obs], float),
                   np.array([o.dec for o in obs], float), np.array([o.filter for o in obs]),
                   np.array([o.start for o in obs], float), np.array([o.exposure_s for o in obs], float))


def _check_fields(p: _Problems, x: _Exposures, config: PlanningConfig) -> None:
    """Known fields where the grid puts them, allowed filters, positive exposures."""
    grid = _grid()
    ids, ra, dec, flt, exp = x.ids, x.ra, x.dec, x.flt, x.exp
    known = np.array([int(f) in grid for f in ids])
    for i in np.flatnonzero(~known):
        p.add("field", f"unknown field {ids[i]}")
    where = np.array([grid.get(int(f), (np.nan, np.nan)) for f in ids], float)
    d_ra = np.abs((where[:, 0] - ra + 180.0) % 360.0 - 180.0)
    off = known & ((d_ra > TOL_POSITION_DEG) | (np.abs(where[:, 1] - dec) > TOL_POSITION_DEG))
    for i in np.flatnonzero(off):
        p.add("field", f"field {ids[i]} at ({ra[i]:.4f}, {dec[i]:.4f}) is not where the grid puts it")
    for i in np.flatnonzero(~np.isin(flt, config.filters)):
        p.add("filter", f"field {ids[i]} in filter {flt[i]!r}, not one of {config.filters}")
    for i in np.flatnonzero(exp <= 0):
        p.add("exposure", f"field {ids[i]} has exposure {exp[i]} s")


def _check_sequence(p: _Problems, x: _Exposures, horizon: float, config: PlanningConfig) -> None:
    """Order, overlaps and overheads (readout, slew and filter change run in parallel); the horizon."""
    ids, ra, dec, flt, start, end = x.ids, x.ra, x.dec, x.flt, x.start, x.end
    for i in np.flatnonzero(np.diff(start) < 0):
        p.add("order", f"exposure {i + 1} (field {ids[i + 1]}) starts before exposure {i}")
    gap = start[1:] - end[:-1]
    need = np.maximum.reduce([
        slew_seconds(ra[:-1], dec[:-1], ra[1:], dec[1:], config.slew),
        np.full(gap.size, config.slew.readout_s),
        np.where(flt[:-1] != flt[1:], config.filter_change_s, 0.0),
    ])
    for i in np.flatnonzero(gap < 0):
        p.add("overlap", f"field {ids[i + 1]} {flt[i + 1]} starts {-gap[i]:.1f} s before field {ids[i]} {flt[i]} ends")
    for i in np.flatnonzero((gap >= 0) & (gap < need - TOL_TIME_S)):
        p.add("slew", f"only {gap[i]:.1f} s from field {ids[i]} {flt[i]} to field {ids[i + 1]} {flt[i + 1]}, needs {need[i]:.1f} s")

    for i in np.flatnonzero((start < -TOL_TIME_S) | (end > horizon + TOL_TIME_S)):
        p.add("horizon", f"field {ids[i]} {flt[i]} at {start[i]:.0f}-{end[i]:.0f} s is outside the horizon 0-{horizon:.0f} s")


def _check_conditions(p: _Problems, x: _Exposures, t0: Time, config: PlanningConfig) -> None:
    """Observing conditions at start, middle and end of each exposure ((3, n) arrays)."""
    ids, ra, dec, flt, start, exp = x.ids, x.ra, x.dec, x.flt, x.start, x.exp
    n = len(ids)
    c = _conditions(t0, np.concatenate([start, start + exp / 2, x.end]), np.tile(ra, 3), np.tile(dec, 3))
    sun_alt, airmass, ha, moon_sep = (a.reshape(3, n) for a in (c.sun_alt, c.airmass, c.ha, c.moon_sep))
    slack = TOL_HA_H * 15.0  # each HA limit may be missed by this much (deg)
    mount_ok = (mount_reachable(ha, dec[None, :], config.ha_max_h) | mount_reachable(ha - slack, dec[None, :], config.ha_max_h)
                | mount_reachable(ha + slack, dec[None, :], config.ha_max_h))
    for i in np.flatnonzero((sun_alt > config.sun_alt_max_deg + TOL_SUN_DEG).any(axis=0)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Sun at {sun_alt[:, i].max():.1f} deg")
    for i in np.flatnonzero((airmass > config.airmass_max + TOL_AIRMASS).any(axis=0)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: airmass {airmass[:, i].max():.2f}")
    for i in np.flatnonzero((~mount_ok).any(axis=0)):
        worst = ha[np.argmax(np.abs(ha[:, i])), i]
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: hour angle {worst / 15:.2f} h "
                        f"(Dec {dec[i]:.1f}) beyond the mount limits")
    for i in np.flatnonzero((moon_sep < config.moon_sep_min_deg - TOL_MOON_DEG).any(axis=0)):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Moon {moon_sep[:, i].min():.1f} deg away")


def _covered(executed: Sequence[ExecutedExposure], done: dict[int, dict[str, np.ndarray]],
             config: PlanningConfig, min_processed_fraction: float) -> set[int]:
    """The fields the record covers: done in both filters (E3), for a sequence the first two (F7)."""
    if len(config.filters) == 2:
        return set(done_pairs(executed, tuple(config.filters), min_processed_fraction, config.cadence_s,
                              config.pair_separation_s).both)
    return set(covered_by_record(done, tuple(config.filters), config.cadence_s, config.pair_separation_s))


def _done_times(executed: Sequence[ExecutedExposure], t0: Time,
                min_processed_fraction: float) -> dict[int, dict[str, np.ndarray]]:
    """Field -> filter -> starts (s since ``t0``, negative before it) of the done executed exposures (E1)."""
    out: dict[int, dict[str, list[float]]] = {}
    for e in executed:
        if is_done(e, min_processed_fraction):
            out.setdefault(e.field_id, {}).setdefault(e.filter, []).append(float((e.start - t0).to_value(u.s)))
    return {f: {b: np.array(v) for b, v in per.items()} for f, per in out.items()}


def _check_cadence(p: _Problems, x: _Exposures, config: PlanningConfig,
                   done: dict[int, dict[str, np.ndarray]] | None = None) -> None:
    """Both filters per field, the cadence apart; a field with done exposures counts them (E3: widest separation)."""
    ids, flt, start = x.ids, x.flt, x.start
    f1, f2 = config.filters
    done = done or {}
    for fid in np.unique(ids):
        sel = ids == fid
        before = done.get(int(fid), {})
        t1 = np.concatenate([start[sel & (flt == f1)], before.get(f1, np.zeros(0))])
        t2 = np.concatenate([start[sel & (flt == f2)], before.get(f2, np.zeros(0))])
        if t1.size == 0 or t2.size == 0:
            p.add("cadence", f"field {fid} is not observed in both {f1} and {f2}")
            continue
        gaps = np.abs(t1[:, None] - t2[None, :])
        if before:  # (E3, P10) some a and b exposure the cadence apart, and within the largest separation
            paired = (gaps >= config.cadence_s - TOL_TIME_S) & (gaps <= config.pair_separation_s + TOL_TIME_S)
            if not paired.any():
                p.add("cadence", f"field {fid}: no {f1} and {f2} exposure {config.cadence_s:.0f} s to "
                                 f"{config.pair_separation_s:.0f} s apart (its executed ones included)")
            continue
        sep = gaps.min()
        if sep < config.cadence_s - TOL_TIME_S:
            p.add("cadence", f"field {fid}: {f1} and {f2} only {sep:.0f} s apart (cadence {config.cadence_s:.0f} s)")
