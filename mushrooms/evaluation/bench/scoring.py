"""How one plan is judged: the independent checker, and the kilonova detection efficiency.

Scoring uses the source model the scheduler shares
(:mod:`~mushrooms.scheduler_core.source.kilonova`: light curves alive from the
merger on; :mod:`~mushrooms.scheduler_core.source.depth`: each exposure's limit
from its airmass, Moon and twilight), on the SAME injections for every plan
of a map (seeded from the map's hash).  Every difference between two plans
of one map is paired (same injections) and reported with its Monte Carlo
error: ``efficiency_<lc>_diff`` / ``_differr`` against the reference row,
and, with ``[bench] legacy_scoring``, the first release's score of the same
plan (``efficiency_<lc>_v1``: flat 300 s limits, light curve dark before
0.202 d) with the paired change ``efficiency_<lc>_v1diff`` / ``_v1differr``.

Beside the Monte Carlo efficiency, ``expected_<lc>`` is the plan's exact
expected detections (X1, the efficiency's expectation over the posterior:
no Monte Carlo error), and ``expected_<lc>_diff`` / ``coverage_diff`` its and
the coverage's paired change against the reference row; ``exposure_mix``
(``30:4 300:20``: exposures of that length) and ``exposure_mean_s`` (mean
exposure of the planned fields weighted by their probability) say which
exposures a plan took.  ``coverage_as_executed`` is the plan's coverage as
ZTF's scheduler would execute its queues: the
plan's queue set executed by the telescope model (the configuration's filters and
cadence for a plan that names none: gwemopt's), with ``coverage_late_<min>``,
``coverage_single_queue`` ("as submitted today": through SkyPortal's ZTF API, ours as the service POSTs it,
one SkyPortal plan per filter pass; a baseline's as one plan, one list queue) and ``n_queues``
beside it (:func:`~mushrooms.evaluation.queue_sim.execution_cells`), with the
shutter-open seconds each run took.  ``coverage_pairs`` is the planned coverage
counted by the pair rule the executed coverage uses (fields with the first two
filters' exposures the cadence apart, each inside its window:
:mod:`~mushrooms.evaluation.pair_coverage`), the same rule for every row, and
``open_shutter_s`` the plan's summed exposure time.
``efficiency_two_detections`` and its siblings are the scoring the planner
does not see (:mod:`.independent`: ZTF's two-detection rule on the executed
record, a kilonova grid, dust, ztf_sim's depth, perturbed execution).
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .rows import fmt
from .settings import BenchSettings

__all__ = ["score_plan", "pair_with_reference", "execution_cells_under"]


def score_plan(plan: Any, skymap: Any, settings: BenchSettings, footprints: Any, injections: Any,
               lightcurves: Mapping[str, Any], merger_time: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Checker verdict, coverage and efficiencies of one plan, and its detections per light curve.

    Parameters
    ----------
    plan : Plan
        The plan to judge.
    skymap : SkyMap
        Its sky map.
    settings : BenchSettings
        The planning configuration (for the checker) and ``[bench]`` (v1 scoring).
    footprints : Footprints
        ZTF field footprints at the map's resolution.
    injections : Injections or None
        The map's kilonova injections (None: no efficiency).
    lightcurves : mapping
        Column suffix -> loaded light curve.
    merger_time : astropy.time.Time or None
        When the light curves start.

    Returns
    -------
    scores : dict
        Row cells (coverage, validity, exposures, ``efficiency_<lc>`` ...).
    hits : dict
        Light-curve suffix -> bool array, one per injection: detected.
    """
    from ...scheduler_core.plan.checker import check_plan

    report = check_plan(plan, skymap, settings.config)
    out = _plan_cells(plan, report)
    hits: dict[str, np.ndarray] = {}
    for key, lc in lightcurves.items():
        if injections is None or merger_time is None:
            out[f"efficiency_{key}"] = ""
            continue
        hits[key], cells = _efficiency_cells(key, lc, plan, settings, footprints, injections, merger_time)
        out.update(cells)
        out[f"expected_{key}"] = _expected(plan, skymap, footprints, lc, merger_time)
    out.update(_exposure_cells(plan, footprints, skymap.prob))
    out.update(execution_cells_under(plan, settings.config, footprints, skymap.prob))
    out.update(pair_cells(plan, settings.config, footprints, skymap.prob))
    out.update(_independent(plan, skymap, settings, footprints, merger_time))
    return out, hits


