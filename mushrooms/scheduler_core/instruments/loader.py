"""Reading a telescope description (TOML) into a :class:`~.description.TelescopeDescription`.

The shipped descriptions live in ``scheduler_core/data/telescopes/`` (their
sources in ``SOURCES.md`` beside them); :func:`load_description` takes one
of their names or the path of any description file.  Everything is checked
at load, and every problem is reported at once, one line each, naming the
file, the table and the key (:class:`~.validate.DescriptionError`, an
:class:`~..errors.InputError`): unknown keys with the nearest known one,
wrong types, values out of range, missing keys and files, values that
contradict each other.
"""

from __future__ import annotations

import difflib
import re
import tomllib
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any, Callable

import numpy as np

from . import schema as S
from .description import (DepthTerms, Execution, FieldCentres, FilterTerms, Footprint, KeepOut, Overheads,
                          PlanningDefaults, PointingLimits, SlewAxis, Site, TelescopeDescription, local_mean_noon)
from .footprint import mosaic_polygons, outer_radius_deg, read_ccd_layout
from .tessellation import declination_band_grid, read_field_list
from .validate import DescriptionError, read_table, shown

__all__ = ["DATA_DIR", "known_telescopes", "description_path", "load_description", "parse_description",
           "MAX_DESCRIPTION_BYTES", "MAX_DATA_BYTES", "MAX_DETECTORS"]

#: The largest description file read (bytes).
MAX_DESCRIPTION_BYTES = 1 << 20
#: The largest grid or layout file a description may name (bytes).
MAX_DATA_BYTES = 64 << 20
#: The most detectors a footprint may have (DECam: 62).
MAX_DETECTORS = 1000
_NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")
_ISO_UTC = re.compile(r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d{1,9})?$")
_FILTER_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,15}$")


def _data_dir() -> Path:
    return Path(str(resources.files("mushrooms.scheduler_core").joinpath("data", "telescopes")))


#: The folder of the shipped descriptions.
DATA_DIR = _data_dir()


def known_telescopes() -> tuple[str, ...]:
    """Names of the shipped descriptions, sorted."""
    return tuple(sorted(p.stem for p in DATA_DIR.glob("*.toml")))


def description_path(name_or_path: str | Path) -> Path:
    """The file of a shipped telescope's name, or the given path (a ``.toml`` or anything with a ``/``).

    Raises
    ------
    DescriptionError
        An unknown name (the known ones and the nearest listed) or a missing file.
    """
    text = str(name_or_path)
    if isinstance(name_or_path, Path) or "/" in text or text.endswith(".toml"):
        path = Path(text).expanduser()
        if not path.is_file():
            raise DescriptionError([f"{shown(text)}: no such description file"])
        return path
    known = known_telescopes()
    if text not in known:
        near = difflib.get_close_matches(text.lower(), known, n=1, cutoff=0.5)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise DescriptionError([f"unknown telescope {shown(text)} (known: {', '.join(known)}){hint}"])
    return DATA_DIR / f"{text}.toml"


_cache: dict[tuple[str, int, int], TelescopeDescription] = {}


def load_description(name_or_path: str | Path) -> TelescopeDescription:
    """The description of a shipped telescope (``ztf``, ``ls4``, ``winter``, ``decam``) or of a TOML file.

    Read once per file version (path, size, modification time) and kept.

    Examples
    --------
    >>> ztf = load_description("ztf")
    >>> len(ztf.grid), len(ztf.footprint.polygons), list(ztf.filters), ztf.queue
    (1778, 16, ['g', 'r', 'i'], 'ztf_too')

    Raises
    ------
    DescriptionError
        Every problem of the file, one line each.
    """
    path = description_path(name_or_path)
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if key not in _cache:
        if stat.st_size > MAX_DESCRIPTION_BYTES:
            raise DescriptionError([f"{path.name}: larger than {MAX_DESCRIPTION_BYTES} bytes"])
        _cache[key] = parse_description(path.read_text(encoding="utf-8", errors="replace"), path)
    return _cache[key]


