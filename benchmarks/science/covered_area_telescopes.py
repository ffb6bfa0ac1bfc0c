"""The covered area of each telescope's fields: pixel centres against a point inside each pixel (issue 53).

For six far-apart fields of LS4, WINTER and DECam (no two footprints meet),
each field's counted area over its covering detectors' area (deg², plane),
at nside 512-4096: with pixel centres (the planner's footprint test) and with
the hashed point inside each pixel (``scheduler_core/sky/covered_area.py``).
Then the area each of the service's part plans (``tests/daemon/data``) says.

    PYTHONPATH=. python benchmarks/science/covered_area_telescopes.py > OUT
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from test_covered_area_telescopes import _covering, _far_apart, _plane_area  # noqa: E402

from mushrooms.scheduler_core.sky.covered_area import area_nside, covered_area_deg2  # noqa: E402
from mushrooms.scheduler_core.sky.fields import Camera, _compute_footprints, telescope_grid  # noqa: E402
from mushrooms.scheduler_core.sky.healpix import hp  # noqa: E402

FILTERS = {"ls4": ("i",), "winter": ("J", "J"), "decam": ("i", "z")}


def _inside_ratio(grid, row: int, camera: Camera, nside: int, area: float) -> float:
    """One field's area with the hashed point inside each pixel, at exactly ``nside``, over ``area``."""
    from mushrooms.scheduler_core.instruments.footprint import inside_polygons
    from mushrooms.scheduler_core.sky.covered_area import sample_points
    from mushrooms.scheduler_core.sky.fields import project

    near = hp.query_disc(nside, hp.ang2vec(grid.ra[row], grid.dec[row], lonlat=True),
                         np.radians(camera.radius_deg), inclusive=True, nest=True)
    ra, dec = sample_points(near, nside)
    x, y = project(ra, dec, grid.ra[row], grid.dec[row])
    return float(inside_polygons(x, y, camera.polygons).sum() * hp.nside2pixarea(nside, degrees=True) / area)


def main() -> None:
    print("telescope nside method    field/area ratio of six far-apart fields (1 = the detectors' area)")
    for name, filters in FILTERS.items():
        telescope, polygons = _covering(name, filters)
        grid, camera, area = telescope_grid(telescope), Camera(polygons, telescope.footprint.radius_deg), \
            _plane_area(polygons)
        fields = _far_apart(telescope, 6)
        decs = [float(grid.dec[grid.index_of(np.array([f]))[0]]) for f in fields]
        print(f"{name}: {len(polygons)} covering detectors, {area:.3f} deg2; fields {fields} at Dec "
              f"{[round(d, 2) for d in decs]}; resolution chosen {area_nside(camera, 64)}")
        for nside in (512, 1024, 2048, 4096):
            rows = grid.index_of(np.array(fields))
            centres = [np.diff(_compute_footprints(grid.select(np.isin(np.arange(len(grid)), [r])), nside,
                                                   camera).indptr)[0] * hp.nside2pixarea(nside, degrees=True) / area
                       for r in rows]
            inside = [_inside_ratio(grid, r, camera, nside, area) for r in rows]
            print(f"  {name:7s} {nside:5d} centres   {np.round(centres, 4).tolist()}")
            print(f"  {name:7s} {nside:5d} inside    {np.round(inside, 4).tolist()}")
    print()
    print("the service's part plans (MS181101ab, nside 64): unique fields, n x detectors' area, union said, time")
    for name, filters in FILTERS.items():
        doc = json.loads((ROOT / "tests" / "daemon" / "data" / f"{name}_part_plan.json").read_text())
        telescope, polygons = _covering(name, tuple(doc["config"]["filters"]))
        grid, camera = telescope_grid(telescope), Camera(polygons, telescope.footprint.radius_deg)
        ids = sorted({o["field_id"] for o in doc["observations"]})
        t0 = time.perf_counter()
        union = covered_area_deg2(grid, ids, camera, doc["config"]["nside"])
        print(f"  {name:7s} {len(ids):4d} fields, {len(ids) * _plane_area(polygons):9.1f} deg2 summed, "
              f"union {union:8.1f} deg2 at nside {area_nside(camera, doc['config']['nside'])}, "
              f"{time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
