"""Each configured telescope's part of a revision, in the outbox (issue 53 items 2 and 4: through the service).

With ``[scheduler] telescopes = ["ztf", "ls4", ...]`` a job (one sky map of an
event) is planned for every telescope: ZTF's plan is the job's revisions, as
for a ZTF-only service (its queue to Kowalski, its SkyPortal plan, its
documents unchanged); every other telescope is planned **around** ZTF's
revision (``docs/design/telescopes.md`` J9,
:func:`~mushrooms.handlers.telescope_plans.plan_telescopes`): in the
configured order, each on the sky ZTF's revision and the parts before it
leave.  Round 1 is planned around revision 1 before it is stored; when the
job's final revision is a revision 2, round 2 is planned around it before it
is stored, each new part marking its telescope's round-1 part ``SUPERSEDED``.
A part goes where its description's ``queue`` says, into one folder of the
outbox directory::

    <[outbound] directory>/telescopes/<superevent>/<job:05d>-<alert type>[-round<n>]/
        joint.json                   ZTF's revision and the parts: joint metrics and bound (mushrooms check)
        <telescope>/
            part.json                telescope, queue, state, plan id, files, why, round, coordinated_with, joint
            targets.json, targets.csv    queue = "target_list": the target list
            skyportal_request.json   queue = "skyportal": the observation plan request ([submit_parts] sends it)
            plan.json                the telescope's plan document (mushrooms check plan.json MAP)
            WITHDRAWN / SUPERSEDED   the event was retracted / a newer map's or ZTF revision's parts replace these

Every file is written atomically (a reader sees the old file or the new one);
names from notices and descriptions are reduced to ``[A-Za-z0-9._-]`` and 64
characters.  The round's ``joint.json`` is written before its parts are
recorded; a part is recorded in the state file (``telescope_parts``: one row
per job and telescope, its latest round) after its files: a kill between two
telescopes' parts leaves the job running, its restart holds the recorded
parts fixed with ZTF's revision and plans the others (the same plans: greedy's
steps depend on their inputs only), and rewrites no recorded one.  A
telescope that cannot observe the map gets ``state: not_observable`` and no
export; one that fails gets ``failed`` with the reason; neither stops the
others, and neither ever stops ZTF's revision.
"""

from __future__ import annotations

import dataclasses
import logging
import re
from pathlib import Path
from typing import Any, Callable, Sequence

from ...handlers.text import storable
from ..state.parts import event_parts, parts_of_job, record_part

__all__ = ["TelescopeParts", "part_folder", "safe_name", "plan_parts", "parts_lines", "parts_words"]

log = logging.getLogger("mushrooms.daemon.parts")

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")

#: marker file of a part that no longer stands, by its state
MARKERS = {"superseded": "SUPERSEDED", "withdrawn": "WITHDRAWN"}


def safe_name(text: Any, limit: int = 64) -> str:
    """``text`` as one path component: ``[A-Za-z0-9._-]``, at most ``limit`` characters, never ``.``/``..``/empty.

    A name that had to change ends with 8 hex digits of its SHA-256: two names never meet in one folder.
    """
    text = str(text)
    name = _UNSAFE.sub("_", text)[:limit].strip(".")
    if name == text and name:
        return name
    import hashlib

    return f"{name[:max(limit - 9, 1)] or '_'}-{hashlib.sha256(text.encode('utf-8', 'replace')).hexdigest()[:8]}"


def job_folder(root: Path, superevent_id: str, job_id: int, alert_type: str, round_: int = 1) -> Path:
    """The outbox folder of one round of a job's parts (``-round2`` ... for the parts of a later ZTF revision)."""
    tail = f"-round{int(round_)}" if int(round_) > 1 else ""
    return root / safe_name(superevent_id) / f"{int(job_id):05d}-{safe_name(alert_type, 24)}{tail}"


def part_folder(root: Path, superevent_id: str, job_id: int, alert_type: str, telescope: str, round_: int = 1) -> Path:
    """The outbox folder of one telescope's part of one job (of one round)."""
    return job_folder(root, superevent_id, job_id, alert_type, round_) / safe_name(telescope)


