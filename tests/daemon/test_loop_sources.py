"""The loop's sources (``[loop] executed_source``): files, a depot directory, and HTTP on loopback.

The HTTP sources are pytest-httpserver contract servers written from
SkyPortal's ``ObservationHandler.get`` and IPAC's depot (``executed_servers.py``),
serving the real-shaped fixtures of ``tests/data/executed`` (failed and
partial exposures among them) or the scenario plan's own exposures.
"""

from __future__ import annotations

import logging
import socket
from pathlib import Path

import pytest
from astropy.time import Time

from mushrooms.daemon.loop import fetch as executed_fetch
from mushrooms.daemon.credentials import CredentialsError, load_executed_token
from mushrooms.daemon.loop.fetch import ExecutedReader, FetchError
from mushrooms.daemon.state.executed import count_executed
from mushrooms.daemon.loop.poll import ExecutedLoop
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.daemon.submission.remote import Unreachable
from mushrooms.handlers.executed_source import parse_executed_source
from mushrooms.tool.config import Config, ConfigError, load_config

from executed_servers import EXECUTED, Depot, SkyPortalObservations
from loop_helpers import after, copy_state, open_pipeline, planned_state, the_plan

TOKEN = "sp-3f9c2e"
NIGHT = (Time("2025-05-14T03:00:00", scale="utc"), Time("2025-05-14T06:00:00", scale="utc"))
DEPOT_NAME = "20250514/ztf_recentproc_20250514.json"


@pytest.fixture
def server(loopback):
    return loopback


def reader(spec: str, token: str | None = None) -> ExecutedReader:
    return ExecutedReader(parse_executed_source(spec), token, timeout_s=5.0)


def summary(exposures):
    return [(e.field_id, e.filter, e.processed_fraction, e.status) for e in exposures]


DEPOT_EXPOSURES = [(600, "g", 1.0, "processed"), (601, "g", 0.3125, "processed"), (600, "r", 0.625, "processed"),
                   (602, "r", 0.0, "failed")]


# ---------------------------------------------------------------- SkyPortal
def test_skyportal_is_read_page_after_page_with_its_token(server, monkeypatch):
    monkeypatch.setattr(executed_fetch, "PAGE_SIZE", 2)
    sp = SkyPortalObservations(server, TOKEN)
    got = reader(f"skyportal:{sp.url}", TOKEN).read(*NIGHT)
    # 600 g twice (0.2 s apart: one exposure), 600 r partial but done, 601 g partial, one sdssr observation skipped
    assert summary(got) == [(600, "g", 1.0, "processed"), (601, "g", 0.3125, "processed"),
                            (600, "r", 0.625, "processed")]
    assert [e["args"]["pageNumber"] for e in sp.log] == ["1", "2", "3"]
    first = sp.log[0]
    assert first["authorization"] == f"token {TOKEN}"
    assert (first["args"]["telescopeName"], first["args"]["instrumentName"], first["args"]["numPerPage"]) == (
        "Palomar 1.2m Oschin", "ZTF", "2")
    assert first["args"]["startDate"] == "2025-05-14T03:00:00.000"


def test_skyportal_refusing_the_token_is_one_error_without_the_token(server):
    sp = SkyPortalObservations(server, TOKEN)
    with pytest.raises(FetchError, match="answered 401: Unauthorized") as err:
        reader(f"skyportal:{sp.url}", "wrong-token").read(*NIGHT)
    assert "wrong-token" not in str(err.value)


def test_an_unreachable_source_raises_unreachable():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nothing listens there
    with pytest.raises(Unreachable):
        reader(f"skyportal:http://127.0.0.1:{port}", TOKEN).read(*NIGHT)


# ---------------------------------------------------------------- the depot
def test_the_depot_over_http_reads_each_night_with_basic_auth(server):
    depot = Depot(server, "ztfuser", "pw", {DEPOT_NAME: (EXECUTED / "ztf_recentproc_20250514.json").read_bytes()})
    got = reader(f"depot:{depot.url}", "ztfuser:pw").read(*NIGHT)
    assert summary(got) == DEPOT_EXPOSURES  # a failed exposure (no quadrant reduced) is kept, as failed
    assert depot.log == ["GET /ztf/depot/20250513/ztf_recentproc_20250513.json",  # 404: nothing yet
                         "GET /ztf/depot/20250514/ztf_recentproc_20250514.json"]
    with pytest.raises(FetchError, match="answered 401"):
        reader(f"depot:{depot.url}", "ztfuser:wrong").read(*NIGHT)


