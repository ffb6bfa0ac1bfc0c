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
    status = h.writeModel(str(path))
    if status != highspy.HighsStatus.kOk:
        raise OSError(f"HiGHS could not write the model to {path} ({status})")
