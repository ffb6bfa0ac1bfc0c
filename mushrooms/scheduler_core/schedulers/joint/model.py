"""The joint slot model of several telescopes on one map (``docs/design/telescopes.md``, J1-J4).

Each telescope ``τ`` keeps its own slot model (``docs/design/milp.md``,
S1-S2 on its own grid, windows, exposures and cadence): its pairs ``x_τ``
and fields ``z_τ``.  The cells over the union of the telescopes' shortlists
(:mod:`.cells`) take one variable ``y_l`` each, and only they couple the
telescopes:

- (J1) ``max Σ_l w_l y_l − Σ_τ p_τ Σ_j z_{τ,j}``, ``y_l ∈ [0, 1]``: a pixel
  counts once however many telescopes cover it;
- (J2) ``y_l − Σ_τ Σ_{j ∈ S_{l,τ}} z_{τ,j} <= 0``;
- (J3) ``z_{τ,j}`` is 1 only through one of τ's complete candidates (its
  S2 row ``z − Σ_k x_k = 0`` over the pairs whose visits keep τ's cadence
  rule by construction, G1-G3);
- (J4) τ's own rows, S1 and S2, on its own variables (the rows are named
  ``<telescope>: S1 ...``): no row mixes two telescopes' schedules.

:func:`decode_joint` times each telescope's chosen pairs with its own real
overheads (the single-telescope :func:`~..slots.schedule.time_slot_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...plan.document import Observation
from ...problem import PlanningProblem
from ...sky.cells import Cells
from ..blocks.schedule import shortlist_footprints
from ..milp.rows import Columns, Family, RowBuilder
from ..milp.solvers import MilpModel
from ..slots.model import SlotInstance, SlotModel, slot_instance, slot_model_rows
from ..slots.schedule import map_start, slot_portfolio, slot_rows, time_slot_plan
from .cells import JointCells, joint_cells, telescope_names

__all__ = ["JointInstance", "JointModel", "joint_instance", "build_joint_model", "decode_joint", "joint_start", "reweighted",
           "NO_CELLS"]

#: The empty cells a telescope's own slot instance carries in the joint model (J2 replaces its S3).
NO_CELLS = Cells(np.zeros(0), np.zeros(1, np.int64), np.zeros(0, np.int64), 0)


@dataclass(frozen=True)
class JointInstance:
    """The telescopes' slot instances and the cells coupling them.

    Attributes
    ----------
    problems : tuple of PlanningProblem
        One per telescope.
    names : tuple of str
        The telescopes' names (row and column prefixes).
    parts : tuple of SlotInstance or None
        Each telescope's instance on its first portfolio grid
        (:func:`~..slots.schedule.slot_portfolio`); None for a telescope with
        no eligible pair (no window long enough) or a one-visit rule (one
        filter): it takes no part in the model (the ascent plans it).
    joint : JointCells
        Cells over the parts' shortlists stacked in telescope order.
    """

    problems: tuple[PlanningProblem, ...]
    names: tuple[str, ...]
    parts: tuple[SlotInstance | None, ...]
    joint: JointCells

    @property
    def n_pairs(self) -> int:
        """Binaries of the model: every part's eligible pairs."""
        return sum(p.n_pairs for p in self.parts if p is not None)


def _part(problem: PlanningProblem) -> SlotInstance | None:
    """One telescope's slot instance on its first grid (n*, phase start), or None."""
    if problem.field_ids.size == 0 or len(problem.config.filters) < 2:  # the slot model plans 2 visits or more
        return None
    rows = slot_rows(problem)
    if rows.size == 0:
        return None
    grids = slot_portfolio(problem, rows)
    if not grids:
        return None
    inst = slot_instance(problem, rows, grids[0], cells=NO_CELLS)
    return inst if inst.n_pairs else None


def joint_instance(problems: Sequence[PlanningProblem], weight: np.ndarray | None = None,
                   names: Sequence[str] | None = None) -> JointInstance:
    """The joint instance: each telescope's slot instance and the cells over their fields.

    Parameters
    ----------
    problems : sequence of PlanningProblem
        One per telescope, on the same map and resolution.
    weight : numpy.ndarray, optional
        Objective weight per pixel (J5: 0 where an executed record covers);
        default the map's probability.
    names : sequence of str, optional
        Telescope names (default: :func:`~.cells.telescope_names`, each problem's ``telescope``).
    """
    problems = tuple(problems)
    names = telescope_names(problems, names)
    parts = tuple(_part(p) for p in problems)
    inst = JointInstance(problems, names, parts, joint_cells([], np.zeros(0), problems[0].footprints.nside))
    return reweighted(inst, problems[0].prob if weight is None else weight)


def reweighted(instance: JointInstance, weight: np.ndarray) -> JointInstance:
    """The instance with its cells weighted by ``weight`` (per pixel; J5, or 0 where fixed plans cover)."""
    prints = [shortlist_footprints(p.footprints, part.rows if part is not None else np.zeros(0, np.int64))
              for p, part in zip(instance.problems, instance.parts)]
    cells = joint_cells(prints, np.asarray(weight, float), instance.problems[0].footprints.nside)
    return JointInstance(instance.problems, instance.names, instance.parts, cells)


