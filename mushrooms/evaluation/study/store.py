"""A study's results on disk: append-only JSON lines, one record per finished task, keyed for resuming.

A result's key is (map, solver, configuration hash): a rerun skips every
key already there with a scored result and retries the failures; a change
of any setting a result depends on (:func:`study_config`) makes new keys.
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any, Mapping

from ...scheduler_core.plan import strict_json
from ..bench.settings import ROW_NAMES_VERSION, BenchSettings

__all__ = ["ResultStore", "result_key", "study_config"]


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

