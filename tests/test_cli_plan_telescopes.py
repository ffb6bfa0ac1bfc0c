"""Issue 53, phase 2: ``mushrooms plan --telescopes NAME`` plans a described telescope alone, checked by ``mushrooms check``.

Real processes, real sky maps (a southern shared map for LS4, the tests' northern map for WINTER), real
descriptions (``scheduler_core/data/telescopes/``); each observation is checked here against the
description with astropy, not with the planner's geometry.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data"
NORTH = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
#: 91.5 % of its probability south of Dec -30 (the shared map with the most after bns_o3/13, whose probability
#: lies next to the Sun in January: no telescope sees it at night); ZTF covers 7 % of it, LS4 about 40 %
SOUTH = Path("/work/shared/data/skymaps/public/obs-scenarios_sim6_HKL.multiorder.fits")
TELESCOPES = Path(__file__).resolve().parents[1] / "mushrooms" / "scheduler_core" / "data" / "telescopes"


def mushrooms(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True, timeout=900)


def one_error_line(r: subprocess.CompletedProcess) -> str:
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    lines = [line for line in r.stderr.splitlines() if "error" in line]  # (INFO lines say which config)
    assert len(lines) == 1, r.stderr
    return lines[0]


@pytest.fixture(scope="module")
def ls4_plan(tmp_path_factory):
    if not SOUTH.is_file():
        pytest.skip("the shared sky maps are not here")
    out = tmp_path_factory.mktemp("ls4")
    config = out / "config.toml"
    config.write_text('[scheduler]\nnside = 128\n')
    r = mushrooms("plan", str(SOUTH), "--telescopes", "ls4", "--solver", "greedy", "--config", str(config),
                  "-o", str(out / "plan.json"))
    assert r.returncode == 0, r.stderr
    return out, json.loads((out / "plan.json").read_text())


def test_an_ls4_plan_of_a_southern_map_keeps_to_ls4(ls4_plan):
    from astropy import units as u
    from astropy.coordinates import AltAz, EarthLocation, SkyCoord, get_body
    from astropy.time import Time

    from mushrooms.scheduler_core.instruments import load_description

    out, doc = ls4_plan
    ls4 = load_description("ls4")
    obs = doc["observations"]
    assert doc["config"]["telescopes"] == ["ls4"] and doc["telescope"] == "LS4" and len(obs) >= 10
    grid = dict(zip(ls4.grid.ids.tolist(), zip(ls4.grid.ra.tolist(), ls4.grid.dec.tolist())))
    for o in obs:  # LS4's grid, its exposure, its planning filter
        assert o["field_id"] in grid and o["exposure_s"] == ls4.planning.exposure_s == 45.0
        assert o["filter"] in ls4.filters and o["filter"] == "i"
        assert np.allclose((o["ra"], o["dec"]), grid[o["field_id"]], atol=1e-6)
        assert ls4.limits.dec_min_deg <= o["dec"] <= ls4.limits.dec_max_deg
    site = ls4.site
    where = EarthLocation.from_geodetic(site.longitude_deg * u.deg, site.latitude_deg * u.deg, site.height_m * u.m)
    starts = Time([o["start"].rstrip("Z") for o in obs], scale="utc")
    for t in (starts, starts + np.array([o["exposure_s"] for o in obs]) * u.s):
        frame = AltAz(obstime=t, location=where)
        sun = get_body("sun", t, where).transform_to(frame).alt.deg
        assert sun.max() <= ls4.limits.sun_alt_max_deg + 0.3  # La Silla's night
        field = SkyCoord([o["ra"] for o in obs] * u.deg, [o["dec"] for o in obs] * u.deg).transform_to(frame)
        assert (1.0 / np.sin(field.alt.rad)).max() <= ls4.limits.airmass_max * 1.01  # from La Silla
        ha = (t.sidereal_time("apparent", longitude=where.lon).deg - np.array([o["ra"] for o in obs]) + 180) % 360 - 180
        assert np.abs(ha).max() <= 15 * ls4.limits.ha_max_h + 0.5
    assert doc["metrics"]["coverage"] > 0.05  # a southern map ZTF barely sees
    from mushrooms.scheduler_core.plan.schema import validate_document

    validate_document(doc)  # the published format holds another telescope's filters and its name
    assert doc["metrics"].get("coverage_as_executed") is None  # the executor model is ZTF's queue


def test_the_ls4_plan_passes_the_checker(ls4_plan):
    out, _ = ls4_plan
    r = mushrooms("check", str(out / "plan.json"), str(SOUTH))
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_a_tampered_ls4_plan_fails_the_checker(ls4_plan):
    out, doc = ls4_plan
    doc = json.loads(json.dumps(doc))
    doc["observations"][0]["field_id"] = 999_999_999  # not an LS4 field
    bad = out / "tampered.json"
    bad.write_text(json.dumps(doc))
    r = mushrooms("check", str(bad), str(SOUTH))
    assert r.returncode == 1, (r.stdout, r.stderr)


def test_no_ztf_queue_for_a_telescope_without_one(ls4_plan, tmp_path):
    r = mushrooms("plan", str(SOUTH), "--telescopes", "ls4", "--solver", "greedy", "-o", str(tmp_path / "p.json"),
                  "--queue", str(tmp_path / "q.json"))
    line = one_error_line(r)
    assert "--queue" in line and "ls4" in line
    assert not (tmp_path / "p.json").exists()


def test_winter_plans_in_j(tmp_path):
    from mushrooms.scheduler_core.instruments import load_description

    winter = load_description("winter")
    config = tmp_path / "config.toml"  # a 1 deg2 field holds less than ZTF's least gain (0.001) of this map
    config.write_text('[scheduler]\nnside = 128\nmin_gain = 0.0001\nmin_coverage = 0.001\n')
    r = mushrooms("plan", str(NORTH), "--telescopes", "winter", "--solver", "greedy", "--config", str(config),
                  "--start", "2022-07-23T04:00:00Z", "-o", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["observations"], doc.get("metrics")
    ids = set(winter.grid.ids.tolist())
    assert {o["filter"] for o in doc["observations"]} == {"J"}
    assert all(o["field_id"] in ids and o["exposure_s"] == 300.0 for o in doc["observations"])
    r = mushrooms("check", str(tmp_path / "plan.json"), str(NORTH))
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_winter_plans_fields_with_its_own_default_thresholds(tmp_path):
    """(I5) No min_gain/min_coverage in the configuration: WINTER's scaled thresholds plan fields (ZTF's planned none)."""
    config = tmp_path / "config.toml"
    config.write_text('[scheduler]\nnside = 128\n')
    r = mushrooms("plan", str(NORTH), "--telescopes", "winter", "--solver", "greedy", "--config", str(config),
                  "--start", "2022-07-23T04:00:00Z", "-o", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc.get("type") != "not_observable" and len(doc["observations"]) >= 5, doc.get("metrics")
    assert 0.0 < doc["config"]["min_gain"] < 1e-4 and 0.0 < doc["config"]["min_coverage"] < 1e-3
    assert doc["metrics"]["coverage"] >= doc["config"]["min_coverage"]
    r = mushrooms("check", str(tmp_path / "plan.json"), str(NORTH))
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_a_description_with_a_bad_key_is_one_line_and_exit_2(tmp_path):
    text = (TELESCOPES / "ls4.toml").read_text().replace("readout_s = 10.0", "readout = 10.0")
    text = text.replace('name = "ls4"', 'name = "mine"')
    (tmp_path / "mine.toml").write_text(text)
    r = mushrooms("plan", str(NORTH), "--telescopes", str(tmp_path / "mine.toml"), "-o", str(tmp_path / "p.json"))
    line = one_error_line(r)
    assert "mine.toml: [overheads] unknown key 'readout' (did you mean 'readout_s'?)" in line
    assert not (tmp_path / "p.json").exists()


def test_an_unknown_telescope_is_one_line_with_a_guess(tmp_path):
    r = mushrooms("plan", str(NORTH), "--telescopes", "lsst4", "-o", str(tmp_path / "p.json"))
    line = one_error_line(r)
    assert "lsst4" in line and "did you mean 'ls4'" in line
    r = mushrooms("plan", str(NORTH), "--telescopes", "ztf,nope", "-o", str(tmp_path / "p.json"))
    assert "nope" in one_error_line(r)


def test_ztf_by_name_is_todays_plan(tmp_path):
    common = ("--solver", "greedy", "--start", "2022-07-23T02:00:00Z")
    assert mushrooms("plan", str(NORTH), *common, "-o", str(tmp_path / "a.json")).returncode == 0
    assert mushrooms("plan", str(NORTH), *common, "--telescopes", "ztf", "-o", str(tmp_path / "b.json")).returncode == 0
    a, b = (json.loads((tmp_path / n).read_text()) for n in ("a.json", "b.json"))
    assert a["plan_id"] == b["plan_id"] and "telescopes" not in b["config"]
    assert a["observations"] == b["observations"]


def test_several_telescopes_plan_each_alone(tmp_path):
    if not SOUTH.is_file():
        pytest.skip("the shared sky maps are not here")
    config = tmp_path / "config.toml"
    config.write_text('[scheduler]\nnside = 64\n')
    r = mushrooms("plan", str(SOUTH), "--telescopes", "ztf,ls4", "--solver", "greedy", "--config", str(config),
                  "-o", str(tmp_path / "plan.json"), "--targets", str(tmp_path / "targets.json"))
    assert r.returncode == 0, r.stderr
    ztf = json.loads((tmp_path / "plan.json").read_text())
    ls4 = json.loads((tmp_path / "plan.ls4.json").read_text())
    assert "telescopes" not in ztf.get("config", {"telescopes": 0}) or ztf.get("type") == "not_observable"
    assert ls4["config"]["telescopes"] == ["ls4"] and ls4["plan_id"] != ztf.get("plan_id")
    # the target list of each: JSON and CSV, one row per planned exposure, in plan order
    targets = json.loads((tmp_path / "targets.ls4.json").read_text())
    assert targets["telescope"] == "ls4" and targets["plan_id"] == ls4["plan_id"]
    want = [{k: o[k] for k in ("field_id", "ra", "dec", "filter", "exposure_s", "start")} for o in ls4["observations"]]
    assert targets["targets"] == want and want
    lines = (tmp_path / "targets.ls4.csv").read_text().splitlines()
    assert lines[0] == "field_id,ra,dec,filter,exposure_s,start" and len(lines) == len(want) + 1
    first = lines[1].split(",")
    assert int(first[0]) == want[0]["field_id"] and first[3] == "i" and first[5] == want[0]["start"]
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_the_configured_telescopes_are_planned_with_the_shipped_config_beside(tmp_path):
    # the shipped config.toml writes ZTF's defaults out (filters g, r; 300 s): LS4's own stay
    shipped = Path(__file__).resolve().parents[1] / "config.toml"
    text = shipped.read_text().replace('telescopes = ["ztf"]', 'telescopes = ["ls4"]').replace("nside = 256", "nside = 64")
    assert 'telescopes = ["ls4"]' in text
    (tmp_path / "config.toml").write_text(text)
    r = mushrooms("plan", str(SOUTH), "--solver", "greedy", "--config", str(tmp_path / "config.toml"),
                  "-o", str(tmp_path / "plan.json"))
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["config"]["telescopes"] == ["ls4"] and doc["config"]["filters"] == ["i"]
    assert {o["exposure_s"] for o in doc["observations"]} == {45.0}


def test_the_service_refuses_another_telescope_in_one_line(capsys):
    from mushrooms.daemon.service import main
    from mushrooms.tool.config import Config
    from mushrooms.scheduler_core import PlanningConfig

    config = Config(scheduler=PlanningConfig.from_mapping({"telescopes": ["ls4", "ztf"]}))  # (phase 4) ztf first
    assert main(lambda: config) == 2
    err = capsys.readouterr().err
    assert "telescopes = ['ls4', 'ztf']" in err and "plans ZTF first" in err and len(err.splitlines()) == 1


def test_a_reload_to_another_telescope_keeps_the_running_configuration():
    from types import SimpleNamespace

    from mushrooms.daemon.reload import reload_service
    from mushrooms.scheduler_core import PlanningConfig
    from mushrooms.tool.config import Config

    said = []
    running = Config()
    both = Config(scheduler=PlanningConfig.from_mapping({"telescopes": ["ztf", "ls4"]}))  # a valid configuration
    service = SimpleNamespace(
        notifier=SimpleNamespace(reloading=lambda: said.append("reloading"), ready=lambda text: said.append(text)),
        pipeline=SimpleNamespace(sink=object()), config=running, reload_config=lambda: both)
    reload_service(service)
    assert service.config is running and said == ["reloading", "reload failed; old configuration kept"]