def pair_cells(plan: Any, config: Any, footprints: Any, prob: np.ndarray) -> dict[str, Any]:
    """``coverage_pairs`` (planned coverage by the pair rule, under ``config``'s filters, cadence and windows)
    and ``open_shutter_s`` (the plan's summed exposure time, s)."""
    from ..pair_coverage import open_shutter_s, planned_pair_coverage

    return dict(coverage_pairs=fmt(planned_pair_coverage(plan, footprints, prob, config)),
                open_shutter_s=fmt(open_shutter_s(plan), 1))


def _independent(plan: Any, skymap: Any, settings: BenchSettings, footprints: Any, merger_time: Any) -> dict:
    """The scoring the planner does not see (:mod:`.independent`), on the plan's executed queue set."""
    from .independent import independent_cells

    return independent_cells(_under_config(plan, settings.config), skymap, footprints, merger_time,
                             getattr(settings, "truth", None))


def _under_config(plan: Any, config: Any) -> Any:
    """``plan`` with the planning configuration's filters and cadence when it names none (gwemopt's plans)."""
    if plan.observations and not plan.config:
        return plan.with_(config={"filters": list(config.filters), "cadence_s": float(config.cadence_s)})
    return plan


def execution_cells_under(plan: Any, config: Any, footprints: Any, prob: np.ndarray) -> dict[str, Any]:
    """What ZTF's scheduler keeps of the plan's queues (Q14): on time, late, and the old single queue.

    A plan that names no filters or cadence (a baseline's) is run under ``config``'s.
    "As submitted today" (``coverage_single_queue``) is the plan through
    SkyPortal's ZTF API as its planner hands it on: ours (a plan with its
    config) as the service POSTs it, one SkyPortal plan per filter pass
    (``[export] skyportal_plans`` default, docs/design/submission.md T1);
    a baseline's as one SkyPortal plan (gwemopt's way today: one list queue).

    A plan without exposures (a not-observable answer) executes nothing: its
    ``coverage_as_executed`` and ``coverage_single_queue`` are 0 (nothing is
    submitted either way), its late cells empty.
    """
    from ..queue_sim import execution_cells

    from ...scheduler_core.plan.exports import ExportConfig

    today = ExportConfig().skyportal_plans if plan.config else "single"
    cells = execution_cells(_under_config(plan, config), footprints, prob, skyportal_plans=today)
    if not plan.observations:
        cells.update(coverage_as_executed=0.0, coverage_single_queue=0.0, open_shutter_executed_s=0.0,
                     open_shutter_single_queue_s=0.0)
    return cells


def _expected(plan: Any, skymap: Any, footprints: Any, lc: Any, merger_time: Any) -> Any:
    """The plan's exact expected detections (X1) of one light curve (empty without distance layers)."""
    from ...scheduler_core.source.depth import ZTF_DEPTH
    from ...scheduler_core.source.detection import expected_detections
    from ...scheduler_core.source.kilonova import Kilonova

    e = expected_detections(plan, skymap, footprints, Kilonova(lc), merger_time, ZTF_DEPTH)
    return fmt(None if e is None else float(e))


