"""``mushrooms check PLAN --executed FILE`` for another telescope's plan (issue 53: several telescopes).

An executed record was read with ZTF's filters only (g, r, i): DECam's z
exposures, LS4's z, WINTER's J were skipped, so a re-plan that observes a
field DECam already did in i and z passed the check (P9 unseen).  The record's
filters are now the plan's telescope's (its description's ``filters``); ZTF's
record is read as before (a z line skipped).  The plans are the service's own
(``tests/daemon/data``: MS181101ab with four telescopes) on MS181101ab's map.
"""

from __future__ import annotations

import base64
import json
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "daemon" / "data"
sys.path.insert(0, str(DATA.parent))


@pytest.fixture(scope="module")
def skymap(tmp_path_factory) -> Path:
    from daemon_helpers import notice_bytes

    path = tmp_path_factory.mktemp("map") / "MS181101ab.fits"
    path.write_bytes(base64.b64decode(json.loads(notice_bytes("MS181101ab-preliminary.json"))["event"]["skymap"]))
    return path


def _executed(tmp_path: Path, observations: list[dict]) -> Path:
    path = tmp_path / "executed.jsonl"
    path.write_text("".join(json.dumps({"field_id": o["field_id"], "filter": o["filter"], "start": o["start"],
                                        "exposure_s": o["exposure_s"], "processed_fraction": 1.0,
                                        "status": "processed"}) + "\n" for o in observations))
    return path


def _check(capsys, *args: str) -> tuple[int, str]:
    from mushrooms.tool.check import main

    code = main(list(args))  # the plan's embedded configuration (its telescope)
    return code, capsys.readouterr().out


def test_decams_z_exposures_count_a_field_done_and_planned_again_fails(tmp_path, skymap, capsys, caplog):
    doc = json.loads((DATA / "decam_part_plan.json").read_text())
    first = doc["observations"][0]["field_id"]
    done = [o for o in doc["observations"] if o["field_id"] == first]
    assert sorted(o["filter"] for o in done) == ["i", "z"]
    plan = tmp_path / "decam.json"
    plan.write_text(json.dumps(doc))
    code, out = _check(capsys, str(plan), str(skymap), "--executed", str(_executed(tmp_path, done)))
    assert "not one of g, r, i" not in caplog.text  # z read as DECam's filter, not skipped
    assert code == 1 and f"field {first}" in out and "planned again" in out, out


def test_an_executed_record_of_the_plans_own_filters_passes(tmp_path, skymap, capsys, caplog):
    doc = json.loads((DATA / "decam_part_plan.json").read_text())
    first = doc["observations"][0]["field_id"]
    rest = {**doc, "observations": [o for o in doc["observations"] if o["field_id"] != first]}
    (tmp_path / "rest.json").write_text(json.dumps(rest))
    done = [o for o in doc["observations"] if o["field_id"] == first]
    code, out = _check(capsys, str(tmp_path / "rest.json"), str(skymap), "--executed",
                       str(_executed(tmp_path, done)))
    assert "not one of" not in caplog.text and "planned again" not in out


def test_a_filter_the_telescope_lacks_is_skipped_with_its_filters_named(tmp_path, skymap, capsys, caplog):
    doc = json.loads((DATA / "ls4_part_plan.json").read_text())
    odd = [{**doc["observations"][0], "filter": "J"}]
    code, out = _check(capsys, str(DATA / "ls4_part_plan.json"), str(skymap), "--executed",
                       str(_executed(tmp_path, odd)))
    assert "filter 'J': not one of g, i, z" in caplog.text and code == 0, out


def test_ztfs_record_is_read_as_before(tmp_path):
    from mushrooms.handlers.executed import read_jsonl
    from mushrooms.scheduler_core.executed import ExecutedExposure

    line = {"field_id": 600, "filter": "z", "start": "2025-05-14T04:10:00.000Z", "exposure_s": 300.0,
            "processed_fraction": 1.0, "status": "processed"}
    path = tmp_path / "ztf.jsonl"
    path.write_text(json.dumps(line) + "\n" + json.dumps({**line, "filter": "g"}) + "\n")
    (only,) = read_jsonl(path)  # the z line skipped, as before
    assert only.filter == "g" and type(only) is ExecutedExposure
