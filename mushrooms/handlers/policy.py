"""Which LVK alerts deserve a ZTF plan: the ``[policy]`` table and its verdict.

The policy is pure: :func:`evaluate` looks at one parsed :class:`~mushrooms.handlers.alert.Alert`,
the configuration and the current time, and says keep or ignore, with a reason an
operator can read.  What to *do* with a kept alert (plan, rerun, nothing, withdraw)
is :mod:`mushrooms.handlers.decisions`' business.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Mapping

from ..scheduler_core.tables import dataclass_from_table
from ..scheduler_core.ranges import require_finite, setting

if TYPE_CHECKING:  # pragma: no cover
    from .alert import Alert, EventDetails

__all__ = ["PolicyConfig", "Verdict", "evaluate", "superevent_kind", "sub_solar_mass", "PLAN_START_CHOICES"]

PLAN_START_CHOICES = ("received", "event", "created")
_ALERT_TYPES = ("EARLYWARNING", "PRELIMINARY", "INITIAL", "UPDATE", "RETRACTION")


@dataclass(frozen=True)
class PolicyConfig:
    """The ``[policy]`` table of ``config.toml``: which alerts get a plan.

    An alert is planned when **all** of these hold: its superevent prefix is
    allowed, its alert type is listed, its group is listed, it is significant
    (if required) and its FAR is at most ``max_far_hz``, it is not older than
    the age limits, and it is likely to contain a neutron star:
    ``P(BNS) + P(NSBH) >= min_p_bns_nsbh`` **or** ``HasNS >= min_has_ns``.
    A RETRACTION is never filtered by the source cuts (it has no ``event``);
    only its prefix and notice age are checked.

    Shapes that the neutron-star cut cannot read are decided by their own
    keys, and every reason names the key that decided it
    (``docs/configuration.md``, "The alert shapes of the next observing
    run"): a sub-solar-mass alert (``search = SSM``, or a sub-solar-mass
    probability ``HasSSM`` without classification) by
    ``plan_sub_solar_mass``; a CBC notice with no classification and no
    ``HasNS`` by ``plan_unclassified``; an early warning whose merger lies
    ahead by ``max_early_warning_lead_s``.  A notice whose sky map is null
    is ignored with a warning (nothing to plan until a map comes).

    Attributes
    ----------
    allow_mock : bool
        Accept mock (``MS...``) and test (``TS...``) superevents.  Default
        False: only real events (prefix ``S``).  ``--allow-mock`` on the
        command line sets it.
    groups : tuple of str
        Accepted ``event.group`` values.  Default ``("CBC",)``: Burst
        candidates carry no neutron-star classification.
    alert_types : tuple of str
        Alert types that may start or update a plan.  Default all of
        ``EARLYWARNING, PRELIMINARY, INITIAL, UPDATE`` (``EARLY_WARNING`` is
        normalised to ``EARLYWARNING`` by the parser).
    require_significant : bool
        Require ``event.significant == true``.  Default True.
    max_far_hz : float
        Largest accepted false-alarm rate (Hz).  Default 3.86e-7 Hz (one per
        month).  ``0`` disables the FAR cut.
    min_p_bns_nsbh : float
        Threshold on ``classification.BNS + classification.NSBH``
        (probability, 0-1).  Default 0.1.
    min_has_ns : float
        Threshold on ``properties.HasNS`` (probability, 0-1).  Default 0.5.
    max_notice_age_s : float
        Ignore a notice received more than this long (s) after its own
        ``time_created`` (a backlog after a long outage; retractions are
        still honoured).  Default 3600 s.  ``0`` disables the check.
    max_event_age_s : float
        Ignore a notice whose merger happened more than this long (s) before
        it was received: the transient has faded.  Default 172800 s (2 days).
        ``0`` disables the check.
    max_notice_bytes : int
        Largest notice (bytes) the parser looks at; a bigger payload is
        rejected before any decoding.  Default 8388608 (8 MiB; real notices
        are 0.4-2.1 MB, GCN's limit is 4 MiB).
    plan_start : str
        Start of the planning horizon.  ``received`` (default): the later of
        the time the notice was received and the merger time, recorded when
        the notice is accepted so that a re-run after a crash gives the same
        plan id.  ``event``: the merger time from the notice (deterministic
        replays of archived events).  ``created``: the notice's own
        ``time_created``.
    use_combined_skymap : bool
        Plan on the joint GW x external localisation
        (``external_coinc.combined_skymap``, e.g. GW x Fermi-GBM) when the
        notice carries one that decodes as a valid sky map; the GW map
        otherwise.  Default True: the joint map is what an observer wants to
        search first, and it is often much smaller.
    max_skymap_bytes : int
        Largest sky map (bytes as carried: packed, for a gzip) a notice or a
        ``mushrooms trigger`` may hand in; a bigger one is rejected unread.
        Default 67108864 (64 MiB: LVK's multi-order notice maps are 1-5 MB,
        a gzipped flat NSIDE 2048 map with distance layers 5-20 MB).  What a
        map may *unpack* to is not bounded here: the reader streams it and
        holds it to its own header (HEALPix NSIDE <= 8192, the declared
        table size), so a flat NSIDE 1024 map that unpacks to 384 MiB is
        accepted and a gzip bomb is refused at its header.
    max_clock_skew_s : float
        A notice whose ``time_created`` or merger time lies more than this
        (s) after the receipt clock is rejected: dated in the future, it is
        broken or hostile.  Default 300 s.
    max_early_warning_lead_s : float
        An ``EARLYWARNING`` is sent *before* its merger: its merger time may
        lie up to this much (s) after receipt, on top of
        ``max_clock_skew_s``.  Default 1200 s: a 1.4 + 1.4 Msun binary spends
        about 17 min above 10 Hz, the longest lead any detector of the next
        run can give.  The plan starts at the merger, never before.
    plan_sub_solar_mass : bool
        Plan sub-solar-mass alerts (the SSM search's: no BNS/NSBH/BBH/
        Terrestrial classification, no ``HasRemnant``, a sub-solar-mass
        probability instead).  Default False: no bright counterpart is
        predicted for a merger with a sub-solar-mass compact object, and
        every plan spends ZTF's target-of-opportunity time.
    plan_unclassified : bool
        Plan a notice that carries neither a source classification nor
        ``HasNS`` (so the neutron-star cut cannot be applied).  Default
        False: most CBC candidates are binary black holes.  The ignore is
        logged as a WARNING so that an operator sees it.
    """

    allow_mock: bool = False
    groups: tuple[str, ...] = ("CBC",)
    alert_types: tuple[str, ...] = ("EARLYWARNING", "PRELIMINARY", "INITIAL", "UPDATE")
    require_significant: bool = True
    max_far_hz: float = setting(3.86e-7, 0, 1, "Hz", why="0 disables")
    min_p_bns_nsbh: float = setting(0.1, 0, 1, why="probability")
    min_has_ns: float = setting(0.5, 0, 1, why="probability")
    max_notice_age_s: float = setting(3600.0, 0, 604_800, "s", why="0 disables; a week at most")
    max_event_age_s: float = setting(172800.0, 0, 2_592_000, "s", why="0 disables; a kilonova fades within days")
    max_notice_bytes: int = setting(8_388_608, 1024, 536_870_912, "bytes", why="GCN's limit is 4 MiB")
    plan_start: str = "received"
    use_combined_skymap: bool = True
    max_skymap_bytes: int = setting(67_108_864, 2880, 4_294_967_296, "bytes", why="one FITS block to 4 GiB")
    max_clock_skew_s: float = setting(300.0, 0, 86400, "s")
    max_early_warning_lead_s: float = setting(1200.0, 0, 3600, "s",
                                              why="a BNS spends ~17 min above 10 Hz")
    plan_sub_solar_mass: bool = False
    plan_unclassified: bool = False

    def __post_init__(self) -> None:
        require_finite(self, "policy")
        if self.plan_start not in PLAN_START_CHOICES:
            raise ValueError(
                f"[policy] plan_start must be one of {', '.join(PLAN_START_CHOICES)}, got {self.plan_start!r}"
            )
        for name in ("min_p_bns_nsbh", "min_has_ns"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ValueError(f"[policy] {name} must be a probability in [0, 1], got {v!r}")
        for name in ("max_far_hz", "max_notice_age_s", "max_event_age_s", "max_clock_skew_s",
                     "max_early_warning_lead_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"[policy] {name} must be a number, got {v!r}")
        if isinstance(self.max_notice_bytes, bool) or not isinstance(self.max_notice_bytes, int) \
                or self.max_notice_bytes < 1024:
            raise ValueError(f"[policy] max_notice_bytes must be an integer >= 1024, got {self.max_notice_bytes!r}")
        if isinstance(self.max_skymap_bytes, bool) or not isinstance(self.max_skymap_bytes, int) \
                or self.max_skymap_bytes < 2880:
            raise ValueError(f"[policy] max_skymap_bytes must be an integer >= 2880, got {self.max_skymap_bytes!r}")
        if self.max_clock_skew_s < 0:
            raise ValueError(f"[policy] max_clock_skew_s must be >= 0, got {self.max_clock_skew_s!r}")
        for name in ("allow_mock", "require_significant", "use_combined_skymap", "plan_sub_solar_mass",
                     "plan_unclassified"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"[policy] {name} must be true or false, got {getattr(self, name)!r}")
        for name in ("groups", "alert_types"):
            v = getattr(self, name)
            if isinstance(v, str) or not all(isinstance(x, str) for x in v):
                raise ValueError(f"[policy] {name} must be a list of strings, got {v!r}")
        bad = sorted(set(self.alert_types) - set(_ALERT_TYPES) - {"EARLY_WARNING"})
        if bad:
            raise ValueError(f"[policy] unknown alert type(s) in alert_types: {', '.join(bad)}")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "PolicyConfig":
        """Build from the parsed ``[policy]`` table; unknown keys are errors.

        Raises
        ------
        ValueError
            On an unknown key or a bad value, with one line naming it.
        """
        return dataclass_from_table(cls, table, "policy")


@dataclass(frozen=True)
class Verdict:
    """The policy's answer for one alert.

    Attributes
    ----------
    keep : bool
        True when the alert passes every cut.
    reason : str
        Short human-readable reason (why kept, or the first cut that failed).
    reject : bool
        The alert is not merely out of scope but invalid (e.g. dated in the
        future): it is recorded as ``rejected``, not ``ignore``.
    warn : bool
        An ignore an operator should see (logged as a WARNING): a candidate
        that could not be classified, or that came without a sky map.
    """

    keep: bool
    reason: str
    reject: bool = False
    warn: bool = False


def superevent_kind(superevent_id: str) -> str:
    """``real`` (``S...``), ``mock`` (``MS...``), ``test`` (``TS...``) or ``unknown``."""
    if superevent_id.startswith("S"):
        return "real"
    if superevent_id.startswith("MS"):
        return "mock"
    if superevent_id.startswith("TS"):
        return "test"
    return "unknown"


def _seconds_between(later: datetime, earlier: datetime) -> float:
    return (later - earlier).total_seconds()


def _in_the_future(alert: "Alert", now: datetime, config: PolicyConfig) -> str | None:
    """Why the notice or its event is dated after ``now`` + the allowed skew, or None.

    An early warning's merger may lie ``max_early_warning_lead_s`` further ahead.
    """
    skew = config.max_clock_skew_s
    times = [("notice time_created", alert.time_created, skew, "")]
    if alert.event is not None and alert.event.time is not None:
        if alert.alert_type == "EARLYWARNING":
            lead = config.max_early_warning_lead_s
            times.append(("early warning's merger time", alert.event.time, skew + lead,
                          f" + max_early_warning_lead_s {lead:.0f}"))
        else:
            times.append(("event time", alert.event.time, skew, ""))
    for what, t, allowed, extra in times:
        ahead = _seconds_between(t, now)
        if ahead > allowed:
            return (f"{what} {t.isoformat()} is {ahead:.0f} s in the future "
                    f"(max_clock_skew_s {skew:.0f}{extra})")
    return None


def evaluate(alert: "Alert", config: PolicyConfig, now: datetime | None = None) -> Verdict:
    """Apply the policy to one alert.

    Parameters
    ----------
    alert : Alert
        Parsed notice.
    config : PolicyConfig
        The ``[policy]`` table.
    now : datetime, optional
        When the notice was received (timezone-aware UTC); default: now.
        Replays pass the notice's own ``time_created``.

    Returns
    -------
    Verdict
    """
    now = now or datetime.now(timezone.utc)
    future = _in_the_future(alert, now, config)
    if future:
        return Verdict(False, future, reject=True)
    kind = superevent_kind(alert.superevent_id)
    if kind == "unknown":
        return Verdict(False, f"unrecognised superevent id prefix {alert.superevent_id!r}")
    if kind != "real" and not config.allow_mock:
        return Verdict(False, f"{kind} event (mock/test events not enabled)")
    if config.max_notice_age_s > 0:
        age = _seconds_between(now, alert.time_created)
        if age > config.max_notice_age_s:
            return Verdict(False, f"notice is {age:.0f} s old (max_notice_age_s {config.max_notice_age_s:.0f})")
    if alert.alert_type == "RETRACTION":
        return Verdict(True, "retraction")
    allowed_types = {"EARLYWARNING" if t == "EARLY_WARNING" else t for t in config.alert_types}
    if alert.alert_type not in allowed_types:
        return Verdict(False, f"alert type {alert.alert_type} not in policy alert_types")
    ev = alert.event
    if ev is None:
        return Verdict(False, f"{alert.alert_type} notice without event")
    cut = _event_cuts(ev, config, now)
    if cut is not None:
        return cut
    verdict = _source_verdict(ev, config)
    notes = [n for n in (_significance_note(ev) if verdict.keep else "", _early_warning_note(alert, now),
                         ev.mchirp_source.summary() if ev.mchirp_source else ev.mchirp_note) if n]
    reason = "; ".join([verdict.reason, *notes])
    if verdict.keep and not ev.has_skymap:
        return Verdict(False, f"{reason}; but the notice carries no sky map (event.skymap is null): nothing to "
                              "plan until a notice brings one", warn=True)
    return dataclasses.replace(verdict, reason=reason)


def _event_cuts(ev: "EventDetails", config: PolicyConfig, now: datetime) -> Verdict | None:
    """The first cut on the event's age, group, significance and FAR that fails, or None."""
    if config.max_event_age_s > 0 and ev.time is not None:
        age = _seconds_between(now, ev.time)
        if age > config.max_event_age_s:
            return Verdict(False, f"event is {age:.0f} s old (max_event_age_s {config.max_event_age_s:.0f})")
    if ev.group not in config.groups:
        return Verdict(False, f"group {ev.group} not in {', '.join(config.groups)}")
    if config.require_significant and not ev.significant:
        return Verdict(False, f"not significant: a low-significance alert (significant = false, FAR {ev.far:.3g} Hz); "
                              "[policy] require_significant = true")
    if config.max_far_hz > 0 and (ev.far is None or ev.far > config.max_far_hz):
        return Verdict(False, f"FAR {ev.far:.3g} Hz above max_far_hz {config.max_far_hz:.3g}"
                       if ev.far is not None else "no FAR")
    return None


def sub_solar_mass(ev: "EventDetails") -> tuple[bool, float | None]:
    """Whether the event is a sub-solar-mass alert, and its sub-solar-mass probability if given.

    An alert of the SSM search (``search == "SSM"``), or one that carries a
    ``HasSSM`` (or ``has_SSM``) property and no source classification.  A
    classified alert with such a property is decided as usual: a property
    added to every alert must not take ordinary BNS alerts with it.
    """
    p = next((v for k, v in ev.properties.items() if k.replace("_", "").lower() == "hasssm"), None)
    return (ev.search.upper() == "SSM" or (p is not None and not ev.classification)), p


def _source_verdict(ev: "EventDetails", config: PolicyConfig) -> Verdict:
    """Keep or ignore on what the source is: sub-solar mass, unclassified, or the neutron-star cut."""
    ssm, p_ssm = sub_solar_mass(ev)
    if ssm:
        what = (f"sub-solar-mass candidate (search {ev.search}"
                + (f", HasSSM {p_ssm:.3f}" if p_ssm is not None else "") + ")")
        key = f"[policy] plan_sub_solar_mass = {str(config.plan_sub_solar_mass).lower()}"
        return Verdict(config.plan_sub_solar_mass, f"{what}; {key}")
    has_ns = ev.properties.get("HasNS")
    if not ev.classification:
        if has_ns is not None:
            ok = has_ns >= config.min_has_ns
            return Verdict(ok, f"no source classification in the notice; HasNS {has_ns:.3f} "
                               f"{'>=' if ok else '<'} {config.min_has_ns}")
        key = f"[policy] plan_unclassified = {str(config.plan_unclassified).lower()}"
        return Verdict(config.plan_unclassified, f"no source classification and no HasNS in the notice (a "
                                                 f"{ev.group}/{ev.pipeline}/{ev.search} candidate): a neutron star "
                                                 f"cannot be told; {key}", warn=not config.plan_unclassified)
    p_ns = ev.classification.get("BNS", 0.0) + ev.classification.get("NSBH", 0.0)
    if p_ns >= config.min_p_bns_nsbh:
        return Verdict(True, f"P(BNS)+P(NSBH) {p_ns:.3f} >= {config.min_p_bns_nsbh}")
    if has_ns is not None and has_ns >= config.min_has_ns:
        return Verdict(True, f"HasNS {has_ns:.3f} >= {config.min_has_ns}")
    best = max(ev.classification.items(), key=lambda kv: kv[1], default=("none", 0.0))
    return Verdict(
        False,
        f"no neutron star: P(BNS)+P(NSBH) {p_ns:.3f} < {config.min_p_bns_nsbh}, HasNS {has_ns or 0.0:.3f} < "
        f"{config.min_has_ns} (most likely {best[0]} {best[1]:.3f})",
    )


def _significance_note(ev: "EventDetails") -> str:
    """Said of a kept low-significance alert (only ``require_significant = false`` keeps one)."""
    return "" if ev.significant else "low-significance alert accepted (require_significant = false)"


def _early_warning_note(alert: "Alert", now: datetime) -> str:
    """Said of an early warning received before its merger: the plan waits for the merger."""
    ev = alert.event
    if alert.alert_type != "EARLYWARNING" or ev is None or ev.time is None or ev.time <= now:
        return ""
    return f"early warning: merger {_seconds_between(ev.time, now):.0f} s after receipt (the plan starts at the merger)"
