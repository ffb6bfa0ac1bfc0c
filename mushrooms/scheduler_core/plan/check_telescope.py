"""The checker's own reading of a described telescope (phase 2): grid, detectors, site, mount.

For ZTF the checker keeps its constants (:mod:`.check_geometry`).  For any
other telescope it reads the description file itself, with the standard
library's TOML reader and its own parsers, not the planner's loader: the
field list and the detector layout files the description names (the same
formats as ZTF's), the detector polygons or the mosaic written out from its
numbers, the site's numbers and the keep-out boxes (I4, written out again).
Independence is of code, not of constants; only a grid built from the field
of view (``[grid] width_deg``, I1-I2: no file to read) is taken from the
planner's loader, as the numbers of the description.
"""

from __future__ import annotations

import csv
import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["CheckScope", "check_scope"]


@dataclass(frozen=True, eq=False)
class CheckScope:
    """A telescope as the checker sees it.

    Attributes
    ----------
    name : str
        The telescope's name.
    positions : dict of int to (float, float)
        Field id -> centre (RA, Dec; deg).
    offsets : numpy.ndarray
        (n, 4, 2) corner offsets (x west, y north; deg) of the detectors that
        make a field covered (those behind every covering filter).
    site : tuple of float
        (latitude deg, longitude deg, height m).
    keep_out : tuple of tuple of float
        Open (HA, Dec) boxes ``(ha_min, ha_max, dec_min, dec_max)`` (deg).
    altaz : bool
        (M1) The mount's axes move in azimuth and altitude (none in hour angle or declination).
    """

    name: str
    positions: dict[int, tuple[float, float]]
    offsets: np.ndarray
    site: tuple[float, float, float]
    keep_out: tuple[tuple[float, float, float, float], ...]
    altaz: bool = False

    def reachable(self, ha_deg: np.ndarray, dec_deg: np.ndarray, ha_max_h: float) -> np.ndarray:
        """(I4) |HA| within ``ha_max_h`` (h) and in no keep-out box."""
        ha, dec = np.asarray(ha_deg, float), np.asarray(dec_deg, float)
        bad = np.abs(ha) / 15.0 > ha_max_h
        for h0, h1, d0, d1 in self.keep_out:
            bad = bad | ((ha > h0) & (ha < h1) & (dec > d0) & (dec < d1))
        return ~bad


def _path(entry: str) -> Path:
    if "/" in entry or entry.endswith(".toml"):
        return Path(entry).expanduser()
    from importlib import resources

    return Path(str(resources.files("mushrooms.scheduler_core").joinpath("data", "telescopes", f"{entry}.toml")))


def _field_list(path: Path) -> dict[int, tuple[float, float]]:
    """id, RA, Dec per line; ``%`` and ``#`` comments."""
    out = {}
    for line in path.read_text().splitlines():
        words = line.split("#")[0].split("%")[0].split()
        if len(words) >= 3:
            out[int(float(words[0]))] = (float(words[1]), float(words[2]))
    return out


def _layout(path: Path) -> list[np.ndarray]:
    """ZTF's layout table format: a header, then ``EW,NS,CCD`` corner rows."""
    corners: dict[int, list[tuple[float, float]]] = {}
    for ew, ns, ccd in csv.reader(path.read_text().splitlines()[1:]):
        corners.setdefault(int(ccd), []).append((float(ew), float(ns)))
    return [np.array(corners[k], float) for k in sorted(corners)]


def _mosaic(fp: dict[str, Any]) -> list[np.ndarray]:
    """Rows of equal rectangles, north row first, each row centred on the pointing."""
    w, h = float(fp["detector_width_deg"]), float(fp["detector_height_deg"])
    gx, gy = float(fp.get("gap_x_deg", 0.0)), float(fp.get("gap_y_deg", 0.0))
    rows = [int(n) for n in fp["mosaic_rows"]]
    out = []
    for r, n in enumerate(rows):
        yc = ((len(rows) - 1) / 2.0 - r) * (h + gy)
        for c in range(n):
            xc = (c - (n - 1) / 2.0) * (w + gx)
            out.append(np.array([[xc - w / 2, yc - h / 2], [xc - w / 2, yc + h / 2],
                                 [xc + w / 2, yc + h / 2], [xc + w / 2, yc - h / 2]]))
    return out


def _detectors(doc: dict[str, Any], folder: Path) -> list[np.ndarray]:
    fp = doc["footprint"]
    if "file" in fp:
        return _layout(folder / fp["file"])
    if "polygons" in fp:
        return [np.array(p, float) for p in fp["polygons"]]
    return _mosaic(fp)


@dataclass(frozen=True, eq=False)
class _Read:
    """What a description file gives the checker, before the covering filters are chosen."""

    doc: dict[str, Any]
    positions: dict[int, tuple[float, float]]
    detectors: list[np.ndarray]


@functools.lru_cache(maxsize=8)
def _read(entry: str, stamp: tuple[int, int]) -> _Read:
    """The file of ``entry`` (``stamp``: its size and modification time, so an edited file is read again)."""
    path = _path(entry)
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    if "file" in doc["grid"]:
        positions = _field_list(path.parent / doc["grid"]["file"])
    else:  # a built grid: the description's numbers (no file to read)
        from ..instruments.loader import load_description

        g = load_description(entry).grid
        positions = {int(i): (float(r), float(d)) for i, r, d in zip(g.ids, g.ra, g.dec)}
    return _Read(doc, positions, _detectors(doc, path.parent))


def check_scope(config: Any) -> CheckScope | None:
    """The checker's telescope for ``config`` (None: ZTF, the checker's own constants).

    The covering detectors follow ``config.filters`` (the first two visits'
    filters; a filter without ``detectors`` lies on all of them).

    Raises
    ------
    ValueError
        Detectors that are not quadrilaterals (the checker's footprint test).
    """
    if config.telescope == "ztf":
        return None
    stat = _path(config.telescope).stat()
    read = _read(config.telescope, (stat.st_size, stat.st_mtime_ns))
    doc = read.doc
    covering = set(range(len(read.detectors)))
    for name in tuple(config.filters)[:2]:
        behind = doc["filters"].get(name, {}).get("detectors")
        covering &= set(behind) if behind else covering
    chosen = [read.detectors[i] for i in sorted(covering)]
    if any(d.shape != (4, 2) for d in chosen):
        raise ValueError(f"{doc['name']}: the checker tests quadrilateral detectors only")
    site = doc["site"]
    boxes = tuple((float(b["ha_min_deg"]), float(b["ha_max_deg"]), float(b["dec_min_deg"]), float(b["dec_max_deg"]))
                  for b in doc["limits"].get("keep_out", ()))
    moved = {str(a["coordinate"]) for a in doc["overheads"]["axes"]}
    altaz = bool(moved & {"azimuth", "altitude"}) and not moved & {"ha", "dec"}  # (M1)
    return CheckScope(doc["name"], read.positions, np.stack(chosen) if chosen else np.zeros((0, 4, 2)),
                      (float(site["latitude_deg"]), float(site["longitude_deg"]), float(site["height_m"])), boxes,
                      altaz)
