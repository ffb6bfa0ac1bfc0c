"""The keys of a telescope description: type, unit, range and meaning of each, declared once.

:mod:`.validate` reads a parsed TOML table against these declarations and
says what is wrong one line per problem; ``docs/design/telescopes.md``
lists the same keys (``tests/scheduler/test_instruments.py`` keeps the two
in step).  A leaf: the standard library only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

__all__ = ["Key", "TOP", "SITE", "GRID", "FOOTPRINT", "FILTER", "DEPTH", "OVERHEADS", "AXIS", "LIMITS",
           "KEEP_OUT", "PLANNING", "EXECUTION", "TABLES", "EXECUTION_KEYS", "FORMAT_VERSION"]

#: The description format this code reads (``format = 1``).
FORMAT_VERSION = 1
_INF = math.inf


@dataclass(frozen=True)
class Key:
    """One key of a description table.

    Attributes
    ----------
    kind : str
        ``number``, ``integer``, ``string``, ``boolean``, ``numbers``,
        ``integers``, ``strings`` (arrays of one type), ``table``,
        ``tables`` (an array of tables), ``polygons`` (an array of arrays
        of [x, y] pairs) or ``ids`` (a table of names to integers).
    meaning : str
        What the value is (one phrase, for the documentation).
    unit : str
        Unit of a number (``deg``, ``s``, ``mag`` ...), or ``""``.
    lo, hi : float
        Inclusive bounds of a number (or of each element of an array).
    lo_open, hi_open : bool
        The bound itself is excluded.
    required : bool
        The key must be present.
    allow_inf : bool
        ``inf`` and ``-inf`` are accepted (open bounds of a keep-out box).
    choices : tuple of str
        The values a string (or each element of ``strings``) may take.
    """

    kind: str
    meaning: str
    unit: str = ""
    lo: float = -_INF
    hi: float = _INF
    lo_open: bool = False
    hi_open: bool = False
    required: bool = True
    allow_inf: bool = False
    choices: tuple[str, ...] = ()

    def range_text(self) -> str:
        """The range as ``[lo, hi] unit`` (empty when unbounded)."""
        if self.lo == -_INF and self.hi == _INF:
            return ""
        lo = "-inf" if self.lo == -_INF else f"{self.lo:g}"
        hi = "inf" if self.hi == _INF else f"{self.hi:g}"
        text = f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"
        return f"{text} {self.unit}".rstrip()


def _source(required: bool = True) -> Key:
    return Key("string", "where the numbers of this group come from (a reference, a file, a commit)",
               required=required)


TOP: Mapping[str, Key] = {
    "format": Key("integer", "description format version (this code reads 1)", lo=1, hi=1),
    "name": Key("string", "short lower-case name, the file's stem (ztf, ls4 ...)"),
    "title": Key("string", "full name of the telescope and camera"),
    "queue": Key("string", "how its part of a plan is carried out", choices=("ztf_too", "skyportal", "target_list")),
    "source": _source(),
    "site": Key("table", "where the telescope is"),
    "grid": Key("table", "the fixed field grid"),
    "footprint": Key("table", "the detectors about the pointing"),
    "filters": Key("table", "one table per filter: the depth model's terms"),
    "depth": Key("table", "depth-model terms shared by the filters"),
    "overheads": Key("table", "readout, settle, filter change and slew axes"),
    "limits": Key("table", "pointing limits"),
    "planning": Key("table", "a plan's defaults for this telescope"),
    "execution": Key("table", "how the queue is executed and exported"),
}

SITE: Mapping[str, Key] = {
    "latitude_deg": Key("number", "geodetic latitude", "deg", -90, 90),
    "longitude_deg": Key("number", "geodetic longitude, east positive", "deg", -180, 180),
    "height_m": Key("number", "height above the WGS84 ellipsoid", "m", -500, 9000),
    "night_anchor_utc": Key("string", "ISO UTC time of a local noon, the planning grid's anchor "
                            "(default: local mean noon of 2000-01-01)", required=False),
    "name": Key("string", "the site's name, as summaries say it ('at Palomar')", required=False),
    "timezone": Key("string", "the site's IANA time zone, for local clock times in summaries "
                    "(default: local mean time from the longitude)", required=False),
    "source": _source(),
}

GRID: Mapping[str, Key] = {
    "file": Key("string", "field list: whitespace columns id, RA, Dec (deg); % or # comments; path relative to "
                "the description", required=False),
    "width_deg": Key("number", "generated grid: width of the tiling rectangle (east-west)", "deg", 0, 60,
                     lo_open=True, required=False),
    "height_deg": Key("number", "generated grid: height of the tiling rectangle (north-south)", "deg", 0, 60,
                      lo_open=True, required=False),
    "overlap": Key("number", "generated grid: least overlap of neighbours, a fraction of the width (I2)", "",
                   0, 0.5, hi_open=True, required=False),
    "first_id": Key("integer", "generated grid: id of the first field (default 1)", "", 0, 1e9, required=False),
    "source": _source(),
}

FOOTPRINT: Mapping[str, Key] = {
    "file": Key("string", "detector corners: ZTF's layout table (CSV EW,NS,CCD; deg); path relative to the "
                "description", required=False),
    "polygons": Key("polygons", "detector outlines, [[x, y], ...] per detector", "deg", -30, 30, required=False),
    "mosaic_rows": Key("integers", "a mosaic of equal detectors: detectors per row, north row first", "", 1, 100,
                       required=False),
    "detector_width_deg": Key("number", "mosaic: detector width (x)", "deg", 0, 30, lo_open=True, required=False),
    "detector_height_deg": Key("number", "mosaic: detector height (y)", "deg", 0, 30, lo_open=True, required=False),
    "gap_x_deg": Key("number", "mosaic: gap between detectors in a row", "deg", 0, 10, required=False),
    "gap_y_deg": Key("number", "mosaic: gap between rows", "deg", 0, 10, required=False),
    "radius_deg": Key("number", "a circle about the pointing holding every detector (default: the farthest "
                      "corner)", "deg", 0, 30, lo_open=True, required=False),
    "source": _source(),
}

FILTER: Mapping[str, Key] = {
    "zenith_depth": Key("number", "5-sigma depth of a reference exposure at the zenith, dark sky (C_b, D1)",
                        "mag", 5, 35),
    "sky_zenith": Key("number", "dark-sky brightness at the zenith (mu_dark, D1)", "mag/arcsec2", 5, 30),
    "extinction": Key("number", "k_b, extinction per airmass (D1)", "mag", 0, 3),
    "zenith_fwhm_arcsec": Key("number", "seeing at the zenith (FWHM_zen, D1)", "arcsec", 0, 20, lo_open=True),
    "sun_minus_v": Key("number", "colour of sunlight, band minus V (moonlight)", "mag", -5, 5),
    "reference_depth": Key("number", "5-sigma depth of the reference images (m_ref, D2); absent: none needed",
                           "mag", 5, 40, required=False),
    "reference_fwhm_arcsec": Key("number", "seeing of the reference images (FWHM_ref, D2)", "arcsec", 0, 20,
                                 lo_open=True, required=False),
    "median_depth": Key("number", "published median 5-sigma depth of a reference exposure", "mag", 5, 35,
                        required=False),
    "detectors": Key("integers", "detectors behind this filter (default all)", "", 0, 10000, required=False),
    "queue_id": Key("integer", "the filter's id in the telescope's queue", "", 0, 1000, required=False),
    "skyportal_name": Key("string", "SkyPortal's name of the filter", required=False),
    "source": _source(),
}

DEPTH: Mapping[str, Key] = {
    "reference_exposure_s": Key("number", "exposure the filters' depths refer to", "s", 0, 86400, lo_open=True),
    "seeing_airmass_exponent": Key("number", "FWHM grows as airmass to this power", "", 0, 2),
    "twilight_slope_mag_per_deg": Key("number", "twilight sky fading per degree of Sun depression", "mag/deg",
                                      0, 2),
    "source": _source(),
}

OVERHEADS: Mapping[str, Key] = {
    "readout_s": Key("number", "detector readout, during the slew", "s", 0, 3600),
    "settle_s": Key("number", "settle after any axis moved", "s", 0, 600),
    "filter_change_s": Key("number", "filter exchange (0: filters fixed on the detectors)", "s", 0, 3600),
    "filter_change_with_slew": Key("boolean", "the filter changes during the slew (else before it)"),
    "axes": Key("tables", "slew axes, one [[overheads.axes]] table each"),
    "source": _source(),
}

AXIS: Mapping[str, Key] = {
    "coordinate": Key("string", "what the axis moves", choices=("ha", "dec", "azimuth", "altitude", "dome_azimuth")),
    "accel_deg_s2": Key("number", "acceleration and deceleration", "deg/s2", 0, 100, lo_open=True),
    "vmax_deg_s": Key("number", "top speed", "deg/s", 0, 100, lo_open=True),
    "source": _source(required=False),
}

LIMITS: Mapping[str, Key] = {
    "airmass_max": Key("number", "largest airmass (sec z)", "", 1, 40),
    "ha_max_h": Key("number", "largest |hour angle|", "h", 0, 12, lo_open=True),
    "dec_min_deg": Key("number", "southern edge of the planned band", "deg", -90, 90),
    "dec_max_deg": Key("number", "northern edge of the planned band", "deg", -90, 90),
    "sun_alt_max_deg": Key("number", "observing with the Sun below this altitude", "deg", -90, 0),
    "moon_sep_min_deg": Key("number", "least distance from a field centre to the Moon", "deg", 0, 180),
    "keep_out": Key("tables", "(HA, Dec) boxes the mount cannot reach, [[limits.keep_out]] tables",
                    required=False),
    "source": _source(),
}

KEEP_OUT: Mapping[str, Key] = {
    "ha_min_deg": Key("number", "box: HA above this (open)", "deg", -180, 180, allow_inf=True),
    "ha_max_deg": Key("number", "box: HA below this (open)", "deg", -180, 180, allow_inf=True),
    "dec_min_deg": Key("number", "box: Dec above this (open)", "deg", -90, 90, allow_inf=True),
    "dec_max_deg": Key("number", "box: Dec below this (open)", "deg", -90, 90, allow_inf=True),
    "why": Key("string", "what is in the way"),
}

PLANNING: Mapping[str, Key] = {
    "exposure_s": Key("number", "exposure of one visit", "s", 0, 86400, lo_open=True),
    "exposure_min_s": Key("number", "shortest exposure the telescope takes", "s", 0, 86400, lo_open=True),
    "exposure_max_s": Key("number", "longest exposure the telescope takes", "s", 0, 86400, lo_open=True),
    "filters": Key("strings", "filter sequence of a field's visits"),
    "cadence_s": Key("number", "least time between two visits of a field", "s", 0, 86400, lo_open=True),
    "filter_change_s": Key("number", "filter change the plan assumes", "s", 0, 3600),
    "slew_estimate_s": Key("number", "mean slew and readout the block MILP assumes", "s", 0, 3600),
    "source": _source(),
}

EXECUTION: Mapping[str, Key] = {
    "survey_step_s": Key("number", "ztf_too: what the survey takes when no target is observable", "s", 0, 3600,
                         lo_open=True, required=False),
    "lost_pointing_slew_s": Key("number", "ztf_too: slew charged after the survey had the telescope", "s", 0, 3600,
                                required=False),
    "default_max_airmass": Key("number", "ztf_too: a target's airmass limit when it gives none", "", 1, 40,
                               required=False),
    "program_ids": Key("ids", "ztf_too: the queue's program ids by program name", "", 0, 1e6, required=False),
    "skyportal_instrument": Key("string", "skyportal: SkyPortal's name of the instrument", required=False),
    "formats": Key("strings", "target_list: files written", choices=("json", "csv"), required=False),
    "source": _source(),
}

#: Section name (as errors show it) -> its keys; ``filters.<name>`` tables use :data:`FILTER`.
TABLES: Mapping[str, Mapping[str, Key]] = {
    "": TOP, "site": SITE, "grid": GRID, "footprint": FOOTPRINT, "filters.<name>": FILTER, "depth": DEPTH,
    "overheads": OVERHEADS, "overheads.axes": AXIS, "limits": LIMITS, "limits.keep_out": KEEP_OUT,
    "planning": PLANNING, "execution": EXECUTION,
}

#: The execution keys each queue kind needs (the others are refused for it).
EXECUTION_KEYS: Mapping[str, tuple[str, ...]] = {
    "ztf_too": ("survey_step_s", "lost_pointing_slew_s", "default_max_airmass", "program_ids"),
    "skyportal": ("skyportal_instrument",),
    "target_list": ("formats",),
}
