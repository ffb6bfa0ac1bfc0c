"""The sky area a plan's fields cover, on its own telescope's grid and detectors (issue 53: several telescopes).

The summary's "the fields cover N deg²" was read from ZTF's field grid and
16 CCDs for every telescope (an LS4 plan said 11,249 deg²), then left out for
any telescope but ZTF.  It is now the union of the plan's fields' footprints
on the telescope's own grid, counted on the detectors behind its covering
filters (LS4's i quadrants, DECam's CCDs and their gaps, WINTER's), in the
summary, the page, the parts' lines and the webhook's words; ZTF's number is
today's.  The plans are the service's own (``tests/daemon/data``: MS181101ab
planned with four telescopes, nside 64).
"""

from __future__ import annotations

import datetime as dt
import json
import re
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "daemon" / "data"
NOW = dt.datetime(2026, 12, 6, 21, 0, tzinfo=dt.timezone.utc)
ZTF_REVISION = (Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "science" / "telescopes"
                / "instr53" / "ztf_revision_MS181101ab.json")


def _doc(name: str) -> dict:
    return json.loads((DATA / f"{name}_part_plan.json").read_text())


def _covering(name: str, filters: tuple[str, ...]):
    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.instruments.active import covering_polygons

    telescope = load_description(name)
    return telescope, covering_polygons(telescope, filters)


def _plane_area(polygons) -> float:
    return sum(0.5 * abs(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1))))
               for p in polygons)


def _far_apart(telescope, n: int) -> list[int]:
    """``n`` fields of the grid, the nearest to points 50 deg apart on the sky (no two footprints meet)."""
    grid = telescope.grid
    ra, dec = np.radians(grid.ra), np.radians(grid.dec)
    aims = np.radians(np.column_stack([20.0 + 50.0 * np.arange(n), np.where(np.arange(n) % 2, 25.0, -15.0)]))
    cos = (np.sin(dec)[:, None] * np.sin(aims[:, 1])[None] + np.cos(dec)[:, None] * np.cos(aims[:, 1])[None]
           * np.cos(ra[:, None] - aims[:, 0][None]))
    rows = np.argmax(cos, axis=0)
    assert np.degrees(np.arccos(np.clip(cos[rows, np.arange(n)], -1, 1))).max() < 10  # near each aim
    return [int(i) for i in grid.ids[rows]]


def _area_said(text: str) -> float | None:
    found = re.search(r"the fields cover ([\d,.]+) deg²", text)
    return None if found is None else float(found.group(1).replace(",", ""))


@pytest.mark.parametrize("name", ["ls4", "winter", "decam"])
def test_far_apart_fields_cover_n_times_their_own_detectors(name):
    from mushrooms.report.sky import covered_area_deg2

    filters = {"ls4": ("i",), "winter": ("J", "J"), "decam": ("i", "z")}[name]
    telescope, polygons = _covering(name, filters)
    fields = _far_apart(telescope, 6)
    area = covered_area_deg2(fields, 64, name, filters)
    expected = len(fields) * _plane_area(polygons)  # the detectors, their gaps excluded (deg², plane)
    # pixelised outlines and the orthographic plane vs the sphere: within 1.5 % (measured 0.1-0.5 %)
    assert area == pytest.approx(expected, rel=0.015)
    assert covered_area_deg2(fields + fields[:2], 64, name, filters) == area  # a field twice counts once


def test_ls4s_area_is_its_i_quadrants_not_the_whole_camera_nor_ztfs():
    from mushrooms.report.sky import covered_area_deg2

    telescope, polygons = _covering("ls4", ("i",))
    one = covered_area_deg2([_far_apart(telescope, 1)[0]], 64, "ls4", ("i",))
    assert len(polygons) == 16 and one == pytest.approx(_plane_area(polygons), rel=0.015)  # 10.4 deg²
    assert one < 0.6 * telescope.footprint.area_deg2  # the g and z quadrants do not make a field covered


def test_an_ls4_summary_says_the_area_of_its_own_fields():
    from mushrooms.report.summary import summary_text
    from mushrooms.scheduler_core.instruments.footprint import seen_by_pointing
    from mushrooms.scheduler_core.sky.healpix import hp

    doc = _doc("ls4")
    said = _area_said(summary_text(doc, now=NOW))
    assert said is not None
    # an independent count: pixel centres at nside 512 near the fields, tested on every field's i detectors
    telescope, polygons = _covering("ls4", ("i",))
    ids = sorted({o["field_id"] for o in doc["observations"]})
    rows = [int(np.flatnonzero(telescope.grid.ids == f)[0]) for f in ids]
    ra, dec = telescope.grid.ra[rows], telescope.grid.dec[rows]
    seen = []
    for r, d in zip(ra, dec):  # one vectorised step per field: its own disc's pixel centres
        near = hp.query_disc(512, hp.ang2vec(r, d, lonlat=True), np.radians(telescope.footprint.radius_deg))
        pra, pdec = hp.pix2ang(512, near, lonlat=True)
        seen.append(near[seen_by_pointing(pra, pdec, r, d, polygons)])
    hit = np.unique(np.concatenate(seen))
    independent = hit.size * hp.nside2pixarea(512, degrees=True)
    assert said == pytest.approx(independent, rel=0.01)
    assert said < len(ids) * _plane_area(polygons)  # neighbouring fields overlap: the union is smaller
    assert said != pytest.approx(11249, rel=0.05)  # never ZTF's grid read with LS4's field ids


