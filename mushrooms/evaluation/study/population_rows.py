"""A simulated population's results, one row per (event, solver), with each event's class and distance.

The study stores bench rows keyed by map (:mod:`.store`); a population's
results are read per *event*: which realised chunk and coincidence it is,
its class (BNS / NSBH, from the injected source-frame masses) and true
distance, and per solver the numbers the papers compare
(:data:`POPULATION_COLUMNS`).  ``coverage_executed`` is the coverage of the
plan as ZTF would execute its queues (the bench row's ``coverage_as_executed``:
the telescope model's cadence-valid coverage, Q14); empty for a result made
before the rows carried it.  ``coverage_executed_single_queue`` is the same
through the one list queue SkyPortal's ZTF API submits for a plan ("as
submitted today", the bench's ``coverage_single_queue``); ``coverage_pairs``
the planned coverage counted by the pair rule (every row alike);
``open_shutter_s`` the plan's summed exposure time (``open_shutter_executed_s``
what the queue set's run kept open); ``efficiency_two_detections`` the
two-detection rule's efficiency where the scoring provides it; ``commit`` the
code that planned the row.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from ..bench.rows import fmt, num
from .mass_models import binary_class
from .provenance import sha256_file

__all__ = ["POPULATION_COLUMNS", "coinc_injections", "source_frame_masses", "population_events",
           "population_row", "population_rows", "write_population_csv", "read_population_csv"]

Record = dict[str, Any]

#: Columns of a population's ``results.csv``: the ten the comparison needs, then what each event is.
POPULATION_COLUMNS = (
    "event", "solver", "coverage", "coverage_executed", "upper_bound", "efficiency_optimistic",
    "efficiency_conservative", "efficiency_nsbh", "valid", "runtime_s",
    "event_class", "distance_mpc", "distmean_mpc", "area90_deg2", "n_exposures", "objective", "status",
    "coverage_pairs", "coverage_executed_single_queue", "efficiency_two_detections", "open_shutter_s",
    "open_shutter_executed_s", "n_problems", "commit",
)


def coinc_injections(events: str | Path) -> dict[int, Record]:
    """The injection behind each coincidence of an events file: ``{coinc_id: {mass1, mass2, spin1z, spin2z,
    distance_mpc, ra_deg, dec_deg}}`` (detector-frame masses, Msun; the true sky position, deg), from its
    ``sim_inspiral <--> coinc_event`` map."""
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    doc = ligolw_utils.load_filename(str(events), contenthandler=ContentHandler)
    sims = {int(s.simulation_id): s for s in lsctables.SimInspiralTable.get_table(doc)}
    defs = {int(d.coinc_def_id) for d in lsctables.CoincDefTable.get_table(doc)
            if d.description.startswith("sim_inspiral<-->coinc_event")}
    links = {int(c.coinc_event_id) for c in lsctables.CoincTable.get_table(doc) if int(c.coinc_def_id) in defs}
    sim_of: dict[int, int] = {}
    coinc_of: dict[int, int] = {}
    for row in lsctables.CoincMapTable.get_table(doc):
        link = int(row.coinc_event_id)
        if link in links:
            (sim_of if row.table_name == "sim_inspiral" else coinc_of)[link] = int(row.event_id)
    out = {}
    for link, coinc in coinc_of.items():
        s = sims[sim_of[link]]
        out[coinc] = dict(mass1=float(s.mass1), mass2=float(s.mass2), spin1z=float(s.spin1z),
                          spin2z=float(s.spin2z), distance_mpc=float(s.distance),
                          ra_deg=math.degrees(float(s.longitude)), dec_deg=math.degrees(float(s.latitude)))
    return out


def source_frame_masses(mass1: Sequence[float], mass2: Sequence[float],
                        distance_mpc: Sequence[float]) -> tuple[Any, Any]:
    """Detector-frame masses divided by ``1 + z`` at the luminosity distance (Planck15, bayestar-inject's
    default cosmology)."""
    import numpy as np
    from astropy.cosmology import Planck15

    z_grid = np.linspace(0.0, 2.0, 4001)
    d_grid = Planck15.luminosity_distance(z_grid).to_value("Mpc")
    z = np.interp(np.asarray(distance_mpc, dtype=float), d_grid, z_grid)
    return np.asarray(mass1, dtype=float) / (1 + z), np.asarray(mass2, dtype=float) / (1 + z)


def population_events(events_files: Sequence[str | Path], prefix: str = "o4") -> dict[tuple[str, int], Record]:
    """Every coincidence of a population's realised chunks, keyed by (events sha256[:16], coinc id).

    ``events_files[k]`` is chunk ``k``'s file.  Each record: ``event``
    (``PREFIX-KKKK-ID``: chunk and coinc id), ``chunk``, ``coinc_id``,
    ``event_class``, ``distance_mpc`` (injected), and the detector-frame
    masses and spins.
    """
    out: dict[tuple[str, int], Record] = {}
    for k, path in enumerate(events_files):
        sha = sha256_file(path)[:16]
        inj = coinc_injections(path)
        ids = sorted(inj)
        if not ids:
            continue
        m1, m2 = source_frame_masses([inj[i]["mass1"] for i in ids], [inj[i]["mass2"] for i in ids],
                                     [inj[i]["distance_mpc"] for i in ids])
        for cid, cls in zip(ids, binary_class(m1, m2)):
            out[(sha, cid)] = dict(event=f"{prefix}-{k:04d}-{cid}", chunk=k, coinc_id=cid, event_class=str(cls),
                                   **inj[cid])
    return out


def population_rows(records: Iterable[Mapping[str, Any]],
                    events: Mapping[tuple[str, int], Record]) -> list[Record]:
    """One :data:`POPULATION_COLUMNS` row per study result whose map is an event of ``events``.

    ``records`` are the study's stored results (:meth:`.store.ResultStore.records`
    values: ``map`` = ``<events sha[:16]>:<coinc id>:<options>``, ``solver``,
    ``row``, ``finished``); ordered by event then solver as given.  An event
    planned by one solver under several configurations keeps the result
    finished last.
    """
    latest: dict[tuple[str, str, str], Mapping[str, Any]] = {}
    for rec in records:
        sha, cid, _ = str(rec["map"]).split(":", 2)
        key = (sha, cid, str(rec["solver"]))
        if key not in latest or str(rec.get("finished", "")) >= str(latest[key].get("finished", "")):
            latest[key] = rec
    out = []
    for rec in latest.values():
        sha, cid, _ = str(rec["map"]).split(":", 2)
        ev = events.get((sha, int(cid)))
        if ev is None:
            continue
        out.append(population_row({**rec["row"], "solver": rec["solver"]}, ev, commit=rec.get("commit")))
    order = {e["event"]: (e["chunk"], e["coinc_id"]) for e in events.values()}
    return sorted(out, key=lambda r: order[r["event"]])


def population_row(row: Mapping[str, Any], event: Mapping[str, Any], commit: str | None = None) -> Record:
    """One :data:`POPULATION_COLUMNS` row from a bench row (:data:`~..bench.rows.COLUMNS`) of an event.

    Parameters
    ----------
    row : mapping
        The bench's row of one solver on the event's map.
    event : mapping
        ``event``, ``event_class``, ``distance_mpc`` (the injected truth).
    commit : str, optional
        The code that planned the row when the row itself does not say.
    """
    return dict(event=event["event"], solver=row["solver"], coverage=row.get("coverage"),
                coverage_executed=row.get("coverage_as_executed", ""), upper_bound=row.get("bound"),
                efficiency_optimistic=row.get("efficiency_optimistic"),
                efficiency_conservative=row.get("efficiency_conservative"),
                efficiency_nsbh=row.get("efficiency_nsbh"), valid=row.get("valid"),
                runtime_s=row.get("runtime_s"), event_class=event["event_class"],
                distance_mpc=event["distance_mpc"], distmean_mpc=row.get("distmean_mpc"),
                area90_deg2=row.get("area90_deg2"), n_exposures=row.get("n_exposures"),
                objective=row.get("objective"), status=row.get("status"),
                coverage_pairs=row.get("coverage_pairs", ""),
                coverage_executed_single_queue=row.get("coverage_single_queue", ""),
                efficiency_two_detections=row.get("efficiency_two_detections", ""),
                open_shutter_s=row.get("open_shutter_s", ""),
                open_shutter_executed_s=row.get("open_shutter_executed_s", ""),
                n_problems=row.get("n_problems", ""), commit=row.get("commit") or commit or "")


def write_population_csv(rows: Iterable[Mapping[str, Any]], path: str | Path) -> None:
    """Write :data:`POPULATION_COLUMNS` rows (floats rounded by the bench's :func:`~..bench.rows.fmt`; atomic)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".partial")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(POPULATION_COLUMNS)
        for r in rows:
            w.writerow([fmt(r.get(c)) for c in POPULATION_COLUMNS])
    os.replace(tmp, path)


def read_population_csv(path: str | Path) -> list[Record]:
    """Rows of a population ``results.csv``; numeric cells as floats (empty: None), ``valid`` as bool."""
    text = {"event", "solver", "event_class", "objective", "status", "commit"}
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            d: Record = {k: (v if k in text else num(v)) for k, v in r.items()}
            d["valid"] = str(r.get("valid")).strip().lower() in ("true", "1")
            out.append(d)
    return out
