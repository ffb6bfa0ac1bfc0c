"""Plans handed on as they are: ZTF's ToO trigger queue and SkyPortal's manual observation plan.

Both follow what SkyPortal itself sends (``skyportal/facility_apis/ztf.py``
builds the queue that ``PUT {ZTF}/api/triggers/ztf`` -- Kowalski's ToO
endpoint -- receives; ``skyportal/handlers/api/observation_plan.py``,
``ObservationPlanManualRequestHandler``, reads the manual plan):

* queue: ``{queue_name, queue_type: "list", validity_window_mjd: [start, end],
  user, targets: [{request_id, program_id, field_id, ra, dec, filter_id,
  exposure_time, program_pi, subprogram_name}]}`` with ``filter_id`` 1, 2, 3
  for g, r, i, ``program_id`` 2 (Partnership) or 3 (Caltech),
  ``program_pi`` ``"<pi>/<user>"`` and ``subprogram_name`` ``"ToO_<name>"``;
* SkyPortal: ``{dateobs, localization_name, allocation_id, plan_name, status,
  payload, observation_plans: [{validity_window_start, validity_window_end,
  status, planned_observations: [{planned_observation_id, dateobs, field_id,
  exposure_time (int), filt ("ztfg"/"ztfr"/"ztfi"), weight,
  overhead_per_exposure (int), limiting_mag}]}]}``; ``limiting_mag`` (the
  exposure's 5-sigma depth, AB, D2) is ours: SkyPortal's handler reads its own
  keys by name and stores no planned depth (its ``PlannedObservation`` has no
  such column), so it passes unread to SkyPortal and is there for whoever reads
  the payload; ``payload`` carries what SkyPortal's
  ZTF API later needs to send the plan to the queue (``queue_name``,
  ``program_id`` as ``Partnership``/``Caltech``, ``subprogram_name``,
  ``start_date``/``end_date``).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping

from ..ranges import setting
from ..tables import dataclass_from_table

if TYPE_CHECKING:  # an annotation only: reading [export] imports no numpy/astropy (the document does)
    from .document import Plan

__all__ = ["ExportConfig", "queue_name_base", "plan_tag", "PLAN_TAG_DIGITS", "OLD_PLAN_TAG_DIGITS", "QUEUE_NAME", "to_trigger_queue", "to_trigger_queues", "timed_queue_set", "timed_passes", "TimedPasses", "filter_passes", "to_skyportal", "to_skyportal_plans", "FILTER_IDS", "PROGRAM_IDS", "SKYPORTAL_FILTERS"]

#: ZTF queue filter ids.
FILTER_IDS = {"g": 1, "r": 2, "i": 3}
#: ZTF queue program ids of the programs SkyPortal's ZTF API knows.
PROGRAM_IDS = {"Partnership": 2, "Caltech": 3}
#: SkyPortal's names of ZTF's filters.
SKYPORTAL_FILTERS = {"g": "ztfg", "r": "ztfr", "i": "ztfi"}
#: ``[export] skyportal_plans``: one SkyPortal plan per filter pass, or one per plan.
SKYPORTAL_PLANS = ("per_pass", "single")


@dataclass(frozen=True)
class ExportConfig:
    """``[export]``: the program fields of the queue and the SkyPortal payload.

    Attributes
    ----------
    program : str
        ZTF program: ``Partnership`` (program_id 2) or ``Caltech`` (3).
    program_pi : str
        PI of the program; the queue gets ``"<program_pi>/<user>"``.
    subprogram_name : str
        Subprogram; the queue gets ``"ToO_<subprogram_name>"``.
    user : str
        The queue's ``user`` (the Kowalski/SkyPortal user submitting it).
    skyportal_allocation_id : int or None
        SkyPortal allocation of the ZTF MMA instrument; ``--skyportal`` needs it.
    skyportal_status : str
        Status of the submitted observation plan.
    skyportal_plans : str
        ``per_pass`` (default): one SkyPortal observation plan per filter pass,
        which SkyPortal's ZTF API turns into the timed queue set of
        :func:`to_trigger_queues`; ``single``: one plan over the whole plan's
        window (one list queue: fewer cadence-valid pairs as executed).
    """

    program: str = "Partnership"
    program_pi: str = "Kulkarni"
    subprogram_name: str = "GW"
    user: str = "mushrooms"
    skyportal_allocation_id: int | None = setting(None, 1, 2_147_483_647, why="a SkyPortal database id")
    skyportal_status: str = "complete"
    skyportal_plans: str = "per_pass"

    def __post_init__(self) -> None:
        if self.skyportal_plans not in SKYPORTAL_PLANS:
            raise ValueError(f"[export] skyportal_plans must be {' or '.join(SKYPORTAL_PLANS)}, "
                             f"got {self.skyportal_plans!r}")
        if self.program not in PROGRAM_IDS:
            raise ValueError(f"[export] program must be {' or '.join(PROGRAM_IDS)}, got {self.program!r}")
        for name in ("program_pi", "subprogram_name", "user"):
            if not str(getattr(self, name)).strip():
                raise ValueError(f"[export] {name} must not be empty")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "ExportConfig":
        """Build from an ``[export]`` table; unknown keys are an error."""
        return dataclass_from_table(cls, table, "export")


#: A plan id of :func:`~.document.make_plan_id`: ``mushrooms-`` and 16 hex digits.
_PLAN_ID = re.compile(r"mushrooms-([0-9a-f]{16})")
#: Hex digits of the plan tag (48 bits: two of 100 plans of an event share a tag with probability
#: ~1.8e-11, against ~1.2e-6 with the 8 digits of the versions before; docs/design/submission.md).
PLAN_TAG_DIGITS = 12
#: The plan tag's digits in the names of queues sent by the versions before (still recognised: :data:`QUEUE_NAME`).
OLD_PLAN_TAG_DIGITS = 8
#: A queue named by :func:`queue_name_base`, ``_<k>``: groups ``event`` (absent for a bare sky map), ``tag``
#: (12 hex digits, or the 8 of a queue sent before the upgrade) and ``k``.
QUEUE_NAME = re.compile(rf"^ToO_[^_]+_(?:(?P<event>.+)_)?(?P<tag>[0-9a-f]{{{PLAN_TAG_DIGITS}}}|"
                        rf"[0-9a-f]{{{OLD_PLAN_TAG_DIGITS}}})_(?P<k>\d+)$")


def plan_tag(plan_id: str) -> str:
    """The hex digits naming a plan (:data:`PLAN_TAG_DIGITS`): the first of its id's hash (any other id: of the
    id's SHA-256)."""
    found = _PLAN_ID.fullmatch(plan_id)
    digest = found.group(1) if found else hashlib.sha256(plan_id.encode()).hexdigest()
    return digest[:PLAN_TAG_DIGITS]