class TelescopeParts:
    """The other telescopes' parts of every job, written into ``<directory>/telescopes``.

    Parameters
    ----------
    directory : str or Path
        ``[outbound] directory`` (whatever the sink: a Kafka sink's service writes the parts there too).
    runs : sequence of (TelescopeDescription, PlanningConfig)
        Every configured telescope after ZTF, each with its own configuration.
    """

    def __init__(self, directory: str | Path, runs: Sequence[tuple[Any, Any]]):
        self.root = Path(directory) / "telescopes"
        self.runs = list(runs)

    @classmethod
    def from_config(cls, config: Any) -> "TelescopeParts | None":
        """The parts of ``config`` (``[scheduler] telescopes`` after ``ztf``); None for ZTF alone."""
        names = tuple(config.scheduler.telescopes)
        if names[1:] == ():
            return None
        from ...scheduler_core.config import PlanningConfig
        from ...scheduler_core.instruments import load_description

        table = _scheduler_table(config.scheduler)
        runs = []
        for name in names[1:]:
            telescope = load_description(name)
            runs.append((telescope, PlanningConfig.for_telescope(telescope, table)))
        return cls(config.outbound.directory, runs)

    @property
    def names(self) -> list[str]:
        """The telescopes with a part here (ZTF's is the revision)."""
        return [t.name for t, _ in self.runs]

    def export_job(self, store: Any, job: Any, skymap: Any, event: Any, start: Any, ztf: tuple[Any, Any],
                   cancelled: Callable[[], bool] = lambda: False, final: bool = True) -> dict[str, str]:
        """Plan and export the parts of ZTF's revision ``ztf`` not yet recorded; supersede what they replace.

        ``ztf``: (ZTF's revision as published, a Plan or its ``NotObservable``
        answer; ZTF's problem).  The parts recorded for this very revision are
        held fixed with it; a part recorded for another revision (an earlier
        round) is superseded by its telescope's new one.  ``final``: the job's
        last revision (its parts must be around it); a revision that is not
        (revision 1 on a restart after a later round began) leaves the parts
        to the final one.  State by telescope.
        """
        from ...handlers.telescope_plans import plan_telescopes, prepare_telescopes

        held_ztf = _held_ztf(*ztf)
        key = _key(held_ztf, ztf[0])
        rows = parts_of_job(store, job.job_id)
        round_ = _round(rows, key)
        if round_ is None and not final:
            return {name: row["state"] for name, row in rows.items()}
        round_ = round_ or max(int(r.get("round") or 1) for r in rows.values()) + 1
        done = {n: r for n, r in rows.items() if r.get("held") == key}
        todo = [t.name for t, _ in self.runs if t.name not in done]
        if todo and not cancelled():
            problems = prepare_telescopes(skymap, self.runs, start)
            held = [held_ztf] + [_held_part(n, problems.get(n), done[n]) for t, _ in self.runs
                                 if (n := t.name) in done]
            plans = plan_telescopes(skymap, problems, todo, held, key, event, should_stop=cancelled)
            joint = self._joint(job, round_, key, ztf, problems, done, plans)
            for telescope, _ in self.runs:
                if telescope.name not in todo:
                    continue
                if cancelled():
                    break
                state = self._export(store, job, telescope, plans[telescope.name], round_, key, joint,
                                     rows.get(telescope.name))
                done[telescope.name] = {"state": state}
        if cancelled():  # a retraction meanwhile: what this job wrote after its withdrawal is withdrawn too
            self.sync(store)
        elif all(t.name in done for t, _ in self.runs):
            self.retire(store, job.superevent_id, "superseded", before_job=job.job_id)
        return {name: row["state"] for name, row in done.items()}

    def _joint(self, job: Any, round_: int, key: str, ztf: tuple[Any, Any], problems: dict[str, Any],
               done: dict[str, dict], plans: dict[str, Any]) -> dict[str, Any]:
        """Write the round's joint document (before any of its parts is recorded); the joint metrics for part.json."""
        from ...scheduler_core.joint_parts import around_document

        entries = [("ztf", ztf[1], _document(ztf[0]), _state(ztf[0]))]
        for telescope, _ in self.runs:
            name = telescope.name
            problem = problems.get(name)
            problem = None if isinstance(problem, BaseException) else problem
            if name in done:
                doc = _recorded_document(done[name])
                entries.append((name, problem, doc, done[name]["state"]))
            else:
                entries.append((name, problem, _document(plans[name]), _state(plans[name])))
        folder = job_folder(self.root, job.superevent_id, job.job_id, job.alert_type, round_)
        details = {"round": round_, "around": key, "ztf_plan_id": getattr(ztf[0], "plan_id", None),
                   "method": "each telescope in order on the sky ZTF's revision and the parts before it leave (J9)"}
        try:
            # J8 without J7 (no cells, no solve): with DECam J7's cells alone took 8 s at nside 64 before ZTF's revision
            doc = around_document(entries, ztf[1].prob, 0.0, details=details)
            _write_json(folder / "joint.json", doc)
        except Exception as exc:  # the joint document never costs a part
            log.error("event=joint_document_failed superevent_id=%s job=%s error=%r", job.superevent_id, job.job_id,
                      str(exc))
            return {"document": None, "error": storable(f"{type(exc).__name__}: {exc}", 300),
                    "ztf_plan_id": details["ztf_plan_id"]}
        metrics = doc["metrics"]
        return {"document": "../joint.json", "plan_id": doc["plan_id"], "ztf_plan_id": details["ztf_plan_id"],
                **{k: metrics[k] for k in ("union", "share", "own", "more_than_once", "upper_bound",
                                           "upper_bound_status") if k in metrics}}

    def _export(self, store: Any, job: Any, telescope: Any, plan: Any, round_: int = 1, key: str | None = None,
                joint: dict | None = None, previous: dict | None = None) -> str:
        """Write one part's files, supersede its telescope's part of an earlier round, then record it; its state."""
        folder = part_folder(self.root, job.superevent_id, job.job_id, job.alert_type, telescope.name, round_)
        state, files, detail = _part_files(folder, telescope, plan)
        part = {"type": "telescope_part", "superevent_id": storable(job.superevent_id, 200), "job_id": job.job_id,
                "alert_type": storable(job.alert_type, 40), "skymap_sha256": job.skymap_sha256,
                "telescope": telescope.name, "title": storable(telescope.title, 200), "queue": telescope.queue,
                "state": state, "plan_id": getattr(plan, "plan_id", None), "files": files, "detail": detail,
                "round": round_, "coordinated_with": {"ztf_plan_id": (joint or {}).get("ztf_plan_id"), "around": key},
                "joint": {k: v for k, v in (joint or {}).items() if k != "ztf_plan_id"}}
        _write_json(folder / "part.json", part)
        if previous is not None and previous.get("folder") and Path(previous["folder"]) != folder \
                and previous.get("state") in ("exported", "not_observable", "failed"):
            _mark_folder(previous, "superseded")  # its telescope's part of an earlier ZTF revision
        record_part(store, job.job_id, telescope.name, job.superevent_id, telescope.queue, state,
                    part["plan_id"], str(folder), detail, round_, key)
        log.info("event=telescope_part superevent_id=%s job=%s telescope=%s queue=%s state=%s plan_id=%s round=%d "
                 "folder=%s", job.superevent_id, job.job_id, telescope.name, telescope.queue, state,
                 part["plan_id"] or "-", round_, folder)
        return state

    def retire(self, store: Any, superevent_id: str, state: str, before_job: int | None = None) -> int:
        """Mark the event's standing parts ``superseded``/``withdrawn``: the marker file first, then the row."""
        from ..state.parts import mark_parts

        rows = [r for r in event_parts(store, superevent_id) if r["state"] in ("exported", "not_observable", "failed")
                and (before_job is None or r["job_id"] < before_job)]
        for row in rows:
            _mark_folder(row, state)
        if rows:
            mark_parts(store, superevent_id, state, before_job)
            log.info("event=telescope_parts_%s superevent_id=%s parts=%d", state, superevent_id, len(rows))
        return len(rows)

    def sync(self, store: Any) -> int:
        """Withdraw the parts of retracted events (after a retraction's outbox message; again after a restart)."""
        try:
            sids = [r[0] for r in store.connection().execute(
                "SELECT DISTINCT p.superevent_id FROM telescope_parts p JOIN events e USING (superevent_id)"
                " WHERE e.retracted=1 AND p.state IN ('exported', 'not_observable', 'failed')")]
        except Exception as exc:  # never stops the outbox
            log.error("event=telescope_parts_sync_failed error=%r", str(exc))
            return 0
        return sum(self.retire(store, sid, "withdrawn") for sid in sids)


