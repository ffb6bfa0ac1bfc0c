"""Intake: raw bytes in, a durable decision out (parse ▸ policy ▸ decide ▸ store, one transaction).

Notices and bare sky maps take one decision rule,
:func:`~mushrooms.handlers.decisions.decide` (a bare map as a
:class:`~mushrooms.handlers.decisions.BareSkymap`, with the operator's
request as its verdict).  The operator's ``trigger --force`` and ``trigger
SUPEREVENT`` bypass it on purpose (a ``rerun`` that supersedes the event's
latest plan).  Size caps: a notice ``[policy] max_notice_bytes``, a sky map
(bare, or decoded from a notice) ``[policy] max_skymap_bytes``.

Bad input never raises: it is a recorded ``rejected`` decision.  Only a
failure to write the state (``sqlite3.Error``, :class:`~mushrooms.daemon.state.store.StoreError`)
raises.
"""

from __future__ import annotations

import dataclasses
import hashlib
import logging
import time
from datetime import datetime, timezone
from typing import Any

from ...handlers.alert import Alert, NoticeError, parse_notice
from ...handlers.decisions import BareSkymap, Decision, decide
from ...handlers.instants import iso_z, now_iso_z
from ...handlers.localization import check_skymap_header, choose_localization
from ...handlers.policy import PolicyConfig, Verdict, evaluate
from ...scheduler_core.plan.messages import withdrawal_message
from ...scheduler_core.sky.sniff import is_fits
from ..outcomes import Accepted, EventRef
from ..state.store import Job, NoticeRecord, Store

__all__ = ["Intake", "aware"]

log = logging.getLogger("mushrooms.daemon.pipeline")


def aware(t: datetime | None) -> datetime:
    """``t`` as an aware UTC datetime (naive means UTC); now when None."""
    if t is None:
        return datetime.now(timezone.utc)
    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t.astimezone(timezone.utc)


def _accepted(decision: Decision, nid: int, job: Job | None, cancelled: list[int], **kw: Any) -> Accepted:
    ref = EventRef(decision.superevent_id, decision.alert_type or None, nid, job.job_id if job else None)
    return Accepted(decision.action, ref, decision.reason, job, tuple(cancelled), **kw)


def _rejected(sid: str | None, reason: str, nid: int, alert_type: str | None = None) -> Accepted:
    return Accepted("rejected", EventRef(sid, alert_type, nid), reason)


