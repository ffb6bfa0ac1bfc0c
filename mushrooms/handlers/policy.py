"""Which LVK alerts deserve a ZTF plan: the ``[policy]`` table and its verdict.

The policy is pure: :func:`evaluate` looks at one parsed :class:`~mushrooms.handlers.alert.Alert`,
the configuration and the current time, and says keep or ignore, with a reason an
operator can read.  What to *do* with a kept alert (plan, rerun, nothing, withdraw)
is :mod:`mushrooms.handlers.decisions`' business.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Mapping

from ..scheduler_core.tables import dataclass_from_table
from ..scheduler_core.ranges import require_finite, setting

if TYPE_CHECKING:  # pragma: no cover
    from .alert import Alert

__all__ = ["PolicyConfig", "Verdict", "evaluate", "superevent_kind", "PLAN_START_CHOICES"]

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
        for name in ("max_far_hz", "max_notice_age_s", "max_event_age_s", "max_clock_skew_s"):
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
        for name in ("allow_mock", "require_significant", "use_combined_skymap"):
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
    """

    keep: bool
    reason: str
    reject: bool = False


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


def _in_the_future(alert: "Alert", now: datetime, skew_s: float) -> str | None:
    """Why the notice or its event is dated after ``now`` + ``skew_s``, or None."""
    times = [("notice time_created", alert.time_created)]
    if alert.event is not None and alert.event.time is not None:
        times.append(("event time", alert.event.time))
    for what, t in times:
        ahead = _seconds_between(t, now)
        if ahead > skew_s:
            return (f"{what} {t.isoformat()} is {ahead:.0f} s in the future "
                    f"(max_clock_skew_s {skew_s:.0f})")
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
    future = _in_the_future(alert, now, config.max_clock_skew_s)
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
    if config.max_event_age_s > 0 and ev.time is not None:
        age = _seconds_between(now, ev.time)
        if age > config.max_event_age_s:
            return Verdict(False, f"event is {age:.0f} s old (max_event_age_s {config.max_event_age_s:.0f})")
    if ev.group not in config.groups:
        return Verdict(False, f"group {ev.group} not in {', '.join(config.groups)}")
    if config.require_significant and not ev.significant:
        return Verdict(False, "not significant")
    if config.max_far_hz > 0 and (ev.far is None or ev.far > config.max_far_hz):
        return Verdict(False, f"FAR {ev.far:.3g} Hz above max_far_hz {config.max_far_hz:.3g}"
                       if ev.far is not None else "no FAR")
    p_ns = ev.classification.get("BNS", 0.0) + ev.classification.get("NSBH", 0.0)
    has_ns = ev.properties.get("HasNS", 0.0)
    if p_ns >= config.min_p_bns_nsbh:
        return Verdict(True, f"P(BNS)+P(NSBH) {p_ns:.3f} >= {config.min_p_bns_nsbh}")
    if has_ns >= config.min_has_ns:
        return Verdict(True, f"HasNS {has_ns:.3f} >= {config.min_has_ns}")
    best = max(ev.classification.items(), key=lambda kv: kv[1], default=("none", 0.0))
    return Verdict(
        False,
        f"no neutron star: P(BNS)+P(NSBH) {p_ns:.3f} < {config.min_p_bns_nsbh}, HasNS {has_ns:.3f} < "
        f"{config.min_has_ns} (most likely {best[0]} {best[1]:.3f})",
    )
