"""The MILP adapter the models share: one backend-neutral model, rows named after their equations.

* :mod:`.rows`: constraint rows built by family, each named after its
  equation of ``docs/design/`` (``S1``, ``B4``, ``U2``...): where the
  models' index arithmetic lives;
* :mod:`.model`: the model (:class:`MilpModel`) and a solve's result;
* :mod:`.solvers`: its solve with HiGHS or Gurobi (:func:`solve_milp`);
* :mod:`.lp_file`: a model written out as an LP file with those names.

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .model import MilpModel, SolveResult
    from .solvers import solve_milp, resolve_backend
    from .rows import RowBuilder, Columns, Family, RowBlock
    from .lp_file import write_lp

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "MilpModel": ".model", "SolveResult": ".model",
    "solve_milp": ".solvers", "resolve_backend": ".solvers",
    "RowBuilder": ".rows", "Columns": ".rows", "Family": ".rows", "RowBlock": ".rows",
    "write_lp": ".lp_file",
}

__all__ = [
    "MilpModel", "SolveResult", "solve_milp", "resolve_backend", "RowBuilder", "Columns", "Family",
    "RowBlock", "write_lp",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