class _Reader:
    """One description being read: its file's name and folder, and the problems found so far."""

    def __init__(self, path: Path) -> None:
        self.path, self.problems = path, []

    def where(self, section: str) -> str:
        return f"{self.path.name}: [{section}]" if section else f"{self.path.name}:"

    def table(self, raw: Any, keys: Any, section: str) -> dict[str, Any]:
        return read_table(raw, keys, self.where(section), self.problems)

    def problem(self, section: str, text: str) -> None:
        self.problems.append(f"{self.where(section)} {text}")

    def data_file(self, section: str, name: str) -> str | None:
        """The text of a file a description names (relative to its folder), or None (a problem noted)."""
        path = (self.path.parent / Path(name).expanduser())
        if not path.is_file():
            self.problem(section, f"file = {shown(name)}: no such file")
            return None
        if path.stat().st_size > MAX_DATA_BYTES:
            self.problem(section, f"file = {shown(name)}: larger than {MAX_DATA_BYTES} bytes")
            return None
        return path.read_text(encoding="utf-8", errors="replace")

    def read(self, raw: Any, keys: Any, section: str, build: Callable[[dict[str, Any]], Any]) -> Any:
        """Read a section and build its value, unless the section has problems of its own."""
        before = len(self.problems)
        values = self.table(raw, keys, section)
        if len(self.problems) > before:
            return None
        try:
            return build(values)
        except _Refused:
            return None


class _Refused(Exception):
    """A builder found a problem (already noted)."""


def _site(r: _Reader, v: dict[str, Any]) -> Site:
    anchor = v.get("night_anchor_utc") or local_mean_noon(v["longitude_deg"])
    if not _ISO_UTC.match(anchor):
        r.problem("site", f"night_anchor_utc = {shown(anchor)}: not an ISO UTC time (2000-01-01T19:47:26.4)")
        raise _Refused
    zone = str(v.get("timezone") or "")
    if zone and not _known_zone(zone):
        r.problem("site", f"timezone = {shown(zone)}: not a time zone of the IANA database (America/Santiago)")
        raise _Refused
    return Site(float(v["latitude_deg"]), float(v["longitude_deg"]), float(v["height_m"]), anchor, v["source"],
                str(v.get("name") or ""), str(v.get("timezone") or ""))


def _known_zone(zone: str) -> bool:
    """Whether the IANA database (``zoneinfo``) knows ``zone``; True when there is no database to ask."""
    try:
        from zoneinfo import ZoneInfo, ZoneInfoNotFoundError, available_timezones
    except ImportError:  # pragma: no cover
        return True
    if not available_timezones():
        return True
    try:
        ZoneInfo(zone)
        return True
    except (ZoneInfoNotFoundError, ValueError, OSError):
        return False


def _grid(r: _Reader, v: dict[str, Any]) -> FieldCentres:
    made = [k for k in ("width_deg", "height_deg", "overlap", "first_id") if k in v]
    if ("file" in v) == bool(made) or ("file" not in v and not {"width_deg", "height_deg"} <= set(v)):
        r.problem("grid", "needs either file or width_deg and height_deg (with overlap, first_id), not both")
        raise _Refused
    if "file" in v:
        text = r.data_file("grid", v["file"])
        if text is None:
            raise _Refused
        try:
            ids, ra, dec = read_field_list(text)
        except ValueError as exc:
            r.problem("grid", f"file = {shown(v['file'])}: {exc}")
            raise _Refused from None
        origin = f"file {Path(v['file']).name}"
    else:
        overlap = float(v.get("overlap", 0.1))
        try:
            ids, ra, dec = declination_band_grid(v["width_deg"], v["height_deg"], overlap, int(v.get("first_id", 1)))
        except ValueError as exc:
            r.problem("grid", str(exc))
            raise _Refused from None
        origin = f"declination bands {v['width_deg']:g} x {v['height_deg']:g} deg, overlap {overlap:g}"
    for a in (ids, ra, dec):
        a.setflags(write=False)
    return FieldCentres(ids, ra, dec, origin, v["source"])


_MOSAIC = ("mosaic_rows", "detector_width_deg", "detector_height_deg", "gap_x_deg", "gap_y_deg")


