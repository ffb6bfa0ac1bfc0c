"""Every subcommand answers ``--help`` (found from the dispatcher's registry, so a new tool is covered), and ``--version``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from mushrooms import __version__
from mushrooms.cli import TOOLS, build_parser, main


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