def test_the_depot_in_a_directory_and_a_file_not_written_yet(tmp_path):
    night = tmp_path / "depot" / "20250514"
    night.mkdir(parents=True)
    (night / "ztf_recentproc_20250514.json").write_bytes((EXECUTED / "ztf_recentproc_20250514.json").read_bytes())
    assert summary(reader(f"depot:{tmp_path / 'depot'}").read(*NIGHT)) == DEPOT_EXPOSURES
    assert reader(f"file:{tmp_path / 'not-yet.jsonl'}").read(*NIGHT) == ()
    assert len(reader(f"file:{EXECUTED / 'executed.jsonl'}").read(*NIGHT)) == 4


# ---------------------------------------------------------------- through the loop
@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("planned"))


def test_the_loop_polls_skyportal_stores_and_re_plans_a_slip(planned, tmp_path, server):
    """SkyPortal serving the plan's first 10 exposures, the 11th late: stored once, one re-plan from now."""
    p = open_pipeline(copy_state(planned, tmp_path), LoopConfig(executed_source="skyportal:http://x.invalid",
                                                                max_slip_s=900.0))
    try:
        obs = the_plan(p)["observations"]
        served = [{"id": 9000 + i, "instrument_id": 1, "instrument_field_id": 6000 + o["field_id"],
                   "observation_id": 400000 + i, "obstime": o["start"].rstrip("Z") + "000",
                   "filt": "ztf" + o["filter"], "exposure_time": int(o["exposure_s"]), "airmass": None,
                   "seeing": 2.0, "limmag": 20.5, "target_name": None, "processed_fraction": 1.0,
                   "field": {"id": 6000 + o["field_id"], "instrument_id": 1, "field_id": o["field_id"],
                             "ra": o["ra"], "dec": o["dec"]}} for i, o in enumerate(obs[:10])]
        sp = SkyPortalObservations(server, TOKEN, served)
        loop = ExecutedLoop(p.loop, p, reader=reader(f"skyportal:{sp.url}", TOKEN))
        now = after(obs[10]["start"], 1020.0)
        first = loop.poll(now)
        assert (first.read, first.stored.added, first.error) == (10, 10, None)
        assert [a.action for a in first.replans] == ["replan"] and "slipped by 1020 s" in first.replans[0].reason
        again = loop.poll(now)
        assert (again.stored.added, again.stored.unchanged, count_executed(p.store)) == (0, 10, 10)
        assert sp.log[0]["args"]["startDate"] == the_plan(p)["start"].rstrip("Z")
    finally:
        p.store.close()


# ---------------------------------------------------------------- [loop] and its token
def test_the_loop_is_off_by_default_and_its_settings_are_validated(tmp_path):
    assert not Config().loop.enabled and Config().loop.min_processed_fraction == 0.5
    cases = [('executed_source = "ftp:x"', "[loop] executed source 'ftp:x': unknown kind 'ftp'"),
             ('executed_source = "skyportal:fritz.science"', "SkyPortal needs an http(s) URL"),
             ("min_processed_fraction = 1.5", "[loop] min_processed_fraction = 1.5: outside its range [0, 1]"),
             ("max_slip_s = -1.0", "[loop] max_slip_s = -1: outside its range"),
             ("poll_every = 3", "unknown [loop] key(s): poll_every")]
    for line, message in cases:
        path = tmp_path / "c.toml"
        path.write_text(f"[loop]\n{line}\n")
        with pytest.raises(ConfigError) as err:
            load_config(path)
        assert message in str(err.value), str(err.value)
    path.write_text('[loop]\nexecuted_source = "depot:/data/depot"\nmax_slip_s = 600.0\n')
    loop = load_config(path).loop
    assert loop.enabled and (loop.source.kind, loop.source.location, loop.max_slip_s) == ("depot", "/data/depot", 600.0)


def test_the_token_comes_from_the_credential_or_the_environment(tmp_path):
    (tmp_path / "executed_token").write_text("from-systemd\n")
    assert load_executed_token({"CREDENTIALS_DIRECTORY": str(tmp_path), "MUSHROOMS_EXECUTED_TOKEN": "env"})[0] \
        == "from-systemd"
    assert load_executed_token({"MUSHROOMS_EXECUTED_TOKEN": "env"})[0] == "env"
    with pytest.raises(CredentialsError, match="MUSHROOMS_EXECUTED_TOKEN"):
        load_executed_token({})