def queue_name_base(subprogram_name: str, plan_id: str, superevent_id: str | None = None) -> str:
    """The name base of a plan's ZTF queues: the one naming rule of every queue mushrooms sends or shows.

    ``ToO_<subprogram_name>_<superevent>_<plan tag>`` (``ToO_<subprogram_name>_<plan
    tag>`` for a sky map without a superevent), the plan tag being
    :func:`plan_tag` of the plan id; the set's queues are ``<base>_<k>``, k =
    1..K in submission order (:func:`to_trigger_queues`), SkyPortal's plans
    the same names without ``ToO_`` (:func:`to_skyportal_plans`); :data:`QUEUE_NAME`
    recognises them, and the names of the versions before (8-digit tags).  The name
    depends on the plan document alone, so the daemon, ``mushrooms plan
    --queue``, ``mushrooms submit`` and every summary (``.txt``, ``.html``,
    ``mushrooms status``) give one plan the same names, known before it is
    sent, and a plan sent twice (a restart, by hand) is the same queue.

    Parameters
    ----------
    subprogram_name : str
        ``[export] subprogram_name``.
    plan_id : str
        The plan's id (distinct plans of an event: distinct names).
    superevent_id : str, optional
        The event (absent, or the plan id itself: left out).
    """
    event = f"_{superevent_id}" if superevent_id and superevent_id != plan_id else ""
    return f"ToO_{subprogram_name}{event}_{plan_tag(plan_id)}"


