"""Kilonova light curves: absolute magnitude per band versus time since merger.

The file format is gwemopt's (POSSIS grids): whitespace text with a header
line ``# t[days] u g r i z y J H K``, then one row per time (days since
merger) with absolute AB magnitudes.  Columns are read by the header's band
NAMES, never by position.  ``nan`` entries mean "no flux computed": the
source is not detectable there.

Two light curves of the paper ship as package data (``data/lightcurves/``,
GPL-3.0, see its ``SOURCES.md``): ``optimistic`` (peak g -15.7, r -16.0) and
``conservative`` (peak g -15.1, r -15.7), plus ``nsbh``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..lightcurve_names import PAPER_LIGHTCURVES

__all__ = [
    "LightCurve",
    "LightCurveError",
    "read_lightcurve",
    "parse_lightcurve",
    "load_lightcurve",
    "PAPER_LIGHTCURVES",
    "NOT_DETECTABLE",
]

#: Magnitude returned where a source cannot be seen (outside the table, NaN).
NOT_DETECTABLE = math.inf



class LightCurveError(InputError):
    """A light-curve file is missing or malformed."""


@dataclass(frozen=True, eq=False)
class LightCurve:
    """Absolute magnitudes of a transient, tabulated per band.

    Attributes
    ----------
    name : str
        Label (file stem or package name).
    t_days : numpy.ndarray
        (n,) strictly increasing times since merger (days).
    bands : tuple of str
        Band names, in column order of ``mags``.
    mags : numpy.ndarray
        (n, len(bands)) absolute AB magnitudes; NaN = not detectable.
    """

    name: str
    t_days: np.ndarray
    bands: tuple[str, ...]
    mags: np.ndarray

    def column(self, band: str) -> np.ndarray:
        """(n,) tabulated absolute magnitudes of one band (NaN = no flux).

        Raises
        ------
        LightCurveError
            When the band is not in the file.
        """
        try:
            k = self.bands.index(band)
        except ValueError:
            raise LightCurveError(
                f"light curve {self.name!r} has no band {band!r} (bands: {', '.join(self.bands)})"
            ) from None
        return self.mags[:, k]

    def absolute_mag(self, band: str, t_days: np.ndarray | float) -> np.ndarray:
        """Absolute magnitude at times since merger, linearly interpolated.

        Parameters
        ----------
        band : str
            Band name as in the file header (``g``, ``r``, ...).
        t_days : array_like
            Times since merger (days).

        Returns
        -------
        numpy.ndarray
            Absolute AB magnitude (mag), same shape as ``t_days``; ``+inf``
            (never brighter than any limit) outside the tabulated time range
            and wherever an interpolation node is NaN.
        """
        t = np.asarray(t_days, dtype=float)
        col = self.column(band)
        with np.errstate(invalid="ignore"):
            m = np.interp(t, self.t_days, col)
        # np.interp propagates a NaN node into its neighbouring interval only
        # partly; mark both intervals around a NaN node as not detectable.
        bad_node = np.isnan(col)
        if bad_node.any():
            j = np.clip(np.searchsorted(self.t_days, t, side="right") - 1, 0, col.size - 1)
            jn = np.clip(j + 1, 0, col.size - 1)
            exact = np.isclose(t, self.t_days[j], rtol=0.0, atol=1e-12)
            m = np.where(bad_node[j] | (bad_node[jn] & ~exact), np.nan, m)
        outside = ~((t >= self.t_days[0]) & (t <= self.t_days[-1]))
        return np.where(outside | np.isnan(m), NOT_DETECTABLE, m)

    def peak(self, band: str) -> tuple[float, float]:
        """Brightest tabulated point of a band.

        Returns
        -------
        (mag, t_days) : tuple of float
            Peak absolute magnitude (mag) and its time since merger (days).
        """
        col = self.column(band)
        k = int(np.nanargmin(col))
        return float(col[k]), float(self.t_days[k])


def parse_lightcurve(text: str, name: str = "<text>") -> LightCurve:
    """Parse light-curve text (``# t[days] band...`` header, numeric rows).

    Parameters
    ----------
    text : str
        File contents.
    name : str
        Label used in messages and on the result.

    Returns
    -------
    LightCurve

    Raises
    ------
    LightCurveError
        Missing or malformed header, rows of the wrong width, non-numeric
        values, fewer than two rows, or times not strictly increasing.
    """
    lines = [ln.strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    if not lines or not lines[0].startswith("#"):
        raise LightCurveError(f"{name}: first line must be a header like '# t[days] u g r ...'")
    header = lines[0].lstrip("#").split()
    if len(header) < 2 or not header[0].lower().startswith("t"):
        raise LightCurveError(f"{name}: header must start with the time column, got {lines[0]!r}")
    bands = tuple(header[1:])
    if len(set(bands)) != len(bands):
        raise LightCurveError(f"{name}: duplicate band names in header {lines[0]!r}")
    rows = [ln for ln in lines[1:] if not ln.startswith("#")]
    try:
        table = np.array([[float(v) for v in ln.split()] for ln in rows], dtype=float)
    except ValueError as exc:
        raise LightCurveError(f"{name}: non-numeric value ({exc})") from None
    if table.ndim != 2 or table.shape[0] < 2 or table.shape[1] != len(header):
        widths = sorted({len(ln.split()) for ln in rows})
        raise LightCurveError(
            f"{name}: need >= 2 rows of {len(header)} columns (header), got {len(rows)} rows of width(s) {widths}"
        )
    t = table[:, 0]
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise LightCurveError(f"{name}: times must be finite and strictly increasing")
    return LightCurve(name=name, t_days=t.copy(), bands=bands, mags=table[:, 1:].copy())


def read_lightcurve(path: str | Path) -> LightCurve:
    """Read a light-curve file (gwemopt/POSSIS format).

    Parameters
    ----------
    path : str or pathlib.Path
        File path.

    Returns
    -------
    LightCurve
        Named after the file stem.
    """
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise LightCurveError(f"cannot read light curve {p}: {exc.strerror or exc}") from None
    return parse_lightcurve(text, name=p.stem)


def load_lightcurve(spec: str | Path) -> LightCurve:
    """A packaged light curve by name, or any file by path.

    Parameters
    ----------
    spec : str or pathlib.Path
        ``optimistic``, ``conservative``, ``nsbh`` (package data) or a path.

    Returns
    -------
    LightCurve
    """
    key = str(spec)
    if key in PAPER_LIGHTCURVES:
        res = resources.files("mushrooms.scheduler_core").joinpath("data/lightcurves", PAPER_LIGHTCURVES[key])
        return parse_lightcurve(res.read_text(), name=key)
    return read_lightcurve(spec)
