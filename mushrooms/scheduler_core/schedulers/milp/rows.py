"""Constraint rows named after their equations: where the MILP models' index arithmetic lives.

A model is written the way its design doc writes it (``docs/design/milp.md``,
``docs/design/detection.md``): variable families first, then one named
block of rows per numbered equation.  :class:`Columns` hands out the
families (``z = cols.family("z", F)``; ``z[f]`` is the column of ``z_f``),
:class:`RowBuilder` collects the blocks, each as (row within the block,
column, coefficient) triplets, and assembles the sparse matrix once.  The
blocks' names and spans travel with the model (:attr:`MilpModel.row_blocks
<.solvers.MilpModel.row_blocks>`), so a written-out LP file
(:func:`~.solvers.write_lp`) names each row after its equation,
``S2_each_field_at_most_once.17``.

Examples
--------
Two fields, one cell seen by both: ``max y`` s.t. (S2-like) ``z_f = x_f``
and (S3-like) ``y <= z_0 + z_1``.

>>> import numpy as np
>>> cols = Columns()
>>> x, z, y = cols.family("x", 2), cols.family("z", 2), cols.family("y", 1)
>>> rows = RowBuilder()
>>> rows.block("S2 each field at most once", 2,
...            [(np.arange(2), z[np.arange(2)], 1.0), (np.arange(2), x[np.arange(2)], -1.0)], 0.0, 0.0)
>>> rows.block("S3 cell coverage", 1, [([0], y[[0]], 1.0), ([0, 0], z[[0, 1]], -1.0)], -np.inf, 0.0)
>>> A, lo, hi = rows.matrix(cols.n)
>>> A.toarray()
array([[-1.,  0.,  1.,  0.,  0.],
       [ 0., -1.,  0.,  1.,  0.],
       [ 0.,  0., -1., -1.,  1.]])
>>> [(b.name, b.start, b.stop) for b in rows.blocks()]
[('S2 each field at most once', 0, 2), ('S3 cell coverage', 2, 3)]
>>> row_names(rows.blocks())
['S2_each_field_at_most_once.0', 'S2_each_field_at_most_once.1', 'S3_cell_coverage.0']
>>> column_names(cols.families())
['x.0', 'x.1', 'z.0', 'z.1', 'y.0']
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["RowBlock", "Family", "Columns", "RowBuilder", "at_least_when", "row_names", "column_names", "lp_label"]


def lp_label(name: str) -> str:
    """``name`` as an LP-file identifier: runs of anything but letters and digits become ``_``."""
    return re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")


@dataclass(frozen=True)
class RowBlock:
    """Rows ``start .. stop-1`` of a model, built by the equation ``name`` (``"C3 cadence"``)."""

    name: str
    start: int
    stop: int

    @property
    def n_rows(self) -> int:
        """Number of rows of the block."""
        return self.stop - self.start


@dataclass(frozen=True)
class Family:
    """Columns ``start .. start+size-1``: one variable family (``x_k``, ``z_f``, ``y_l``)."""

    name: str
    start: int
    size: int

    @property
    def stop(self) -> int:
        """One past the family's last column."""
        return self.start + self.size

    def __getitem__(self, index) -> np.ndarray:
        """Columns of the members ``index`` (an int or an array of member indices, not checked)."""
        return self.start + np.asarray(index, np.int64)

    @property
    def columns(self) -> np.ndarray:
        """Every column of the family, in member order."""
        return np.arange(self.start, self.stop, dtype=np.int64)


class Columns:
    """Variable families laid out one after the other."""

    def __init__(self) -> None:
        self._families: list[Family] = []
        self.n = 0

    def family(self, name: str, size: int) -> Family:
        """Append a family of ``size`` variables named ``name``."""
        fam = Family(name, self.n, int(size))
        self._families.append(fam)
        self.n += int(size)
        return fam

    def families(self) -> tuple[Family, ...]:
        """The families, in column order."""
        return tuple(self._families)