def _base(plan: Plan, export: ExportConfig) -> str:
    return queue_name_base(export.subprogram_name, plan.plan_id, plan.event.superevent_id)


def _iso_space(t: Any) -> str:
    """``YYYY-MM-DD HH:MM:SS`` (UTC), the format SkyPortal's ZTF API parses with ``format="iso"``."""
    return t.utc.iso[:19]


def to_trigger_queue(plan: Plan, export: ExportConfig = ExportConfig(), queue_name: str | None = None
                     ) -> dict[str, Any]:
    """The plan as ZTF's ToO trigger queue (what SkyPortal sends to ``api/triggers/ztf``).

    Parameters
    ----------
    plan : Plan
        A plan with at least one observation.
    export : ExportConfig
        Program fields.
    queue_name : str, optional
        Defaults to :func:`queue_name_base` of the plan.

    Raises
    ------
    ValueError
        For a plan without observations (ZTF refuses an empty queue) or a
        filter ZTF does not have.
    """
    if not plan.observations:
        raise ValueError(f"plan {plan.plan_id} has no observations: no queue to send")
    bad = sorted({o.filter for o in plan.observations} - set(FILTER_IDS))
    if bad:
        raise ValueError(f"plan {plan.plan_id}: filter(s) {', '.join(bad)} are not ZTF filters (g, r, i)")
    targets = [
        {
            "request_id": i + 1,
            "program_id": PROGRAM_IDS[export.program],
            "field_id": int(o.field_id),
            "ra": float(o.ra),
            "dec": float(o.dec),
            "filter_id": FILTER_IDS[o.filter],
            "exposure_time": float(o.exposure_s),
            "program_pi": f"{export.program_pi}/{export.user}",
            "subprogram_name": f"ToO_{export.subprogram_name}",
        }
        for i, o in enumerate(plan.observations)
    ]
    return {
        "queue_name": queue_name or _base(plan, export),
        "queue_type": "list",
        "validity_window_mjd": [float(plan.start.mjd), float(plan.end.mjd)],
        "user": export.user,
        "targets": targets,
    }


def filter_passes(plan: "Plan") -> list[tuple[int, int]]:
    """The plan's filter passes: maximal runs ``[i, j)`` of consecutive observations in one filter (Q11)."""
    obs = plan.observations
    cuts = [0] + [k for k in range(1, len(obs)) if obs[k].filter != obs[k - 1].filter] + [len(obs)]
    return [(a, b) for a, b in zip(cuts, cuts[1:]) if b > a]


def to_trigger_queues(plan: "Plan", export: ExportConfig = ExportConfig(), name_base: str | None = None,
                      slack_s: float | None = None, robust: bool = True) -> list[dict[str, Any]]:
    """The plan as the set of timed ToO list queues that makes ZTF's scheduler follow it (Q11-Q13).

    One queue per filter pass (:func:`filter_passes`; a block of a g-r-g
    sequence is three passes, the last one run on into the next block's
    first when both are g), in plan order, named
    ``f"{name_base}_{k}"`` (k = 1..K), each holding the pass's observations
    in plan order.  ZTF's scheduler (``docs/design/executed.md``, Q1-Q3)
    takes, from its survey, the last queue in submission order whose window
    is open and which has targets (ztf_sim's main loop; a first-wins
    scheduler the first), and runs it as fast as it can; so each
    pass's window opens at its planned start, or later when the telescope
    model (:func:`~..telescope.queue_windows.time_pass_windows`) says one of
    its fields would otherwise come back sooner than the cadence (plus a
    margin) after its previous visit, and closes a slack after the model's
    end of the pass, or sooner when two queues would be open at one switch
    of the on-time run (Q20: the set runs the same under either rule) or
    when that keeps more pairs with the telescope late or off-speed
    (Q16-Q18, ``robust``).  A pass that could not open before the plan's
    end is left out.

    Parameters
    ----------
    plan : Plan
        A plan with at least one observation.
    export : ExportConfig
        Program fields.
    name_base : str, optional
        Defaults to :func:`queue_name_base` of the plan.
    slack_s : float, optional
        How long (s) a pass stays open after the model's end of it (default
        :data:`~..telescope.queue_windows.PASS_SLACK_S`).
    robust : bool
        Choose each close for a late or off-speed telescope (Q16-Q18; the
        on-time execution is the same either way).

    Returns
    -------
    list of dict
        Queue payloads of :func:`to_trigger_queue`'s shape, in submission order.
    """
    return timed_queue_set(plan, export, name_base, slack_s, robust)[0]


