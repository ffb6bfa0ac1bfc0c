"""Telescope descriptions: the shipped ones load, a bad one is refused one line per problem, grids cover the sky."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.instruments import (DATA_DIR, QUEUE_KINDS, DescriptionError, declination_band_grid,
                                                  known_telescopes, load_description, parse_description,
                                                  points_seen)
from mushrooms.scheduler_core.instruments import schema
from mushrooms.scheduler_core.instruments.footprint import mosaic_polygons, seen_by_pointing

ROOT = Path(__file__).resolve().parents[2]
ZTF_TEXT = (DATA_DIR / "ztf.toml").read_text()


# --------------------------------------------------------------------------- the shipped descriptions
def test_four_telescopes_are_shipped():
    assert known_telescopes() == ("decam", "ls4", "winter", "ztf")


@pytest.mark.parametrize("name", ["decam", "ls4", "winter", "ztf"])
def test_each_shipped_description_loads_whole(name):
    d = load_description(name)
    assert d.name == name and d.queue in QUEUE_KINDS
    assert len(d.grid) > 1000 and np.unique(d.grid.ids).size == len(d.grid)
    assert ((0 <= d.grid.ra) & (d.grid.ra < 360)).all() and (np.abs(d.grid.dec) <= 90).all()
    assert not d.grid.ids.flags.writeable  # shared by every caller: read-only
    assert d.footprint.polygons and d.footprint.radius_deg > 0
    assert set(d.planning.filters) <= set(d.filters)
    for f in d.filters.values():
        assert all(0 <= k < len(d.footprint.polygons) for k in f.detectors)
    # every value group says where its numbers come from
    groups = [d, d.site, d.grid, d.footprint, d.depth, d.overheads, d.limits, d.planning, d.execution,
              *d.filters.values()]
    assert all(g.source.strip() for g in groups)
    assert abs(d.site.location.lat.deg - d.site.latitude_deg) < 1e-9
    assert load_description(name) is d  # read once


def test_the_published_numbers_are_the_descriptions():
    ls4, decam, winter = load_description("ls4"), load_description("decam"), load_description("winter")
    # LS4 (Miller et al. 2025): 32 CCDs, ~20 deg2, g/i/z 21.5/20.9/20.3 in 45 s, two quadrants i
    assert len(ls4.footprint.polygons) == 32 and ls4.field_of_view_deg2 == pytest.approx(20.7, abs=0.1)
    assert ls4.depth.reference_exposure_s == 45.0
    assert {k: f.zenith_depth for k, f in ls4.filters.items()} == {"g": 21.5, "i": 20.9, "z": 20.3}
    assert [len(f.detectors) for f in ls4.filters.values()] == [8, 16, 8]
    assert sorted(sum((f.detectors for f in ls4.filters.values()), ())) == list(range(32))
    assert ls4.overheads.filter_change_s == 0.0 and ls4.site.latitude_deg < -29
    # DECam: 62 CCDs, ~2.8 deg2 of silicon; WINTER: one square degree in J
    assert len(decam.footprint.polygons) == 62 and decam.field_of_view_deg2 == pytest.approx(2.78, abs=0.02)
    assert list(winter.filters) == ["J"] and winter.queue == "skyportal"


# --------------------------------------------------------------------------- bad descriptions
def _load(tmp_path: Path, text: str, name: str = "ztf") -> DescriptionError:
    """Write a description (its data files by absolute path) and return the error loading it raises."""
    text = text.replace('"../ZTF_Fields.txt"', repr(str(DATA_DIR.parent / "ZTF_Fields.txt")).replace("'", '"'))
    text = text.replace('"../ztf_ccd_layout.tbl"', repr(str(DATA_DIR.parent / "ztf_ccd_layout.tbl")).replace("'", '"'))
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    with pytest.raises(DescriptionError) as err:
        load_description(path)
    assert isinstance(err.value, InputError)  # the tools answer it with exit status 2
    return err.value


def test_a_copy_of_ztf_toml_elsewhere_loads(tmp_path):
    path = tmp_path / "ztf.toml"
    path.write_text(ZTF_TEXT.replace('"../', f'"{DATA_DIR.parent}/'))
    assert len(load_description(path).grid) == 1778


def test_an_unknown_key_says_which_key_was_meant(tmp_path):
    err = _load(tmp_path, ZTF_TEXT.replace("readout_s = 8.0", "readout = 8.0"))
    assert err.problems == ("ztf.toml: [overheads] unknown key 'readout' (did you mean 'readout_s'?)",
                            "ztf.toml: [overheads] missing key 'readout_s' (detector readout, during the slew, s)")


def test_a_wrong_type(tmp_path):
    err = _load(tmp_path, ZTF_TEXT.replace("height_m = 1707.0", 'height_m = "high"'))
    assert err.problems == ("ztf.toml: [site] height_m = 'high': expected a number, got a string",)


@pytest.mark.parametrize("old, new, line", [
    ("latitude_deg = 33.35728", "latitude_deg = 133.35728",
     "ztf.toml: [site] latitude_deg = 133.357: outside its range [-90, 90] deg"),
    ("airmass_max = 2.5", "airmass_max = nan", "ztf.toml: [limits] airmass_max = nan: not a number (nan)"),
    ("readout_s = 8.0", "readout_s = inf", "ztf.toml: [overheads] readout_s = inf: not finite; range [0, 3600] s"),
    ('queue = "ztf_too"', 'queue = "kowalski"',
     "ztf.toml: queue = 'kowalski': must be one of ztf_too, skyportal, target_list"),
    ("vmax_deg_s = 2.5", "vmax_deg_s = 0.0",
     "ztf.toml: [overheads.axes.0] vmax_deg_s = 0: outside its range (0, 100] deg/s"),
    ("ha_max_deg = -17.6", "ha_max_deg = -317.6",
     "ztf.toml: [limits.keep_out.0] ha_max_deg = -317.6: outside its range [-180, 180] deg"),
])
def test_a_value_out_of_its_range(tmp_path, old, new, line):
    assert _load(tmp_path, ZTF_TEXT.replace(old, new, 1)).problems == (line,)


def test_a_missing_file_and_a_missing_key(tmp_path):
    text = ZTF_TEXT.replace('file = "../ZTF_Fields.txt"', 'file = "nope.txt"').replace("extinction = 0.17\n", "")
    assert _load(tmp_path, text).problems == (
        "ztf.toml: [grid] file = 'nope.txt': no such file",
        "ztf.toml: [filters.g] missing key 'extinction' (k_b, extinction per airmass (D1), mag)")


def test_every_problem_at_once_one_line_each(tmp_path):
    text = (ZTF_TEXT.replace("format = 1", "format = 2").replace("settle_s = 1.0", "settle_s = -1.0")
            .replace('filters = ["g", "r"]', 'filters = ["g", "y"]').replace("dec_min_deg = -31.0", "dec_min_deg = 88.0")
            + "\n[extras]\nx = 1\n")
    problems = _load(tmp_path, text).problems
    assert problems == (
        "ztf.toml: format = 2: outside its range [1, 1]",
        "ztf.toml: unknown key 'extras' (known: format, name, title, queue, source, site, grid, footprint, filters, "
        "depth, overheads, limits, planning, execution)",
        "ztf.toml: [overheads] settle_s = -1: outside its range [0, 600] s",
        "ztf.toml: [limits] dec_min_deg (88) must be less than dec_max_deg (87.5)",
        "ztf.toml: [planning] filters = ['g', 'y']: 1 or more of this telescope's filters (g, r, i)")
    assert all("\n" not in p for p in problems)


@pytest.mark.parametrize("edit, line", [
    (lambda t: t.replace('name = "ztf"', 'name = "P48"'),
     "ztf.toml: name = 'P48': lower-case letters, digits, - and _, the file's stem ('ztf')"),
    (lambda t: t.replace('file = "../ztf_ccd_layout.tbl"', 'file = "../ztf_ccd_layout.tbl"\nmosaic_rows = [1]'),
     "ztf.toml: [footprint] needs exactly one of file, polygons or mosaic_rows (with detector_width_deg, "
     "detector_height_deg, gap_x_deg, gap_y_deg)"),
    (lambda t: t.replace("survey_step_s = 38.0\n", 'survey_step_s = 38.0\nformats = ["csv"]\n'),
     "ztf.toml: [execution] formats is not for queue = 'ztf_too' (it takes survey_step_s, lost_pointing_slew_s, "
     "default_max_airmass, program_ids)"),
    (lambda t: t.replace("reference_fwhm_arcsec = 2.39\n", ""),
     "ztf.toml: [filters.g] reference_depth and reference_fwhm_arcsec go together (D2)"),
    (lambda t: t.replace("queue_id = 1\n", "queue_id = 1\ndetectors = [16]\n"),
     "ztf.toml: [filters.g] detectors: the footprint has 16 detectors (0 to 15)"),
    (lambda t: t.replace("ha_max_deg = -17.6", "ha_max_deg = -inf", 1),
     "ztf.toml: [limits.keep_out.0] needs ha_min_deg < ha_max_deg and dec_min_deg < dec_max_deg"),
    (lambda t: t.replace('night_anchor_utc = "2000-01-01T19:47:26.4"', 'night_anchor_utc = "noon"'),
     "ztf.toml: [site] night_anchor_utc = 'noon': not an ISO UTC time (2000-01-01T19:47:26.4)"),
])
def test_values_that_contradict_each_other(tmp_path, edit, line):
    assert _load(tmp_path, edit(ZTF_TEXT)).problems == (line,)


def test_not_toml_and_unknown_names(tmp_path):
    assert _load(tmp_path, "name = \n").problems[0].startswith("ztf.toml: not TOML: ")
    with pytest.raises(DescriptionError) as err:
        load_description("ztff")
    assert str(err.value) == "unknown telescope 'ztff' (known: decam, ls4, winter, ztf); did you mean 'ztf'?"
    with pytest.raises(DescriptionError, match="no such description file"):
        load_description(tmp_path / "missing.toml")


def test_a_hostile_grid_file_is_named_by_line_never_shown(tmp_path):
    secret = "token=s3cr3t-abcdef"
    grid = tmp_path / "grid.txt"
    grid.write_text("1 10.0 20.0\n2 11.0 21.0\n" + secret + " 1 2\n")
    text = ZTF_TEXT.replace('file = "../ZTF_Fields.txt"', f'file = "{grid}"')
    err = _load(tmp_path, text)
    assert len(err.problems) == 1 and err.problems[0].endswith(": line 3: expected a field id, RA and Dec (deg)")
    assert secret not in str(err)
    grid.write_text("1 10.0 20.0\n1 11.0 21.0\n")
    assert _load(tmp_path, text).problems[0].endswith("a field id is repeated")
    grid.write_text("1 400.0 20.0\n")
    assert "line 1: id must be a whole number" in _load(tmp_path, text).problems[0]


def test_a_huge_description_is_refused_unread(tmp_path):
    path = tmp_path / "ztf.toml"
    path.write_text(ZTF_TEXT + "#" * (1 << 20))
    with pytest.raises(DescriptionError, match="larger than 1048576 bytes"):
        load_description(path)


def test_a_grid_or_camera_too_big_is_refused_before_it_is_built(tmp_path):
    ls4 = (DATA_DIR / "ls4.toml").read_text()
    err = _load(tmp_path, ls4.replace("width_deg = 4.55", "width_deg = 0.0001"), name="ls4")
    assert err.problems == ("ls4.toml: [grid] a 0.0001 x 4.55 deg field would need more than 200000 fields",)
    err = _load(tmp_path, ls4.replace("mosaic_rows = [8, 8, 8, 8]", "mosaic_rows = [" + "100, " * 20 + "]"),
                name="ls4")
    assert err.problems == ("ls4.toml: [footprint] mosaic_rows needs detector_width_deg and detector_height_deg, "
                            "and at most 1000 detectors",)


def test_a_loaded_description_cannot_be_changed():
    d = load_description("ztf")  # shared by every caller of load_description
    with pytest.raises(TypeError):
        d.filters["u"] = d.filters["g"]
    with pytest.raises(TypeError):
        d.execution.program_ids["Mine"] = 9
    with pytest.raises(ValueError):
        d.footprint.polygons[0][0, 0] = 1.0


def test_parse_description_alone():
    d = parse_description(ZTF_TEXT, DATA_DIR / "ztf.toml")
    assert d.name == "ztf" and len(d.grid) == 1778


# --------------------------------------------------------------------------- built grids (I1-I2)
def _uniform_sphere(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, 360.0, n), np.degrees(np.arcsin(rng.uniform(-1.0, 1.0, n)))


def _rectangle(w: float, h: float) -> tuple[np.ndarray, ...]:
    return (np.array([[-w / 2, -h / 2], [-w / 2, h / 2], [w / 2, h / 2], [w / 2, -h / 2]]),)


@pytest.mark.parametrize("w, h, f", [(4.55, 4.55, 0.1), (1.0, 1.0, 0.05), (1.54, 1.30, 0.05), (6.9, 6.9, 0.0),
                                     (0.8, 2.5, 0.3), (40.0, 25.0, 0.2)])
def test_a_built_grid_covers_the_whole_sphere(w, h, f):
    _, ra, dec = declination_band_grid(w, h, f)
    pra, pdec = _uniform_sphere(100_000, seed=int(w * 100))
    # and the awkward places: the poles, the equator, the edges of the polar caps
    pra = np.concatenate([pra, np.linspace(0, 360, 721)[:-1].repeat(5)])
    pdec = np.concatenate([pdec, np.tile([-90.0, -89.99, 0.0, 89.99, 90.0], 720)])
    seen = points_seen(pra, pdec, ra, dec, _rectangle(w, h))
    assert seen.all(), f"{(~seen).sum()} points outside every field"


def test_the_coverage_test_finds_holes():
    # the same grid seen through a smaller field: some points fall between fields
    _, ra, dec = declination_band_grid(4.55, 4.55, 0.0)
    pra, pdec = _uniform_sphere(50_000, seed=7)
    assert not points_seen(pra, pdec, ra, dec, _rectangle(4.0, 4.0)).all()


def test_neighbours_in_a_band_overlap_by_the_asked_fraction():
    w = 4.55
    _, ra, dec = declination_band_grid(w, w, 0.1)
    on_band = np.isclose(dec, dec[np.argmin(np.abs(dec))])  # the band nearest the equator
    step = np.diff(np.sort(ra[on_band])).max()
    assert step * np.cos(np.radians(np.abs(dec[on_band]).min() + w / 2)) <= w * 0.9 + 1e-9


def test_the_shipped_built_grids_are_covered_by_their_cameras():
    # LS4's and WINTER's cameras are their tiling rectangles: every point falls on a detector
    for name in ("ls4", "winter"):
        d = load_description(name)
        pra, pdec = _uniform_sphere(50_000, seed=11)
        assert points_seen(pra, pdec, d.grid.ra, d.grid.dec, d.footprint.polygons).all(), name


def test_a_mosaic_is_its_rows_of_detectors():
    polys = mosaic_polygons([3, 4], 1.0, 0.5, 0.1, 0.2)
    centres = np.array([p.mean(axis=0) for p in polys])
    assert np.allclose(centres[:3], [[-1.1, 0.35], [0.0, 0.35], [1.1, 0.35]])
    assert np.allclose(centres[3:, 1], -0.35) and np.allclose(centres[3:, 0], [-1.65, -0.55, 0.55, 1.65])
    # a point in a gap is seen by no detector; one on a detector is
    assert not seen_by_pointing(0.0, 0.0, 0.0, 0.0, polys)  # the gap between the rows
    assert seen_by_pointing(0.0, 0.35, 0.0, 0.0, polys)  # the middle detector of the north row, dec 0.35


# --------------------------------------------------------------------------- the format's document
def test_the_design_note_lists_every_key():
    note = (ROOT / "docs" / "design" / "telescopes.md").read_text()
    rows = set(re.findall(r"^\| `([a-z0-9_]+)` \|", note, re.MULTILINE))
    declared = {key for table in schema.TABLES.values() for key in table}
    assert declared <= rows, f"keys missing from docs/design/telescopes.md: {sorted(declared - rows)}"
