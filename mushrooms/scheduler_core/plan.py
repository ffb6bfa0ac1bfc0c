"""The observing plan: dataclasses, the JSON plan document, ZTF queue export.

Times inside the library are seconds (float) since the plan's ``start``;
the document carries ISO-8601 UTC strings.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Mapping, Sequence

import numpy as np
from astropy.time import Time, TimeDelta

__all__ = [
    "Observation",
    "EventInfo",
    "PlanMetrics",
    "Plan",
    "make_plan_id",
    "iso_utc",
    "to_trigger_queue",
    "PLAN_KEYS",
    "OBSERVATION_KEYS",
    "METRIC_KEYS",
]

PLAN_KEYS = (
    "plan_id", "created", "event", "telescope", "start", "end",
    "supersedes", "observations", "metrics",
)
OBSERVATION_KEYS = ("field_id", "ra", "dec", "filter", "start", "exposure_s", "block")
METRIC_KEYS = (
    "coverage", "solver", "status", "mip_gap", "mip_bound", "runtime_s",
    "n_fields", "n_exposures", "latency_s", "upper_bound",
    "expected_detections",
)
FILTER_IDS = {"g": 1, "r": 2, "i": 3}


def iso_utc(t: Time) -> str:
    """ISO-8601 UTC string with millisecond precision and a trailing ``Z``."""
    return Time(t, scale="utc").isot[:23] + "Z"


def parse_time(value: str | Time) -> Time:
    """Parse an ISO-8601 UTC string (a trailing ``Z`` is allowed).

    Raises
    ------
    ValueError
        When the string is not an ISO time.
    """
    if isinstance(value, Time):
        return value
    text = str(value).strip()
    if text.endswith("Z"):
        text = text[:-1]
    try:
        return Time(text, format="isot", scale="utc")
    except ValueError:
        try:
            return Time(text, format="iso", scale="utc")
        except ValueError:
            raise ValueError(f"not an ISO-8601 UTC time: {value!r}") from None


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
    """

    field_id: int
    ra: float
    dec: float
    filter: str
    start: float
    exposure_s: float
    block: int

    @property
    def end(self) -> float:
        """Exposure end (s since the plan start)."""
        return self.start + self.exposure_s


@dataclass(frozen=True)
class EventInfo:
    """What the plan answers; all None for a bare sky map."""

    superevent_id: str | None = None
    alert_type: str | None = None
    time_created: str | None = None
    skymap_sha256: str | None = None


@dataclass(frozen=True)
class PlanMetrics:
    """Summary numbers of a plan.

    Attributes
    ----------
    coverage : float
        Probability inside the union of the planned fields' footprints.
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
        problem reaches (:mod:`.bound`; None when not computed, e.g. greedy).
    expected_detections : float or None
        Probability that the plan detects a kilonova of the configured light
        curve (``detection_lightcurve``), from the sky map's distance
        posterior and each exposure's depth (:mod:`.detection`, equation
        X1); None without distance layers.
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
    expected_detections: float | None = None


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
        """The plan document of DESIGN.md as a JSON-ready dict."""
        starts = self.absolute_time([o.start for o in self.observations]) if self.observations else []
        obs = [
            {
                "field_id": int(o.field_id),
                "ra": round(float(o.ra), 6),
                "dec": round(float(o.dec), 6),
                "filter": o.filter,
                "start": iso_utc(t),
                "exposure_s": float(o.exposure_s),
                "block": int(o.block),
            }
            for o, t in zip(self.observations, starts)
        ]
        return {
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

    def to_json(self, indent: int | None = 1) -> str:
        """The plan document as JSON text."""
        return json.dumps(self.to_document(), indent=indent)

    @classmethod
    def from_document(cls, doc: Mapping[str, Any]) -> "Plan":
        """Read a plan document back.

        Raises
        ------
        ValueError
            When a key is missing or a value has the wrong type.
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
                observations.append(
                    Observation(
                        field_id=int(o["field_id"]), ra=float(o["ra"]), dec=float(o["dec"]),
                        filter=str(o["filter"]), start=float(t),
                        exposure_s=float(o["exposure_s"]), block=int(o["block"]),
                    )
                )
            m = doc["metrics"]
            metrics = PlanMetrics(**{k: m.get(k) for k in METRIC_KEYS})
            ev = doc["event"] or {}
            event = EventInfo(**{k: ev.get(k) for k in ("superevent_id", "alert_type", "time_created", "skymap_sha256")})
            return cls(
                plan_id=str(doc["plan_id"]), start=start, end=end,
                observations=tuple(observations), metrics=metrics, event=event,
                supersedes=doc["supersedes"], created=parse_time(doc["created"]),
                telescope=str(doc["telescope"]),
            )
        except (TypeError, KeyError, AttributeError) as exc:
            raise ValueError(f"malformed plan document: {exc}") from None


def to_trigger_queue(
    plan: Plan,
    program_pi: str = "Kulkarni",
    subprogram_name: str = "GW",
    queue_name: str | None = None,
) -> dict[str, Any]:
    """Export a plan in ZTF's trigger-queue format (as SkyPortal submits it).

    Parameters
    ----------
    plan : Plan
        The plan to export.
    program_pi, subprogram_name : str
        ZTF program fields copied into every target.
    queue_name : str, optional
        Defaults to ``ToO_<superevent or plan id>``.

    Returns
    -------
    dict
        ``{queue_name, queue_type: "list", validity_window_mjd, targets}``.
    """
    tag = plan.event.superevent_id or plan.plan_id
    name = queue_name or f"ToO_{tag}"
    targets = [
        {
            "request_id": i + 1,
            "field_id": int(o.field_id),
            "ra": float(o.ra),
            "dec": float(o.dec),
            "filter_id": FILTER_IDS[o.filter],
            "exposure_time": float(o.exposure_s),
            "program_pi": program_pi,
            "subprogram_name": subprogram_name,
        }
        for i, o in enumerate(plan.observations)
    ]
    return {
        "queue_name": name,
        "queue_type": "list",
        "validity_window_mjd": [float(plan.start.mjd), float(plan.end.mjd)],
        "targets": targets,
    }


def sorted_observations(observations: Sequence[Observation]) -> tuple[Observation, ...]:
    """Observations in time order."""
    return tuple(sorted(observations, key=lambda o: (o.start, o.field_id, o.filter)))