def timed_queue_set(plan: "Plan", export: ExportConfig = ExportConfig(), name_base: str | None = None,
                    slack_s: float | None = None, robust: bool = True) -> tuple[list[dict[str, Any]], Any]:
    """:func:`to_trigger_queues`, and the telescope model's observability grid of the queues' targets.

    The grid (a :class:`~..telescope.executor.SkyGrid`, from the plan's first
    observation to its end) is what timing the windows cost (the Sun, the
    Moon and every target's altitude on a 60 s grid); executing the queues
    from the first observation reuses it instead of computing it again.
    """
    import numpy as np

    out, kept, sky = _timed_passes(plan, export, name_base, slack_s, robust)
    rows = [i for a, b in kept for i in range(a, b)]
    return out, sky.take(np.asarray(rows, int))


def _timed_passes(plan: "Plan", export: ExportConfig, name_base: str | None, slack_s: float | None,
                  robust: bool) -> tuple[list[dict[str, Any]], list[tuple[int, int]], Any]:
    """The timed queue set, the observation rows ``[a, b)`` of each of its queues, and the sky grid."""
    import numpy as np

    from ..telescope.executor import SkyGrid, queue_set_from_payloads
    from ..telescope.queue_windows import PASS_SLACK_S, time_pass_windows
    from ..telescope.timing import TelescopeTiming

    base = name_base or _base(plan, export)
    single = to_trigger_queue(plan, export, queue_name=base)  # refuses a plan without observations
    passes = filter_passes(plan)
    end_s = float((plan.end - plan.start).to_value("s"))
    drafts = [{**single, "validity_window_mjd": None, "targets": single["targets"][a:b]} for a, b in passes]
    qs = queue_set_from_payloads(drafts, plan.start)
    planned = np.asarray([o.start for o in plan.observations], float)
    sky = SkyGrid(qs, plan.start, float(planned.min()), end_s, 60.0, TelescopeTiming())
    cadence_s = float((plan.config or {}).get("cadence_s", 1800.0))
    weight = np.asarray([_field_weight(o) for o in plan.observations], float)
    opens, closes = time_pass_windows(qs, plan.start, planned, end_s, cadence_s,
                                      slack_s=PASS_SLACK_S if slack_s is None else slack_s, sky=sky, weight=weight,
                                      robust=robust)
    out, kept = [], []
    for (a, b), draft, t_open, t_close in zip(passes, drafts, opens, closes):
        if not t_open < end_s:
            continue
        window = plan.absolute_time([t_open, max(t_close, t_open + 1.0)]).mjd
        targets = [dict(t, request_id=i + 1) for i, t in enumerate(draft["targets"])]
        out.append({**draft, "queue_name": f"{base}_{len(out) + 1}",
                    "validity_window_mjd": [float(window[0]), float(window[1])], "targets": targets})
        kept.append((a, b))
    return out, kept, sky


@dataclass(frozen=True)
class TimedPasses:
    """A plan's timed queue set (:func:`to_trigger_queues`) and the observation rows ``[a, b)`` of each queue."""

    queues: list[dict[str, Any]]
    rows: list[tuple[int, int]]


def timed_passes(plan: "Plan", export: ExportConfig = ExportConfig(), name_base: str | None = None) -> TimedPasses:
    """:func:`to_trigger_queues` (robust closes) with each queue's observation rows, timed once for both
    the queues and :func:`to_skyportal_plans` (give it ``passes``)."""
    out, kept, _ = _timed_passes(plan, export, name_base, None, True)
    return TimedPasses(out, kept)


