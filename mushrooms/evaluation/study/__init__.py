"""The paper's experiment at population scale, as a library: sky maps made or taken, planned and
scored on a Dask task graph, the paper's tables and figures.

Stages (each a task, or one task per event / per (map, solver)):

(a) **sky maps** — one of

    * a new population simulated with ligo.skymap's own command-line tools
      (:mod:`.population`: ``bayestar-sample-model-psd`` → ``bayestar-inject``
      → one ``bayestar-realize-coincs`` task per chunk of injections),
    * a file of realised coincidences (default the packaged O3 BNS
      population), localised one task per coincidence with BAYESTAR, each
      map cached on disk (:mod:`.localisation`),
    * or a directory of existing sky maps;

(b)+(c) **plan and score** — one task per (map, solver): the benchmark's own
    :func:`~mushrooms.evaluation.bench.bench_map` on that map with that one
    row (:mod:`.graph`), each finished result appended at once to
    ``<out>/results.jsonl`` (:mod:`.store`; a rerun skips what is there);

(d) **tables and figures** in the paper's layout (:mod:`.tables`, :mod:`.figures`).

:func:`run_study` (:mod:`.run`) runs them from plain
:class:`StudySettings` and :class:`StudyInputs`; ``mushrooms study``
(:mod:`mushrooms.tool.study`) reads the command line into them and prints
the outcome.  The names below are imported on first use (PEP 562): the
command's parser reads :mod:`.defaults` without loading numpy or dask.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from .figures import make_figures
    from .graph import StudyRun, open_client, plan_and_score, run_graph
    from .localisation import (DEFAULT_EVENTS, Localisation, MapTask, localise, localised_path,
                               maps_from_directory, maps_from_events)
    from .population import (Population, SimulationError, cached_chunk, chunks_needed, coinc_ids,
                             inject_population, realize_chunk, simulate_population, split_injections)
    from .run import StudyInputs, StudyOutcome, StudySettings, run_study
    from .store import ResultStore, result_key, study_config
    from .tables import paper_tables, similar_length_maps

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "make_figures": ".figures",
    "StudyRun": ".graph", "open_client": ".graph", "plan_and_score": ".graph", "run_graph": ".graph",
    "DEFAULT_EVENTS": ".localisation", "Localisation": ".localisation", "MapTask": ".localisation",
    "localise": ".localisation", "localised_path": ".localisation", "maps_from_directory": ".localisation",
    "maps_from_events": ".localisation",
    "Population": ".population", "SimulationError": ".population", "cached_chunk": ".population",
    "chunks_needed": ".population",
    "coinc_ids": ".population", "inject_population": ".population", "realize_chunk": ".population",
    "simulate_population": ".population", "split_injections": ".population",
    "StudyInputs": ".run", "StudyOutcome": ".run", "StudySettings": ".run", "run_study": ".run",
    "ResultStore": ".store", "result_key": ".store", "study_config": ".store",
    "paper_tables": ".tables", "similar_length_maps": ".tables",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
