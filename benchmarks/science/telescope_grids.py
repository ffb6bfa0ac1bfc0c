"""The four shipped telescopes' field grids on the sky, and the built grids against gwemopt's.

Writes into OUTDIR (default ``benchmarks/results/science/telescopes/``):

* ``telescope_grids.png``: one Mollweide panel per telescope (ZTF, LS4,
  WINTER, DECam): every field centre (coloured inside the description's
  declination band, grey outside), and the camera's detector outlines drawn
  at true size at a few pointings; the site's latitude marked.
* ``grids.txt``: per telescope, the number of fields, the field of view,
  and the fraction of 200 000 random sky positions that fall on a detector
  of some field (``points_seen``: gaps count as missed), all sky and inside
  the declination band.
* with ``--gwemopt DIR`` (a checkout of skyportal/gwemopt: its
  ``gwemopt/data/tesselations/WINTER.tess`` and ``DECam.tess``, read, never
  copied), ``grids.txt`` also gives the same numbers for gwemopt's grids
  seen through the same cameras.

    PYTHONPATH=. .venv/bin/python benchmarks/science/telescope_grids.py [OUTDIR] [--gwemopt DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mushrooms.scheduler_core.instruments import load_description, points_seen, read_field_list  # noqa: E402
from mushrooms.scheduler_core.sky.fields import deproject  # noqa: E402

ORDER = ("ztf", "ls4", "winter", "decam")
COLOURS = {"ztf": "tab:blue", "ls4": "tab:red", "winter": "tab:purple", "decam": "tab:green"}
#: Pointings (RA, Dec; deg) at which the camera outline is drawn.
SHOWN = ((30.0, -60.0), (100.0, 0.0), (170.0, 40.0), (250.0, -25.0), (320.0, 70.0))
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "results" / "science" / "telescopes"


def _sky_x(ra_deg: np.ndarray) -> np.ndarray:
    """Mollweide longitude (rad): RA increasing to the left, 0 h in the middle."""
    return -np.radians((np.asarray(ra_deg) + 180.0) % 360.0 - 180.0)


def _outline(polygon: np.ndarray, ra0: float, dec0: float, per_edge: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A detector's outline on the sky (densified edges), split where it wraps in RA (NaN breaks)."""
    closed = np.vstack([polygon, polygon[:1]])
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
    xy = np.concatenate([a + t[:, None] * (b - a) for a, b in zip(closed[:-1], closed[1:])] + [closed[-1:]])
    ra, dec = deproject(xy[:, 0], xy[:, 1], ra0, dec0)
    x, y = _sky_x(ra), np.radians(dec)
    jumps = np.flatnonzero(np.abs(np.diff(x)) > np.pi)
    return np.insert(x, jumps + 1, np.nan), np.insert(y, jumps + 1, np.nan)


def _sky_panel(ax, d, colour: str) -> None:
    """One telescope's field centres (coloured inside its declination band) and camera outlines."""
    band = (d.grid.dec >= d.limits.dec_min_deg) & (d.grid.dec <= d.limits.dec_max_deg)
    size = max(0.2, min(6.0, 6000.0 / len(d.grid)))
    ax.scatter(_sky_x(d.grid.ra[~band]), np.radians(d.grid.dec[~band]), s=size, c="0.75", lw=0, rasterized=True)
    ax.scatter(_sky_x(d.grid.ra[band]), np.radians(d.grid.dec[band]), s=size, c=colour, lw=0, rasterized=True)
    for ra0, dec0 in SHOWN:
        for poly in d.footprint.polygons:
            ax.plot(*_outline(poly, ra0, dec0), c="k", lw=0.6)
    ax.axhline(np.radians(d.site.latitude_deg), c=colour, lw=0.8, ls="--")
    ax.set_title(f"{d.name.upper()}: {len(d.grid)} fields ({d.grid.origin})\nDec {d.limits.dec_min_deg:g} to "
                 f"{d.limits.dec_max_deg:g} coloured, site latitude {d.site.latitude_deg:+.1f} dashed", fontsize=9)
    ticks = np.radians(np.arange(-150, 151, 30))
    ax.set_xticks(ticks)
    ax.set_xticklabels([f"{round(np.degrees(-t) % 360 / 15):d}h" for t in ticks], fontsize=7)
    ax.tick_params(axis="y", labelsize=7)
    ax.grid(True, lw=0.3)