class Intake:
    """Parse, filter, decide and store notices, bare sky maps and operators' reruns.

    Parameters
    ----------
    policy : PolicyConfig
        ``[policy]``: the cuts, the size caps, ``plan_start``, ``use_combined_skymap``.
    store : Store
        Where decisions (and jobs, withdrawals) are recorded.
    """

    def __init__(self, policy: PolicyConfig, store: Store):
        self.policy = policy
        self.store = store

    # ------------------------------------------------------------ notices
    def accept(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Parse, filter and decide one notice; record it durably.

        Parameters
        ----------
        raw : bytes
            The notice (message value or file content).
        origin : str
            Where it came from (``kafka:topic:partition:offset``, a file name).
        received_at : datetime, optional
            The clock of the policy (age cuts) and of ``plan_start = received``;
            default now.  Replays pass the notice's ``time_created``.

        Returns
        -------
        Accepted
            Never raises for bad input (``action == "rejected"``).
        """
        wall = time.time()
        now = aware(received_at)
        if isinstance(raw, str):
            raw = raw.encode("utf-8", "surrogatepass")
        raw = bytes(raw) if not isinstance(raw, bytes) else raw
        policy = self.policy
        sha = hashlib.sha256(raw).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(raw), received_at=iso_z(now))
        try:
            alert = parse_notice(raw, max_bytes=policy.max_notice_bytes)
        except NoticeError as exc:
            keep = raw if len(raw) <= policy.max_notice_bytes else None
            nid = self.store.record_rejected(dataclasses.replace(record, raw=keep), str(exc))
            log.warning("notice origin=%s superevent_id=- decision=rejected reason=%r bytes=%d sha256=%s",
                        origin, str(exc), len(raw), sha[:12])
            return _rejected(None, str(exc), nid)
        record = dataclasses.replace(record, superevent_id=alert.superevent_id, alert_type=alert.alert_type,
                                     time_created=iso_z(alert.time_created), raw=raw)
        try:
            verdict = evaluate(alert, policy, now)
        except Exception as exc:  # a policy bug must not block the stream: record and go on
            log.exception("notice origin=%s superevent_id=%s: policy evaluation failed", origin, alert.superevent_id)
            reason = f"policy evaluation failed: {type(exc).__name__}: {exc}"
            nid = self.store.record_rejected(dataclasses.replace(record, raw=None), reason)
            return _rejected(alert.superevent_id, reason, nid, alert.alert_type)

        def withdrawal(d: Decision, notice_id: int) -> dict[str, Any]:
            return withdrawal_message(d.superevent_id, d.plan_ids, sha, alert.alert_type,
                                      iso_z(alert.time_created), d.reason, now_iso_z())

        localization = None
        if verdict.keep and not alert.is_retraction:
            localization = choose_localization(
                alert, policy.use_combined_skymap,
                # headers only (bounded, milliseconds): the full decode is the job's, off the consume loop
                check=lambda data: check_skymap_header(data, max_bytes=policy.max_skymap_bytes))
            if localization is not None and localization.note and localization.kind == "gw" \
                    and alert.external_coinc is not None:
                log.warning("notice origin=%s superevent_id=%s: %s", origin, alert.superevent_id, localization.note)

        nid, decision, job, cancelled, key = self.store.record_decision(
            record,
            lambda ledger: decide(alert, verdict, ledger, localization),
            lambda d: self.plan_start(alert, now),
            received_wall=wall,
            withdrawal=withdrawal,
        )
        acc = _accepted(
            decision, nid, job, cancelled,
            plan_id=decision.plan_ids[-1] if decision.action == "duplicate" and decision.plan_ids else None,
            plan_ids=decision.plan_ids if decision.action == "withdraw" else (),
            withdrawal_id=key,
        )
        level = logging.WARNING if decision.action == "rejected" or (verdict.warn and decision.action == "ignore") \
            else logging.INFO  # an unclassified candidate, a notice without a map: the operator should see it
        log.log(level, "notice origin=%s superevent_id=%s alert_type=%s decision=%s reason=%r%s%s",
                origin, alert.superevent_id, alert.alert_type, decision.action, decision.reason,
                f" job={job.job_id} start={job.start}" if job else "",
                f" cancelled_jobs={','.join(map(str, cancelled))}" if cancelled else "")
        return acc

    def plan_start(self, alert: Alert, now: datetime) -> str | None:
        """The horizon start of a job planning ``alert`` (``[policy] plan_start``); None without a sky map.

        Never before the merger: an early warning is created (and received)
        before it, and nothing is there to observe until it has happened.
        """
        ev = alert.event
        if ev is None or not ev.skymap:
            return None
        mode = self.policy.plan_start
        if mode == "event":
            return iso_z(ev.time)
        if mode == "created":
            return iso_z(max(alert.time_created, ev.time))
        return iso_z(max(now, ev.time))

    # ------------------------------------------------------------ bare sky maps
    def accept_skymap(self, data: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a bare sky map (``mushrooms trigger SKYMAP.fits``); no policy cut applies.

        Refused unless it is FITS (plain or gzipped) of at most ``[policy]
        max_skymap_bytes`` as carried.  Decided by
        :func:`~mushrooms.handlers.decisions.decide` like a notice (the same
        map again is a ``duplicate``, unless its planning failed: degrade,
        never drop).  The map is planned from the receipt time
        (``plan_start = event`` uses the notice's time only, which a bare map
        does not have).
        """
        wall = time.time()
        now = aware(received_at)
        data = bytes(data)
        sha = hashlib.sha256(data).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(data), received_at=iso_z(now))
        limit = self.policy.max_skymap_bytes
        if len(data) > limit or not is_fits(data):
            reason = f"sky map of {len(data)} bytes, more than [policy] max_skymap_bytes = {limit} (gzip it)" \
                if is_fits(data) else "not a FITS sky map"
            nid = self.store.record_rejected(record, reason)
            log.warning("skymap origin=%s decision=rejected reason=%r", origin, reason)
            return _rejected(None, reason, nid)
        bare = BareSkymap(f"skymap-{sha[:12]}", sha)
        record = dataclasses.replace(record, superevent_id=bare.superevent_id, alert_type=bare.alert_type, raw=data)
        verdict = Verdict(True, "manual trigger")
        nid, decision, job, cancelled, _ = self.store.record_decision(
            record, lambda ledger: decide(bare, verdict, ledger), lambda d: iso_z(now), received_wall=wall)
        log.info("skymap origin=%s superevent_id=%s decision=%s reason=%r", origin, bare.superevent_id,
                 decision.action, decision.reason)
        return _accepted(decision, nid, job, cancelled, plan_id=decision.plan_ids[-1] if decision.plan_ids else None)

    # ------------------------------------------------------------ operators
    def rerun_superevent(self, superevent_id: str, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a superevent again from its newest stored notice (``mushrooms trigger SUPEREVENT_ID``).

        An operator's explicit request: no policy and no duplicate check; the
        new plan supersedes the event's latest plan.  The horizon starts as
        ``plan_start`` says, with now as the receipt time.
        """
        wall = time.time()
        now = aware(received_at)
        sid = superevent_id.strip()
        found = self.store.latest_planned_notice(sid)
        record = NoticeRecord(origin=origin, sha256=hashlib.sha256(sid.encode()).hexdigest(), size=len(sid),
                              received_at=iso_z(now), superevent_id=sid or None)
        if found is None:
            reason = f"no stored notice of {sid!r} to plan from"
            nid = self.store.record_rejected(record, reason)
            log.warning("trigger origin=%s superevent_id=%s decision=rejected reason=%r", origin, sid or "-", reason)
            return _rejected(sid or None, reason, nid)
        _, raw = found
        alert = parse_notice(raw)
        record = dataclasses.replace(record, sha256=hashlib.sha256(raw).hexdigest(), size=len(raw),
                                     alert_type=alert.alert_type, time_created=iso_z(alert.time_created), raw=raw)
        return self._record_rerun(record, alert, "manual rerun requested", origin, now, wall, logging.INFO)

    def force_plan(self, raw: bytes, origin: str, received_at: datetime | None = None) -> Accepted:
        """Plan a notice past the policy and the duplicate check (``mushrooms trigger --force``).

        The notice is stored like any other; the decision is ``rerun`` (it
        supersedes the event's latest plan, if any) with the reason
        ``forced by operator``.  A notice without a sky map is rejected.
        """
        wall = time.time()
        now = aware(received_at)
        raw = bytes(raw)
        sha = hashlib.sha256(raw).hexdigest()
        record = NoticeRecord(origin=origin, sha256=sha, size=len(raw), received_at=iso_z(now))
        try:
            alert = parse_notice(raw, max_bytes=self.policy.max_notice_bytes)
        except NoticeError as exc:
            nid = self.store.record_rejected(record, str(exc))
            return _rejected(None, str(exc), nid)
        sid = alert.superevent_id
        if alert.event is None or not alert.event.skymap:
            reason = "forced, but the notice has no sky map to plan"
            nid = self.store.record_rejected(dataclasses.replace(record, superevent_id=sid), reason)
            return _rejected(sid, reason, nid, alert.alert_type)
        record = dataclasses.replace(record, superevent_id=sid, alert_type=alert.alert_type,
                                     time_created=iso_z(alert.time_created), raw=raw)
        return self._record_rerun(record, alert, "forced by operator", origin, now, wall, logging.WARNING)

    def _record_rerun(self, record: NoticeRecord, alert: Alert, reason: str, origin: str, now: datetime,
                      wall: float, level: int) -> Accepted:
        """Store an operator's ``rerun`` of a notice: no policy, supersedes the event's latest plan."""
        sid = alert.superevent_id
        loc = choose_localization(alert, self.policy.use_combined_skymap)
        sha, kind = (loc.sha256, loc.kind) if loc is not None else (alert.skymap_sha256, "gw")

        def dec(ledger: Any) -> Decision:
            st = ledger.event_state(sid)
            latest = st.latest_plan_id if st is not None else None
            return Decision("rerun", sid, f"{reason} ({kind} map)", alert.alert_type, sha,
                            supersedes=latest, localization=kind, time_created=iso_z(alert.time_created))

        nid, decision, job, cancelled, _ = self.store.record_decision(
            record, dec, lambda d: self.plan_start(alert, now), received_wall=wall)
        log.log(level, "trigger origin=%s superevent_id=%s decision=%s reason=%r%s", origin, sid, decision.action,
                decision.reason, f" job={job.job_id}" if job else "")
        return _accepted(decision, nid, job, cancelled)
