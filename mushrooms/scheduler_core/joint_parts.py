"""Telescopes planned around plans held fixed: the service's coordinated parts (``docs/design/telescopes.md``, J9).

(J9) The service publishes ZTF's revisions as a ZTF-only service does (its
queue set to Kowalski, its ids and documents unchanged); every other
telescope is planned *around* them.  The plans held fixed (ZTF's published
revision, and the parts already recorded for it) set the weight of every
pixel they cover, by each telescope's own cadence rule
(:func:`~.schedulers.joint.cells.covered_pixels`), to 0; each telescope still
to plan, in the configured order, gets its fast plan (greedy's step of the
joint room, :func:`~.schedulers.joint.ascent.plan_alone`) on the weights
left, is built and checked on the map itself (least-gain rule, metrics,
checker, ``not_observable``), and what it covers is set to 0 for the next.
Greedy takes the probability nobody covers first; with time to spare it
may still add fields the held plans cover (the union never falls below the
parts made alone on the shared maps).
This is the first sweep of the coordinate ascent J6 started from ZTF's plan,
with ZTF never re-solved: gwemopt's iterative tiling, ZTF first.

A part depends only on the map, its telescope's problem and the plans held
fixed (greedy's step has no time limit), so a restart that holds the
recorded parts fixed plans the rest as an uninterrupted run did.  A part's
id is its plan id alone re-hashed with what it was planned around
(:func:`around_key`): the same telescope around another ZTF revision is
another plan.

:func:`around_document` is the ``joint_plan`` document of ZTF's revision and
the parts (``docs/design/plan-format.md``, ``mushrooms check`` reads it):
every telescope with a plan, the joint metrics (J8: union, shares, own
shares, covered more than once) and the certified bound J8 over them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .plan.document import EventInfo, Plan, make_plan_id
from .problem import PlanningProblem, StopCheck
from .sky.skymap import SkyMap

__all__ = ["Held", "around_key", "left_weight", "plan_around", "around_document", "fields_of", "AROUND_SOLVER"]

#: What a part's document names as its method (``metrics.method`` of the joint document).
AROUND_SOLVER = "around"


@dataclass(frozen=True)
class Held:
    """A telescope's plan held fixed: what the others are planned around.

    Attributes
    ----------
    name : str
        The telescope (``ztf``, ``ls4``).
    problem : PlanningProblem or None
        Its problem on the map (None: it covers nothing, e.g. it could not be prepared).
    fields : tuple of int
        The fields its plan observes (empty: ``not_observable``, failed).
    """

    name: str
    problem: PlanningProblem | None
    fields: tuple[int, ...] = ()


def around_key(held: Sequence[tuple[str, str | None, Sequence[int]]]) -> str:
    """16 hex digits naming what a part was planned around: each held (name, plan id, fields)."""
    text = json.dumps([[str(n), p, sorted(int(f) for f in fields)] for n, p, fields in held])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def left_weight(prob: np.ndarray, held: Sequence[Held]) -> np.ndarray:
    """(J9) The map's probability with 0 on every pixel a held plan covers."""
    from .schedulers.joint.cells import covered_pixels

    w = np.array(prob, float)
    for h in held:
        if h.problem is not None and h.fields:  # a field its problem does not know (a hand-edited part) is skipped
            known = np.asarray(h.fields, np.int64)
            w[covered_pixels(h.problem, known[np.isin(known, h.problem.field_ids)])] = 0.0
    return w