def _held_ztf(plan: Any, problem: Any) -> Any:
    """ZTF's revision held fixed: its fields (none for its ``not_observable`` answer)."""
    from ...scheduler_core.joint_parts import Held

    return Held("ztf", problem, _fields(_document(plan)))


def _key(held_ztf: Any, plan: Any) -> str:
    """What a round's parts are planned around: ZTF's revision (its id and fields)."""
    from ...scheduler_core.joint_parts import around_key

    return around_key([("ztf", getattr(plan, "plan_id", None), held_ztf.fields)])


def _round(rows: dict[str, dict], key: str) -> int | None:
    """The round of the parts planned around ``key``; None when a later round was begun meanwhile.

    Rounds only move forward (no folder is written twice): the job's latest
    round when it is ``key``'s, one after it when ``key`` has no part, and
    None when ``key``'s parts belong to an earlier round than the latest
    (the caller starts a new round only for the job's final revision).
    """
    latest = max((int(r.get("round") or 1) for r in rows.values()), default=0)
    mine = [int(r.get("round") or 1) for r in rows.values() if r.get("held") == key]
    if not mine:
        return latest + 1
    return latest if max(mine) == latest else None


def _document(plan: Any) -> dict | None:
    """A plan's document; None for a ``not_observable`` answer, an exception or nothing."""
    from ...scheduler_core.plan.document import Plan

    return plan.to_document() if isinstance(plan, Plan) else None


