"""The names of the queues a plan goes to, as an observer is shown them (``.txt``, ``.html``, ``status``).

One rule names every queue:
:func:`~mushrooms.scheduler_core.plan.exports.queue_name_base` of the plan
document, ``_<k>`` for the k-th queue of its set.  :func:`queue_names`
gives the names :func:`~.rules.build_body` sends (or would send) for a
document, :func:`publish_queues` what the outbox's summary says beside a
plan when it is published (the names, and whether they are to be sent),
:func:`row_queues` what a ``submissions`` row holds, :func:`few_names` those
names in a one-line message (the webhook's, ``status``'s attention lines).
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from .rules import gate, name_of, set_of

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from .settings import SubmitConfig

__all__ = ["queue_names", "publish_queues", "row_queues", "few_names", "FEW_NAMES", "queues_phrase", "pending_queue_names"]

#: How many queue names a one-line message spells out before ``+N more``.
FEW_NAMES = 3


def queue_names(document: Mapping[str, Any], export: ExportConfig, target: str = "kowalski",
                passes: Any = None) -> tuple[str, ...]:
    """The ZTF queue names of a plan document as the daemon submits it to ``target`` (in submission order).

    Kowalski (and ``none``: what it would be): the timed queue set's names;
    SkyPortal: its plans' names with ``ToO_``, the queues SkyPortal's ZTF API
    makes of them (one per filter pass, or one with ``[export]
    skyportal_plans = "single"``).  Empty for a document without observations.
    ``passes``: the plan's :func:`~mushrooms.scheduler_core.plan.exports.timed_passes`
    under its name base, when the caller has it (not timed again).
    """
    from ...scheduler_core import Plan
    from ...scheduler_core.plan.exports import queue_name_base, timed_passes

    if document.get("type", "plan") != "plan" or not document.get("observations"):
        return ()
    base = queue_name_base(export.subprogram_name, str(document["plan_id"]),
                           (document.get("event") or {}).get("superevent_id"))
    if target == "skyportal" and export.skyportal_plans == "single":
        return (base,)
    if passes is None or (passes.queues and not passes.queues[0]["queue_name"].startswith(f"{base}_")):
        passes = timed_passes(Plan.from_document(dict(document)), export, base)
    return tuple(q["queue_name"] for q in passes.queues)


def publish_queues(submit: SubmitConfig, export: ExportConfig, why_not: str | None = None
                   ) -> Callable[[Mapping[str, Any]], tuple[tuple[str, ...], str]]:
    """For the outbox's summaries: ``doc -> (queue names, what becomes of them)`` when the plan is published.

    The words say whether the names are sent: ``to be submitted to kowalski``,
    or ``not submitted: <why>`` (``why_not``, e.g. a replay; ``[submit]
    target`` none; a dry run; a gate of :func:`~.rules.gate`); a plan that
    cannot be expressed as queues gets no names.
    """
    def shown(doc: Mapping[str, Any]) -> tuple[tuple[str, ...], str]:
        try:
            names = queue_names(doc, export, submit.target)
        except (KeyError, TypeError, ValueError):
            return (), ""
        if why_not:
            return names, f"not submitted ({why_not}), named as the service would"
        if submit.target == "none":
            return names, "not submitted ([submit] target is none), named as the service would"
        why = gate(dict(doc), submit)
        if why is None and submit.dry_run:
            why = "[submit] dry_run"
        return names, f"not submitted ({why})" if why else f"to be submitted to {submit.target}"
    return shown


def row_queues(target: str, state: str, body: Any, base: str | None) -> tuple[tuple[str, ...], str]:
    """The queue names of a ``submissions`` row (its stored body; SkyPortal's plan names with ``ToO_``) and
    its state in words."""
    if isinstance(body, str):
        try:
            body = json.loads(body)
        except ValueError:
            body = None
    names = [name_of(part) for part in set_of(body)] or ([base] if base else [])
    if target == "skyportal":
        names = [n if n.startswith("ToO_") else f"ToO_{n}" for n in names]
    from ...report.files import submission_words

    return tuple(names), submission_words(state, target)


def few_names(names: Sequence[str] | str | None, most: int = FEW_NAMES) -> str:
    """Queue names for a one-line message: ``A, B, C +2 more`` (the first ``most``), ``-`` for none.

    Parameters
    ----------
    names : sequence of str, str or None
        The names in submission order (one name alone: itself).
    most : int
        Names spelled out before ``+N more`` (at least 1).
    """
    if isinstance(names, str):
        names = [names]
    names = [str(n) for n in names or () if n]
    if not names:
        return "-"
    most = max(1, int(most))
    rest = len(names) - most
    return ", ".join(names[:most]) + (f" +{rest} more" if rest > 0 else "")


def queues_phrase(names: Sequence[str] | str | None) -> str:
    """``queue A``, or ``queues A, B, C +N more`` (:func:`few_names`): the queues a message is about."""
    if isinstance(names, str):
        names = [names]
    many = len([n for n in names or () if n]) > 1
    return ("queues " if many else "queue ") + few_names(names)


def pending_queue_names(oldest: Mapping[str, Any]) -> tuple[str, ...]:
    """The queue names of :func:`~mushrooms.daemon.state.views.oldest_pending_submission`'s row (its stored body;
    the name base when it has none)."""
    return row_queues(str(oldest.get("target") or ""), "pending", oldest.get("body"), oldest.get("queue_name"))[0]
