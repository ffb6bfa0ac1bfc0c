"""What a telescope is, as the planner needs it: frozen dataclasses built from a description file.

One :class:`TelescopeDescription` per telescope: its site, field grid,
camera footprint, filters with the depth model's terms, overheads,
pointing limits, planning defaults and how its queue is executed and
exported.  Built and validated by :mod:`.loader` from a TOML file
(``docs/design/telescopes.md`` lists every key); every value group keeps
the ``source`` string that says where its numbers come from.

Angles are degrees, times seconds, magnitudes AB, unless a name says
otherwise (``ha_max_h``: hours; ``*_arcsec``: arcseconds).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

import numpy as np

if TYPE_CHECKING:  # astropy is imported by Site.location only
    from astropy.coordinates import EarthLocation

__all__ = ["QUEUE_KINDS", "AXIS_COORDINATES", "Site", "FieldCentres", "Footprint", "FilterTerms", "DepthTerms",
           "SlewAxis", "Overheads", "KeepOut", "PointingLimits", "PlanningDefaults", "Execution",
           "TelescopeDescription", "local_mean_noon"]

#: How a telescope's part of a plan is carried out: ZTF's ToO queue (Kowalski), a SkyPortal
#: observation plan, or a target list (JSON and CSV) for a telescope without a queue API.
QUEUE_KINDS = ("ztf_too", "skyportal", "target_list")
#: The coordinates a slew axis moves in: an equatorial mount's hour angle and declination, an
#: alt-azimuth mount's azimuth and altitude, and a dome's azimuth.
AXIS_COORDINATES = ("ha", "dec", "azimuth", "altitude", "dome_azimuth")


@dataclass(frozen=True)
class Site:
    """Where the telescope is.

    Attributes
    ----------
    latitude_deg, longitude_deg : float
        Geodetic latitude and longitude (deg, east positive).
    height_m : float
        Height above the WGS84 ellipsoid (m).
    night_anchor_utc : str
        An ISO UTC time at local noon: the planning grid's anchor, nights run
        from one local noon to the next.  When a description gives none, the
        local mean noon of 2000-01-01 at this longitude, to 0.1 s
        (:func:`local_mean_noon`).
    source : str
        Where the numbers come from.
    name : str
        The site's name as a summary says it (``Palomar``; empty: unnamed).
    timezone : str
        IANA time zone of the site's clocks (``America/Los_Angeles``; empty:
        local mean time from the longitude).
    """

    latitude_deg: float
    longitude_deg: float
    height_m: float
    night_anchor_utc: str
    source: str
    name: str = ""
    timezone: str = ""

    @property
    def location(self) -> "EarthLocation":
        """The site as an :class:`astropy.coordinates.EarthLocation`."""
        from astropy import units as u
        from astropy.coordinates import EarthLocation

        return EarthLocation.from_geodetic(lon=self.longitude_deg * u.deg, lat=self.latitude_deg * u.deg,
                                           height=self.height_m * u.m)


def local_mean_noon(longitude_deg: float) -> str:
    """Local mean noon on 2000-01-01 at ``longitude_deg`` (deg, east positive), ISO UTC to 0.1 s.

    Examples
    --------
    >>> local_mean_noon(-116.86)  # Palomar's, the planner's grid anchor
    '2000-01-01T19:47:26.4'
    """
    tenths = round((12.0 - longitude_deg / 15.0) * 36000.0) % (24 * 36000)
    hours, rest = divmod(tenths, 36000)
    minutes, rest = divmod(rest, 600)
    return f"2000-01-01T{hours:02d}:{minutes:02d}:{rest // 10:02d}.{rest % 10}"


@dataclass(frozen=True, eq=False)
class FieldCentres:
    """The telescope's fixed field grid.

    Attributes
    ----------
    ids : numpy.ndarray
        (n,) int64 field ids, unique.
    ra, dec : numpy.ndarray
        (n,) field centres (deg, ICRS/J2000).
    origin : str
        ``file <name>`` or ``declination bands <w> x <h> deg, overlap <f>``.
    source : str
        Where the grid comes from.
    """

    ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    origin: str
    source: str

    def __len__(self) -> int:
        return int(self.ids.size)


@dataclass(frozen=True, eq=False)
class Footprint:
    """The camera on the sky about a pointing: one polygon per detector.

    Offsets are in the orthographic plane of the pointing (deg; ``x`` grows
    to the west, ``x = -cos(dec) sin(ra - ra0)``, ``y`` to the north), the
    plane of ZTF's CCD layout table and of the planner's footprints.

    Attributes
    ----------
    polygons : tuple of numpy.ndarray
        Detector outlines, each (k, 2) corners (x, y) in polygon order.
    radius_deg : float
        Radius (deg) of a circle about the pointing holding every detector.
    source : str
        Where the layout comes from.
    """

    polygons: tuple[np.ndarray, ...]
    radius_deg: float
    source: str

    @property
    def area_deg2(self) -> float:
        """Summed detector area (deg², in the plane; the gaps excluded)."""
        def shoelace(p: np.ndarray) -> float:
            x, y = p[:, 0], p[:, 1]
            return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
        return float(sum(shoelace(p) for p in self.polygons))

    def corners(self) -> np.ndarray:
        """(n_detectors, k, 2) corners when every detector has k corners (ZTF: (16, 4, 2))."""
        return np.stack(self.polygons)


@dataclass(frozen=True)
class FilterTerms:
    """One filter and the terms of the depth model (D1)-(D2) for it (``source/depth.py``).

    Attributes
    ----------
    name : str
        The filter's name in plans (``g``, ``J`` ...).
    zenith_depth : float
        5-sigma depth (mag) of an exposure of ``DepthTerms.reference_exposure_s``
        at the zenith on a dark night (``C_b`` of D1 for a 30 s reference).
    sky_zenith : float
        Dark-sky surface brightness at the zenith (mag arcsec^-2).
    extinction : float
        ``k_b`` (mag per airmass).
    zenith_fwhm_arcsec : float
        Seeing at the zenith (arcsec).
    sun_minus_v : float
        Colour of sunlight (mag, this band minus V): the colour of moonlight.
    reference_depth, reference_fwhm_arcsec : float or None
        5-sigma depth (mag) and seeing (arcsec) of the reference images (D2);
        None: a reference much deeper than one exposure (D2 adds nothing).
    median_depth : float or None
        Published median 5-sigma depth (mag) of a reference exposure, the
        calibration target (ZTF: Bellm et al. 2019).
    detectors : tuple of int
        Indices of the detectors behind this filter (a filter fixed on part
        of the camera, as LS4's); empty: all of them.
    queue_id : int or None
        The filter's id in the telescope's queue (ZTF: 1 g, 2 r, 3 i).
    skyportal_name : str or None
        SkyPortal's name of the filter (ZTF: ``ztfg``).
    source : str
        Where the numbers come from.
    """

    name: str
    zenith_depth: float
    sky_zenith: float
    extinction: float
    zenith_fwhm_arcsec: float
    sun_minus_v: float
    reference_depth: float | None
    reference_fwhm_arcsec: float | None
    median_depth: float | None
    detectors: tuple[int, ...]
    queue_id: int | None
    skyportal_name: str | None
    source: str


@dataclass(frozen=True)
class DepthTerms:
    """The depth model's terms shared by every filter.

    Attributes
    ----------
    reference_exposure_s : float
        Exposure (s) the filters' ``zenith_depth`` and ``median_depth`` refer to.
    seeing_airmass_exponent : float
        FWHM ∝ X^exponent (0.6 for Kolmogorov turbulence).
    twilight_slope_mag_per_deg : float
        How fast the twilight sky fades with the Sun's depression (mag deg^-1).
    source : str
        Where the numbers come from.
    """

    reference_exposure_s: float
    seeing_airmass_exponent: float
    twilight_slope_mag_per_deg: float
    source: str


@dataclass(frozen=True)
class SlewAxis:
    """One axis of a slew: a trapezoidal move (``telescope/slew.py``, ``axis_time``).

    Attributes
    ----------
    coordinate : str
        One of :data:`AXIS_COORDINATES`.
    accel_deg_s2 : float
        Acceleration and deceleration (deg s^-2).
    vmax_deg_s : float
        Top speed (deg s^-1).
    source : str
        Where the numbers come from (empty: the overheads' source).
    """

    coordinate: str
    accel_deg_s2: float
    vmax_deg_s: float
    source: str


@dataclass(frozen=True)
class Overheads:
    """What the telescope takes between two exposures.

    Attributes
    ----------
    readout_s : float
        Detector readout (s); it overlaps the slew.
    settle_s : float
        Settle (s) after any axis moved.
    filter_change_s : float
        Filter exchange (s); 0 for a camera whose filters do not move.
    filter_change_with_slew : bool
        The filter changes while the telescope slews (overhead
        ``max(change, slew, readout)``); false: before it (ztf_sim's P48,
        ``change + max(slew, readout)``, ``telescope/timing.py``).
    axes : tuple of SlewAxis
        The axes that move; a slew lasts as long as the slowest, plus the settle.
    source : str
        Where the numbers come from.
    """

    readout_s: float
    settle_s: float
    filter_change_s: float
    filter_change_with_slew: bool
    axes: tuple[SlewAxis, ...]
    source: str

    def axis(self, coordinate: str) -> SlewAxis | None:
        """The axis moving in ``coordinate`` (None when the telescope has none)."""
        return next((a for a in self.axes if a.coordinate == coordinate), None)


@dataclass(frozen=True)
class KeepOut:
    """A region of (hour angle, declination) the mount cannot point at (open box, bounds may be infinite).

    Attributes
    ----------
    ha_min_deg, ha_max_deg : float
        Hour-angle range (deg, in [-180, 180)); the box holds ``ha_min < HA < ha_max``.
    dec_min_deg, dec_max_deg : float
        Declination range (deg); the box holds ``dec_min < Dec < dec_max``.
    why : str
        What is in the way.
    """

    ha_min_deg: float
    ha_max_deg: float
    dec_min_deg: float
    dec_max_deg: float
    why: str


@dataclass(frozen=True)
class PointingLimits:
    """Where and when the telescope observes.

    Attributes
    ----------
    airmass_max : float
        Largest airmass (sec z).
    ha_max_h : float
        Largest |hour angle| (h).
    dec_min_deg, dec_max_deg : float
        Fields outside this band (deg) are never planned.
    sun_alt_max_deg : float
        Observing only with the Sun below this altitude (deg).
    moon_sep_min_deg : float
        Least angular distance (deg) from a field centre to the Moon.
    keep_out : tuple of KeepOut
        Regions of (HA, Dec) the mount cannot reach (:func:`.limits.pointing_allowed`).
    source : str
        Where the numbers come from.
    """

    airmass_max: float
    ha_max_h: float
    dec_min_deg: float
    dec_max_deg: float
    sun_alt_max_deg: float
    moon_sep_min_deg: float
    keep_out: tuple[KeepOut, ...]
    source: str


@dataclass(frozen=True)
class PlanningDefaults:
    """What a plan for this telescope uses unless the configuration says otherwise.

    Attributes
    ----------
    exposure_s : float
        Exposure of one visit (s).
    exposure_min_s, exposure_max_s : float
        Shortest and longest exposure the telescope takes (s).
    filters : tuple of str
        The filter sequence a field is visited in (names of :attr:`TelescopeDescription.filters`).
    cadence_s : float
        Least time (s) between two visits of a field.
    filter_change_s : float
        Filter change (s) the plan assumes (ZTF: the MUSHROOMS paper's 2 min).
    slew_estimate_s : float
        Mean slew and readout (s) the block MILP assumes before the order is known.
    source : str
        Where the numbers come from.
    """

    exposure_s: float
    exposure_min_s: float
    exposure_max_s: float
    filters: tuple[str, ...]
    cadence_s: float
    filter_change_s: float
    slew_estimate_s: float
    source: str


@dataclass(frozen=True)
class Execution:
    """How the telescope carries out its queue, and where the plan goes (``queue`` kind's keys).

    Attributes
    ----------
    queue : str
        One of :data:`QUEUE_KINDS`.
    survey_step_s, lost_pointing_slew_s, default_max_airmass : float or None
        ``ztf_too``: what the survey takes when no ToO target is observable
        (s), the slew charged after the survey had the telescope (s), and a
        target's airmass limit when it gives none (``telescope/executor.py``).
    program_ids : mapping of str to int
        ``ztf_too``: the queue's program ids by program name.
    skyportal_instrument : str or None
        ``skyportal``: SkyPortal's name of the instrument.
    formats : tuple of str
        ``target_list``: the files written (``json``, ``csv``).
    source : str
        Where the numbers come from.
    """

    queue: str
    survey_step_s: float | None
    lost_pointing_slew_s: float | None
    default_max_airmass: float | None
    program_ids: Mapping[str, int]
    skyportal_instrument: str | None
    formats: tuple[str, ...]
    source: str


@dataclass(frozen=True, eq=False)
class TelescopeDescription:
    """A telescope, as a plan needs it (``docs/design/telescopes.md``).

    Attributes
    ----------
    name : str
        Short lower-case name (``ztf``), the description file's stem.
    title : str
        Full name.
    source : str
        Where the description as a whole comes from.
    path : str
        The file it was read from.
    site, grid, footprint, depth, overheads, limits, planning, execution
        The value groups (see their classes).
    filters : mapping of str to FilterTerms
        The camera's filters, in the description's order.
    """

    name: str
    title: str
    source: str
    path: str
    site: Site
    grid: FieldCentres
    footprint: Footprint
    filters: Mapping[str, FilterTerms]
    depth: DepthTerms
    overheads: Overheads
    limits: PointingLimits
    planning: PlanningDefaults
    execution: Execution

    @property
    def queue(self) -> str:
        """How the plan is carried out: one of :data:`QUEUE_KINDS`."""
        return self.execution.queue

    @property
    def field_of_view_deg2(self) -> float:
        """The detectors' summed area (deg²)."""
        return self.footprint.area_deg2

    def summary(self) -> dict[str, object]:
        """One line's worth: name, site, field of view, fields, filters, queue, source."""
        return {"name": self.name, "title": self.title,
                "site": {"latitude_deg": self.site.latitude_deg, "longitude_deg": self.site.longitude_deg,
                         "height_m": self.site.height_m},
                "field_of_view_deg2": round(self.field_of_view_deg2, 2), "fields": len(self.grid),
                "filters": list(self.filters), "queue": self.queue, "source": self.source}