def _state(plan: Any) -> str:
    from ...scheduler_core.plan.observability import NotObservable

    if isinstance(plan, BaseException):
        return "failed"
    return "not_observable" if isinstance(plan, NotObservable) else "exported"


def _fields(doc: dict | None) -> tuple[int, ...]:
    from ...scheduler_core.joint_parts import fields_of

    return fields_of(doc)


def _recorded_document(row: dict) -> dict | None:
    """A recorded part's plan document (its ``plan.json``); None when not exported or unreadable."""
    import json

    if row.get("state") != "exported" or not row.get("folder"):
        return None
    try:
        doc = json.loads((Path(row["folder"]) / "plan.json").read_text())
        return doc if isinstance(doc, dict) and isinstance(doc.get("observations"), list) else None
    except (OSError, ValueError) as exc:  # an operator removed it: held as covering nothing
        log.error("event=telescope_part_unreadable telescope=%s folder=%s error=%r", row.get("telescope"),
                  row.get("folder"), str(exc))
        return None


def _held_part(name: str, problem: Any, row: dict) -> Any:
    """A part recorded for this revision, held fixed (covering nothing without its plan or its problem)."""
    from ...scheduler_core.joint_parts import Held

    problem = None if isinstance(problem, BaseException) else problem
    return Held(name, problem, _fields(_recorded_document(row)) if problem is not None else ())


def _scheduler_table(planning: Any) -> dict[str, Any]:
    """The service's ``[scheduler]`` as a table: keys it sets to other than ZTF's defaults win for every telescope."""
    table = {f.name: getattr(planning, f.name) for f in dataclasses.fields(planning) if f.name != "telescopes"}
    slew = table.get("slew")
    if dataclasses.is_dataclass(slew):
        table["slew"] = dataclasses.asdict(slew)
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in table.items()}