def plan_around(skymap: SkyMap, held: Sequence[Held], todo: Sequence[tuple[str, PlanningProblem]], key: str,
                event: EventInfo | None = None, should_stop: StopCheck | None = None) -> dict[str, Any]:
    """(J9) Each telescope of ``todo``, in order, planned on the sky the held plans and the earlier ones leave.

    Parameters
    ----------
    skymap : SkyMap
        The map every problem was prepared on (same working resolution).
    held : sequence of Held
        The plans held fixed (ZTF's revision first).
    todo : sequence of (name, PlanningProblem)
        The telescopes to plan, in the configured order.
    key : str
        :func:`around_key` of what the parts are planned around (it keys their plan ids).
    event : EventInfo, optional
    should_stop : callable, optional

    Returns
    -------
    dict
        By name: the checked :class:`Plan`, its ``NotObservable`` answer
        (nothing left for it above ``min_coverage``: covers nothing for the
        next), or the exception that telescope raised (the others go on).
    """
    from .anytime import FIRST_SOLVER
    from .plan.observability import not_observable
    from .schedulers.joint.cells import covered_pixels

    if not todo:
        return {}
    w = left_weight(todo[0][1].prob, held)
    out: dict[str, Any] = {}
    for name, problem in todo:
        try:
            if problem.prob.shape != w.shape:
                raise ValueError(f"{name}: not at the working resolution of the plans held fixed")
            plan = _part(skymap, problem, w, key, FIRST_SOLVER, event, should_stop)
            answer = not_observable(plan, skymap, problem.config)
            out[name] = plan if answer is None else answer
            if answer is None:
                w[covered_pixels(problem, [o.field_id for o in plan.observations])] = 0.0
        except Exception as exc:  # this telescope's failure only
            out[name] = exc
    return out


def _part(skymap: SkyMap, problem: PlanningProblem, weight: np.ndarray, key: str, solver: str,
          event: EventInfo | None, should_stop: StopCheck | None) -> Plan:
    """One telescope's checked plan on ``weight`` (built and measured on the map), its id keyed by ``key``."""
    from .anytime import checked_plan
    from .schedulers.joint.ascent import plan_alone

    result, _ = plan_alone(problem, weight, None, should_stop, greedy=True)
    # the least-gain rule is judged on the map (build_plan), not on ``weight``: judged against the held plans
    # it lost 0.001-0.01 of union on the shared maps (results/science/telescopes/service_coordinated/*leastgain*)
    plan = checked_plan(problem, result, skymap, solver, event=event)
    return plan.with_(plan_id=make_plan_id(plan.plan_id, AROUND_SOLVER, key))


def around_document(entries: Sequence[tuple[str, PlanningProblem | None, dict | None, str]], prob: np.ndarray,
                    bound_time_limit_s: float | None = None, details: dict | None = None) -> dict:
    """The ``joint_plan`` document of ZTF's revision and its parts (J8 metrics and bound over those with a plan).

    Parameters
    ----------
    entries : sequence of (name, problem, plan document or None, state)
        Every configured telescope in order: its problem (None when it could
        not be prepared), its plan document when it has one (ZTF's revision,
        an exported part), and its state (``exported``, ``not_observable``,
        ``failed``).
    prob : numpy.ndarray
        The map's probability per pixel (the problems' working resolution).
    bound_time_limit_s : float, optional
        Budget of J7 (default the telescopes' largest ``bound_time_limit_s``); 0: J8 without J7
        (:func:`~.schedulers.joint.bound.quick_joint_bound`: no cells, no solve; the service's).
    details : dict, optional
        Added under ``coordination`` (round, what the parts were planned around).

    Returns
    -------
    dict
        As :func:`~.joint_plans.joint_document`, with ``metrics.method``
        ``around`` and ``not_planned`` (telescopes without a plan: their state).
    """
    from .joint_plans import joint_metrics_document
    from .schedulers.joint.bound import joint_upper_bound, quick_joint_bound
    from .schedulers.joint.cells import joint_metrics

    planned = [(n, p, d) for n, p, d, _ in entries if d is not None and p is not None]
    names = [n for n, _, _ in planned]
    problems = [p for _, p, _ in planned]
    docs = [d for _, _, d in planned]
    fields = [{o["field_id"] for o in d.get("observations", [])} for d in docs]
    metrics = joint_metrics(problems, fields, prob) if problems else None
    if not problems:
        bound = None
    elif bound_time_limit_s is not None and bound_time_limit_s <= 0:
        bound = quick_joint_bound(problems, prob)
    else:
        bound = joint_upper_bound(problems, prob, bound_time_limit_s, names)
    doc = joint_metrics_document(names, docs, metrics, bound, AROUND_SOLVER)
    doc["not_planned"] = {n: s for n, p, d, s in entries if d is None or p is None}
    doc["coordination"] = dict(details or {})
    return doc


def fields_of(document: dict | None) -> tuple[int, ...]:
    """The fields a plan document observes, in first-visit order (none for no document)."""
    if not document:
        return ()
    return tuple(dict.fromkeys(int(o["field_id"]) for o in document.get("observations", [])
                               if isinstance(o, dict) and isinstance(o.get("field_id"), int)))