def _exposure_cells(plan: Any, footprints: Any, prob: np.ndarray) -> dict[str, Any]:
    """``exposure_mix`` (``length:count`` of the plan's exposures) and ``exposure_mean_s`` (per field, weighted
    by the field's probability; the longest of a field's exposures)."""
    obs = plan.observations
    if not obs:
        return dict(exposure_mix="", exposure_mean_s="")
    lengths, counts = np.unique([float(o.exposure_s) for o in obs], return_counts=True)
    per: dict[int, float] = {}
    for o in obs:
        per[o.field_id] = max(per.get(o.field_id, 0.0), float(o.exposure_s))
    w = np.array([footprints.coverage({f}, prob) for f in per])
    e = np.array(list(per.values()))
    mean = float((w * e).sum() / w.sum()) if w.sum() > 0 else float(e.mean())
    return dict(exposure_mix=" ".join(f"{x:g}:{n}" for x, n in zip(lengths, counts)), exposure_mean_s=fmt(mean, 1))


def _plan_cells(plan: Any, report: Any) -> dict[str, Any]:
    """The checker's verdict and the plan's size: coverage, validity, exposures, fields, length."""
    obs = plan.observations
    return dict(
        coverage=fmt(float(report.coverage)),
        coverage_reported=fmt(float(plan.metrics.coverage)),
        valid=bool(report.ok),
        n_problems=len(report.problems),
        first_problem=(report.problems[0][:200] if report.problems else ""),
        n_exposures=len(obs),
        n_fields=len({o.field_id for o in obs}),
        schedule_length_s=fmt(float(obs[-1].end - obs[0].start), 1) if obs else 0.0,
        first_exposure_s=fmt(float(obs[0].start), 1) if obs else "",
        expected_detections=fmt(getattr(plan.metrics, "expected_detections", None)),
    )


def _efficiency_cells(key: str, lc: Any, plan: Any, settings: BenchSettings, footprints: Any, injections: Any,
                      merger_time: Any) -> tuple[np.ndarray, dict[str, Any]]:
    """Detections of one light curve (the shared source model) and its cells, v1 scoring included if asked."""
    from ...scheduler_core.source.depth import ZTF_DEPTH
    from ...scheduler_core.source.kilonova import Kilonova
    from ..efficiency import detected, paired_difference

    h = detected(plan, Kilonova(lc), footprints, injections, merger_time, ZTF_DEPTH)
    cells = {f"efficiency_{key}": fmt(float(h.mean()))}
    if settings.bench.legacy_scoring:
        h1 = detected(plan, lc, footprints, injections, merger_time, settings.bench.maglim)
        d, e = paired_difference(h, h1)
        cells.update({f"efficiency_{key}_v1": fmt(float(h1.mean())), f"efficiency_{key}_v1diff": fmt(d),
                      f"efficiency_{key}_v1differr": fmt(e)})
    return h, cells


def pair_with_reference(rows: list[dict[str, Any]], hits: Mapping[str, Mapping[str, np.ndarray]],
                        reference: str) -> None:
    """Add ``efficiency_<lc>_diff`` / ``_differr`` (paired, vs ``reference``), ``expected_<lc>_diff`` and
    ``coverage_diff`` to each row in place."""
    from ..efficiency import paired_difference
    from .rows import num

    ref = hits.get(reference)
    ref_row = next((r for r in rows if r["solver"] == reference), None)
    if not ref or ref_row is None:
        return
    for row in rows:
        mine = hits.get(str(row["solver"]))
        if not mine or row["solver"] == reference:
            continue
        for key, h in mine.items():
            if key in ref:
                d, e = paired_difference(h, ref[key])
                row[f"efficiency_{key}_diff"] = fmt(d)
                row[f"efficiency_{key}_differr"] = fmt(e)
            a, b = num(row.get(f"expected_{key}")), num(ref_row.get(f"expected_{key}"))
            if a is not None and b is not None:
                row[f"expected_{key}_diff"] = fmt(a - b)
        a, b = num(row.get("coverage")), num(ref_row.get("coverage"))
        if a is not None and b is not None:
            row["coverage_diff"] = fmt(a - b)
