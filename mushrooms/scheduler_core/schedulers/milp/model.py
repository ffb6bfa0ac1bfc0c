"""The backend-neutral MILP: the model every equation block is built into, and what a solve returns.

:class:`MilpModel` (sparse constraint matrix, row and column bounds,
integrality, objective, the rows' equation names) is what the models of
:mod:`..blocks`, :mod:`..slots`, :mod:`..bounds`, :mod:`..detection` and
:mod:`..portfolio` build; :func:`~.solvers.solve_milp` solves it with HiGHS
or Gurobi and answers with a :class:`SolveResult` of one shape for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .rows import Family, RowBlock

__all__ = ["MilpModel", "SolveResult", "relative_gap"]


@dataclass(frozen=True)
class MilpModel:
    """A maximisation MILP ``max c·x`` s.t. ``row_lo <= A x <= row_hi``, ``col_lo <= x <= col_hi``.

    Attributes
    ----------
    c : numpy.ndarray
        (n,) objective coefficients (maximised).
    A : scipy.sparse.csr_matrix
        (m, n) constraint matrix.
    row_lo, row_hi : numpy.ndarray
        (m,) row bounds (``-inf`` / ``inf`` allowed).
    col_lo, col_hi : numpy.ndarray
        (n,) variable bounds.
    integer : numpy.ndarray
        (n,) True for integer variables.
    row_blocks : tuple of RowBlock
        The rows' equations (:mod:`.rows`), in row order; empty for a model
        built without names.  Only :func:`~.lp_file.write_lp` reads them.
    col_families : tuple of Family
        The columns' variable families, in column order (may be empty).
    """

    c: np.ndarray
    A: sp.csr_matrix
    row_lo: np.ndarray
    row_hi: np.ndarray
    col_lo: np.ndarray
    col_hi: np.ndarray
    integer: np.ndarray
    row_blocks: tuple[RowBlock, ...] = ()
    col_families: tuple[Family, ...] = ()

    @property
    def n_vars(self) -> int:
        """Number of variables."""
        return int(self.c.size)

    @property
    def n_rows(self) -> int:
        """Number of constraints."""
        return int(self.A.shape[0])

    @property
    def n_integer(self) -> int:
        """Number of integer variables."""
        return int(np.count_nonzero(self.integer))

    def size(self) -> dict[str, int]:
        """Model size: variables, integer variables, constraints, nonzeros."""
        return {"vars": self.n_vars, "int_vars": self.n_integer,
                "rows": self.n_rows, "nonzeros": int(self.A.nnz)}


@dataclass
class SolveResult:
    """What a solve returned, in one shape for every backend.

    Attributes
    ----------
    backend : str
        ``highs`` or ``gurobi`` (the one that really ran).
    status : str
        ``optimal``, ``time_limit``, ``work_limit`` (the work clock's, A2),
        ``interrupted``, ``infeasible`` or ``error: ...``.
    x : numpy.ndarray or None
        Best solution found (None without an incumbent).
    objective : float or None
        Objective of ``x``.
    bound : float or None
        Best (upper) bound on the optimum.
    gap : float or None
        Relative gap ``(bound - objective) / max(|objective|, 1e-10)``.
    runtime_s : float
        Wall time (s) of the solve.
    time_to_first_s : float or None
        Wall time (s) to the first incumbent.
    time_to_gap_s : float or None
        Wall time (s) until the gap first fell to 1 % or less.
    note : str
        Why a fallback happened, if it did.
    """

    backend: str
    status: str
    x: np.ndarray | None = None
    objective: float | None = None
    bound: float | None = None
    gap: float | None = None
    runtime_s: float = 0.0
    time_to_first_s: float | None = None
    time_to_gap_s: float | None = None
    note: str = ""
    progress: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def has_solution(self) -> bool:
        """True when an incumbent exists."""
        return self.x is not None


def relative_gap(objective: float | None, bound: float | None) -> float | None:
    """Relative MIP gap of a maximisation, ``(bound - obj) / max(|obj|, 1e-10)``, >= 0."""
    if objective is None or bound is None or not math.isfinite(objective) or not math.isfinite(bound):
        return None
    return max(0.0, bound - objective) / max(abs(objective), 1e-10)