def _field_weight(o: Any) -> float:
    """What a field's pair is worth when the closes are chosen (Q17): its share, else its probability, else 1."""
    for value in (o.probability_share, o.probability):
        if value is not None:
            return float(value)
    return 1.0


def to_skyportal(plan: Plan, export: ExportConfig = ExportConfig(), localization_name: str | None = None
                 ) -> dict[str, Any]:
    """The plan as the body of SkyPortal's ``POST /api/observation_plan/manual``.

    Parameters
    ----------
    plan : Plan
        A plan with at least one observation and a known event time.
    export : ExportConfig
        Allocation and program fields (``skyportal_allocation_id`` required).
    localization_name : str, optional
        SkyPortal's name of the sky map; default the plan's ``skymap_name``,
        else ``"healpix"`` (SkyPortal's own name for an unnamed map).

    Raises
    ------
    ValueError
        No allocation id, no observations, no event time, or a non-ZTF filter.
    """
    if export.skyportal_allocation_id is None:
        raise ValueError("a SkyPortal payload needs [export] skyportal_allocation_id (the ZTF allocation)")
    if not plan.observations:
        raise ValueError(f"plan {plan.plan_id} has no observations: no SkyPortal plan to submit")
    if not plan.event.event_time:
        raise ValueError(f"plan {plan.plan_id} has no event time: SkyPortal finds the event by its dateobs")
    bad = sorted({o.filter for o in plan.observations} - set(SKYPORTAL_FILTERS))
    if bad:
        raise ValueError(f"plan {plan.plan_id}: filter(s) {', '.join(bad)} are not ZTF filters (g, r, i)")
    starts = plan.absolute_time([o.start for o in plan.observations])
    readout = float((plan.config or {}).get("slew", {}).get("readout_s", 8.0))
    planned = []
    previous_end: float | None = None
    for i, (o, t) in enumerate(zip(plan.observations, starts)):
        # the gap since the previous exposure when it is a slew (up to 10 min), else the readout
        overhead = readout if previous_end is None else max(o.start - previous_end, 0.0)
        if overhead > 600.0:
            overhead = readout
        previous_end = o.end
        planned.append({
            "planned_observation_id": i,
            "dateobs": t.utc.isot[:23],
            "field_id": int(o.field_id),
            "exposure_time": int(round(o.exposure_s)),
            "filt": SKYPORTAL_FILTERS[o.filter],
            "weight": round(float(o.probability), 6) if o.probability is not None else 0.0,
            "overhead_per_exposure": int(round(overhead)),
            **({} if o.limiting_mag is None else {"limiting_mag": round(float(o.limiting_mag), 2)}),
        })
    name = _base(plan, export).removeprefix("ToO_")
    return {
        "dateobs": plan.event.event_time.rstrip("Z"),
        "localization_name": localization_name or plan.event.skymap_name or "healpix",
        "allocation_id": int(export.skyportal_allocation_id),
        "plan_name": name,
        "status": export.skyportal_status,
        "payload": {
            "queue_name": name,
            "program_id": export.program,
            "subprogram_name": export.subprogram_name,
            "start_date": _iso_space(plan.start),
            "end_date": _iso_space(plan.end),
            "filter_strategy": "block",
            "exposure_time": _plan_exposure_s(plan),
            "filters": _payload_filters(plan),
            "field_ids": ",".join(str(f) for f in plan.field_ids),
        },
        "observation_plans": [{
            "validity_window_start": plan.start.utc.isot[:23],
            "validity_window_end": plan.end.utc.isot[:23],
            "status": export.skyportal_status,
            "planned_observations": planned,
        }],
    }