class RowBuilder:
    """Sparse rows ``lo <= A x <= hi``, appended one named block (equation) at a time.

    ``prefix`` (default empty) is put before the name of every block appended
    while it is set: a model holding several telescopes' rows
    (``docs/design/telescopes.md``, J4) names each telescope's ``ztf: S1 ...``.
    """

    def __init__(self, prefix: str = "") -> None:
        self.prefix = prefix
        self._r: list[np.ndarray] = []
        self._c: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._lo: list[np.ndarray] = []
        self._hi: list[np.ndarray] = []
        self._blocks: list[list] = []  # [name, start, stop]
        self.n_rows = 0

    def _open(self, name: str, n_rows: int) -> None:
        name = self.prefix + name
        last = self._blocks[-1] if self._blocks else None
        if last is not None and last[0] == name and last[2] == self.n_rows:
            last[2] += n_rows  # the same equation again: one block
        else:
            self._blocks.append([name, self.n_rows, self.n_rows + n_rows])

    def block(self, name: str, n_rows: int, terms, lo, hi) -> None:
        """Append ``n_rows`` rows of the equation ``name``.

        Parameters
        ----------
        name : str
            The equation, number first (``"B4 cell coverage"``).
        n_rows : int
            Rows in the block.
        terms : list of (rows, columns, coefficients)
            Arrays (coefficients may be a scalar); ``rows`` count from the block's first row.
        lo, hi : float or numpy.ndarray
            Row bounds (``-inf`` / ``inf`` for a one-sided row), broadcast to ``n_rows``.
        """
        for rr, cc, vv in terms:
            rr = np.asarray(rr, np.int64)
            self._r.append(rr + self.n_rows)
            self._c.append(np.asarray(cc, np.int64))
            self._v.append(np.broadcast_to(np.asarray(vv, float), rr.shape).copy())
        self._lo.append(np.broadcast_to(np.asarray(lo, float), (n_rows,)).copy())
        self._hi.append(np.broadcast_to(np.asarray(hi, float), (n_rows,)).copy())
        self._open(name, n_rows)
        self.n_rows += n_rows

    def row(self, name: str, cols, vals, lo: float, hi: float) -> None:
        """Append one row ``lo <= Σ vals · x[cols] <= hi`` of the equation ``name``."""
        self._r.append(np.full(len(cols), self.n_rows, np.int64))
        self._c.append(np.asarray(cols, np.int64))
        self._v.append(np.asarray(vals, float))
        self._lo.append(np.array([lo], float))
        self._hi.append(np.array([hi], float))
        self._open(name, 1)
        self.n_rows += 1

    def matrix(self, n_cols: int) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
        """``(A, row_lo, row_hi)``; entries of a row repeated on one column are summed."""
        if not self._lo:
            return sp.csr_matrix((0, n_cols)), np.zeros(0), np.zeros(0)
        r = np.concatenate(self._r) if self._r else np.zeros(0, np.int64)
        c = np.concatenate(self._c) if self._c else np.zeros(0, np.int64)
        v = np.concatenate(self._v) if self._v else np.zeros(0)
        A = sp.csr_matrix((v, (r, c)), shape=(self.n_rows, n_cols))
        A.sum_duplicates()
        return A, np.concatenate(self._lo), np.concatenate(self._hi)

    def blocks(self) -> tuple[RowBlock, ...]:
        """The named blocks, in row order."""
        return tuple(RowBlock(name, start, stop) for name, start, stop in self._blocks)


def _indexed(named: list[tuple[str, int]]) -> list[str]:
    """``label.i`` for each (name, count), i = 0 .. count-1."""
    return [f"{lp_label(name)}.{i}" for name, count in named for i in range(count)]


def row_names(blocks: tuple[RowBlock, ...] | list[RowBlock]) -> list[str]:
    """One LP identifier per row: the block's label and the row's index within it."""
    return _indexed([(b.name, b.n_rows) for b in blocks])


def column_names(families: tuple[Family, ...] | list[Family]) -> list[str]:
    """One LP identifier per column: the family's name and the member's index."""
    return _indexed([(f.name, f.size) for f in families])


def at_least_when(rows: RowBuilder, name: str, cols, vals, rhs: float, when, big_m: float) -> None:
    """Append ``Σ vals · x[cols] >= rhs``, enforced only when every binary literal of ``when`` holds (big-M).

    Parameters
    ----------
    rows : RowBuilder
        Where the row goes.
    name : str
        The equation (``"C4 one exposure at a time"``).
    cols, vals : sequence
        The row's columns and coefficients.
    rhs : float
        Right-hand side when every literal holds.
    when : sequence of (column, value)
        Binary columns and the value (1 or 0) the row needs; each literal
        that does not hold relaxes the row by ``big_m``: the row is
        ``Σ vals x >= rhs - M Σ_{b = 1 wanted} (1 - b) - M Σ_{b = 0 wanted} b``.
    big_m : float
        M, at least the most the left side can fall short of ``rhs``.
    """
    lit_cols = [c for c, _ in when]
    lit_vals = [-big_m if want else big_m for _, want in when]
    n_on = sum(1 for _, want in when if want)
    rows.row(name, [*cols, *lit_cols], [*vals, *lit_vals], rhs - n_on * big_m, np.inf)
