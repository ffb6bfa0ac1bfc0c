"""A model written out as an LP file, its rows named after their equations.

HiGHS writes the file (``Highs.writeModel``, the format from the suffix:
``.lp`` CPLEX LP, ``.mps`` MPS); the names come from the model's row
blocks and column families (:mod:`.rows`), so a reader of
``slots.lp`` finds ``S2_each_field_at_most_once.17`` where the design doc
has (S2).
"""

from __future__ import annotations

from .rows import column_names, row_names
from .solvers import MilpModel, highs_lp

__all__ = ["write_lp"]


def write_lp(model: MilpModel, path) -> None:
    """Write the model as an LP file, each row named after its equation (``C3_cadence.4``).

    Rows and columns of a model built without names get HiGHS's defaults.

    Parameters
    ----------
    model : MilpModel
        The model; its :attr:`~MilpModel.row_blocks` and
        :attr:`~MilpModel.col_families` name the rows and columns.
    path : str or os.PathLike
        Where to write; the suffix ``.lp`` selects HiGHS's LP writer.

    Examples
    --------
    One cell seen by two fields, at most one field (``max y``, ``y <= x_0 + x_1``, ``x_0 + x_1 <= 1``):

    >>> import numpy as np, tempfile, pathlib
    >>> from mushrooms.scheduler_core.schedulers.milp.rows import Columns, RowBuilder
    >>> cols = Columns()
    >>> x, y = cols.family("x", 2), cols.family("y", 1)
    >>> rows = RowBuilder()
    >>> rows.block("S3 cell coverage", 1, [([0], y[[0]], 1.0), ([0, 0], x[[0, 1]], -1.0)], -np.inf, 0.0)
    >>> rows.block("K at most one field", 1, [([0, 0], x[[0, 1]], 1.0)], -np.inf, 1.0)
    >>> A, lo, hi = rows.matrix(cols.n)
    >>> model = MilpModel(np.array([0.0, 0.0, 1.0]), A, lo, hi, np.zeros(3), np.ones(3),
    ...                   np.array([True, True, False]), rows.blocks(), cols.families())
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "tiny.lp"
    >>> write_lp(model, path)
    >>> text = path.read_text()
    >>> "S3_cell_coverage.0" in text and "K_at_most_one_field.0" in text and "x.1" in text
    True
    """
    import highspy

    lp = highs_lp(model, highspy)
    names = row_names(model.row_blocks)
    if len(names) == model.n_rows and names:
        lp.row_names_ = names
    cols = column_names(model.col_families)
    if len(cols) == model.n_vars and cols:
        lp.col_names_ = cols
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.passModel(lp)
    status = h.writeModel(str(path))  # a warning: HiGHS named what had no name
    if status == highspy.HighsStatus.kError:
        raise OSError(f"HiGHS could not write the model to {path} ({status})")
