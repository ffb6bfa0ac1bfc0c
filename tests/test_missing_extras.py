"""A command that needs a missing optional extra ends in one line naming it, exit 2.

Each test makes the import fail for real (``sys.modules[name] = None``: Python's
own "import halted"), in-process through the CLI, or in a fresh interpreter.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from mushrooms.cli import main as cli_main
from mushrooms.tool.common import OPTIONAL_MODULES, execute, missing_extra

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def _error_lines(err: str, command: str) -> list[str]:
    """Lines the command itself wrote (log lines have a timestamp and a level first)."""
    return [x for x in err.splitlines() if x.startswith(f"mushrooms {command}")]


def _the_one_line(capsys, command: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err
    lines = _error_lines(err, command)
    assert len(lines) == 1, err
    assert err.rstrip().splitlines()[-1] == lines[0]  # the command ends with it
    return lines[0]


@pytest.fixture
def maps(tmp_path) -> Path:
    d = tmp_path / "maps"
    d.mkdir()
    (d / MAP.name).symlink_to(MAP)
    return d


def test_study_without_distributed(maps, tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    rc = cli_main(["study", "--maps", str(maps), "--out", str(tmp_path / "out"), "--no-figures"])
    assert rc == 2
    assert _the_one_line(capsys, "study") == ("mushrooms study: error: needs the 'study' extra: "
                                              "pip install 'mushrooms[study]' (No module named 'distributed')")
    assert not (tmp_path / "out").exists()  # refused before any work


EVENTS = ROOT / "mushrooms" / "data" / "populations" / "bns_o3" / "events.xml.gz"


@pytest.mark.parametrize("source", [["--simulate", "10"], ["--events", str(EVENTS)], []])
@pytest.mark.parametrize("module", ["lal", "igwn_ligolw"])
def test_study_simulate_or_localise_without_lalsuite_or_ligolw(module, source, tmp_path, monkeypatch, capsys) -> None:
    """--simulate, --events and the default (the packaged population) run bayestar-* tools: the 'simulate' extra."""
    monkeypatch.setitem(sys.modules, module, None)
    rc = cli_main(["study", *source, "--out", str(tmp_path / "out"), "--cache", str(tmp_path / "c")])
    assert rc == 2
    assert _the_one_line(capsys, "study") == ("mushrooms study: error: needs the 'simulate' extra: "
                                              f"pip install 'mushrooms[simulate]' (No module named '{module}')")
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("command", ["bench", "study"])
@pytest.mark.parametrize("row", ["gwemopt", "gwemopt-repaired"])
def test_gwemopt_rows_without_gwemopt_or_its_cache(command, row, maps, tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.delenv("MUSHROOMS_GWEMOPT_PYTHON", raising=False)
    monkeypatch.setitem(sys.modules, "gwemopt", None)
    args = [command, str(maps)] if command == "bench" else [command, "--maps", str(maps), "--no-figures"]
    out = ["-o", str(tmp_path / "r.csv")] if command == "bench" else ["--out", str(tmp_path / "out")]
    rc = cli_main([*args, "--solvers", f"greedy,{row}", "--injections", "100", *out])
    assert rc == 2
    line = _the_one_line(capsys, command)
    assert line.startswith(f"mushrooms {command}: error: needs the 'gwemopt' extra: pip install 'mushrooms[gwemopt]'")
    assert "MUSHROOMS_GWEMOPT_PYTHON" in line and f"--solvers {row}" in line and "gwemopt_cache_dir" in line
    assert not (tmp_path / "r.csv").exists() and not (tmp_path / "out").exists()


def test_an_optional_import_deep_inside_a_command_is_the_same_line(monkeypatch, capsys) -> None:
    """The safety net of ``execute``: a command that imports an optional package without asking first."""
    import argparse

    def run(args: argparse.Namespace) -> int:
        import distributed  # noqa: F401

        return 0

    monkeypatch.setitem(sys.modules, "distributed", None)
    assert execute("study", argparse.Namespace(), run) == 2
    assert _the_one_line(capsys, "study") == ("mushrooms study: error: needs the 'study' extra: "
                                              "pip install 'mushrooms[study]' (No module named 'distributed')")
    assert missing_extra(ModuleNotFoundError("No module named 'numpy'", name="numpy")) is None  # not an extra


def test_every_optional_module_names_an_extra_of_pyproject() -> None:
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(OPTIONAL_MODULES.values()) <= set(extras)
    assert any(x.startswith("distributed") for x in extras["study"])
    assert {"lalsuite", "igwn-ligolw"} <= {x.split(">")[0].split("=")[0] for x in extras["simulate"]}
    assert extras["gwemopt"] == ["gwemopt"]


def test_study_without_distributed_in_a_fresh_interpreter(maps, tmp_path) -> None:
    """The installed entry point's path, in a process of its own: stderr ends with the one line."""
    code = ("import sys; sys.modules['distributed'] = None; from mushrooms.cli import main; "
            f"sys.exit(main(['study', '--maps', {str(maps)!r}, '--out', {str(tmp_path / 'out')!r}]))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = _error_lines(proc.stderr, "study")
    assert lines == ["mushrooms study: error: needs the 'study' extra: pip install 'mushrooms[study]' "
                     "(No module named 'distributed')"]
    assert proc.stderr.rstrip().splitlines()[-1] == lines[0]