def _footprint(r: _Reader, v: dict[str, Any]) -> Footprint:
    kinds = [k for k in ("file", "polygons", "mosaic_rows") if k in v]
    stray = [k for k in _MOSAIC[1:] if k in v and "mosaic_rows" not in v]
    if len(kinds) != 1 or stray:
        r.problem("footprint", "needs exactly one of file, polygons or mosaic_rows (with detector_width_deg, "
                  "detector_height_deg, gap_x_deg, gap_y_deg)")
        raise _Refused
    if "file" in v:
        text = r.data_file("footprint", v["file"])
        if text is None:
            raise _Refused
        try:
            polygons = read_ccd_layout(text)
        except ValueError as exc:
            r.problem("footprint", f"file = {shown(v['file'])}: {exc}")
            raise _Refused from None
    elif "polygons" in v:
        polygons = tuple(np.array(p, float) for p in v["polygons"])
    else:
        if not {"detector_width_deg", "detector_height_deg"} <= set(v) or sum(v["mosaic_rows"]) > MAX_DETECTORS:
            r.problem("footprint", f"mosaic_rows needs detector_width_deg and detector_height_deg, and at most "
                      f"{MAX_DETECTORS} detectors")
            raise _Refused
        polygons = mosaic_polygons(v["mosaic_rows"], v["detector_width_deg"], v["detector_height_deg"],
                                   v.get("gap_x_deg", 0.0), v.get("gap_y_deg", 0.0))
    if len(polygons) > MAX_DETECTORS:
        r.problem("footprint", f"{len(polygons)} detectors, more than {MAX_DETECTORS}")
        raise _Refused
    for p in polygons:
        p.setflags(write=False)
    return Footprint(polygons, float(v.get("radius_deg", outer_radius_deg(polygons))), v["source"])


def _filters(r: _Reader, raw: Any, n_detectors: int | None) -> dict[str, FilterTerms]:
    """The filters read whole (a filter with a problem is left out, the problem noted)."""
    if not isinstance(raw, dict) or not raw:
        r.problem("filters", "needs at least one [filters.<name>] table")
        return {}
    out = {}
    for name, table in raw.items():
        section = f"filters.{name}"
        if not _FILTER_NAME.match(str(name)):
            r.problem("filters", f"filter name {shown(name)}: letters, digits and _ (1-16, a letter first)")
            continue
        before = len(r.problems)
        v = r.table(table, S.FILTER, section)
        if ("reference_depth" in v) != ("reference_fwhm_arcsec" in v):
            r.problem(section, "reference_depth and reference_fwhm_arcsec go together (D2)")
        det = tuple(int(d) for d in v.get("detectors", ()))
        if n_detectors is not None and any(d >= n_detectors for d in det):
            r.problem(section, f"detectors: the footprint has {n_detectors} detectors (0 to {n_detectors - 1})")
        if len(r.problems) > before:
            continue
        out[name] = FilterTerms(name, float(v["zenith_depth"]), float(v["sky_zenith"]), float(v["extinction"]),
                                float(v["zenith_fwhm_arcsec"]), float(v["sun_minus_v"]),
                                _opt(v, "reference_depth"), _opt(v, "reference_fwhm_arcsec"),
                                _opt(v, "median_depth"), det, v.get("queue_id"), v.get("skyportal_name"),
                                v["source"])
    return out


def _opt(v: dict[str, Any], key: str) -> float | None:
    return float(v[key]) if key in v else None


def _overheads(r: _Reader, v: dict[str, Any]) -> Overheads:
    axes = []
    for i, table in enumerate(v["axes"]):
        a = r.table(table, S.AXIS, f"overheads.axes.{i}")
        if set(S.AXIS) - {"source"} <= set(a):
            axes.append(SlewAxis(a["coordinate"], float(a["accel_deg_s2"]), float(a["vmax_deg_s"]),
                                 a.get("source", "")))
    coords = [a.coordinate for a in axes]
    if not v["axes"] or len(set(coords)) != len(coords):
        r.problem("overheads", "axes: one [[overheads.axes]] table per coordinate, at least one")
    if len(axes) != len(v["axes"]) or not axes or len(set(coords)) != len(coords):
        raise _Refused
    return Overheads(float(v["readout_s"]), float(v["settle_s"]), float(v["filter_change_s"]),
                     bool(v["filter_change_with_slew"]), tuple(axes), v["source"])


def _limits(r: _Reader, v: dict[str, Any]) -> PointingLimits:
    boxes, bad = [], False
    for i, table in enumerate(v.get("keep_out", [])):
        section = f"limits.keep_out.{i}"
        before = len(r.problems)
        b = r.table(table, S.KEEP_OUT, section)
        if len(r.problems) == before and not (b["ha_min_deg"] < b["ha_max_deg"] and b["dec_min_deg"] < b["dec_max_deg"]):
            r.problem(section, "needs ha_min_deg < ha_max_deg and dec_min_deg < dec_max_deg")
        if len(r.problems) > before:
            bad = True
            continue
        boxes.append(KeepOut(float(b["ha_min_deg"]), float(b["ha_max_deg"]), float(b["dec_min_deg"]),
                             float(b["dec_max_deg"]), b["why"]))
    if v["dec_min_deg"] >= v["dec_max_deg"]:
        r.problem("limits", f"dec_min_deg ({v['dec_min_deg']:g}) must be less than dec_max_deg ({v['dec_max_deg']:g})")
        bad = True
    if bad:
        raise _Refused
    return PointingLimits(float(v["airmass_max"]), float(v["ha_max_h"]), float(v["dec_min_deg"]),
                          float(v["dec_max_deg"]), float(v["sun_alt_max_deg"]), float(v["moon_sep_min_deg"]),
                          tuple(boxes), v["source"])


