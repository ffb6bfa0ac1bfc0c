"""What every tool shares: the common options, and running a command with one-line errors.

Bad input (:class:`~mushrooms.scheduler_core.errors.InputError`,
:class:`~mushrooms.tool.config.ConfigError`,
:class:`~mushrooms.daemon.credentials.CredentialsError`, and a state file the store refuses:
:class:`~mushrooms.daemon.state.file.StoreError`) is answered by one line on stderr and
exit status 2; an internal fault by one line and status 70 unless
``--debug``.

A missing optional extra (``pyproject.toml``'s ``[project.optional-dependencies]``:
``study``, ``simulate``, ``gwemopt``) is bad input too: one line naming the
extra to install, status 2 (:class:`MissingExtra`, :func:`require_extra`;
an import of one of :data:`OPTIONAL_MODULES` failing anywhere in a command
is answered the same way).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from typing import Callable, Iterator

__all__ = ["SOLVER_CHOICES", "SOLVER_METAVAR", "EXIT_INPUT", "EXIT_INTERNAL", "OPTIONAL_MODULES", "MissingExtra",
           "require_extra", "missing_extra", "add_common_options", "tool_parser", "quiet_time_warnings", "execute"]

class _SolverNames(Sequence[str]):
    """The registry's scheduler names (:mod:`~mushrooms.scheduler_core.solvers_registry`), read when first used.

    ``--solver``'s ``choices``: argparse only looks into them when it checks
    a value or lists them in an error, never for ``--help`` (the option has a
    metavar, :data:`SOLVER_METAVAR`), so building the parser imports no
    scheduler code.
    """

    def _names(self) -> tuple[str, ...]:
        from ..scheduler_core.solvers_registry import SOLVER_NAMES

        return SOLVER_NAMES

    def __getitem__(self, i):  # type: ignore[override]
        return self._names()[i]

    def __len__(self) -> int:
        return len(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __repr__(self) -> str:
        return repr(list(self._names()))


#: ``--solver`` names: the registry's (scheduler_core.solvers_registry.SOLVER_NAMES), looked up lazily.
SOLVER_CHOICES: Sequence[str] = _SolverNames()
#: ``--solver``'s metavar (the names are in :data:`SOLVER_HELP`).
SOLVER_METAVAR = "SOLVER"

EXIT_INPUT = 2
EXIT_INTERNAL = 70

SOLVER_HELP = ("scheduler: greedy | slots | blocks (the paper's block MILP; milp = blocks) | hybrid "
               "(default from config: hybrid)")


#: Top-level modules of the optional extras -> the extra that brings them (pyproject.toml).
OPTIONAL_MODULES = {
    "distributed": "study", "dask": "study",  # mushrooms study: the task graph
    "lal": "simulate", "lalsimulation": "simulate", "igwn_ligolw": "simulate",  # study --simulate, localisation
    "gwemopt": "gwemopt",  # the gwemopt baseline rows of bench / study
}


class MissingExtra(Exception):
    """An optional extra a command needs is not installed; ``str()`` is the one line to print.

    Parameters
    ----------
    extra : str
        The extra (``study``, ``simulate``, ``gwemopt``).
    detail : str
        What failed (``No module named 'distributed'``).
    hint : str
        Anything else to do (gwemopt: its interpreter).
    """

    def __init__(self, extra: str, detail: str, hint: str = "") -> None:
        self.extra, self.detail, self.hint = extra, detail, hint
        super().__init__(f"needs the '{extra}' extra: pip install 'mushrooms[{extra}]'{hint} ({detail})")


def _import_detail(exc: ImportError) -> str:
    name = getattr(exc, "name", None)
    return f"No module named {name!r}" if isinstance(exc, ModuleNotFoundError) and name else str(exc)


def missing_extra(exc: BaseException) -> MissingExtra | None:
    """The :class:`MissingExtra` behind a failed import of an optional module, else None."""
    if not isinstance(exc, ImportError):
        return None
    name = (getattr(exc, "name", None) or "").split(".")[0]
    extra = OPTIONAL_MODULES.get(name)
    return MissingExtra(extra, _import_detail(exc)) if extra else None


def require_extra(extra: str, modules: Sequence[str] | None = None) -> None:
    """Import ``modules`` (default: every module of ``extra``); :class:`MissingExtra` on the first failing.

    Called by a command before it starts work, so that a missing extra is
    one line and exit status 2 at once, not an error hours later.
    """
    names = list(modules) if modules is not None else [m for m, e in OPTIONAL_MODULES.items() if e == extra]
    for module in names:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise MissingExtra(extra, _import_detail(exc)) from None


def add_common_options(sp: argparse.ArgumentParser) -> None:
    """``--config``, and the global ``--debug`` / ``--log-level`` accepted after the subcommand too."""
    sp.add_argument("--config", metavar="FILE",
                    help="config file; default $MUSHROOMS_CONFIG, else ./config.toml, else embedded defaults")
    # SUPPRESS keeps the global value when the option is not repeated after the subcommand
    sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    sp.add_argument("--log-level", default=argparse.SUPPRESS, help=argparse.SUPPRESS)


def tool_parser(name: str, help_text: str) -> argparse.ArgumentParser:
    """A parser for one tool run on its own (``main(args)`` of a tool module)."""
    return argparse.ArgumentParser(prog=f"mushrooms {name}", description=help_text)


def quiet_time_warnings() -> None:
    """No ERFA/IERS chatter: far-off times are reported once, in one line, by the command."""
    import warnings

    warnings.filterwarnings("ignore", message=r".*dubious year.*")
    warnings.filterwarnings("ignore", message=r".*polar motions for times.*")
    warnings.filterwarnings("ignore", message=r".*outside of range covered by IERS table.*")
    warnings.filterwarnings("ignore", message=r".*IERS.*")
    try:
        from erfa import ErfaWarning
    except ImportError:  # pragma: no cover - astropy always brings pyerfa
        return
    warnings.filterwarnings("ignore", category=ErfaWarning)


def execute(name: str, args: argparse.Namespace, run: Callable[[argparse.Namespace], int]) -> int:
    """Set up logging and the config path, run a command, and turn its errors into one line and a status."""
    debug = bool(getattr(args, "debug", False))
    log_level = getattr(args, "log_level", "INFO")
    level = logging.DEBUG if debug else getattr(logging, str(log_level).upper(), None)
    if not isinstance(level, int):
        print(f"mushrooms {name}: error: --log-level {log_level!r}: expected DEBUG, INFO, WARNING "
              "or ERROR", file=sys.stderr)
        return EXIT_INPUT
    logging.basicConfig(
        level=level,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    quiet_time_warnings()
    from .quiet import SOLVING_COMMANDS, silence_solver_banner

    if name in SOLVING_COMMANDS:
        silence_solver_banner()  # HiGHS's banner on stdout, once per process
    from ..daemon.credentials import CredentialsError
    from ..daemon.state.file import StoreError  # a link, not SQLite, damaged, a newer schema: the state path given
    from ..scheduler_core.errors import InputError
    from .config import ConfigError, resolve_config_path

    try:
        if hasattr(args, "config"):
            given = args.config
            path, why = resolve_config_path(given)
            args.config, args.config_explicit = (str(path) if path else None), bool(given)
            logging.getLogger("mushrooms.config").info("config: %s (%s)", path or "embedded defaults", why)
        return int(run(args) or 0)
    except (InputError, ConfigError, CredentialsError, StoreError, MissingExtra) as exc:
        print(f"mushrooms {name}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print(f"mushrooms {name}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal fault: still one line unless --debug
        if (extra := missing_extra(exc)) is not None:  # an optional package imported deep inside the command
            print(f"mushrooms {name}: error: {extra}", file=sys.stderr)
            return EXIT_INPUT
        if debug:
            raise
        print(f"mushrooms {name}: internal error: {type(exc).__name__}: {exc} (rerun with --debug)",
              file=sys.stderr)
        return EXIT_INTERNAL


def read_json_object(path: str, what: str = "plan") -> dict:
    """A JSON object from a regular file (a plan document), or :class:`InputError` with one line.

    Never reads a FIFO or a device (:func:`mushrooms.inputs.read_regular_file`), and
    refuses NaN and infinities, which Python's parser accepts and JSON does not have.
    """
    import json

    from ..inputs import read_regular_file
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.plan.strict_json import non_finite_path

    data = read_regular_file(path, what=what)
    try:
        doc = json.loads(data.decode())
    except UnicodeDecodeError as exc:
        raise InputError(f"cannot read {what} {path}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{path} is not JSON: {exc}") from None
    if (where := non_finite_path(doc)) is not None:
        raise InputError(f"{path} is not valid JSON: NaN or infinity at {where}")
    if not isinstance(doc, dict):
        raise InputError(f"{path} is not a {what} document (not a JSON object)")
    return doc