@pytest.mark.parametrize("name", ["ls4", "winter", "decam"])
def test_every_telescopes_summary_and_page_show_its_area(name):
    from mushrooms.report.page import summary_html
    from mushrooms.report.sky import covered_area_deg2
    from mushrooms.report.summary import summary_text

    doc = _doc(name)
    ids = [o["field_id"] for o in doc["observations"]]
    area = covered_area_deg2(ids, doc["config"]["nside"], name, tuple(doc["config"]["filters"]))
    assert area is not None and area > 0
    words = f"the fields cover {area:,.0f} deg²"
    assert words in summary_text(doc, now=NOW)
    assert words in summary_html(doc, now=NOW)


def test_ztfs_area_is_todays():
    from mushrooms.report.summary import summary_text
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.healpix import hp

    doc = json.loads(ZTF_REVISION.read_text())
    ids = sorted({o["field_id"] for o in doc["observations"]})
    nside = doc["config"]["nside"]
    today = field_footprints(load_ztf_fields(), nside).union(ids).size * hp.nside2pixarea(nside, degrees=True)
    text = summary_text(doc, now=NOW)
    assert "Area       11 deg² (50 %), 35 deg² (90 %); the fields cover 1,999 deg²" in text
    assert _area_said(text) == float(f"{today:.0f}")


def test_a_description_files_plan_says_no_area_and_reads_no_file(tmp_path):
    from mushrooms.report.summary import summary_text

    doc = _doc("ls4")
    doc["config"] = {**doc["config"], "telescopes": [str(tmp_path / "ls4.toml")]}  # a file that is not there
    assert "the fields cover" not in summary_text(doc, now=NOW)
    bad = {**_doc("ls4"), "config": {**_doc("ls4")["config"], "filters": ["r"]}}  # a filter LS4 lacks
    assert "the fields cover" not in summary_text(bad, now=NOW)


def _part_row(tmp_path: Path, name: str, queue: str) -> dict:
    folder = tmp_path / name
    folder.mkdir()
    doc = _doc(name)
    (folder / "plan.json").write_text(json.dumps(doc))
    return {"telescope": name, "queue": queue, "state": "exported", "plan_id": doc["plan_id"], "folder": str(folder)}


def test_the_parts_lines_and_webhook_words_say_each_telescopes_area(tmp_path):
    from mushrooms.daemon.planning.parts import parts_lines, parts_words
    from mushrooms.report.sky import covered_area_deg2

    parts = [_part_row(tmp_path, "ls4", "target_list"), _part_row(tmp_path, "winter", "skyportal"),
             {"telescope": "decam", "queue": "target_list", "state": "not_observable", "detail": "south"}]
    areas = {}
    for name in ("ls4", "winter"):
        doc = _doc(name)
        areas[name] = covered_area_deg2([o["field_id"] for o in doc["observations"]], doc["config"]["nside"], name,
                                        tuple(doc["config"]["filters"]))
    lines = "\n".join(parts_lines(parts))
    words = parts_words(parts)
    for name in ("ls4", "winter"):
        assert f"{name} (" in lines and f"fields cover {areas[name]:,.0f} deg²" in lines
        assert re.search(rf"{name} \w+ exported at \w[\w ]* \(fields cover {areas[name]:,.0f} deg²\)", words)
    assert "decam target_list not_observable at Cerro Tololo," in words + ","  # nothing planned: no area
    assert "decam (target_list): not_observable at Cerro Tololo: south" in lines


def test_the_webhook_says_ztfs_area_beside_the_other_telescopes(tmp_path):
    from mushrooms.daemon.ops.announce import NotifyingSink

    class Sink:
        def publish(self, message):
            pass

    class Hook:
        def __init__(self):
            self.said = []

        def post(self, kind, text, details):
            self.said.append(text)

    doc = json.loads(ZTF_REVISION.read_text())
    parts = [_part_row(tmp_path, "ls4", "target_list")]
    hook = Hook()
    NotifyingSink(Sink(), hook, parts=lambda plan_id: parts).publish(doc)
    (text,) = hook.said
    assert "ZTF at Palomar: this plan (fields cover 1,999 deg²); other telescopes: ls4 target_list exported" in text


def test_a_plan_of_every_winter_field_is_counted_coarser_never_hung(monkeypatch):
    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.sky import covered_area
    from mushrooms.scheduler_core.sky.fields import Camera, telescope_grid

    telescope, polygons = _covering("winter", ("J", "J"))
    grid, camera = telescope_grid(load_description("winter")), Camera(polygons, telescope.footprint.radius_deg)
    calls = []
    real = covered_area.hp.query_disc

    def counted(nside, *args, **kwargs):
        calls.append(nside)
        return real(nside, *args, **kwargs)

    monkeypatch.setattr(covered_area.hp, "query_disc", counted)
    covered_area.covered_area_deg2(grid, grid.ids[:3000], camera, 64)
    disc = 2 * np.pi * (1 - np.cos(np.radians(camera.radius_deg)))
    assert len(calls) == 3000 and set(calls) == {1024}  # 2048 for a few fields, 1024 for 3000 (of 46 311)
    assert 3000 * disc / covered_area.hp.nside2pixarea(1024) <= covered_area.MAX_POINTS
    assert 3000 * disc / covered_area.hp.nside2pixarea(2048) > covered_area.MAX_POINTS
