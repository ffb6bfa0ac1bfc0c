"""``mushrooms telescopes``: the known telescopes, one in full, JSON, and a bad description as bad input."""

from __future__ import annotations

import json

from mushrooms.cli import TOOLS, main


def test_the_tool_is_registered():
    assert "telescopes" in TOOLS  # and so tests/test_cli_tools.py runs its --help


def test_the_listing_names_every_telescope_with_its_numbers(capsys):
    assert main(["telescopes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:2] == ["name", "site"] and lines[0].rstrip().endswith("source")
    rows = {line.split()[0]: line for line in lines[1:]}
    assert sorted(rows) == ["decam", "ls4", "winter", "ztf"]
    assert "+33.3573, -116.8599; 1707" in rows["ztf"] and " 47.70 " in rows["ztf"] and " 1778 " in rows["ztf"]
    assert " g r i " in rows["ztf"] and " ztf_too " in rows["ztf"]
    assert " 20.71 " in rows["ls4"] and " g i z " in rows["ls4"] and " target_list " in rows["ls4"]
    assert "arXiv:2503.14579" in rows["ls4"]  # the source
    assert " skyportal " in rows["winter"] and " J " in rows["winter"]


def test_the_listing_as_json(capsys):
    assert main(["telescopes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == ["decam", "ls4", "winter", "ztf"]
    ztf = rows[-1]
    assert ztf["fields"] == 1778 and ztf["filters"] == ["g", "r", "i"] and ztf["queue"] == "ztf_too"
    assert ztf["site"] == {"latitude_deg": 33.35728, "longitude_deg": -116.85986, "height_m": 1707.0}
    assert set(ztf) == {"name", "title", "site", "field_of_view_deg2", "fields", "filters", "queue", "source"}


def test_one_telescope_in_full(capsys):
    assert main(["telescopes", "ztf"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("ztf: Zwicky Transient Facility")
    for text in ("site: 33.35728, -116.85986 deg, 1707 m; night anchor 2000-01-01T19:47:26.4 UTC",
                 "grid: 1778 fields (file ZTF_Fields.txt)", "footprint: 16 detectors, 47.70 deg2",
                 "overheads: readout 8 s, settle 1 s, filter change 135 s (before the slew); axes: ha 0.4 deg/s2, "
                 "2.5 deg/s; dec 0.5 deg/s2, 3 deg/s; dome_azimuth 0.5 deg/s2, 3 deg/s",
                 "keep out -17.6 < HA < inf, -inf < Dec < -45 deg", "planning: 300 s exposures",
                 "execution: ZTF ToO queue"):
        assert text in out
    assert out.count("  source: ") >= 10  # every group with its source


def test_one_telescope_as_json(capsys):
    assert main(["telescopes", "ls4", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["grid"]["fields"] == 2568 and len(doc["footprint"]["polygons"]) == 32
    assert doc["filters"]["i"]["zenith_depth"] == 20.9 and doc["depth"]["reference_exposure_s"] == 45.0
    assert doc["execution"]["formats"] == ["json", "csv"]
    assert main(["telescopes", "ztf", "--json"]) == 0
    ztf = json.loads(capsys.readouterr().out)  # infinite keep-out bounds as strings: JSON has no infinity
    assert ztf["limits"]["keep_out"][0]["ha_min_deg"] == "-inf"


def test_an_unknown_name_is_bad_input(capsys):
    assert main(["telescopes", "ztff"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["mushrooms telescopes: error: unknown telescope 'ztff' (known: decam, ls4, winter, ztf); "
                   "did you mean 'ztf'?"]


def test_a_bad_description_file_one_line_per_problem(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text('format = 1\nname = "mine"\ntitle = "x"\nqueue = "fax"\nsource = "here"\n')
    assert main(["telescopes", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == "mushrooms telescopes: error: mine.toml: queue = 'fax': must be one of ztf_too, skyportal, target_list"
    assert err[1:] == [f"mushrooms telescopes: error: mine.toml: missing key {k!r} ({what})" for k, what in (
        ("site", "where the telescope is"), ("grid", "the fixed field grid"),
        ("footprint", "the detectors about the pointing"),
        ("filters", "one table per filter: the depth model's terms"),
        ("depth", "depth-model terms shared by the filters"),
        ("overheads", "readout, settle, filter change and slew axes"), ("limits", "pointing limits"),
        ("planning", "a plan's defaults for this telescope"),
        ("execution", "how the queue is executed and exported"))]
    assert "Traceback" not in capsys.readouterr().err