def to_skyportal_plans(plan: "Plan", export: ExportConfig = ExportConfig(), name_base: str | None = None,
                       localization_name: str | None = None, passes: "TimedPasses | None" = None
                       ) -> list[dict[str, Any]]:
    """The plan as the SkyPortal observation plans to POST, in submission order (``[export] skyportal_plans``).

    ``per_pass``: one plan per queue of :func:`to_trigger_queues` (the same
    filter passes and validity windows, not derived again), named
    ``f"{name_base}_{k}"`` like the queues, each holding its pass's planned
    observations, with ``start_date``/``end_date`` (and the plan's validity
    window) = the queue's window, to the millisecond.  SkyPortal's ZTF API
    sends each as one list queue ``ToO_<queue_name>`` over that window with
    those targets in order: the Kowalski target's queue set
    (docs/design/submission.md, (T1)).  ``single``: :func:`to_skyportal`
    named ``name_base`` (one list queue over the plan's window).

    Parameters
    ----------
    plan : Plan
        A plan with at least one observation and a known event time.
    export : ExportConfig
        Allocation and program fields, and ``skyportal_plans``.
    name_base : str, optional
        Plan name (SkyPortal adds ``ToO_`` for the queue); default that of
        :func:`to_skyportal`.
    localization_name : str, optional
        As :func:`to_skyportal`.
    passes : TimedPasses, optional
        The plan's timed queue set named ``f"ToO_{name_base}"``
        (:func:`timed_passes`), when the caller already has it (the queues
        submitted beside): the windows are then not timed again.

    Raises
    ------
    ValueError
        As :func:`to_skyportal`, or no pass of the plan can open before its end.
    """
    whole = to_skyportal(plan, export, localization_name)
    base = name_base or whole["plan_name"]
    whole["plan_name"] = base
    whole["payload"] = dict(whole["payload"], queue_name=base)
    if export.skyportal_plans == "single":
        return [whole]
    if passes is None or (passes.queues and not passes.queues[0]["queue_name"].startswith(f"ToO_{base}_")):
        passes = timed_passes(plan, export, f"ToO_{base}")
    queues, kept = passes.queues, passes.rows
    if not queues:
        raise ValueError(f"plan {plan.plan_id}: no filter pass opens before the plan's end: no SkyPortal plan")
    planned = whole["observation_plans"][0]["planned_observations"]
    out = []
    for k, (queue, (a, b)) in enumerate(zip(queues, kept), start=1):
        name = f"{base}_{k}"
        start, end = _time_from_mjd(queue["validity_window_mjd"])
        observations = plan.observations[a:b]
        out.append({**whole, "plan_name": name,
                    "payload": {**whole["payload"], "queue_name": name, "start_date": start.utc.iso[:23],
                                "end_date": end.utc.iso[:23], "filters": observations[0].filter,
                                "exposure_time": _plan_exposure_s(plan.with_(observations=observations)),
                                "field_ids": ",".join(str(int(o.field_id)) for o in observations)},
                    "observation_plans": [{**whole["observation_plans"][0],
                                           "validity_window_start": start.utc.isot[:23],
                                           "validity_window_end": end.utc.isot[:23],
                                           "planned_observations": planned[a:b]}]})
    return out


def _time_from_mjd(window: list[float]) -> Any:
    from astropy.time import Time

    return Time(window, format="mjd", scale="utc")


def _payload_filters(plan: "Plan") -> str:
    """SkyPortal's ``filters``: the plan's filters in order of first use, or its sequence (``g,r,g``) when longer than a pair."""
    sequence = list((plan.config or {}).get("filters", ()))
    if len(sequence) > 2:
        return ",".join(sequence)
    return ",".join(dict.fromkeys(o.filter for o in plan.observations))


def _plan_exposure_s(plan: "Plan") -> int:
    """One exposure (s) for SkyPortal's payload: that of most fields (ties: the longest).

    Each planned observation carries its own ``exposure_time``; a plan
    whose fields all share one exposure gives that one.
    """
    per_field: dict[int, float] = {}
    for o in plan.observations:
        per_field.setdefault(o.field_id, float(o.exposure_s))
    counts: dict[float, int] = {}
    for e in per_field.values():
        counts[e] = counts.get(e, 0) + 1
    return int(round(max(counts, key=lambda e: (counts[e], e))))
