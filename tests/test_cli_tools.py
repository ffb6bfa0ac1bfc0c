"""Every subcommand answers ``--help`` (found from the dispatcher's registry, so a new tool is covered), and ``--version``."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from mushrooms import __version__
from mushrooms.cli import TOOLS, build_parser, main

MAP = Path(__file__).resolve().parent / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def test_the_registry_is_the_parser():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert list(sub.choices) == list(TOOLS)


@pytest.mark.parametrize("name", list(TOOLS))
def test_every_subcommand_has_help(name, capsys):
    with pytest.raises(SystemExit) as stop:
        main([name, "--help"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: mushrooms {name}")
    assert TOOLS[name].HELP.split()[0] in out
    assert "--config FILE" in out


@pytest.mark.parametrize("name", list(TOOLS))
def test_every_tool_runs_on_its_own(name, capsys):
    # the tool module's own main(args): the same options as under the dispatcher
    with pytest.raises(SystemExit) as stop:
        TOOLS[name].main(["--help"])
    assert stop.value.code == 0
    alone = capsys.readouterr().out
    with pytest.raises(SystemExit):
        main([name, "--help"])
    assert capsys.readouterr().out == alone


def test_version(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"mushrooms {__version__}"


def test_help_imports_nothing_heavy():
    code = ("import sys; from mushrooms.cli import build_parser; build_parser().format_help(); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'astropy', 'highspy') "
            "or m.startswith('mushrooms.scheduler_core')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"


#: run ``mushrooms`` in this interpreter, then print which modules of a few packages were loaded.
_LOADED = ("import runpy, sys\n"
           "sys.argv = ['mushrooms'] + sys.argv[1:]\n"
           "try:\n    runpy.run_module('mushrooms.cli', run_name='__main__')\n"
           "except SystemExit:\n    pass\n"
           "print(sorted(m for m, v in sys.modules.items() if v is not None\n"
           "             and m.split('.')[0] in ('matplotlib', 'ligo')))\n")


def _plan_loads(tmp_path, *extra: str) -> list[str]:
    out = tmp_path / "plan.json"
    r = subprocess.run([sys.executable, "-c", _LOADED, "plan", str(MAP), "--solver", "greedy", "-o", str(out),
                        *extra], capture_output=True, text=True, check=True, cwd=tmp_path)
    assert out.exists(), r.stderr
    return ast.literal_eval(r.stdout.strip().splitlines()[-1])


def test_a_greedy_plan_imports_no_plotting_nor_gracedb(tmp_path):
    # matplotlib (through healpy's plotting half) and ligo.skymap.io (GraceDB's client)
    # were a second of a 3.5 s `mushrooms plan --solver greedy`
    loaded = _plan_loads(tmp_path)
    assert "ligo.skymap" in loaded  # the probe sees what the plan loads
    assert not [m for m in loaded if m.startswith("matplotlib")]
    assert not [m for m in loaded if m.startswith(("ligo.gracedb", "ligo.skymap.io"))]


def test_a_plan_with_plot_still_draws(tmp_path):
    loaded = _plan_loads(tmp_path, "--plot", str(tmp_path / "plan.png"))
    assert "matplotlib" in loaded
    assert (tmp_path / "plan.png").stat().st_size > 10_000
