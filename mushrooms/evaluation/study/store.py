"""A study's results on disk: append-only JSON lines, one record per finished task, keyed for resuming.

A result's key is (map, solver, configuration hash): a rerun skips every
key already there with a scored result and retries the failures; a change
of any setting a result depends on (:func:`study_config`) makes new keys.

A store travels as a committed copy (:func:`export_records`: the last record
of every key, gzip'd, without the configuration each record repeats) that
another machine's store is seeded from (:func:`seed_records`), so a study
there skips what was planned here.  The map part of a key names no path (a
file's bytes, or an events file's bytes, a coincidence and the localisation
options), so a seeded record is recognised wherever the study's directories
are, as long as the configuration hash is the same; the configuration holds
``[bench] gwemopt_cache_dir``, so a different cache path is a different
configuration and plans everything again.
"""

from __future__ import annotations

import dataclasses
import gzip
import json
import os
from pathlib import Path
from typing import Any, Mapping

from ...scheduler_core.plan import strict_json
from ..bench.settings import ROW_NAMES_VERSION, BenchSettings

__all__ = ["ResultStore", "result_key", "study_config", "EXPORT_DROP", "export_records", "seed_records"]

#: Fields a committed copy of a store leaves out: the configuration (every record repeats it; its hash is in the
#: key and in ``config_hash``, and the configuration file is committed once beside the copy).
EXPORT_DROP = ("config",)


def study_config(settings: BenchSettings) -> dict[str, Any]:
    """The configuration a result depends on (JSON-able; its hash is part of every result key).

    The planning configuration, every ``[bench]`` key, the start, the
    injections per map, the ``service`` row's supersede margin and the
    meaning of the row names; not the rows asked
    for (each result is one row's).
    """
    d = dataclasses.asdict(settings.bench)
    d.update(config=dataclasses.asdict(settings.config), start_iso=settings.start_iso,
             n_injections=settings.n_injections, supersede_min_gain=settings.supersede_min_gain)
    d["row_names"] = ROW_NAMES_VERSION  # a row named after a solver became what the service publishes
    return json.loads(json.dumps(d, sort_keys=True, default=str))


class ResultStore:
    """Append-only JSON-lines file of (map, solver) results: ``<out>/results.jsonl``.

    Each line is one finished task: ``key``, ``map``, ``skymap``, ``solver``,
    ``ok``, ``row``, ``error``, ``traceback``, ``versions``, ``config_hash``,
    ``config``, ``finished`` (UTC).  The last line of a key wins.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def records(self) -> dict[str, dict[str, Any]]:
        """The last record of every key (a torn last line, from a killed run, is ignored)."""
        out: dict[str, dict[str, Any]] = {}
        if not self.path.exists():
            return out
        with open(self.path) as fh:
            for line in fh:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if rec.get("kind") == "result":
                    out[rec["key"]] = rec
        return out

    def append(self, record: Mapping[str, Any]) -> None:
        """Write one record and put it on disk now."""
        with open(self.path, "a") as fh:
            fh.write(strict_json.dumps(record, default=str) + "\n")
            fh.flush()
            os.fsync(fh.fileno())


def result_key(map_key: str, solver: str, config_hash: str) -> str:
    """Identity of one (map, solver) result under one configuration."""
    return f"{map_key}|{solver}|{config_hash}"



def _lines(path: Path) -> list[dict[str, Any]]:
    """The result records of a JSON-lines file, plain or gzip'd (torn lines skipped)."""
    opener = gzip.open if path.suffix == ".gz" else open
    out = []
    with opener(path, "rt") as fh:
        for line in fh:
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(rec, dict) and rec.get("kind") == "result" and "key" in rec:
                out.append(rec)
    return out


def export_records(source: str | Path, target: str | Path) -> int:
    """Write the last record of every key of the store ``source`` to ``target`` without :data:`EXPORT_DROP`.

    Sorted by key; gzip'd when ``target`` ends in ``.gz`` (no name, no time
    in the header: the same records give the same bytes).  Written to a
    temporary file and renamed.  Returns the number of records.
    """
    records = ResultStore(source).records()
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    text = "".join(strict_json.dumps({k: v for k, v in records[key].items() if k not in EXPORT_DROP},
                                     default=str, sort_keys=True) + "\n" for key in sorted(records))
    tmp = target.with_name(target.name + ".partial")
    with open(tmp, "wb") as raw:
        if target.suffix == ".gz":
            with gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as fh:
                fh.write(text.encode())
        else:
            raw.write(text.encode())
    os.replace(tmp, target)
    return len(records)


def seed_records(source: str | Path, store: str | Path) -> int:
    """Append to the store ``store`` the records of ``source`` (an :func:`export_records` copy) it lacks.

    A record is appended when the store has no record of its key, or only a
    failed one while the copy's is scored (``ok``); a key the store already
    holds scored is left alone.  Returns the number appended.
    """
    target = ResultStore(store)
    have = target.records()
    new = []
    for rec in _lines(Path(source)):
        mine = have.get(rec["key"])
        if mine is None or (not mine.get("ok") and rec.get("ok")):
            new.append(strict_json.dumps(rec, default=str) + "\n")
            have[rec["key"]] = rec
    if new:
        if target.path.exists() and target.path.stat().st_size:
            with open(target.path, "rb") as fh:
                fh.seek(-1, os.SEEK_END)
                if fh.read(1) != b"\n":  # a torn last line (a killed run): the first seeded record starts anew
                    new.insert(0, "\n")
        with open(target.path, "a") as fh:
            fh.write("".join(new))
            fh.flush()
            os.fsync(fh.fileno())
    return len(new)
