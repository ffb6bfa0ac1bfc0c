"""Detector outlines about a pointing: read from ZTF's layout table, built as a mosaic, tested against points.

The plane is the one of ZTF's CCD layout table and of the planner's
footprints (``sky/fields.py``): orthographic offsets from the pointing in
degrees of direction cosine, ``x = -cos(dec) sin(ra - ra0)`` (growing to
the west) and ``y = cos(dec0) sin(dec) - sin(dec0) cos(dec) cos(ra - ra0)``
(to the north).  (I3) a sky position is seen by a pointing when it lies on
the pointing's side of the sky and its offsets fall inside one detector's
polygon (even-odd rule: any simple polygon, convex or not).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["project", "read_ccd_layout", "mosaic_polygons", "outer_radius_deg", "inside_polygons",
           "seen_by_pointing"]


def project(ra_deg: ArrayLike, dec_deg: ArrayLike, ra0_deg: ArrayLike,
            dec0_deg: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offsets (deg) of sky positions from pointings in the layout's plane, and which side they lie on (broadcasts).

    Returns
    -------
    x, y : numpy.ndarray
        Offsets (deg; x to the west, y to the north).
    near : numpy.ndarray of bool
        The position is less than 90 deg from the pointing.
    """
    ra, dec = np.radians(np.asarray(ra_deg, float)), np.radians(np.asarray(dec_deg, float))
    ra0, dec0 = np.radians(np.asarray(ra0_deg, float)), np.radians(np.asarray(dec0_deg, float))
    x = -np.cos(dec) * np.sin(ra - ra0)
    y = np.cos(dec0) * np.sin(dec) - np.sin(dec0) * np.cos(dec) * np.cos(ra - ra0)
    near = np.sin(dec0) * np.sin(dec) + np.cos(dec0) * np.cos(dec) * np.cos(ra - ra0) > 0
    return np.degrees(x), np.degrees(y), near


def read_ccd_layout(text: str) -> tuple[np.ndarray, ...]:
    """Detector corners from ZTF's layout table (CSV ``EW,NS,CCD`` after one header line; deg).

    The corners of each CCD in the order listed; CCDs by number (the
    planner's ``sky.fields.ccd_corners`` reads the same file the same way).

    Raises
    ------
    ValueError
        A row that is not three numbers (the line number is given, not the line).
    """
    rows = []
    for n, line in enumerate(text.splitlines()[1:], start=2):
        if not line.strip():
            continue
        words = line.split(",")
        try:
            if len(words) != 3:
                raise ValueError
            rows.append((float(words[0]), float(words[1]), int(words[2])))
        except ValueError:
            raise ValueError(f"line {n}: expected EW,NS,CCD (two numbers and a CCD number)") from None
    if not rows:
        raise ValueError("no corners")
    table = np.array(rows, float)
    ccds, corners = np.unique(table[:, 2], return_counts=True)
    if corners.min() < 3 or ccds.size > 1000:
        raise ValueError("every CCD needs 3 or more corners, and at most 1000 CCDs")
    return tuple(table[table[:, 2] == c, :2].copy() for c in ccds)


def mosaic_polygons(rows: ArrayLike, width_deg: float, height_deg: float, gap_x_deg: float = 0.0,
                    gap_y_deg: float = 0.0) -> tuple[np.ndarray, ...]:
    """Equal rectangular detectors in centred rows, north row first (DECam's 3-4-5-6-6-7-7-6-6-5-4-3, LS4's 8x4).

    Parameters
    ----------
    rows : array_like of int
        Detectors in each row, from the north.
    width_deg, height_deg : float
        A detector's size (deg) along x and y.
    gap_x_deg, gap_y_deg : float
        Gaps (deg) between detectors of a row and between rows.

    Returns
    -------
    tuple of numpy.ndarray
        (4, 2) corners per detector, numbered row by row (north first), within a
        row from negative to positive x (east to west).

    Examples
    --------
    >>> [p.mean(axis=0).round(3).tolist() for p in mosaic_polygons([2], 1.0, 1.0, 0.5)]
    [[-0.75, 0.0], [0.75, 0.0]]
    """
    counts = np.asarray(rows, int)
    pitch_x, pitch_y = width_deg + gap_x_deg, height_deg + gap_y_deg
    row_y = ((counts.size - 1) / 2.0 - np.arange(counts.size)) * pitch_y
    hw, hh = width_deg / 2.0, height_deg / 2.0
    out = []
    for n, y in zip(counts.tolist(), row_y.tolist()):
        for x in ((np.arange(n) - (n - 1) / 2.0) * pitch_x).tolist():
            out.append(np.array([[x - hw, y - hh], [x - hw, y + hh], [x + hw, y + hh], [x + hw, y - hh]]))
    return tuple(out)


def outer_radius_deg(polygons: tuple[np.ndarray, ...]) -> float:
    """Angular distance (deg) from the pointing to the farthest corner."""
    r = max(float(np.hypot(p[:, 0], p[:, 1]).max()) for p in polygons)
    return float(np.degrees(np.arcsin(min(1.0, np.radians(r)))))


def inside_polygons(x: ArrayLike, y: ArrayLike, polygons: tuple[np.ndarray, ...]) -> np.ndarray:
    """(I3) Offsets inside any of the polygons (even-odd rule; broadcasts over ``x``, ``y``)."""
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    hit = np.zeros(x.shape, bool)
    for poly in polygons:  # one vectorised pass per detector, never per point
        inside = np.zeros(x.shape, bool)
        x0, y0 = poly[:, 0], poly[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        for ax, ay, bx, by in zip(x0, y0, x1, y1):
            crosses = (ay > y) != (by > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                at = ax + (y - ay) * (bx - ax) / (by - ay)
            inside ^= crosses & (x < at)
        hit |= inside
    return hit


def seen_by_pointing(ra_deg: ArrayLike, dec_deg: ArrayLike, ra0_deg: ArrayLike, dec0_deg: ArrayLike,
                     polygons: tuple[np.ndarray, ...]) -> np.ndarray:
    """(I3) Sky positions falling on a detector of pointings at (ra0, dec0) (broadcasts)."""
    x, y, near = project(ra_deg, dec_deg, ra0_deg, dec0_deg)
    return near & inside_polygons(x, y, polygons)
