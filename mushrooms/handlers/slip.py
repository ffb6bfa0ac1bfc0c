"""Has a published plan slipped?  The loop's re-plan rule (``docs/design/executed.md`` L3-L5).

A plan goes to ZTF as a list queue; the telescope walks it as the night
allows.  Compared with what was executed, a plan needs re-planning when

* (L4) it *slipped*: its first observation not yet executed was planned to
  start more than ``max_slip_s`` before now (a late start, a closure, another
  ToO, a queue that skipped what no longer fit), or
* (L5) an exposure of it *failed*: a record of one of its (field, filter)
  pairs inside its window that is not done (E1), not made up by a later
  done exposure of the same pair; (L17) one ``processed`` below the done
  threshold is still being reduced, not failed, until ``settle_s`` after
  its end.

(L3) matching: inside the plan's window, the k-th done exposure of a
(field, filter) pair executes the pair's k-th planned observation (time
order); exposures before the plan's start belong to earlier plans.

Pure: plan documents and :class:`~mushrooms.scheduler_core.executed.ExecutedExposure`
records in, a :class:`Slip` out.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from astropy.time import Time

from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, SAME_START_S, ExecutedExposure, is_done

__all__ = ["Slip", "slip_of", "document_times"]


@dataclass(frozen=True)
class Slip:
    """How a published plan compares with what was executed, at one instant.

    Attributes
    ----------
    replan : bool
        L4 or L5 holds, and the plan's window has not ended.
    reason : str
        One phrase for the log and the decision (``slipped by 1834 s (more than max_slip_s 900 s)``).
    slip_s : float or None
        Now minus the planned start of the first observation not executed (s);
        None when every observation due was executed or none is due.
    executed : int
        Planned observations matched by a done exposure (L3).
    planned : int
        Observations of the plan.
    failed : tuple of ExecutedExposure
        The failed exposures of L5.
    """

    replan: bool
    reason: str
    slip_s: float | None
    executed: int
    planned: int
    failed: tuple[ExecutedExposure, ...] = ()


def document_times(values: Sequence[str]) -> np.ndarray:
    """Unix times (s) of ISO-8601 UTC strings as plan documents write them (``...Z``), vectorised."""
    if not len(values):
        return np.zeros(0)
    return np.atleast_1d(Time([str(v).rstrip("Z") for v in values], format="isot", scale="utc").unix)


def slip_of(plan: Mapping[str, Any], exposures: Sequence[ExecutedExposure], now: Time, max_slip_s: float,
            min_processed_fraction: float = MIN_PROCESSED_FRACTION, settle_s: float = 0.0) -> Slip:
    """Compare a plan document with the executed record (L3-L5).

    Parameters
    ----------
    plan : mapping
        A plan document (``start``, ``end``, ``observations[]`` with ``field_id``,
        ``filter``, ``start``); a ``not_observable`` answer never slips.
    exposures : sequence of ExecutedExposure
        What was executed (any span; only the plan's window counts).
    now : astropy.time.Time
        The instant of the comparison (UTC).
    max_slip_s : float
        Allowed lateness (s) of the first observation not executed (L4).
    min_processed_fraction : float
        The done rule's threshold (E1).
    settle_s : float
        (L17) An exposure ``processed`` below the threshold that ended less
        than this (s) before ``now`` is still being reduced: it counts as
        executed for L3/L4, and as failed (L5) only once it is older.

    Returns
    -------
    Slip
    """
    obs = plan.get("observations") or []
    t_now = float(now.utc.unix)
    if plan.get("type", "plan") != "plan" or not obs:
        return Slip(False, "nothing planned", None, 0, len(obs))
    t0, t1 = document_times([plan["start"], plan["end"]])
    if t_now >= t1:
        return Slip(False, "the plan's window has ended", None, 0, len(obs))
    planned: dict[tuple[int, str], list[float]] = {}
    for o, t in zip(obs, document_times([o["start"] for o in obs])):
        planned.setdefault((int(o["field_id"]), str(o["filter"])), []).append(float(t))
    done: dict[tuple[int, str], int] = {}
    failed_by: dict[tuple[int, str], list[ExecutedExposure]] = {}
    settling = 0
    for e in exposures:
        key = (e.field_id, e.filter)
        if key not in planned or not t0 - SAME_START_S <= float(e.start.unix) <= t_now:
            continue
        if is_done(e, min_processed_fraction) or _settling(e, t_now, settle_s):
            done[key] = done.get(key, 0) + 1  # (L17) an exposure still being reduced was taken: not late
            settling += 0 if is_done(e, min_processed_fraction) else 1
        else:
            failed_by.setdefault(key, []).append(e)
    # (L3) the first done[key] planned observations of each pair are executed; the rest are not
    left = [t for key, times in planned.items() for t in sorted(times)[done.get(key, 0):]]
    executed = len(obs) - len(left)
    # (L5) a failure counts while the pair still lacks a done exposure for each planned one
    failed = tuple(e for key, es in failed_by.items() if done.get(key, 0) < len(planned[key]) for e in es)
    due = min(left) if left else None
    slip_s = t_now - due if due is not None and due < t_now else None  # (L4)
    if failed:
        return Slip(True, f"{len(failed)} exposure(s) failed (field {failed[0].field_id} "
                          f"{failed[0].filter}: {failed[0].status}, processed {failed[0].processed_fraction:g})",
                    slip_s, executed, len(obs), failed)
    if slip_s is not None and slip_s > max_slip_s:
        return Slip(True, f"slipped by {slip_s:.0f} s (more than max_slip_s {max_slip_s:g} s; "
                          f"{executed} of {len(obs)} observations executed)", slip_s, executed, len(obs))
    being = f"; {settling} still being reduced" if settling else ""
    return Slip(False, f"on time ({executed} of {len(obs)} observations executed{being})", slip_s, executed,
                len(obs))


def _settling(e: ExecutedExposure, t_now: float, settle_s: float) -> bool:
    """(L17) ``processed`` but below the done threshold, and ended less than ``settle_s`` before ``t_now``."""
    return e.status == "processed" and t_now - (float(e.start.unix) + e.exposure_s) < settle_s
