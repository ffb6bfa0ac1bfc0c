"""One event's coordinated ZTF + LS4 plan on the sky, coloured by telescope (issue 53 item 3's picture).

The coordinated plan of ``joint_plan.py`` (``joint_schedule``, nside 128, 2 work s per
telescope, 24 h from the merger) on one shared map; the pixels covered by ZTF only
(blue), by LS4 only (red) and by both (purple) over the probability in greys, the
90 % credible contour, each observed field's centre marked by telescope.  Left the
whole sky (Mollweide), right a zoom on the covered probability.

    nice PYTHONPATH=. .venv/bin/python benchmarks/science/joint_plan_sky.py [MAP]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from joint_plan import SHARED, _described  # noqa: E402

from mushrooms.scheduler_core import read_skymap  # noqa: E402
from mushrooms.scheduler_core.schedulers.joint import joint_metrics, joint_schedule  # noqa: E402
from mushrooms.scheduler_core.schedulers.joint.cells import covered_pixels  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "results/science/joint_plan/joint_plan_sky.png"
MAP = SHARED / "public/G483432_bayestar.multiorder.fits"
#: ZTF blue, LS4 red (benchmarks/science/telescope_grids.py), both purple.
COLOURS = ("tab:blue", "tab:red", "tab:purple")
NSIDE = 128


def plan(path: Path):
    """The map, the two problems and the coordinated schedules."""
    skymap = read_skymap(path, nside=NSIDE)
    problems = _described(skymap, skymap.event_time, NSIDE, 2.0, ("ztf", "ls4"))
    joint = joint_schedule(problems, names=("ztf", "ls4"))
    return skymap, problems, list(joint.schedules), joint


def layers(skymap, problems, schedules) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Probability per deg², the covered-by category (NaN: none; 0 ZTF only, 1 LS4 only, 2 both), 90 % levels."""
    import healpy as hp
    from ligo.skymap.postprocess import find_greedy_credible_levels

    prob = skymap.prob
    masks = []
    for p, s in zip(problems, schedules):
        m = np.zeros(prob.size, bool)
        m[covered_pixels(p, {o.field_id for o in s.observations})] = True
        masks.append(m)
    cat = np.full(prob.size, np.nan)
    cat[masks[0] & ~masks[1]] = 0.0
    cat[masks[1] & ~masks[0]] = 1.0
    cat[masks[0] & masks[1]] = 2.0
    return prob / hp.nside2pixarea(NSIDE, degrees=True), cat, 100.0 * find_greedy_credible_levels(prob)


def _panel(ax, density, cat, levels, problems, schedules, marker_size: float) -> None:
    from matplotlib.colors import ListedColormap

    ax.imshow_hpx((density, "ICRS"), nested=True, cmap="Greys", vmin=0.0, vmax=float(density.max()))
    ax.imshow_hpx((cat, "ICRS"), nested=True, cmap=ListedColormap(COLOURS), vmin=-0.5, vmax=2.5, alpha=0.55)
    ax.contour_hpx((levels, "ICRS"), nested=True, levels=[90.0], colors="black", linewidths=1.2)
    world = ax.get_transform("world")
    for p, s, c, m in zip(problems, schedules, COLOURS, ("s", "D")):
        ids = sorted({o.field_id for o in s.observations})
        rows = np.searchsorted(p.field_ids, ids)
        ax.scatter(p.ra[rows], p.dec[rows], transform=world, s=marker_size, marker=m, facecolor="none",
                   edgecolor=c, linewidths=1.0)
    ax.grid(alpha=0.3)


def zoom_region(prob: np.ndarray, covered: np.ndarray, reach_deg: float = 30.0) -> tuple[float, float, float]:
    """Centre (RA, Dec, deg) and radius (deg) of the zoom: the covered probability near the richest covered pixel."""
    import healpy as hp

    pix = np.flatnonzero(covered)
    vec = np.array(hp.pix2vec(NSIDE, pix, nest=True)).T
    peak = vec[np.argmax(prob[pix])]
    near = np.degrees(np.arccos(np.clip(vec @ peak, -1, 1))) <= reach_deg
    mean = (vec[near] * prob[pix[near], None]).sum(axis=0)
    mean /= np.linalg.norm(mean)
    radius = float(np.degrees(np.arccos(np.clip(vec[near] @ mean, -1, 1))).max()) * 1.1
    ra, dec = hp.vec2ang(mean, lonlat=True)
    return float(ra[0]), float(dec[0]), radius


def draw(path: Path = MAP, out: Path = OUT) -> str:
    """Draw the picture; return its caption line."""
    import ligo.skymap.plot  # noqa: F401  (the astro projections)
    from astropy import units as u
    from astropy.coordinates import SkyCoord
    from matplotlib.patches import Patch

    skymap, problems, schedules, joint = plan(path)
    density, cat, levels = layers(skymap, problems, schedules)
    m = joint_metrics(problems, [{o.field_id for o in s.observations} for s in schedules], skymap.prob)
    fig = plt.figure(figsize=(15, 6.6))
    sky = fig.add_axes([0.02, 0.10, 0.52, 0.76], projection="astro hours mollweide")
    _panel(sky, density, cat, levels, problems, schedules, 6.0)
    import healpy as hp

    ra_c, dec_c, radius = zoom_region(skymap.prob, ~np.isnan(cat))
    centre = SkyCoord(ra_c * u.deg, dec_c * u.deg)
    zoom = fig.add_axes([0.58, 0.08, 0.38, 0.80], projection="astro degrees zoom", center=centre,
                        radius=radius * u.deg)
    _panel(zoom, density, cat, levels, problems, schedules, 30.0)
    for ax in (sky, zoom):
        ax.tick_params(labelsize=8)
    zoom.coords[0].set_axislabel("RA")
    zoom.coords[1].set_axislabel("Dec")
    n = [len({o.field_id for o in s.observations}) for s in schedules]
    handles = [Patch(color=COLOURS[0], alpha=0.6, label=f"ZTF only ({n[0]} fields, g-r pairs, Palomar)"),
               Patch(color=COLOURS[1], alpha=0.6, label=f"LS4 only ({n[1]} fields, one i visit, La Silla)"),
               Patch(color=COLOURS[2], alpha=0.6, label="covered by both"),
               plt.Line2D([], [], color="black", lw=1.2, label="90 % credible region")]
    sky.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.02), ncol=2, fontsize=9, frameon=False)
    title = (f"{path.name}: coordinated ZTF + LS4 plan, 24 h from the merger — union {m.union:.3f} "
             f"(ZTF {m.share[0]:.3f}, LS4 {m.share[1]:.3f}, covered twice {m.more_than_once:.3f}), "
             f"certified bound {joint.bound.value:.3f}")
    fig.suptitle(title + "\nwhole sky (left, probability in greys) and zoom on the richest covered region (right); "
                 "squares ZTF field centres, diamonds LS4's (an LS4 field covers its two i quadrants only: the "
                 "checkerboard)", fontsize=11)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return title


if __name__ == "__main__":
    print(draw(Path(sys.argv[1]) if len(sys.argv) > 1 else MAP))
