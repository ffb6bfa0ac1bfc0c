"""The benchmark as a library: every scheduler on a set of sky maps, judged by numbers.

For each sky map the problem is prepared once, each requested row runs
(``greedy``, ``slots``, ``blocks`` (alias ``milp``), ``hybrid`` as
``make_plan`` publishes them; ``<solver>-coverage`` / ``-detection`` with
the objective forced; ``service`` and ``service-grg``; ``gwemopt``,
``gwemopt-repaired`` and gwemopt's named configurations ``gwemopt-o4`` and
``gwemopt-skyportal``), every plan goes
through the independent plan checker, and the detection efficiency of each
plan is computed with the SAME injections for three kilonova models
(optimistic and conservative BNS, NSBH).  One row per (sky map, solver).

Modules, one idea each:

* :mod:`.settings` — ``[bench]`` (:class:`BenchConfig`), one run
  (:class:`BenchSettings`), the row names;
* :mod:`.per_map` — one map: prepare, plan each row (:func:`bench_map`);
* :mod:`.scoring` — the checker and the detection efficiency of one plan;
* :mod:`.rows`, :mod:`.compare` — the CSV rows, and rows of one map side by side;
* :mod:`.summary`, :mod:`.plots` — the summary table and the figures;
* :mod:`.run` — many maps in worker processes (:func:`run_bench`).

From Python::

    from mushrooms.evaluation.bench import BenchSettings, run_bench, summarize
    from mushrooms.scheduler_core import PlanningConfig
    rows = run_bench(BenchSettings(config=PlanningConfig(), solvers=("greedy", "hybrid")), ["map.fits"])
    print(summarize(rows))

``mushrooms bench`` (:mod:`mushrooms.tool.bench`) reads the command line and
``config.toml``, calls :func:`run_bench`, writes the CSV and prints.  The
names below are imported on first use (PEP 562): reading ``[bench]``
(:mod:`.settings`) loads no numpy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from .compare import SIMILAR_LENGTH, TIE_COVERAGE, TIE_EFFICIENCY, best_of
    from .per_map import bench_map
    from .plots import make_plots
    from .rows import COLUMNS, read_csv, write_csv
    from .run import find_skymaps, run_bench, skymaps_in
    from .settings import OURS, SOLVERS, BenchConfig, BenchSettings, is_row_name, row_solver
    from .summary import summarize

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "BenchConfig": ".settings", "BenchSettings": ".settings", "OURS": ".settings", "SOLVERS": ".settings",
    "row_solver": ".settings", "is_row_name": ".settings",
    "COLUMNS": ".rows", "read_csv": ".rows", "write_csv": ".rows",
    "SIMILAR_LENGTH": ".compare", "TIE_COVERAGE": ".compare", "TIE_EFFICIENCY": ".compare", "best_of": ".compare",
    "bench_map": ".per_map",
    "find_skymaps": ".run", "skymaps_in": ".run", "run_bench": ".run",
    "summarize": ".summary",
    "make_plots": ".plots",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
