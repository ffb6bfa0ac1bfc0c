"""Files of any kind, and the smaller command-line findings (outputs, paths), one parser of times.

Outputs go only to regular files or new paths, never onto an input, never replacing a FIFO or a
symbolic link, atomically and with the usual umask; inputs are read only from regular files
(one reader, ``mushrooms.inputs``).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mushrooms.cli import main

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
OTHER_MAP = ROOT / "tests" / "data" / "skymaps" / "S200129m_cWB_RING.fits.gz"
FAST = '[scheduler]\nsolver = "greedy"\nnside = 64\ntime_step_s = 600.0\n'


@pytest.fixture
def cfg(tmp_path: Path) -> Path:
    path = tmp_path / "fast.toml"
    path.write_text(FAST)
    return path


def one_error(capsys) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(lines) == 1, lines
    return lines[0]


def cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """The real command in its own process (an input that blocks must not block the test run)."""
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=timeout)


# ----------------------------------------------------------------------------------------- outputs


def test_plan_onto_its_own_input_map_is_refused(tmp_path, cfg, capsys):
    skymap = tmp_path / "map.fits"
    shutil.copy(MAP, skymap)
    before = skymap.read_bytes()
    assert main(["plan", str(skymap), "--config", str(cfg), "-o", str(skymap)]) == 2
    assert "is the input" in one_error(capsys)
    assert skymap.read_bytes() == before
    assert main(["plan", str(skymap), "--config", str(cfg), "-o", str(tmp_path / "p.json"),
                 "--queue", str(cfg)]) == 2  # nor onto the config it reads
    assert "is the input" in one_error(capsys)


def test_two_outputs_of_one_command_must_differ(tmp_path, cfg, capsys):
    out = tmp_path / "p.json"
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(out), "--queue", str(out)]) == 2
    assert "the same file as -o/--output" in one_error(capsys)
    assert not out.exists()


def test_an_output_onto_a_fifo_is_refused_and_the_fifo_stays(tmp_path, cfg, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for option in ("-o", "--queue", "--plot"):
        args = ["plan", str(MAP), "--config", str(cfg), "-o", str(tmp_path / "p.json"), option, str(fifo)]
        assert main(args) == 2
        assert "not a regular file" in one_error(capsys)
        assert stat.S_ISFIFO(fifo.lstat().st_mode)


def test_an_output_onto_a_device_node_is_refused_and_the_node_stays(tmp_path, cfg, capsys):
    """``plan -o`` used to os.replace whatever was at the path: a character device (a node like
    /dev/null, made here in tmp_path) became a regular file."""
    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError) as exc:
        pytest.skip(f"cannot make a device node here: {exc}")
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(node)]) == 2
    assert "not a regular file" in one_error(capsys)
    assert stat.S_ISCHR(node.lstat().st_mode)


def test_an_output_through_a_symbolic_link_keeps_the_link(tmp_path, cfg):
    real = tmp_path / "real.json"
    real.write_text("{}")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(link)]) == 0
    assert link.is_symlink() and json.loads(real.read_text())["type"] == "plan"


def test_plan_and_queue_files_get_the_usual_umask(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(FAST + "min_coverage = 0.0\n")
    old = os.umask(0o022)
    try:
        out, queue = tmp_path / "p.json", tmp_path / "q.json"
        assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(out), "--queue", str(queue)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o644 and stat.S_IMODE(queue.stat().st_mode) == 0o644
    out.chmod(0o640)  # an existing file keeps the mode its owner gave it
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(out)]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o640


def test_bench_output_onto_a_fifo_is_refused_before_any_work(tmp_path, cfg, capsys):
    fifo = tmp_path / "results.csv"
    os.mkfifo(fifo)
    assert main(["bench", str(tmp_path), "--config", str(cfg), "-o", str(fifo)]) == 2
    assert "not a regular file" in one_error(capsys)


# ------------------------------------------------------------------------------------------ inputs


def test_plan_of_a_fifo_is_refused_at_once(tmp_path, cfg):
    fifo = tmp_path / "map.fits"
    os.mkfifo(fifo)
    r = cli("plan", str(fifo), "--config", str(cfg), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "a FIFO, not a regular file" in r.stderr


def test_check_with_a_fifo_for_the_map_or_the_plan_is_refused_at_once(tmp_path, cfg):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    plan = tmp_path / "p.json"
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(plan)]) == 0
    for args in ((str(plan), str(fifo)), (str(fifo), str(MAP))):
        r = cli("check", *args)
        assert r.returncode == 2 and "a FIFO, not a regular file" in r.stderr, r.stderr


def test_plan_of_a_device_is_refused_without_reading_it(tmp_path, cfg, capsys):
    assert main(["plan", "/dev/zero", "--config", str(cfg), "-o", str(tmp_path / "p.json")]) == 2
    assert "/dev/zero: a device, not a regular file" in one_error(capsys)


def test_a_config_or_a_notice_from_a_fifo_is_refused(tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    r = cli("plan", str(MAP), "--config", str(fifo), "-o", str(tmp_path / "p.json"))
    assert r.returncode == 2 and "cannot read config" in r.stderr and "FIFO" in r.stderr
    cfg = tmp_path / "c.toml"
    cfg.write_text(FAST)
    r = cli("replay", str(fifo), "--config", str(cfg), "--out", str(tmp_path / "out"))
    assert "a FIFO, not a regular file" in r.stdout + r.stderr


# ---------------------------------------------------------------------------------- smaller items


@pytest.mark.parametrize("start, why", [("9999-12-31T23:59:59Z", "outside 1800-01-01 to 2200-01-01"),
                                        ("", "empty"), ("  ", "empty"), ("nan", "positive day number")])
def test_a_start_that_is_no_usable_time_is_one_line_exit_2(tmp_path, cfg, capsys, start, why):
    assert main(["plan", str(MAP), "--config", str(cfg), "--start", start, "-o", str(tmp_path / "p.json")]) == 2
    line = one_error(capsys)
    assert "--start" in line and why in line and "ISO-8601" in line


@pytest.mark.parametrize("deadline", ["nan", "inf", "-1", "0"])
def test_a_deadline_must_be_a_finite_positive_number(tmp_path, cfg, capsys, deadline):
    assert main(["plan", str(MAP), "--config", str(cfg), "--deadline", deadline, "-o", str(tmp_path / "p.json")]) == 2
    assert "--deadline" in one_error(capsys)


def _plan(tmp_path: Path, cfg: Path) -> tuple[Path, dict]:
    plan = tmp_path / "p.json"
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(plan)]) == 0
    return plan, json.loads(plan.read_text())


@pytest.mark.parametrize("value", ["NaN", "Infinity", "400.0"])
def test_check_of_a_plan_with_an_impossible_ra_is_one_line(tmp_path, cfg, capsys, value):
    plan, doc = _plan(tmp_path, cfg)
    text = plan.read_text().replace(f'"ra": {doc["observations"][0]["ra"]}', f'"ra": {value}', 1)
    assert value in text
    plan.write_text(text)
    capsys.readouterr()
    assert main(["check", str(plan), str(MAP)]) == 2
    assert "ra" in one_error(capsys)


def test_check_against_another_map_says_so_in_one_line(tmp_path, cfg, capsys):
    plan, _ = _plan(tmp_path, cfg)
    capsys.readouterr()
    assert main(["check", str(plan), str(OTHER_MAP)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert "FAILED" in out[0] and "the plan was made for another sky map" in out[1]
    assert main(["check", str(plan), str(MAP)]) == 0


def _flat_map(path: Path, distmu=None, distsigma=None, distnorm=None, ordering: str | None = "NESTED") -> Path:
    """A flat NSIDE 64 map from the test map (ligo.skymap's writer), distance layers replaced or removed."""
    from astropy.io import fits
    from astropy.table import Table
    from ligo.skymap.io import write_sky_map

    from mushrooms.scheduler_core import read_skymap

    m = read_skymap(MAP, nside=64)
    cols = {"PROB": m.prob}
    if distmu is not None:
        cols.update(DISTMU=np.broadcast_to(distmu, m.prob.shape).astype(float),
                    DISTSIGMA=np.broadcast_to(distsigma, m.prob.shape).astype(float),
                    DISTNORM=np.broadcast_to(distnorm, m.prob.shape).astype(float))
    write_sky_map(str(path), Table(cols, meta={"nest": True, "gps_time": 1342648664.0, "objid": "MS220722v"}))
    with fits.open(path, mode="update") as hdus:
        if ordering is None:
            del hdus[1].header["ORDERING"]
        else:
            hdus[1].header["ORDERING"] = ordering
    return path


def test_a_flat_map_without_ordering_is_refused_with_the_reason(tmp_path, cfg, capsys):
    skymap = _flat_map(tmp_path / "flat.fits", ordering=None)
    assert main(["plan", str(skymap), "--config", str(cfg), "-o", str(tmp_path / "p.json")]) == 2
    line = one_error(capsys)
    assert "without ORDERING" in line and "pixel order is unknown" in line


@pytest.mark.parametrize("layers", [(np.nan, np.nan, np.nan), (np.inf, 1.0, 0.0), (100.0, -5.0, 1e-4),
                                    (-100.0, 10.0, -1.0)], ids=["nan", "inf-1-0", "sigma<0", "norm<0"])
def test_unusable_distance_layers_are_absent_with_one_warning(tmp_path, cfg, caplog, layers):
    from mushrooms.scheduler_core import read_skymap

    skymap = _flat_map(tmp_path / "flat.fits", *layers)
    with caplog.at_level(logging.WARNING):
        m = read_skymap(skymap, nside=64)
    assert not m.has_distance
    assert sum("distance layers hold no usable value" in r.getMessage() for r in caplog.records) == 1
    out = tmp_path / "p.json"
    assert main(["plan", str(skymap), "--config", str(cfg), "-o", str(out), "--start", "2022-07-23T04:00:00Z"]) == 0
    assert json.loads(out.read_text())["metrics"]["expected_detections"] is None


def test_usable_distance_layers_still_count(tmp_path):
    from mushrooms.scheduler_core import read_skymap

    m = read_skymap(_flat_map(tmp_path / "flat.fits", 200.0, 50.0, 2.3e-5), nside=64)
    assert m.has_distance and np.all(m.distmu == 200.0)


def test_config_before_the_subcommand_is_accepted(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(FAST.replace("nside = 64", "nside = 32"))
    out = tmp_path / "p.json"
    assert main(["--config", str(cfg), "plan", str(MAP), "-o", str(out)]) == 0
    assert json.loads(out.read_text())["config"]["nside"] == 32
    other = tmp_path / "other.toml"
    other.write_text(FAST)
    assert main(["--config", str(cfg), "plan", str(MAP), "-o", str(out), "--config", str(other)]) == 0
    assert json.loads(out.read_text())["config"]["nside"] == 64  # the subcommand's own wins


def test_plan_without_a_map_is_refused_not_the_demo(tmp_path, cfg, capsys):
    out = tmp_path / "x.json"
    assert main(["plan", "--config", str(cfg), "-o", str(out)]) == 2
    assert "mushrooms demo" in one_error(capsys)
    assert not out.exists()


# ------------------------------------------------------------------------------- one time parser


@pytest.mark.parametrize("text", ["2022-07-23T04:00:00+02:00", "2022-07-23T02:00:00Z", "2022-07-23 02:00:00",
                                  "59783.083333333336"])
def test_plan_and_bench_read_start_times_alike(tmp_path, cfg, capsys, text):
    """``bench --start`` once took only ``...Z``; now both use ``scheduler_core.times.parse_time``."""
    import argparse

    from mushrooms.tool.bench import load_settings
    from mushrooms.tool.plan import parse_start

    args = argparse.Namespace(config=str(cfg), solvers="greedy", injections=10, jobs=1, start=text)
    assert load_settings(args).start_iso == parse_start(text).isot == "2022-07-23T02:00:00.000"


def test_plan_and_bench_refuse_a_bad_start_in_the_same_words(tmp_path, cfg, capsys):
    assert main(["plan", str(MAP), "--config", str(cfg), "--start", "next tuesday", "-o", str(tmp_path / "p.json")]) == 2
    plan_line = one_error(capsys).split("error: ", 1)[1]
    assert main(["bench", str(tmp_path), "--config", str(cfg), "--start", "next tuesday"]) == 2
    assert one_error(capsys).split("error: ", 1)[1] == plan_line


def test_notices_and_plan_documents_use_the_same_parser():
    from datetime import datetime, timezone

    from mushrooms.handlers.alert import NoticeError, parse_time as notice_time
    from mushrooms.scheduler_core.plan.document import parse_time as document_time
    from mushrooms.scheduler_core.times import parse_time

    assert notice_time("2022-07-23T04:00:00+02:00") == datetime(2022, 7, 23, 2, tzinfo=timezone.utc)
    assert document_time("2022-07-23T02:00:00.000Z").isot == parse_time("2022-07-23T04:00:00+02:00").isot
    with pytest.raises(NoticeError, match="a number, not a date"):
        notice_time("59783.08")  # an MJD only where a person types it
    with pytest.raises(ValueError, match="outside 1800-01-01 to 2200-01-01"):
        document_time("9999-12-31T23:59:59Z")
    assert parse_time("2016-12-31T23:59:60Z").isot == "2016-12-31T23:59:60.000"