@dataclass(frozen=True)
class JointModel:
    """The assembled joint MILP: variables ``[x_τ | z_τ]`` per telescope, then ``y``.

    Attributes
    ----------
    milp : MilpModel
    instance : JointInstance
    x, z : tuple of Family or None
        Each telescope's pair and field columns (None: no part).
    y : Family
        The cells' columns.
    """

    milp: MilpModel
    instance: JointInstance
    x: tuple[Family | None, ...]
    z: tuple[Family | None, ...]
    y: Family

    def start_vector(self, pairs: Sequence[Sequence[int]]) -> np.ndarray:
        """A full solution choosing, per telescope, the given pair indices (x, z, and the best y)."""
        v = np.zeros(self.milp.n_vars)
        z_cols = []
        for part, x, z, chosen in zip(self.instance.parts, self.x, self.z, pairs):
            if part is None:
                continue
            chosen = np.asarray(list(chosen), np.int64)
            v[x[chosen]] = 1.0
            v[z[part.pair_field[chosen]]] = 1.0
            z_cols.append(z.columns)
        cells = self.instance.joint.cells
        if cells.n_cells and z_cols:
            stacked = np.concatenate(z_cols)
            cell_of = np.repeat(np.arange(cells.n_cells), np.diff(cells.indptr))
            covered = np.zeros(cells.n_cells)
            np.maximum.at(covered, cell_of, v[stacked[cells.fields]])
            v[self.y.columns] = covered
        return v


def build_joint_model(instance: JointInstance) -> JointModel:
    """Assemble the joint slot model, J1-J4 of ``docs/design/telescopes.md``."""
    cols = Columns()
    xs: list[Family | None] = []
    zs: list[Family | None] = []
    for name, part in zip(instance.names, instance.parts):
        xs.append(None if part is None else cols.family(f"{name}.x", part.n_pairs))
        zs.append(None if part is None else cols.family(f"{name}.z", part.n_fields))
    cells = instance.joint.cells
    y = cols.family("y", cells.n_cells)
    rows = RowBuilder()
    for name, part, x, z in zip(instance.names, instance.parts, xs, zs):
        if part is None:
            continue
        # (J3) z_{τ,j} = Σ over τ's complete candidates (its S2 row); (J4) τ's own rows S1, S2, named after τ
        rows.prefix = f"{name}: "
        slot_model_rows(rows, part, x, z, None, cover=False)
    rows.prefix = ""
    # (J2) coverage through any telescope: y_l - Σ_τ Σ_{j ∈ S_{l,τ}} z_{τ,j} <= 0 (stacked rows -> columns)
    stacked = np.concatenate([z.columns for z in zs if z is not None] or [np.zeros(0, np.int64)])
    C = cells.n_cells
    cell_of = np.repeat(np.arange(C), np.diff(cells.indptr))
    rows.block("J2 coverage through any telescope", C,
               [(np.arange(C), y[np.arange(C)], 1.0), (cell_of, stacked[cells.fields], -1.0)], -np.inf, 0.0)
    A, lo, hi = rows.matrix(cols.n)
    # (J1) objective: Σ_l w_l y_l - Σ_τ p_τ Σ_j z_{τ,j}, a pixel counted once
    obj = np.zeros(cols.n)
    obj[y.columns] = cells.weight
    integer = np.zeros(cols.n, bool)
    for problem, x, z in zip(instance.problems, xs, zs):
        if x is not None:
            obj[z.columns] = -float(problem.config.penalty)
            integer[x.columns] = True
    milp = MilpModel(obj, A, lo, hi, np.zeros(cols.n), np.ones(cols.n), integer, rows.blocks(), cols.families())
    return JointModel(milp, instance, tuple(xs), tuple(zs), y)


def joint_start(model: JointModel, plans: Sequence[Sequence[Observation]]) -> np.ndarray | None:
    """A start vector placing each telescope's plan on its grid (:func:`~..slots.schedule.map_start`); None if empty."""
    pairs = []
    for problem, part, obs in zip(model.instance.problems, model.instance.parts, plans):
        if part is None:
            pairs.append([])
            continue
        first: dict[int, float] = {}
        for o in obs:
            first[o.field_id] = min(o.start, first.get(o.field_id, np.inf))
        field_of = {int(problem.field_ids[r]): f for f, r in enumerate(part.rows)}
        pairs.append(map_start(part, {field_of[f]: t for f, t in first.items() if f in field_of}).tolist())
    return model.start_vector(pairs) if any(pairs) else None


def decode_joint(model: JointModel, x: np.ndarray) -> list[tuple[list[Observation], list[int]]]:
    """Each telescope's exposures, timed with its own real overheads, and the fields its timing dropped."""
    out = []
    for problem, part, fam in zip(model.instance.problems, model.instance.parts, model.x):
        if part is None:
            out.append(([], []))
            continue
        own = SlotModel(model.milp, part)  # time_slot_plan reads the instance and x[:n_pairs]
        obs, dropped, _ = time_slot_plan(problem, own, np.asarray(x)[fam.columns])
        out.append((obs, dropped))
    return out
