"""What to do with an alert, given what we already did for its superevent.

Pure logic: :func:`decide` reads the superevent's state through a small
:class:`Ledger` protocol (the daemon's SQLite store implements it; tests can
use :class:`MemoryLedger`) and returns a :class:`Decision`.  Recording the
decision is the caller's job.

State machine per superevent (keyed on ``superevent_id``):

========================  ==========================  ==========
state                     alert                       decision
========================  ==========================  ==========
unknown                   kept by the policy          ``plan``
planned, map M            kept, map M                 ``duplicate``
accepted, map M, no plan  kept, map M                 ``plan`` (unless its job is still open)
planned, map M            kept, map M' != M           ``rerun`` (supersedes the latest plan)
retracted                 kept (e.g. a later INITIAL) ``plan`` (planned again)
planned (not retracted)   RETRACTION                  ``withdraw`` (all the event's plans)
unknown or retracted      RETRACTION                  ``ignore`` (unknown: remembered as retracted)
any                       refused by the policy       ``ignore``
planned on a joint map    kept, GW map only           ``duplicate`` (the joint map stands)
any, newest accepted T    created before T            ``ignore`` (stale: never supersedes)
========================  ==========================  ==========

Order by creation, not arrival: a notice created (``time_created``) before
the newest notice already accepted for the event (planned, confirmed as a
duplicate, or a retraction) never supersedes it, and nothing created before
a retraction re-opens the event (a stale retraction does not withdraw a
newer plan either).  This is the order ``mushrooms replay`` processes notices
in (sorted by ``time_created``), so a live daemon that receives them out of
order (several partitions, operator triggers) ends in the same state.  The
one exception is degrade-never-drop: an older notice is still planned when
the event has no plan, no open job and no retraction (the newer notice's
planning failed).  Operators' ``trigger --force`` and ``trigger SUPEREVENT``
bypass :func:`decide` and may plan any notice.

A bare sky map (``mushrooms trigger SKYMAP.fits``) is decided by the same
rule: :class:`BareSkymap` is what :func:`decide` reads of it (its event id
is ``skymap-<sha256[:12]>``, it has no ``time_created``, and no policy cut
applies: the verdict is the operator's request).

"Map" is the localisation chosen for planning
(:func:`~mushrooms.handlers.localization.choose_localization`): the joint GW x
external map when the notice has a usable one, else the GW map.  A notice
that brings a new joint map is a new sky map (``rerun``).  Once an event is
planned on a joint map, a later notice with only a GW map (no coincidence in
it, or a joint map that does not decode) does not silently replace it: the
joint plan stands and the reason says so; a retraction still withdraws it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from datetime import datetime
from typing import Protocol

from .alert import Alert
from .instants import iso_z, parse_instant
from .localization import COMBINED, GW, Localization
from .policy import Verdict

__all__ = ["Decision", "EventState", "Ledger", "MemoryLedger", "BareSkymap", "decide", "newest_created", "ACTIONS"]

ACTIONS = ("plan", "rerun", "duplicate", "withdraw", "ignore", "rejected")


def newest_created(a: str | None, b: str | None) -> str | None:
    """The later of two ``time_created`` values (ISO-8601 UTC), either of which may be None."""
    ta, tb = parse_instant(a), parse_instant(b)
    if ta is None:
        return b if tb is not None else a
    if tb is None:
        return a
    return b if tb > ta else a


@dataclass(frozen=True)
class EventState:
    """What has been decided so far for one superevent.

    Attributes
    ----------
    superevent_id : str
    skymap_sha256 : str or None
        SHA-256 of the last sky map accepted for planning.
    plan_ids : tuple of str
        Plans stored for the event that are not withdrawn, oldest first.
    retracted : bool
        A retraction was processed and no alert was planned since.
    localization : str or None
        ``gw`` or ``combined``: which localisation ``skymap_sha256`` is.
    open_job : bool
        A planning job of the event is pending or running.
    latest_created : str or None
        ``time_created`` (ISO-8601 UTC) of the newest notice accepted for the
        event (planned, duplicate or retraction); older notices are stale.
    """

    superevent_id: str
    skymap_sha256: str | None = None
    plan_ids: tuple[str, ...] = ()
    retracted: bool = False
    localization: str | None = None
    open_job: bool = False
    latest_created: str | None = None

    @property
    def latest_plan_id(self) -> str | None:
        return self.plan_ids[-1] if self.plan_ids else None


class Ledger(Protocol):
    """Read access to per-superevent state (implemented by the daemon's store)."""

    def event_state(self, superevent_id: str) -> EventState | None:
        """State of a superevent, or None if it was never planned or retracted."""
        ...


@dataclass
class MemoryLedger:
    """A dict-backed :class:`Ledger` (tests, notebooks)."""

    events: dict[str, EventState] = field(default_factory=dict)

    def event_state(self, superevent_id: str) -> EventState | None:
        return self.events.get(superevent_id)

    def apply(self, decision: "Decision", plan_id: str | None = None) -> None:
        """Update the state as a store would after ``decision`` (and its plan)."""
        sid = decision.superevent_id
        st = self.events.get(sid, EventState(sid))
        created = newest_created(st.latest_created, decision.time_created)
        if decision.action in ("plan", "rerun"):
            ids = st.plan_ids if not st.retracted else ()
            if plan_id:
                ids = ids + (plan_id,)
            self.events[sid] = EventState(sid, decision.skymap_sha256, ids, False, decision.localization,
                                          latest_created=created)
        elif decision.action == "withdraw":
            self.events[sid] = EventState(sid, st.skymap_sha256, (), True, st.localization, latest_created=created)
        elif decision.action == "duplicate" and sid in self.events:
            self.events[sid] = replace(st, latest_created=created)
        elif decision.retracts_unknown and sid not in self.events:
            self.events[sid] = EventState(sid, retracted=True, latest_created=decision.time_created)


@dataclass(frozen=True)
class BareSkymap:
    """A sky map handed in without a notice, as :func:`decide` reads an alert.

    Attributes
    ----------
    superevent_id : str
        ``skymap-<sha256[:12]>``.
    skymap_sha256 : str
    alert_type : str
        ``SKYMAP``.
    time_created : None
        A bare map has no creation time: it is never stale and never makes
        an event's creation order.
    """

    superevent_id: str
    skymap_sha256: str
    alert_type: str = "SKYMAP"
    time_created: datetime | None = None


@dataclass(frozen=True)
class Decision:
    """What to do with one alert.

    Attributes
    ----------
    action : str
        One of :data:`ACTIONS`.
    superevent_id : str
    reason : str
        One line for the log and the store.
    alert_type : str
    skymap_sha256 : str or None
        Map to plan (``plan``/``rerun``).
    supersedes : str or None
        Latest plan of the event when the decision was taken (``rerun``).
    plan_ids : tuple of str
        Plans to withdraw (``withdraw``); the event's live plans (``duplicate``).
    localization : str or None
        ``gw`` or ``combined``: which of the notice's maps ``skymap_sha256`` is.
    time_created : str or None
        The notice's ``time_created`` (ISO-8601 UTC): an accepted decision
        (``plan``, ``rerun``, ``duplicate``, ``withdraw``) makes it the
        event's :attr:`EventState.latest_created` unless that is newer.
    retracts_unknown : bool
        An ``ignore`` of a retraction of an event without any state: nothing
        is withdrawn, but the event is recorded as retracted as of
        ``time_created``, so a notice created before the retraction that
        arrives after it stays unplanned (stale), while a later one plans.
    """

    action: str
    superevent_id: str
    reason: str
    alert_type: str = ""
    skymap_sha256: str | None = None
    supersedes: str | None = None
    plan_ids: tuple[str, ...] = ()
    localization: str | None = None
    time_created: str | None = None
    retracts_unknown: bool = False

    @property
    def accepted(self) -> bool:
        """The notice counts for the event's creation order (see :attr:`EventState.latest_created`)."""
        return self.action in ("plan", "rerun", "duplicate", "withdraw")

    @property
    def needs_plan(self) -> bool:
        return self.action in ("plan", "rerun")


def decide(alert: Alert | BareSkymap, verdict: Verdict, ledger: Ledger,
           localization: Localization | None = None) -> Decision:
    """Decide what to do with a parsed alert.

    Parameters
    ----------
    alert : Alert or BareSkymap
        The parsed notice (or a bare sky map).
    verdict : Verdict
        The policy's answer (:func:`~mushrooms.handlers.policy.evaluate`).
    ledger : Ledger
        Per-superevent state.
    localization : Localization, optional
        The map chosen for planning
        (:func:`~mushrooms.handlers.localization.choose_localization`);
        default the notice's GW map.

    Returns
    -------
    Decision
    """
    sid = alert.superevent_id
    created = iso_z(alert.time_created) if alert.time_created is not None else None
    base = dict(superevent_id=sid, alert_type=alert.alert_type, time_created=created)
    if not verdict.keep:
        return Decision("rejected" if verdict.reject else "ignore", reason=verdict.reason, **base)
    state = ledger.event_state(sid)
    stale = _stale(alert, state)
    if stale:
        return Decision("ignore", reason=stale, **base)
    if alert.alert_type == "RETRACTION":
        if state is None:
            # nothing to withdraw, but remembered (creation order): a notice of the event created
            # before it and arriving later must not plan a retracted event
            return Decision("ignore", reason="retraction of an event we never planned (remembered: older notices "
                                             "of it stay unplanned)", retracts_unknown=True, **base)
        if state.retracted:
            return Decision("ignore", reason="event already retracted", **base)
        n = len(state.plan_ids)
        return Decision("withdraw", reason=f"retracted by LVK; withdrawing {n} plan(s)",
                        plan_ids=state.plan_ids, **base)
    if localization is None:
        sha, kind, note, keep_joint = alert.skymap_sha256, GW, "", True
    else:
        sha, kind, note = localization.sha256, localization.kind, localization.note
        keep_joint = localization.joint_preferred
    base["localization"] = kind
    where = f"{kind} map" + (f"; {note}" if note else "")
    if state is None:
        return Decision("plan", reason=f"new event ({verdict.reason}); {where}", skymap_sha256=sha, **base)
    if state.retracted:
        return Decision("plan", reason=f"{alert.alert_type} after a retraction: planning again; {where}",
                        skymap_sha256=sha, **base)
    if not state.plan_ids and not state.open_job and (state.skymap_sha256 is None or state.skymap_sha256 == sha):
        # degrade, never drop: no plan went out for this event and none is coming
        return Decision("plan", reason=f"no plan published for this event yet; planning again ({verdict.reason}); "
                                       f"{where}",
                        skymap_sha256=sha, **base)
    if state.skymap_sha256 == sha:
        return Decision("duplicate", reason=f"same {kind} sky map {str(sha)[:12]} as already planned",
                        skymap_sha256=sha, plan_ids=state.plan_ids, **base)
    if state.localization == COMBINED and kind == GW and keep_joint and state.plan_ids:
        return Decision("duplicate",
                        reason=(f"keeping the joint localisation {str(state.skymap_sha256)[:12]}: this "
                                f"{alert.alert_type} brings only a GW map {str(sha)[:12]}"
                                + (f" ({note})" if note else " (no external coincidence in it)")),
                        skymap_sha256=state.skymap_sha256, plan_ids=state.plan_ids,
                        **{**base, "localization": COMBINED})
    return Decision(
        "rerun",
        reason=f"sky map changed {str(state.skymap_sha256)[:12]} -> {str(sha)[:12]} ({where})",
        skymap_sha256=sha,
        supersedes=state.latest_plan_id,
        **base,
    )


def _stale(alert: Alert | BareSkymap, state: EventState | None) -> str:
    """Why ``alert`` is older than what the event already accepted ("" when it is not)."""
    newest = parse_instant(state.latest_created) if state is not None else None
    if state is None or newest is None or alert.time_created is None or parse_instant(alert.time_created) >= newest:
        return ""
    mine = iso_z(alert.time_created)
    if state.retracted:
        return (f"stale: {alert.alert_type} created {mine}, before the retraction of {state.latest_created}; "
                "nothing older than a retraction re-opens the event")
    if alert.alert_type != "RETRACTION" and not state.plan_ids and not state.open_job:
        return ""  # degrade, never drop: the event has no plan at all, so the older map is better than none
    return (f"stale: {alert.alert_type} created {mine}, before the newest accepted notice of the event "
            f"({state.latest_created}); a notice never supersedes a newer one")