def _part_files(folder: Path, telescope: Any, plan: Any) -> tuple[str, list[str], str]:
    """Write the part's export; (state, files written, why) by what ``plan`` is."""
    from ...scheduler_core.plan.observability import NotObservable

    if isinstance(plan, BaseException):
        return "failed", [], storable(f"{type(plan).__name__}: {plan}", 400)
    if isinstance(plan, NotObservable):
        return "not_observable", [], storable("; ".join(plan.sentences) or "below min_coverage", 400)
    files = {"plan.json": plan.to_document()}
    if telescope.queue == "target_list":
        from ...scheduler_core.plan.target_list import target_list_csv, target_list_document

        files["targets.json"] = target_list_document(plan, telescope.name)
        _write_bytes(folder / "targets.csv", target_list_csv(plan).encode())
    elif telescope.queue == "skyportal":
        files["skyportal_request.json"] = _skyportal_request(plan, telescope)
    for name, doc in files.items():
        _write_json(folder / name, doc)
    written = sorted([*files, *(["targets.csv"] if telescope.queue == "target_list" else [])])
    return "exported", written, ""


def _skyportal_request(plan: Any, telescope: Any) -> dict[str, Any]:
    """SkyPortal's observation plan request for the telescope's instrument ([submit_parts] sends it)."""
    from ..submission.part_request import part_request

    return part_request(plan, telescope)


def _mark_folder(row: dict[str, Any], state: str) -> None:
    """The ``SUPERSEDED``/``WITHDRAWN`` marker and ``part.json``'s state, in a part's folder (atomically)."""
    import json

    if not row.get("folder"):
        return
    folder = Path(row["folder"])
    try:
        part = json.loads((folder / "part.json").read_text())
    except (OSError, ValueError):
        part = {"type": "telescope_part", "telescope": row["telescope"], "superevent_id": row["superevent_id"]}
    part["state"] = state
    _write_bytes(folder / MARKERS[state], f"{state}: {row['telescope']} part of job {row['job_id']}\n".encode())
    _write_json(folder / "part.json", part)


def _write_json(path: Path, doc: Any) -> None:
    from ...outputs import write_json_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, doc)


def _write_bytes(path: Path, data: bytes) -> None:
    from ...outputs import write_bytes_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, data)


def plan_parts(store: Any, plan_id: str | None) -> list[dict[str, Any]]:
    """The other telescopes' parts of the job whose ZTF revision is ``plan_id`` ([] for none, or no table)."""
    try:
        row = store.connection().execute("SELECT job_id FROM plans WHERE plan_id=?", (plan_id,)).fetchone()
        return [] if row is None or row[0] is None else list(parts_of_job(store, row[0]).values())
    except Exception as exc:  # the words about other telescopes never stop ZTF's message
        log.error("event=telescope_parts_unread plan_id=%s error=%r", plan_id, str(exc))
        return []


def parts_lines(parts: list[dict[str, Any]]) -> list[str]:
    """Every telescope's part of a revision in words, for its summary and page (none without parts)."""
    from ...report.site import site_words
    from ...report.sky import area_words, part_area_deg2
    from ..state.parts import part_line

    if not parts:
        return []
    return ([f"Telescopes ztf (ztf_too): this plan{site_words('ztf')}"]
            + [f"           {part_line(p)}{area_words(part_area_deg2(p))}"
               for p in sorted(parts, key=lambda p: p["telescope"])])


def parts_words(parts: list[dict[str, Any]]) -> str:
    """The webhook's few words: ``other telescopes: ls4 target_list exported at La Silla (fields cover N deg²)``."""
    from ...report.site import site_words
    from ...report.sky import area_words, part_area_deg2

    return ("other telescopes: " + ", ".join(f"{p['telescope']} {p['queue']} {p['state']}{site_words(p['telescope'])}"
                                             f"{area_words(part_area_deg2(p))}"
                                             for p in sorted(parts, key=lambda p: p["telescope"]))) if parts else ""