def _camera_panel(ax, d, colour: str) -> None:
    """The detectors in the pointing's plane, each filter's share shaded, the tiling rectangle dashed."""
    shade = {}
    for f in d.filters.values():
        for k in f.detectors:
            shade.setdefault(k, []).append(f.name)
    for k, poly in enumerate(d.footprint.polygons):
        closed = np.vstack([poly, poly[:1]])
        ax.fill(closed[:, 0], closed[:, 1], color=colour, alpha=0.25 + 0.15 * (len(shade.get(k, "")) % 3))
        ax.plot(closed[:, 0], closed[:, 1], c="k", lw=0.6)
        if k in shade:
            ax.text(*poly.mean(axis=0), "".join(shade[k]), ha="center", va="center", fontsize=6)
    note = d.grid.origin.split(",")[0]
    if note.startswith("declination bands"):
        w, h = (float(v) for v in note.split()[2:5:2])
        ax.plot([-w / 2, -w / 2, w / 2, w / 2, -w / 2], [-h / 2, h / 2, h / 2, -h / 2, -h / 2], "k--", lw=0.8)
    r = d.footprint.radius_deg * 1.05
    ax.set_xlim(-r, r)  # x grows to the west: north up, east on the left, as on the sky
    ax.set_ylim(-r, r)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.set_title(f"{d.name.upper()} camera: {len(d.footprint.polygons)} detectors, {d.field_of_view_deg2:.2f} deg²"
                 + ("\n(tiling rectangle dashed)" if note.startswith("declination") else ""), fontsize=9)
    ax.set_xlabel("x (deg, to the west); y to the north", fontsize=7)


def draw(descs: dict, out: Path) -> None:
    """Four sky panels and, under them, the four cameras."""
    fig = plt.figure(figsize=(14, 11.5))
    grid = fig.add_gridspec(3, 4, height_ratios=[1.0, 1.0, 0.8])
    for k, name in enumerate(ORDER):
        sky = fig.add_subplot(grid[k // 2, 2 * (k % 2):2 * (k % 2) + 2], projection="mollweide")
        _sky_panel(sky, descs[name], COLOURS[name])
        _camera_panel(fig.add_subplot(grid[2, k]), descs[name], COLOURS[name])
    fig.suptitle("Field grids of the shipped telescope descriptions: field centres, and each camera drawn at true "
                 "size at five pointings (top); the cameras in the pointing's plane (bottom)", fontsize=11)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def _seen_fraction(ra: np.ndarray, dec: np.ndarray, polygons: tuple, pra: np.ndarray, pdec: np.ndarray,
                   band: tuple[float, float]) -> tuple[float, float]:
    seen = points_seen(pra, pdec, ra, dec, polygons)
    inside = (pdec >= band[0]) & (pdec <= band[1])
    return float(seen.mean()), float(seen[inside].mean())


def measure(descs: dict, gwemopt: Path | None) -> str:
    """The table of grids.txt."""
    rng = np.random.default_rng(2026)
    pra = rng.uniform(0.0, 360.0, 200_000)
    pdec = np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, 200_000)))
    lines = ["grid                           fields  FoV_deg2  seen_all_sky  seen_in_dec_band  (200000 random positions; "
             "detector gaps count as missed)"]
    rows = [(name, descs[name], descs[name].grid.ra, descs[name].grid.dec, f"{name} (description)") for name in ORDER]
    if gwemopt is not None:
        for name, tess in (("winter", "WINTER.tess"), ("decam", "DECam.tess")):
            _, ra, dec = read_field_list((gwemopt / "gwemopt" / "data" / "tesselations" / tess).read_text())
            rows.append((name, descs[name], ra, dec, f"{name} (gwemopt {tess})"))
    for name, d, ra, dec, label in rows:
        t = time.perf_counter()
        sky, band = _seen_fraction(ra, dec, d.footprint.polygons, pra, pdec, (d.limits.dec_min_deg, d.limits.dec_max_deg))
        lines.append(f"{label:<30} {ra.size:>6}  {d.field_of_view_deg2:>8.2f}  {sky:>12.4f}  {band:>16.4f}  "
                     f"({time.perf_counter() - t:.1f} s)")
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("outdir", nargs="?", type=Path, default=DEFAULT_OUT)
    p.add_argument("--gwemopt", type=Path, help="a checkout of skyportal/gwemopt (its tessellations are read)")
    args = p.parse_args()
    args.outdir.mkdir(parents=True, exist_ok=True)
    descs = {name: load_description(name) for name in ORDER}
    draw(descs, args.outdir / "telescope_grids.png")
    (args.outdir / "grids.txt").write_text(measure(descs, args.gwemopt))
    print((args.outdir / "grids.txt").read_text())


if __name__ == "__main__":
    main()
