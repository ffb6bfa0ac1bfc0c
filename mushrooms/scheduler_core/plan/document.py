"""The observing plan: dataclasses and the JSON plan document (exports: :mod:`.exports`).

Times inside the library are seconds (float) since the plan's ``start``;
the document carries ISO-8601 UTC strings.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from . import strict_json
from ..times import iso_utc  # the plan's times as written (defined with the parser, below the plan)

__all__ = [
    "Observation",
    "EventInfo",
    "PlanMetrics",
    "Plan",
    "make_plan_id",
    "iso_utc",
    "PLAN_KEYS",
    "OBSERVATION_KEYS",
    "METRIC_KEYS",
    "TIMING_FIELDS",
    "without_timing",
]

PLAN_KEYS = (
    "plan_id", "created", "event", "telescope", "start", "end",
    "supersedes", "observations", "metrics",
)
OBSERVATION_KEYS = ("field_id", "ra", "dec", "filter", "start", "exposure_s", "block")
EVENT_KEYS = ("superevent_id", "alert_type", "time_created", "skymap_sha256", "localization", "external_coinc",
              "event_time", "skymap_name", "merger_time_source", "classification", "far_hz", "distance_mpc",
              "distance_std_mpc", "area_50_deg2", "area_90_deg2")
METRIC_KEYS = (
    "coverage", "solver", "status", "mip_gap", "mip_bound", "runtime_s",
    "n_fields", "n_exposures", "latency_s", "upper_bound", "upper_bound_method",
    "expected_detections", "coverage_executed", "coverage_as_executed", "sequence_coverage_as_executed",
    "budget",
)
FILTER_IDS = {"g": 1, "r": 2, "i": 3}
#: The fields of a plan document that say when and how fast it was made (docs/design/plan-format.md): under the
#: work budget (``[scheduler] deterministic``) two runs of one input differ in these only.
TIMING_FIELDS = ("created", "metrics.runtime_s", "metrics.latency_s")


def without_timing(document: dict[str, Any]) -> dict[str, Any]:
    """A copy of a plan (or not_observable) document without its :data:`TIMING_FIELDS`."""
    out = json.loads(json.dumps(document))
    for name in TIMING_FIELDS:
        *path, key = name.split(".")
        where = out
        for part in path:
            where = where.get(part) or {}
        where.pop(key, None)
    return out


def parse_time(value: str | Time, what: str = "time") -> Time:
    """A plan document's time: :func:`mushrooms.scheduler_core.times.parse_time` (ISO-8601, no MJD).

    Raises
    ------
    ValueError
        (:class:`~mushrooms.scheduler_core.errors.InputError`) when the string is not an ISO time.
    """
    from ..times import parse_time as parse

    return parse(value, what)


@dataclass(frozen=True)
class Observation:
    """One exposure of one field.

    Attributes
    ----------
    field_id : int
        ZTF field ID.
    ra, dec : float
        Field centre (deg, ICRS).
    filter : str
        Filter name (``g``, ``r``, ``i``).
    start : float
        Exposure start (s since the plan start).
    exposure_s : float
        Exposure time (s).
    block : int
        Observing block index (0-based).
    airmass : float or None
        Airmass (sec z) at mid-exposure.
    probability : float or None
        Sky-map probability inside the field's footprint (0-1), overlaps
        with other fields counted in full.
    probability_share : float or None
        The field's own share (0-1): each pixel's probability divided
        equally among the planned fields whose footprints hold it; the
        shares of a plan's fields add up to its ``coverage``.
    coverage_after : float or None
        Probability inside the union of the fields visited up to and
        including this exposure (0-1; a re-plan: outside the fields done
        before, like ``metrics.coverage``).
    limiting_mag : float or None
        5-sigma limiting magnitude (AB) of the exposure's difference image
        at mid-exposure (``source/depth.py``, D2): what the plan expects the
        exposure to reach under that sky, airmass and Moon.
    """

    field_id: int
    ra: float
    dec: float
    filter: str
    start: float
    exposure_s: float
    block: int
    airmass: float | None = None
    probability: float | None = None
    probability_share: float | None = None
    coverage_after: float | None = None
    limiting_mag: float | None = None

    @property
    def end(self) -> float:
        """Exposure end (s since the plan start)."""
        return self.start + self.exposure_s


@dataclass(frozen=True)
class EventInfo:
    """What the plan answers; all None for a bare sky map.

    Attributes
    ----------
    superevent_id, alert_type, time_created : str or None
        From the notice (``time_created`` ISO UTC).
    skymap_sha256 : str or None
        SHA-256 of the sky map planned on.
    localization : str or None
        Which map that is: ``gw`` (the GW sky map) or ``combined`` (the
        joint GW x external-trigger map of ``external_coinc``).
    external_coinc : dict or None
        The coincident external trigger (observatory, search, time
        difference in s, coincidence FARs in Hz), when the notice has one.
    event_time : str or None
        Merger time (ISO UTC): the kilonova clock of the plan (light curves,
        detection objective, ``metrics.expected_detections``); the notice's
        ``event.time`` when there is a notice, else the sky map's header
        (:mod:`~mushrooms.scheduler_core.clock`).
    skymap_name : str or None
        The sky map's file name (SkyPortal's localization name), when known.
    merger_time_source : str or None
        Where ``event_time`` came from: ``notice`` or ``skymap`` (None
        without a merger time).
    classification : dict or None
        The notice's source classification (``BNS``, ``NSBH``, ``BBH``,
        ``Terrestrial`` probabilities, 0-1).
    far_hz : float or None
        The notice's false-alarm rate (Hz).
    distance_mpc, distance_std_mpc : float or None
        Posterior mean and standard deviation of the luminosity distance
        (Mpc) over the whole sky, from the map's distance layers.
    area_50_deg2, area_90_deg2 : float or None
        Areas of the 50 % and 90 % credible regions of the map (deg²).
    """

    superevent_id: str | None = None
    alert_type: str | None = None
    time_created: str | None = None
    skymap_sha256: str | None = None
    localization: str | None = None
    external_coinc: dict[str, Any] | None = None
    event_time: str | None = None
    skymap_name: str | None = None
    merger_time_source: str | None = None
    classification: dict[str, float] | None = None
    far_hz: float | None = None
    distance_mpc: float | None = None
    distance_std_mpc: float | None = None
    area_50_deg2: float | None = None
    area_90_deg2: float | None = None


@dataclass(frozen=True)
class PlanMetrics:
    """Summary numbers of a plan.

    Attributes
    ----------
    coverage : float
        Probability inside the union of the planned fields' footprints (a
        re-plan: outside the fields already done in both filters, P8).
    solver : str
        Which scheduler produced the plan (``greedy``, ``milp:highs``, ...).
    status : str
        Solver status (``optimal``, ``time_limit``, ``greedy``, ...).
    mip_gap : float or None
        Relative MIP gap at the end of the solve (None for greedy).
    mip_bound : float or None
        The MILP's best bound on its objective (covered probability minus
        the field penalty): no block plan can do better (None for greedy).
    runtime_s : float
        Wall time of the planning (s).
    n_fields, n_exposures : int
        Distinct fields and exposures in the plan.
    latency_s : float or None
        Alert receipt to plan published (s), filled in by the service.
    upper_bound : float or None
        Certified upper bound on the coverage any rule-abiding plan of this
        problem reaches (:mod:`..schedulers.bounds.certified_bound`: the least of the
        online bound U4 and the interval bound V; None when not computed,
        e.g. greedy).
    upper_bound_method : str or None
        Which bound ``upper_bound`` is: ``online`` (U4), ``interval`` (V,
        when below U4) or ``milp`` (U0 solved); None with no bound.
    expected_detections : float or None
        Probability that the plan detects a kilonova of the configured light
        curve (``detection_lightcurve``), from the sky map's distance
        posterior and each exposure's depth (:mod:`.detection`, equation
        X1); None without distance layers.  In a re-plan, of the plan's own
        exposures (the executed ones not counted).
    coverage_executed : float or None
        A re-plan's (:func:`~.replan.plan_remaining`): probability inside the
        fields the executed record holds done in both filters, which
        ``coverage`` does not count again (P8: the total after the plan is
        ``coverage_executed + coverage``); None for a plan made without an
        executed record.
    coverage_as_executed : float or None
        Probability inside the fields that ZTF's scheduler, as the telescope
        model has it (:mod:`..telescope`, equations Q1-Q13 of
        ``docs/design/executed.md``), observes in both filters at least the
        cadence apart when it runs the queues submitted for this plan
        (:func:`.exports.to_trigger_queues`) on a clear night from the
        plan's first observation: what of ``coverage`` survives execution.
        None when not computed (a plan read from an older document).
    sequence_coverage_as_executed : float or None
        The same run of the queues, counting only the fields whose every
        visit of the filter sequence is executed, each at least the cadence
        after the previous (F2, ``docs/design/sequences.md``; Q21 of
        ``docs/design/executed.md``): what of a g-r-g plan is done whole.
        Equal to ``coverage_as_executed`` for a pair or a single filter; at
        most it.  None when not computed.
    budget : dict or None
        The budget the optimisation ran under (:mod:`..budget`): ``kind``
        ``work`` (``unit`` ``work_s``, the ``spent`` work: a function of the
        inputs) or ``wall`` (``unit`` ``s``), and ``interrupted`` (a
        wall-clock stop ended it: the plan then depends on the machine's
        load).  None for greedy (no budget) and older documents.
    """

    coverage: float
    solver: str
    status: str
    mip_gap: float | None
    runtime_s: float
    n_fields: int
    n_exposures: int
    latency_s: float | None = None
    mip_bound: float | None = None
    upper_bound: float | None = None
    upper_bound_method: str | None = None
    expected_detections: float | None = None
    coverage_executed: float | None = None
    coverage_as_executed: float | None = None
    sequence_coverage_as_executed: float | None = None
    budget: dict | None = None


def make_plan_id(*parts: Any) -> str:
    """Stable plan id: the same inputs and configuration give the same id.

    Parameters
    ----------
    *parts
        JSON-serialisable inputs (sky map hash, start, configuration, solver).

    Returns
    -------
    str
        ``"mushrooms-"`` followed by 16 hex digits of a SHA-256.
    """
    blob = json.dumps(parts, sort_keys=True, default=str).encode()
    return "mushrooms-" + hashlib.sha256(blob).hexdigest()[:16]


@dataclass(frozen=True)
class Plan:
    """A ZTF observing plan over one horizon.

    Attributes
    ----------
    plan_id : str
        Stable id (see :func:`make_plan_id`).
    start, end : astropy.time.Time
        Planning horizon (UTC).
    observations : tuple of Observation
        In time order.
    metrics : PlanMetrics
        Coverage and solver summary.
    event : EventInfo
        The alert this plan answers.
    supersedes : str or None
        plan_id of the plan this one replaces.
    created : astropy.time.Time
        When the plan was made.
    telescope : str
        Always ``"ZTF"``.
    config : dict or None
        The ``[scheduler]`` configuration the plan was made with (a
        ``PlanningConfig`` as a dict); ``mushrooms check`` uses it.
    """

    plan_id: str
    start: Time
    end: Time
    observations: tuple[Observation, ...]
    metrics: PlanMetrics
    event: EventInfo = field(default_factory=EventInfo)
    supersedes: str | None = None
    created: Time = field(default_factory=Time.now)
    telescope: str = "ZTF"
    config: dict[str, Any] | None = None

    def with_(self, **changes: Any) -> "Plan":
        """Copy with some attributes replaced."""
        return replace(self, **changes)

    def absolute_time(self, seconds: float | np.ndarray) -> Time:
        """Seconds since ``start`` as an absolute UTC time."""
        return self.start + TimeDelta(np.asarray(seconds, float), format="sec")

    @property
    def field_ids(self) -> list[int]:
        """Distinct field IDs in order of first visit."""
        return list(dict.fromkeys(o.field_id for o in self.observations))

    def to_document(self) -> dict[str, Any]:
        """The plan document (docs/design/plan-format.md) as a JSON-ready dict."""
        starts = self.absolute_time([o.start for o in self.observations]) if self.observations else []
        ends = self.absolute_time([o.end for o in self.observations]) if self.observations else []
        obs = [
            {
                "field_id": int(o.field_id),
                "ra": round(float(o.ra), 6),
                "dec": round(float(o.dec), 6),
                "filter": o.filter,
                "start": iso_utc(t),
                "end": iso_utc(t_end),
                "exposure_s": float(o.exposure_s),
                "block": int(o.block),
                "airmass": None if o.airmass is None else round(float(o.airmass), 4),
                "probability": None if o.probability is None else round(float(o.probability), 6),
                **_share_keys(o),
            }
            for o, t, t_end in zip(self.observations, starts, ends)
        ]
        doc = {
            "type": "plan",
            "plan_id": self.plan_id,
            "created": iso_utc(self.created),
            "event": asdict(self.event),
            "telescope": self.telescope,
            "start": iso_utc(self.start),
            "end": iso_utc(self.end),
            "supersedes": self.supersedes,
            "observations": obs,
            "metrics": asdict(self.metrics),
        }
        if self.config is not None:
            doc["config"] = self.config
        return doc

    def to_json(self, indent: int | None = 1) -> str:
        """The plan document as JSON text."""
        return strict_json.dumps(self.to_document(), indent=indent)

    @classmethod
    def from_document(cls, doc: Mapping[str, Any]) -> "Plan":
        """Read a plan document back.

        Raises
        ------
        ValueError
            When a key is missing or a value has the wrong type.

        Examples
        --------
        A plan survives its document (JSON and back):

        >>> import json
        >>> from importlib.resources import files
        >>> from astropy.time import Time
        >>> from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
        >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
        >>> config = PlanningConfig(solver="greedy", nside=64)
        >>> plan = make_plan(read_skymap(path, nside=64), config, start=Time("2019-05-01T03:00:00", scale="utc"))
        >>> again = Plan.from_document(json.loads(json.dumps(plan.to_document())))
        >>> again.plan_id == plan.plan_id, len(again.observations) == len(plan.observations)
        (True, True)
        >>> again.to_document() == plan.to_document()
        True
        """
        try:
            missing = [k for k in PLAN_KEYS if k not in doc]
            if missing:
                raise ValueError(f"plan document lacks key(s): {', '.join(missing)}")
            start = parse_time(doc["start"])
            end = parse_time(doc["end"])
            observations = []
            for i, o in enumerate(doc["observations"]):
                lacking = [k for k in OBSERVATION_KEYS if k not in o]
                if lacking:
                    raise ValueError(f"observation {i} lacks key(s): {', '.join(lacking)}")
                t = (parse_time(o["start"]) - start).to_value("s")
                _check_pointing(i, o)
                observations.append(
                    Observation(
                        field_id=int(o["field_id"]), ra=float(o["ra"]), dec=float(o["dec"]),
                        filter=str(o["filter"]), start=float(t),
                        exposure_s=float(o["exposure_s"]), block=int(o["block"]),
                        airmass=None if o.get("airmass") is None else float(o["airmass"]),
                        probability=None if o.get("probability") is None else float(o["probability"]),
                        probability_share=_optional_float(o, "probability_share"),
                        coverage_after=_optional_float(o, "coverage_after"),
                        limiting_mag=_optional_float(o, "limiting_mag"),
                    )
                )
            m = doc["metrics"]
            metrics = PlanMetrics(**{k: m.get(k) for k in METRIC_KEYS})
            ev = doc["event"] or {}
            event = EventInfo(**{k: ev.get(k) for k in EVENT_KEYS})
            return cls(
                plan_id=str(doc["plan_id"]), start=start, end=end,
                observations=tuple(observations), metrics=metrics, event=event,
                supersedes=doc["supersedes"], created=parse_time(doc["created"]),
                telescope=str(doc["telescope"]), config=doc.get("config"),
            )
        except (TypeError, KeyError, AttributeError) as exc:
            raise ValueError(f"malformed plan document: {exc}") from None


def _share_keys(o: Observation) -> dict[str, float]:
    """The optional keys ``probability_share``, ``coverage_after`` and ``limiting_mag`` an observation has."""
    keys = {key: round(float(value), 6) for key, value in (("probability_share", o.probability_share),
                                                          ("coverage_after", o.coverage_after))
            if value is not None}
    if o.limiting_mag is not None and math.isfinite(o.limiting_mag):
        keys["limiting_mag"] = round(float(o.limiting_mag), 2)
    return keys


def _optional_float(o: Mapping[str, Any], key: str) -> float | None:
    return None if o.get(key) is None else float(o[key])


def _check_pointing(i: int, o: Mapping[str, Any]) -> None:
    """Refuse an observation whose numbers are not numbers a telescope could use (NaN, inf, RA beyond 360)."""
    for key, lo, hi in (("ra", 0.0, 360.0), ("dec", -90.0, 90.0), ("exposure_s", 0.0, 86400.0)):
        value = float(o[key])
        if not (math.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"observation {i}: {key} = {o[key]!r} is not a finite number in [{lo:g}, {hi:g}]")


def sorted_observations(observations: Sequence[Observation]) -> tuple[Observation, ...]:
    """Observations in time order."""
    return tuple(sorted(observations, key=lambda o: (o.start, o.field_id, o.filter)))