def _planning(r: _Reader, v: dict[str, Any], filters: list[str]) -> PlanningDefaults:
    unknown = [f for f in v["filters"] if f not in filters]
    if not v["filters"] or unknown:
        r.problem("planning", f"filters = {shown(v['filters'])}: 1 or more of this telescope's filters "
                  f"({', '.join(filters)})")
        raise _Refused
    if not v["exposure_min_s"] <= v["exposure_s"] <= v["exposure_max_s"]:
        r.problem("planning", "needs exposure_min_s <= exposure_s <= exposure_max_s")
        raise _Refused
    return PlanningDefaults(float(v["exposure_s"]), float(v["exposure_min_s"]), float(v["exposure_max_s"]),
                            tuple(v["filters"]), float(v["cadence_s"]), float(v["filter_change_s"]),
                            float(v["slew_estimate_s"]), v["source"])


def _execution(r: _Reader, v: dict[str, Any], queue: str | None) -> Execution:
    if queue is None:
        raise _Refused
    wanted = S.EXECUTION_KEYS[queue]
    for key in sorted(set(v) - {"source"} - set(wanted)):
        r.problem("execution", f"{key} is not for queue = {queue!r} (it takes {', '.join(wanted)})")
    for key in wanted:
        if key not in v:
            r.problem("execution", f"missing key {key!r} (queue = {queue!r}: {S.EXECUTION[key].meaning})")
    if set(v) - {"source"} != set(wanted):
        raise _Refused
    return Execution(queue, _opt(v, "survey_step_s"), _opt(v, "lost_pointing_slew_s"),
                     _opt(v, "default_max_airmass"), MappingProxyType(dict(v.get("program_ids", {}))),
                     v.get("skyportal_instrument"),
                     tuple(v.get("formats", ())), v["source"])


def parse_description(text: str, path: Path) -> TelescopeDescription:
    """A description from its TOML text; ``path`` names it in messages and anchors the files it names.

    Raises
    ------
    DescriptionError
        Every problem, one line each.
    """
    r = _Reader(Path(path))
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DescriptionError([f"{r.path.name}: not TOML: {exc}"]) from None
    top = r.table(doc, S.TOP, "")
    if "name" in top and not (_NAME.match(top["name"]) and top["name"] == r.path.stem):
        r.problem("", f"name = {shown(top['name'])}: lower-case letters, digits, - and _, the file's stem "
                  f"({shown(r.path.stem)})")
    section = {k: top[k] for k in S.TOP if S.TOP[k].kind == "table" and k in top}
    site = r.read(section.get("site"), S.SITE, "site", lambda v: _site(r, v)) if "site" in section else None
    grid = r.read(section.get("grid"), S.GRID, "grid", lambda v: _grid(r, v)) if "grid" in section else None
    foot = (r.read(section["footprint"], S.FOOTPRINT, "footprint", lambda v: _footprint(r, v))
            if "footprint" in section else None)
    filters = _filters(r, section["filters"], len(foot.polygons) if foot else None) if "filters" in section else {}
    declared = [str(k) for k in section["filters"]] if isinstance(section.get("filters"), dict) else []
    parts: dict[str, Any] = {}
    builders = {"depth": (S.DEPTH, lambda v: DepthTerms(float(v["reference_exposure_s"]),
                                                          float(v["seeing_airmass_exponent"]),
                                                          float(v["twilight_slope_mag_per_deg"]), v["source"])),
                "overheads": (S.OVERHEADS, lambda v: _overheads(r, v)), "limits": (S.LIMITS, lambda v: _limits(r, v)),
                "planning": (S.PLANNING, lambda v: _planning(r, v, declared)),
                "execution": (S.EXECUTION, lambda v: _execution(r, v, top.get("queue")))}
    for name, (keys, build) in builders.items():
        if name in section:
            parts[name] = r.read(section[name], keys, name, build)
    if r.problems:
        raise DescriptionError(r.problems)
    return TelescopeDescription(top["name"], top["title"], top["source"], str(path), site, grid, foot,
                                MappingProxyType(filters), **parts)
