"""Loop benchmark, executor half: how ZTF's scheduler carries out the queues of a published plan.

A user of the telescope model (:mod:`mushrooms.scheduler_core.telescope`,
equations Q1-Q14 of ``docs/design/executed.md``, from ztf_sim's source):
:func:`execute_plan` exports the plan as it is submitted
(:func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queues`, or the
older single list queue :func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queue`)
and plays the queues with weather closures, returning
:class:`~mushrooms.scheduler_core.executed.ExecutedExposure` records, the
same the readers of :mod:`mushrooms.handlers.executed` return for the real
telescope; :func:`achieved_coverage` scores them.

Pure functions, no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np
from astropy.time import Time, TimeDelta

from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from ..scheduler_core.plan.document import Plan
from ..scheduler_core.plan.exports import to_trigger_queue, to_trigger_queues
from ..scheduler_core.sky.footprints import Footprints
from ..scheduler_core.sky.skymap import SkyMap
from ..scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues
from ..scheduler_core.telescope.timing import TelescopeTiming

__all__ = ["Closure", "random_closure", "execute_plan", "achieved_coverage", "execution_cells", "submitted_today",
           "EXPORTS", "LATE_STARTS_S"]

#: How a plan goes to ZTF: ``queues`` (timed queues per filter pass) or ``single`` (one list queue).
EXPORTS = ("queues", "single")
#: Late starts (s) the benchmark executes every plan with: another ToO or the weather holding the telescope.
LATE_STARTS_S = (900.0, 1800.0, 3600.0)


@dataclass(frozen=True)
class Closure:
    """The dome closed for weather from ``start`` to ``end`` (UTC).

    Attributes
    ----------
    start, end : astropy.time.Time
        Closure span, ``start < end``.
    """

    start: Time
    end: Time

    def __post_init__(self) -> None:
        if not (isinstance(self.start, Time) and isinstance(self.end, Time)):
            raise TypeError("Closure start and end are astropy Times")
        if not self.start < self.end:
            raise ValueError(f"closure must end after it starts ({self.start.isot} .. {self.end.isot})")

    @property
    def duration_s(self) -> float:
        """Length of the closure (s)."""
        return float((self.end - self.start).to_value("s"))


def random_closure(night_start: Time, night_end: Time, seed: int | np.random.Generator,
                   min_h: float = 1.0, max_h: float = 3.0) -> Closure:
    """A weather closure of random length at a random time inside a night.

    Parameters
    ----------
    night_start, night_end : astropy.time.Time
        The night (UTC), e.g. the span of the plan's windows.
    seed : int or numpy.random.Generator
        Same seed, same closure.
    min_h, max_h : float
        Closure length (h), uniform in ``[min_h, max_h]``, cut to the night's length.

    Returns
    -------
    Closure
        Lies inside ``[night_start, night_end]``; start uniform over the
        times that leave room for the length drawn.
    """
    night_s = float((night_end - night_start).to_value("s"))
    if not night_s > 0:
        raise ValueError("the night must end after it starts")
    if not 0 < min_h <= max_h:
        raise ValueError(f"need 0 < min_h <= max_h, got {min_h}, {max_h}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    length = min(rng.uniform(min_h, max_h) * 3600.0, night_s)
    offset = rng.uniform(0.0, night_s - length)
    start = night_start + TimeDelta(offset, format="sec")
    return Closure(start, start + TimeDelta(length, format="sec"))


def execute_plan(plan: Plan, start: Time | None = None, closures: Iterable[Closure] = (), export: str = "queues",
                 timing: TelescopeTiming = TelescopeTiming()) -> tuple[ExecutedExposure, ...]:
    """What ZTF's scheduler executes of a plan's queues (Q1-Q10), with weather closures.

    Parameters
    ----------
    plan : Plan
        The published plan.
    start : astropy.time.Time, optional
        When the telescope is free for the queues (default the plan's first
        observation; a later time is a late start).
    closures : iterable of Closure
        Weather closures: nothing runs inside; an exposure one cuts is
        ``aborted`` (fraction 0) and stays queued (Q10).
    export : str
        ``queues`` (:func:`to_trigger_queues`) or ``single`` (:func:`to_trigger_queue`).
    timing : TelescopeTiming
        The telescope.

    Returns
    -------
    tuple of ExecutedExposure
        In execution order, aborted attempts included.
    """
    if export not in EXPORTS:
        raise ValueError(f"export must be one of {', '.join(EXPORTS)}, got {export!r}")
    if not plan.observations:
        return ()
    queues = to_trigger_queues(plan) if export == "queues" else [to_trigger_queue(plan)]
    first = plan.observations[0].start
    late = 0.0 if start is None else max(0.0, float((start - plan.start).to_value("s")) - first)
    spans = [(float((c.start - plan.start).to_value("s")), float((c.end - plan.start).to_value("s")))
             for c in closures]
    return execute_plan_queues(plan, queues, late, timing, closures_s=spans)


def achieved_coverage(executed: Iterable[ExecutedExposure], skymap: SkyMap, footprints: Footprints,
                      filters: tuple[str, ...] = ("g", "r"), require: str = "both",
                      min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0) -> float:
    """Probability inside the footprints of the fields observed (Q14).

    The plan's own ``metrics.coverage`` counts each planned field, and a
    plan visits each field in both filters; ``require="both"`` counts a field
    on the same terms (done in both filters (E3), at least ``cadence_s``
    apart), ``"any"`` once one done exposure (E1) in either filter exists.
    The union is taken by :meth:`Footprints.coverage`, as the bench does.

    Parameters
    ----------
    executed : iterable of ExecutedExposure
        What was executed (any source).
    skymap : SkyMap
        The sky map, at ``footprints.nside``.
    footprints : Footprints
        Footprints of (at least) the executed fields.
    filters : tuple of str
        The plan's filter sequence (a field is covered by its first two, F1).
    require : str
        ``both`` or ``any``.
    min_processed_fraction : float
        Threshold of the done rule (E1).
    cadence_s : float
        Least separation (s) of a field's two filters with ``require="both"``.

    Returns
    -------
    float
        Coverage (0-1).
    """
    if skymap.nside != footprints.nside:
        raise ValueError(f"sky map nside {skymap.nside} differs from the footprints' {footprints.nside}")
    return cadence_coverage(executed, footprints, skymap.prob, filters, cadence_s, require, min_processed_fraction)


def execution_cells(plan: Plan, footprints: Footprints, prob: np.ndarray,
                    late_starts_s: Iterable[float] = LATE_STARTS_S, skyportal_plans: str = "single"
                    ) -> dict[str, float | int | str]:
    """What ZTF's scheduler would keep of a plan (Q14), for the benchmark's row.

    The plan's queue set (:func:`to_trigger_queues`, timed once) is executed
    on time and ``late_starts_s`` late, and the old single list queue on
    time; each scored as cadence-valid coverage (the plan's filters and
    cadence, defaults g/r and 1800 s for a plan without its config).

    ``coverage_single_queue`` is the plan "as submitted today": what
    SkyPortal's ZTF API queues for the observation plans that hold it
    (:mod:`~mushrooms.evaluation.skyportal_queue`: one ``list`` queue per
    plan, valid over its start and end, its planned observations in order).
    ``skyportal_plans`` says how many: ``single``, one plan over the plan's
    horizon (a plan made in SkyPortal, gwemopt's: one list queue, the
    plan's times lost); ``per_pass``, one per filter pass with that pass's
    queue window, as the service POSTs its plans (``[export]
    skyportal_plans``, docs/design/submission.md T1: they execute as its
    queue set).

    Returns
    -------
    dict
        ``coverage_as_executed`` (queue set, on time), ``coverage_single_queue``
        (the old export, on time), ``coverage_late_<min>`` (queue set, late),
        ``n_queues`` (queues per revision) and the shutter-open seconds of what
        each on-time run took (``open_shutter_executed_s``,
        ``open_shutter_single_queue_s``: exposures done, E1); empty cells for a
        plan without observations.
    """
    from ..scheduler_core.plan.exports import timed_queue_set

    lates = [float(x) for x in late_starts_s]
    keys = ["coverage_as_executed", "coverage_single_queue", *[f"coverage_late_{int(x // 60)}" for x in lates]]
    if not plan.observations:
        return {**dict.fromkeys(keys, ""), "n_queues": 0, "open_shutter_executed_s": "",
                "open_shutter_single_queue_s": ""}
    config = plan.config or {}
    filters = tuple(config.get("filters", ("g", "r")))[:2]
    cadence_s = float(config.get("cadence_s", 1800.0))
    queues, _ = timed_queue_set(plan)

    shutter: dict[str, float] = {}

    def kept(payloads, late_s, name=None):
        done = execute_plan_queues(plan, payloads, late_s) if payloads else ()
        if name is not None:
            shutter[name] = round(sum(float(e.exposure_s) for e in done if is_done(e)), 1)
        return round(cadence_coverage(done, footprints, prob, filters, cadence_s), 6)  # type: ignore[arg-type]

    out: dict[str, float | int | str] = {
        "coverage_as_executed": kept(queues, 0.0, "open_shutter_executed_s"),
        "coverage_single_queue": kept(submitted_today(plan, skyportal_plans), 0.0, "open_shutter_single_queue_s")}
    out.update({key: kept(queues, x) for key, x in zip(keys[2:], lates)})
    out.update(shutter)
    out["n_queues"] = len(queues)
    return out


def submitted_today(plan: Plan, skyportal_plans: str = "single") -> list[dict]:
    """The list queues SkyPortal's ZTF API sends ZTF for a plan held in SkyPortal as ``skyportal_plans`` says.

    ``single``: one observation plan over the plan's horizon, one list
    queue of its observations in order (:func:`to_trigger_queue`, what
    :func:`~mushrooms.evaluation.skyportal_queue.skyportal_queue` makes of
    it).  ``per_pass``: the plans the service POSTs
    (:func:`~mushrooms.scheduler_core.plan.exports.to_skyportal_plans`), each
    queued by :func:`~mushrooms.evaluation.skyportal_queue.skyportal_queue`.
    """
    import dataclasses

    from ..scheduler_core.plan.exports import ExportConfig, to_skyportal_plans
    from .skyportal_queue import skyportal_queue

    if skyportal_plans == "single":
        return [to_trigger_queue(plan)]
    if not plan.event.event_time:  # SkyPortal finds the event by it; the queue does not depend on it
        plan = plan.with_(event=dataclasses.replace(plan.event, event_time=plan.start.utc.isot + "Z"))
    try:
        bodies = to_skyportal_plans(plan, ExportConfig(skyportal_allocation_id=1, skyportal_plans=skyportal_plans))
    except ValueError:  # no filter pass opens before the plan's end: the service sends nothing
        return []
    return [skyportal_queue(b) for b in bodies]
