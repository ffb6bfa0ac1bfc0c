"""The bench row's independent-scoring cells (:mod:`~mushrooms.evaluation.independent_scoring`).

Every row of a map is scored on the same sources and the same perturbation
seeds (both from the map's SHA-256): at a simulated event's injected truth
when the settings carry it (:attr:`~.settings.BenchSettings.truth`, set by the
study for a population's coincidences), else drawn from the map's 3-D
posterior.  Cells (fractions of the sources):

``efficiency_two_detections``
    ZTF's vetting rule (two detections at least 15 min apart) on the nominal
    executed record, kilonovae over the Bulla (2019) grid, SFD extinction,
    the depth the ZTF/GROWTH campaigns reached (flat 20.8, Kasliwal et al.
    2020): the one depth that owes nothing to the planner's model.
``efficiency_one_detection``
    The same with one detection.
``efficiency_two_detections_overheads`` / ``_perturbed``
    Means over :data:`BENCH_PERTURBATIONS` seeded draws of the overheads,
    and of the overheads with weather losses (:mod:`~mushrooms.evaluation.perturbed_execution`).
``efficiency_two_detections_ztf_sim``
    The nominal record under ztf_sim's limiting-magnitude formula (0.4-0.9 mag
    deeper than the campaigns at 30-300 s: the models disagree, so both are kept).
``efficiency_two_detections_mushrooms``
    The nominal record under the planner's own depth model, for comparison.
"""

from __future__ import annotations

from typing import Any

from .rows import fmt

__all__ = ["BENCH_PERTURBATIONS", "BENCH_SOURCES", "independent_cells", "scoring_sources"]

#: Seeded perturbation draws of each kind per row.
BENCH_PERTURBATIONS = 4
#: Sources per map (posterior) or per event (truth).
BENCH_SOURCES = 2000

_SOURCES: dict[tuple, Any] = {}  # the last map's sources: every row of a map shares them


def scoring_sources(skymap: Any, nside: int, truth: tuple[float, float, float] | None = None) -> Any:
    """The map's sources (at the truth when given), made once per map and process."""
    from ..independent_scoring import posterior_sources, scoring_seed, truth_sources

    key = (skymap.sha256, nside, truth)
    if key not in _SOURCES:
        _SOURCES.clear()
        seed = scoring_seed(skymap.sha256)
        _SOURCES[key] = (truth_sources(*truth, nside=nside, n=BENCH_SOURCES, seed=seed) if truth is not None
                         else posterior_sources(skymap, BENCH_SOURCES, seed=seed))
    return _SOURCES[key]


def independent_cells(plan: Any, skymap: Any, footprints: Any, merger_time: Any,
                      truth: tuple[float, float, float] | None = None) -> dict[str, Any]:
    """The independent-scoring cells of one plan (empty cells without sources or a merger time).

    ``plan`` must name its filters and cadence (a baseline's plan is given the
    configuration's first, as for ``coverage_as_executed``).
    """
    from ..independent_scoring import independent_scores, scoring_seed, score_record
    from ..perturbed_execution import execute_perturbed, submitted_queues

    keys = ("efficiency_one_detection", "efficiency_two_detections", "efficiency_one_detection_overheads",
            "efficiency_two_detections_overheads", "efficiency_one_detection_perturbed",
            "efficiency_two_detections_perturbed", "efficiency_two_detections_ztf_sim",
            "efficiency_two_detections_mushrooms")
    sources = scoring_sources(skymap, footprints.nside, truth) if merger_time is not None else None
    if sources is None:
        return dict.fromkeys(keys, "")
    scores = independent_scores(plan, merger_time, sources, footprints, depth_model="campaign",
                                perturbations=BENCH_PERTURBATIONS, seed=scoring_seed(skymap.sha256, "perturbations"))
    record = execute_perturbed(plan, None, submitted_queues(plan)) if plan.observations else ()
    for model in ("ztf_sim", "mushrooms"):
        scores[f"efficiency_two_detections_{model}"] = score_record(record, merger_time, sources, footprints,
                                                                    _fields(), depth_model=model)["two_detections"]
    return {k: fmt(float(scores[k])) if k in scores else 0.0 for k in keys}


def _fields() -> Any:
    from ...scheduler_core.sky.fields import load_ztf_fields

    return load_ztf_fields()
