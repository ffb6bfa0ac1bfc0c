"""Is the sky map observable at all?  The ``not_observable`` answer and its reasons.

When the best rule-abiding plan covers less than ``min_coverage``, the answer
published is not a plan but a ``not_observable`` document saying why, with
the reasons measured from the map over the horizon: where the probability
is, in four exclusive parts that sum to 1,

``outside_limits``
    outside the declination band, or never inside the airmass and P48 mount
    limits at any time of the horizon (whatever the Sun does);
``daylight``
    reachable, but only while the Sun is above ``sun_alt_max_deg`` (the map
    is too close to the Sun);
``moon``
    reachable at night, but only closer to the Moon than ``moon_sep_min_deg``;
``observable``
    reachable at night away from the Moon (yet the plan still fell short:
    too little probability per field, or too little time);

plus the night (Sun below the limit) in the horizon and the probability
weighted median separation from the Sun.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from astropy.coordinates import get_body
from astropy.time import Time, TimeDelta

from ..config import PlanningConfig
from .document import Plan
from ..sky.healpix import hp
from ..sky.skymap import SkyMap
from ..sky.visibility import constraint_masks, site

__all__ = ["SkyReasons", "NotObservable", "sky_reasons", "not_observable"]

#: Resolution (HEALPix nside) and time step (s) of the reasons: coarse is plenty
REASONS_NSIDE = 32
REASONS_STEP_S = 600.0


@dataclass(frozen=True)
class SkyReasons:
    """Where the sky map's probability is, for ZTF, over one horizon.

    Attributes
    ----------
    outside_limits, daylight, moon, observable : float
        Exclusive probability fractions (sum 1), see the module docstring.
    night_h : float
        Hours of the horizon with the Sun below ``sun_alt_max_deg``.
    sun_separation_deg : float
        Probability-weighted median angular distance (deg) of the map from
        the Sun at the horizon start.
    """

    outside_limits: float
    daylight: float
    moon: float
    observable: float
    night_h: float
    sun_separation_deg: float

    def sentences(self, config: PlanningConfig) -> list[str]:
        """The reasons, largest first, as sentences an observer can read."""
        out = []
        if self.night_h <= 0:
            out.append(f"no night in the horizon: the Sun never sets below {config.sun_alt_max_deg:g} deg "
                       f"in {config.horizon_h:g} h")
        parts = [
            (self.daylight, f"{self.daylight:.1%} of the probability is within the Sun limit: above airmass "
                            f"{config.airmass_max:g} only while the Sun is above {config.sun_alt_max_deg:g} deg "
                            f"(median {self.sun_separation_deg:.0f} deg from the Sun)"),
            (self.outside_limits, f"{self.outside_limits:.1%} is outside the declination "
                                  f"[{config.dec_min_deg:g}, {config.dec_max_deg:g}] deg or "
                                  f"{_mount(config)} mount/airmass limits"),
            (self.moon, f"{self.moon:.1%} is observable at night only within {config.moon_sep_min_deg:g} deg "
                        f"of the Moon"),
        ]
        out.extend(text for share, text in sorted(parts, key=lambda p: -p[0]) if share >= 0.005)
        out.append(f"{self.observable:.1%} is observable at night")
        return out


def sky_reasons(skymap: SkyMap, config: PlanningConfig, start: Time) -> SkyReasons:
    """Measure where the map's probability is for ZTF over ``[start, start + horizon]``.

    Parameters
    ----------
    skymap : SkyMap
        The sky map (any nside; degraded to :data:`REASONS_NSIDE`).
    config : PlanningConfig
        Horizon and limits.
    start : astropy.time.Time
        Horizon start (UTC).

    Returns
    -------
    SkyReasons
    """
    prob = hp.ud_grade(skymap.prob, REASONS_NSIDE, order_in="NESTED", order_out="NESTED", power=-2)
    prob = prob / prob.sum()
    ra, dec = hp.pix2ang(REASONS_NSIDE, np.arange(prob.size), nest=True, lonlat=True)

    n_steps = int(np.floor(config.horizon_s / REASONS_STEP_S)) + 1
    times = start + TimeDelta(np.arange(n_steps) * REASONS_STEP_S, format="sec")
    masks = constraint_masks(ra, dec, times, config)  # the schedulers' own constraints, one by one
    night, away = masks.night, masks.moon_clear
    reach = masks.reachable & ((dec >= config.dec_min_deg) & (dec <= config.dec_max_deg))[:, None]
    sun = get_body("sun", times[:1], site(config.telescope))

    any_time = reach.any(axis=1)
    at_night = (reach & night[None, :]).any(axis=1)
    dark = (reach & night[None, :] & away).any(axis=1)
    sun_sep = _separation_deg(ra, dec, float(sun.ra.deg[0]), float(sun.dec.deg[0]))
    order = np.argsort(sun_sep)
    median_sep = float(sun_sep[order][np.searchsorted(np.cumsum(prob[order]), 0.5)])
    return SkyReasons(
        outside_limits=round(float(prob[~any_time].sum()), 6),
        daylight=round(float(prob[any_time & ~at_night].sum()), 6),
        moon=round(float(prob[at_night & ~dark].sum()), 6),
        observable=round(float(prob[dark].sum()), 6),
        night_h=round(float(night.sum()) * REASONS_STEP_S / 3600.0, 2),
        sun_separation_deg=round(median_sep, 1),
    )


def _separation_deg(ra1: Any, dec1: Any, ra2: Any, dec2: Any) -> np.ndarray:
    """Angular separation (deg) of points given in deg; broadcasts."""
    r1, d1, r2, d2 = (np.radians(np.asarray(x, float)) for x in (ra1, dec1, ra2, dec2))
    cos = np.sin(d1) * np.sin(d2) + np.cos(d1) * np.cos(d2) * np.cos(r1 - r2)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


@dataclass(frozen=True)
class NotObservable:
    """The answer when no plan reaches ``min_coverage``: published instead of the plan.

    It carries the plan it replaces (its id, horizon, event and metrics, so
    that it takes the plan's place in the event's history) and the reasons.

    Attributes
    ----------
    plan : Plan
        The best plan found (not published).
    reasons : SkyReasons
        Measured from the map.
    min_coverage : float
        The threshold it fell short of.
    sentences : tuple of str
        The reasons in words.
    """

    plan: Plan
    reasons: SkyReasons
    min_coverage: float
    sentences: tuple[str, ...] = field(default=())

    # the attributes of a Plan the daemon reads
    @property
    def plan_id(self) -> str:
        return self.plan.plan_id

    @property
    def metrics(self) -> Any:
        return self.plan.metrics

    @property
    def supersedes(self) -> str | None:
        return self.plan.supersedes

    @property
    def summary(self) -> str:
        """One line: not observable, and the main reason."""
        return (f"not observable: best coverage {self.plan.metrics.coverage:.4f} < {self.min_coverage:g}; "
                f"{self.sentences[0] if self.sentences else ''}")

    def with_(self, **changes: Any) -> "NotObservable":
        """Copy with attributes of the underlying plan replaced."""
        return dataclasses.replace(self, plan=self.plan.with_(**changes))

    def to_document(self) -> dict[str, Any]:
        """The ``not_observable`` document (see docs/design/plan-format.md)."""
        plan_doc = self.plan.to_document()
        keep = ("plan_id", "created", "event", "telescope", "start", "end", "supersedes", "config")
        doc: dict[str, Any] = {"type": "not_observable"}
        doc.update({k: plan_doc[k] for k in keep if k in plan_doc})
        doc.update(
            reasons=list(self.sentences),
            sky=dataclasses.asdict(self.reasons),
            best_coverage=float(self.plan.metrics.coverage),
            min_coverage=float(self.min_coverage),
            metrics=plan_doc["metrics"],
        )
        return doc


def not_observable(plan: Plan, skymap: SkyMap, config: PlanningConfig) -> NotObservable | None:
    """The ``not_observable`` answer when ``plan`` covers less than ``config.min_coverage``, else None.

    Parameters
    ----------
    plan : Plan
        The checked plan (after the least-gain rule).
    skymap : SkyMap
        Its sky map.
    config : PlanningConfig
        Planning parameters (``min_coverage``).
    """
    if plan.metrics.coverage >= config.min_coverage and plan.observations:
        return None
    reasons = sky_reasons(skymap, config, plan.start)
    return NotObservable(plan, reasons, config.min_coverage, tuple(reasons.sentences(config)))


def _mount(config: PlanningConfig) -> str:
    """Whose mount a reason names: the P48 (ZTF), else the telescope's name."""
    from ..instruments.active import telescope_name

    return "P48" if config.telescope == "ztf" else telescope_name(config.telescope).upper()
