"""A FIFO, a directory or a device given as the state file is named for what it is, exit 2, nothing created.

``mushrooms status --state DIR`` said "no such state file" of a directory that
exists; ``trigger``, ``replay`` and ``run`` went on and died in SQLite
(``disk I/O error``, exit 70), ``run --state /dev/null`` after creating
``/dev/null-journal`` and ``/dev/mushrooms-triggers``.  Every command that takes
``--state`` refuses such a path with one line saying what it is, exit 2 (which
the unit does not restart on), before it creates anything.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTICE = ROOT / "mushrooms" / "data" / "demo" / "MS260605l-preliminary.json"


def _cli(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_CONFIG"}
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "--log-level", "WARNING", *args],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)  # a hang guard


@pytest.fixture(params=["fifo", "directory", "device"])
def odd_state(request, tmp_path) -> tuple[Path, str]:
    home = tmp_path / "home"
    home.mkdir()
    if request.param == "fifo":
        path = home / "state.sqlite"
        os.mkfifo(path)
        return path, "a FIFO"
    if request.param == "directory":
        path = home / "state.sqlite"
        path.mkdir()
        return path, "a directory"
    # a device: a link to /dev/null in a directory of ours, so nothing can be created beside the device itself
    path = home / "state.sqlite"
    path.symlink_to("/dev/null")
    return path, "a device"


@pytest.mark.parametrize("command", [["status"], ["trigger", "MS260605l"],
                                     ["replay", str(NOTICE), "--out", "replay-out"]])
def test_a_tool_names_what_the_state_path_is_and_exits_2(tmp_path, odd_state, command):
    path, kind = odd_state
    before = sorted(p.name for p in path.parent.iterdir())
    r = _cli(tmp_path, *command, "--state", str(path))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{path}: {kind}, not a state file" in lines[0], r.stderr
    assert "no such state file" not in r.stderr
    assert sorted(p.name for p in path.parent.iterdir()) == before  # no -journal, no triggers directory
    if command == ["status"]:  # and a state file that is not there is still called so
        r = _cli(tmp_path, "status", "--state", str(path.parent / "nope.sqlite"))
        assert r.returncode == 2 and f"{path.parent / 'nope.sqlite'}: no such state file" in r.stderr


def test_the_service_refuses_it_before_creating_anything(tmp_path, odd_state):
    path, kind = odd_state
    before = sorted(p.name for p in path.parent.iterdir())
    r = _cli(tmp_path, "run", "--state", str(path), "--bootstrap", "127.0.0.1:9")
    assert r.returncode == 2, r.stderr[-3000:]
    assert r.stderr == f"mushrooms run: error: {path}: {kind}, not a state file (an SQLite file the service creates)\n"
    assert sorted(p.name for p in path.parent.iterdir()) == before


def test_the_store_refuses_it_too(tmp_path):
    # the library's own check (a caller that builds the Store itself): a StoreError, the service's exit 65;
    # a device is given through a link, which the store refuses first (its older rule)
    from mushrooms.daemon.state.store import Store, StoreError

    fifo, directory = tmp_path / "fifo.sqlite", tmp_path / "dir.sqlite"
    os.mkfifo(fifo)
    directory.mkdir()
    for path, kind in ((fifo, "a FIFO"), (directory, "a directory")):
        with pytest.raises(StoreError, match=f"{kind}, not a state file"):
            Store(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.sqlite", "fifo.sqlite"]


@pytest.fixture(params=["link", "not_sqlite", "newer_schema"])
def unusable_state(request, tmp_path) -> tuple[Path, str]:
    """A state path the store refuses (a StoreError): a link to a real SQLite file, not SQLite, a newer schema."""
    import sqlite3

    home = tmp_path / "home"
    home.mkdir()
    path = home / "state.sqlite"
    if request.param == "link":
        real = home / "real.sqlite"
        sqlite3.connect(real).execute("CREATE TABLE t (x)").connection.close()
        path.symlink_to(real)
        return path, "the state file is a symbolic link; give the real path"
    if request.param == "not_sqlite":
        path.write_bytes(bytes(range(256)) * 32)
        return path, "not a usable SQLite database"
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA user_version = 999")
    conn.close()
    return path, "schema version 999 is newer than this program's"


@pytest.mark.parametrize("command", [["trigger", "MS260605l"], ["trigger", str(NOTICE), "--allow-mock"],
                                     ["replay", str(NOTICE), "--out", "replay-out"]])
def test_a_state_file_the_store_refuses_is_one_line_and_exit_2(tmp_path, unusable_state, command):
    """A StoreError in ``trigger`` or ``replay`` was "internal error: StoreError ... (rerun with --debug)", exit 70."""
    path, why = unusable_state
    r = _cli(tmp_path, *command, "--state", str(path))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"mushrooms {command[0]}: error: {path}: {why}"), r.stderr
    assert "internal error" not in r.stderr and "Traceback" not in r.stderr
