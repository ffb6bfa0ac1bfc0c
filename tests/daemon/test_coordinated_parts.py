"""The service's parts are coordinated with ZTF's published revision (issue 53 items 2 and 4).

The daemon's own wiring (``open_pipeline``: real SQLite, a directory outbox,
greedy at nside 64, real HiGHS for the joint bound) on MS230425l's map, which
ZTF and LS4 both see: every other telescope is planned on the sky ZTF's published
revision leaves (the iterative tiling with ZTF held fixed), the joint document
is in the outbox beside the parts, a later ZTF revision re-plans the parts and
supersedes the earlier ones, a southern event ZTF cannot observe still gives
LS4 its plan, a restart after a kill holds the recorded parts fixed, and a
ZTF-only service publishes exactly main's documents.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from coordinated_setup import footprint, joint_file, notice_skymap, southern_notice, union_and_twice
from telescope_parts_setup import SID, part, part_folders, part_rows, parts_config

#: MS230425l's PRELIMINARY renamed MS181101ab (the helpers' event), its GW map only: a map ZTF and LS4 both see (ZTF 0.32, LS4 0.46
#: alone at nside 64, 0.08 of it covered by both when each plans alone)
PRELIMINARY = "MS230425l-preliminary.json"


def notice_bytes(name: str) -> bytes:
    from coordinated_setup import gw_only

    from daemon_helpers import notice_bytes as read

    return gw_only(read(name, SID)) if name == PRELIMINARY else read(name)
#: ZTF's revision of :data:`PRELIMINARY` with ZTF alone (``directory_outbox_config``), as main (23450c2) plans it.
MAIN_ZTF_PLAN_ID = "mushrooms-a06a97c231b37049"


def _pipeline(tmp_path: Path, telescopes: list[str], min_coverage: float = 0.0, solver: str = "greedy", **kw):
    from mushrooms.daemon.settings import resolve_paths
    from mushrooms.daemon.wiring import open_pipeline
    from mushrooms.tool.config import load_config

    cfg = parts_config(tmp_path, telescopes)
    text = cfg.read_text().replace("min_coverage = 0.0", f"min_coverage = {min_coverage!r}")
    text = text.replace('solver = "greedy"', f"solver = {solver!r}".replace("'", '"'), 1)
    cfg.write_text(text.replace("[policy]\n", '[policy]\nplan_start = "created"\n', 1))  # the same start every run
    config = load_config(str(cfg))
    return open_pipeline(config, resolve_paths(config.daemon), **kw)


def _run(tmp_path: Path, telescopes: list[str], notices: list[bytes], **kw) -> list:
    pipeline, close = _pipeline(tmp_path, telescopes, **kw)
    try:
        return [pipeline.handle(raw, "test:coordinated") for raw in notices]
    finally:
        close()


def _ztf_docs(outbox: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(outbox.glob("mushrooms-*.json"))]


def _plan(folder: Path) -> dict:
    return json.loads((folder / "plan.json").read_text())


def _alone(tmp_path: Path, telescopes: list[str], raw: bytes, start: str) -> dict[str, dict]:
    """Each other telescope's plan alone (today's main: ``plan_alone``), as documents."""
    from astropy.time import Time

    from mushrooms.daemon.planning.parts import TelescopeParts
    from mushrooms.handlers.telescope_plans import plan_alone
    from mushrooms.tool.config import load_config

    (tmp_path / "alone").mkdir(exist_ok=True)
    parts = TelescopeParts.from_config(load_config(str(parts_config(tmp_path / "alone", telescopes))))
    skymap = notice_skymap(raw)
    return {t.name: plan_alone(skymap, t, c, Time(start.rstrip("Z"), scale="utc")).to_document()
            for t, c in parts.runs}


def test_ls4_part_avoids_what_ztfs_revision_covers_and_the_joint_document_is_beside_it(tmp_path, capsys):
    raw = notice_bytes(PRELIMINARY)
    (out,) = _run(tmp_path, ["ztf", "ls4"], [raw])
    outbox = tmp_path / "outbox"
    (ztf,) = _ztf_docs(outbox)
    ls4 = part_folders(outbox)[("00001-PRELIMINARY", "ls4")]
    coordinated, doc = _plan(ls4), part(ls4)
    assert doc["state"] == "exported" and coordinated["observations"]
    alone = _alone(tmp_path, ["ztf", "ls4"], raw, ztf["start"])["ls4"]
    prob = notice_skymap(raw).prob
    union_alone, twice_alone = union_and_twice(prob, [ztf, alone])
    union, twice = union_and_twice(prob, [ztf, coordinated])
    print(f"alone: union {union_alone:.4f} twice {twice_alone:.4f}; coordinated: union {union:.4f} twice {twice:.4f}")
    assert twice < 0.7 * twice_alone and twice_alone > 0.03  # LS4 leaves to ZTF what ZTF's revision covers
    assert union >= union_alone - 0.002
    # the part says what it was coordinated with, and carries the joint metrics
    assert doc["coordinated_with"]["ztf_plan_id"] == ztf["plan_id"] == out.plan_id
    joint = json.loads(joint_file(outbox, "00001-PRELIMINARY").read_text())
    assert joint["type"] == "joint_plan" and joint["telescopes"] == ["ztf", "ls4"]
    assert [p["plan_id"] for p in joint["plans"]] == [ztf["plan_id"], coordinated["plan_id"]]
    assert abs(joint["metrics"]["more_than_once"] - twice) < 0.01 and abs(joint["metrics"]["union"] - union) < 0.01
    assert joint["metrics"]["union"] <= joint["metrics"]["upper_bound"]
    assert doc["joint"]["union"] == joint["metrics"]["union"]
    assert doc["joint"]["more_than_once"] == joint["metrics"]["more_than_once"]
    assert doc["joint"]["share"] == joint["metrics"]["share"]
    # mushrooms check reads the joint document: every part, and the joint metrics under the bound
    import base64

    from mushrooms.cli import main

    skymap = tmp_path / "map.fits"
    skymap.write_bytes(base64.b64decode(json.loads(raw)["event"]["skymap"]))
    capsys.readouterr()
    status = main(["check", str(joint_file(outbox, "00001-PRELIMINARY")), str(skymap)])
    said = capsys.readouterr().out
    assert status == 0 and "OK: joint plan of ztf, ls4" in said, said


def _halved_first_plan(real):
    """A scheduler whose fast plan keeps the first half of greedy's fields and whose optimised plan is greedy's:
    ZTF's revision 2 then covers more than revision 1, whatever the machine (no time-limited solve)."""
    from mushrooms.scheduler_core.anytime import FIRST_SOLVER

    def scheduler(problem, solver, should_stop=None):
        result = real(problem, FIRST_SOLVER, should_stop)
        if solver != FIRST_SOLVER:
            return result
        fields = list(dict.fromkeys(o.field_id for o in result.observations))
        keep = set(fields[: max(1, len(fields) // 2)])
        import dataclasses

        return dataclasses.replace(result, observations=tuple(o for o in result.observations if o.field_id in keep))

    return scheduler


def test_ztfs_second_revision_replans_the_parts_and_supersedes_the_first(tmp_path):
    from mushrooms.scheduler_core.planner import run_scheduler

    tmp = tmp_path
    (out,) = _run(tmp, ["ztf", "ls4"], [notice_bytes(PRELIMINARY)], solver="slots",
                  planner=_halved_first_plan(run_scheduler))
    outbox = tmp / "outbox"
    docs = _ztf_docs(outbox)
    assert out.revision == 2 and len({d["plan_id"] for d in docs}) == 2
    second = next(d for d in docs if d["plan_id"] == out.plan_id)
    first = next(d for d in docs if d["plan_id"] != out.plan_id)
    folders = part_folders(outbox)
    old, new = folders[("00001-PRELIMINARY", "ls4")], folders[("00001-PRELIMINARY-round2", "ls4")]
    assert part(old)["state"] == "superseded" and (old / "SUPERSEDED").is_file()
    assert part(old)["coordinated_with"]["ztf_plan_id"] == first["plan_id"]
    assert part(new)["state"] == "exported" and not (new / "SUPERSEDED").exists()
    assert part(new)["coordinated_with"]["ztf_plan_id"] == second["plan_id"]
    assert part(new)["plan_id"] != part(old)["plan_id"]
    for folder, ztf in (("00001-PRELIMINARY", first), ("00001-PRELIMINARY-round2", second)):
        joint = json.loads(joint_file(outbox, folder).read_text())
        assert joint["plans"][0]["plan_id"] == ztf["plan_id"]
    assert part_rows(tmp / "state.sqlite") == [(1, "ls4", "exported", part(new)["plan_id"])]
    # LS4's second part leaves ZTF's larger revision 2 alone as much as the first left revision 1
    prob = notice_skymap(notice_bytes(PRELIMINARY)).prob
    assert union_and_twice(prob, [second, _plan(new)])[1] <= union_and_twice(prob, [second, _plan(old)])[1]


def test_a_southern_event_ztf_cannot_observe_still_gives_ls4_its_plan(tmp_path):
    raw = southern_notice()
    (out,) = _run(tmp_path, ["ztf", "ls4"], [raw], min_coverage=0.001)
    outbox = tmp_path / "outbox"
    (ztf,) = [json.loads(p.read_text()) for p in outbox.glob("*.json") if json.loads(p.read_text()).get(
        "plan_id") == out.plan_id]
    assert ztf["type"] == "not_observable"
    ls4 = part_folders(outbox)[("00001-PRELIMINARY", "ls4")]
    assert part(ls4)["state"] == "exported"
    alone = _alone(tmp_path, ["ztf", "ls4"], raw, _plan(ls4)["start"])["ls4"]
    # planned as if ZTF covered nothing: LS4's fields are its plan alone
    assert [o["field_id"] for o in _plan(ls4)["observations"]] == [o["field_id"] for o in alone["observations"]]
    joint = json.loads(joint_file(outbox, "00001-PRELIMINARY").read_text())
    assert joint["telescopes"] == ["ls4"] and joint["not_planned"] == {"ztf": "not_observable"}
    assert joint["metrics"]["more_than_once"] == 0.0 and joint["metrics"]["union"] > 0.1


def _second_ls4(tmp_path: Path) -> Path:
    """LS4's description as a second telescope ``ls4b`` at the same site."""
    from telescope_parts_setup import SHIPPED

    path = tmp_path / "ls4b.toml"
    path.write_text((SHIPPED / "ls4.toml").read_text().replace('name = "ls4"', 'name = "ls4b"'))
    return path


def test_a_restart_holds_the_recorded_parts_fixed_and_ends_as_an_uninterrupted_run(tmp_path, monkeypatch):
    from mushrooms.daemon.planning.parts import TelescopeParts

    raw = notice_bytes(PRELIMINARY)
    telescopes = ["ztf", "ls4", str(_second_ls4(tmp_path))]  # a second LS4: it competes for LS4's sky
    whole = tmp_path / "whole"
    whole.mkdir()
    _run(whole, telescopes, [raw])

    class Killed(BaseException):
        """Stands for SIGKILL right after ls4's part is recorded (the slow kill -9 test does it for real)."""

    real = TelescopeParts._export

    def export(self, store, job, telescope, plan, *args, **kw):
        state = real(self, store, job, telescope, plan, *args, **kw)
        if telescope.name == "ls4":
            raise Killed
        return state

    cut = tmp_path / "cut"
    cut.mkdir()
    monkeypatch.setattr(TelescopeParts, "_export", export)
    with pytest.raises(Killed):
        _run(cut, telescopes, [raw])
    monkeypatch.setattr(TelescopeParts, "_export", real)
    assert [r[1] for r in part_rows(cut / "state.sqlite")] == ["ls4"]
    ls4 = part_folders(cut / "outbox")[("00001-PRELIMINARY", "ls4")]
    before = {p.name: p.read_bytes() for p in ls4.iterdir()}
    pipeline, close = _pipeline(cut, telescopes)
    try:
        (out,) = pipeline.resume()
    finally:
        close()
    assert out.decision == "plan"
    assert {p.name: p.read_bytes() for p in ls4.iterdir()} == before  # recorded: not rewritten
    for name in ("ls4", "ls4b"):
        a = _plan(part_folders(whole / "outbox")[("00001-PRELIMINARY", name)])
        b = _plan(part_folders(cut / "outbox")[("00001-PRELIMINARY", name)])
        assert (a["plan_id"], a["observations"]) == (b["plan_id"], b["observations"])
    ja, jb = (json.loads(joint_file(d / "outbox", "00001-PRELIMINARY").read_text()) for d in (whole, cut))
    assert ja["plan_id"] == jb["plan_id"] and ja["metrics"] == jb["metrics"]


def test_the_default_configuration_publishes_mains_ztf_documents(tmp_path):
    """ZTF alone (the default): no part, no joint document, main's plan; with LS4 added ZTF's revision is the same."""
    raw = notice_bytes(PRELIMINARY)
    alone, both = tmp_path / "alone", tmp_path / "both"
    alone.mkdir(), both.mkdir()
    (a,) = _run(alone, ["ztf"], [raw])
    (b,) = _run(both, ["ztf", "ls4"], [raw])
    assert not (alone / "outbox" / "telescopes").exists() and part_rows(alone / "state.sqlite") == []
    assert a.plan_id == b.plan_id == MAIN_ZTF_PLAN_ID
    (da,), (db,) = _ztf_docs(alone / "outbox"), _ztf_docs(both / "outbox")
    assert da["observations"] == db["observations"] and da["config"] == db["config"]
    assert np.isclose(da["metrics"]["coverage"], db["metrics"]["coverage"])
    assert footprint(da).sum() > 0


def test_a_kill_in_the_second_round_ends_with_every_part_around_revision_2_and_no_folder_written_twice(
        tmp_path, monkeypatch):
    from mushrooms.daemon.planning.parts import TelescopeParts
    from mushrooms.scheduler_core.planner import run_scheduler

    class Killed(BaseException):
        """Stands for SIGKILL right after ls4's round-2 part is recorded, before ls4b's."""

    real = TelescopeParts._export

    def export(self, store, job, telescope, plan, round_=1, *args, **kw):
        state = real(self, store, job, telescope, plan, round_, *args, **kw)
        if telescope.name == "ls4" and round_ == 2:
            raise Killed
        return state

    telescopes = ["ztf", "ls4", str(_second_ls4(tmp_path))]
    kw = dict(solver="slots", planner=_halved_first_plan(run_scheduler))
    monkeypatch.setattr(TelescopeParts, "_export", export)
    with pytest.raises(Killed):
        _run(tmp_path, telescopes, [notice_bytes(PRELIMINARY)], **kw)
    monkeypatch.setattr(TelescopeParts, "_export", real)
    outbox = tmp_path / "outbox"
    ls4_round2 = part_folders(outbox)[("00001-PRELIMINARY-round2", "ls4")]
    before = {p.name: p.read_bytes() for p in ls4_round2.iterdir()}
    pipeline, close = _pipeline(tmp_path, telescopes, **kw)
    try:
        (out,) = pipeline.resume()
    finally:
        close()
    assert out.revision == 2
    assert {p.name: p.read_bytes() for p in ls4_round2.iterdir()} == before  # recorded: not rewritten
    folders = part_folders(outbox)
    for name in ("ls4", "ls4b"):
        old, new = folders[("00001-PRELIMINARY", name)], folders[("00001-PRELIMINARY-round2", name)]
        assert (old / "SUPERSEDED").is_file() and part(old)["state"] == "superseded"
        assert not (new / "SUPERSEDED").exists() and part(new)["state"] == "exported"
        assert part(new)["coordinated_with"]["ztf_plan_id"] == out.plan_id
    assert {k[0] for k in folders} == {"00001-PRELIMINARY", "00001-PRELIMINARY-round2"}  # no third round
    assert [(r[1], r[2]) for r in part_rows(tmp_path / "state.sqlite")] == [("ls4", "exported"), ("ls4b", "exported")]
    joint = json.loads(joint_file(outbox, "00001-PRELIMINARY-round2").read_text())
    assert joint["telescopes"] == ["ztf", "ls4", "ls4b"] and joint["plans"][0]["plan_id"] == out.plan_id


def test_a_state_file_with_the_parts_table_of_main_gets_the_round_columns(tmp_path):
    """main's ``telescope_parts`` (no ``round``, ``held``): the next open adds them, its rows stay round 1."""
    import sqlite3

    from mushrooms.daemon.state.parts import parts_of_job, record_part
    from mushrooms.daemon.state.store import Store

    path = tmp_path / "state.sqlite"
    Store(path).close()
    conn = sqlite3.connect(path)
    conn.executescript("DROP TABLE telescope_parts; CREATE TABLE telescope_parts (job_id INTEGER NOT NULL,"
                       " telescope TEXT NOT NULL, superevent_id TEXT NOT NULL, queue TEXT NOT NULL,"
                       " state TEXT NOT NULL, plan_id TEXT, folder TEXT, detail TEXT, created_at TEXT NOT NULL,"
                       " updated_at TEXT NOT NULL, PRIMARY KEY (job_id, telescope));"
                       " INSERT INTO telescope_parts VALUES (1, 'ls4', 'S1', 'target_list', 'exported', 'p1', 'f',"
                       " '', 't', 't');")
    conn.commit()
    conn.close()
    store = Store(path)
    try:
        (row,) = parts_of_job(store, 1).values()
        assert row["round"] == 1 and row["held"] is None
        assert record_part(store, 1, "ls4", "S1", "target_list", "exported", "p2", "g", "", 2, "k2")
        assert not record_part(store, 1, "ls4", "S1", "target_list", "exported", "p3", "h", "", 2, "k2")
        row = parts_of_job(store, 1)["ls4"]
        assert (row["plan_id"], row["round"], row["held"], row["folder"]) == ("p2", 2, "k2", "g")
    finally:
        store.close()
