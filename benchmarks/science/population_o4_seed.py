#!/usr/bin/env python3
"""Seed a population run's ROOT from its committed folder, so a new machine goes on where the last one stopped.

``population_o4.sh`` calls this before its stages (``SEED_FROM``: the committed ``population/`` folder; its
sibling ``study/`` holds the committed result records, ``population_o4_results.py`` writes both):

* the population (``population.json``, ``psds.xml``, ``intrinsic_samples.ecsv``, ``injections.xml.gz``
  unpacked, every realised chunk) into ``ROOT/cache/populations/<key>/`` when ``population.key`` is the
  recipe's key: the study takes those chunks as they are and simulates only what was never realised;
* the configuration ``study/config.toml`` to ``CONFIG`` when there is none yet: every result key holds its hash,
  so the seeded results are recognised only under the very same configuration (a warning says so when
  ``CONFIG`` exists and differs);
* the result records ``study/results.jsonl.gz`` into ``ROOT/study/results.jsonl`` (the keys ROOT lacks, or holds
  only as failures: :func:`mushrooms.evaluation.study.store.seed_records`), and the logs ``realizations.jsonl``
  and ``localisations.jsonl`` when ROOT has none: the study skips every (map, row) already planned, and an event
  whose rows are all done is not localised again.

The sky maps are not committed: ``bayestar-localize-coincs`` makes a map again, deterministically, when one of
its event's rows is still to plan.

    python benchmarks/science/population_o4_seed.py --population o4-real --from DIR --root ROOT --config FILE
"""

from __future__ import annotations

import argparse
import gzip
import shutil
import sys
from pathlib import Path

from mushrooms.evaluation.study.recipes import RECIPES, recipe_population
from mushrooms.evaluation.study.store import seed_records


def seed_population(population: str, injections: int, seed: int, source: Path, root: Path) -> str:
    """Copy the committed population into ROOT's cache (nothing already there is replaced); what was done."""
    pop, _ = recipe_population(population, injections, seed=seed)
    key = pop.key()
    if not (source / "chunks").is_dir():
        return f"no population in {source}"
    committed = (source / "population.key").read_text().strip() if (source / "population.key").exists() else ""
    if committed != key:
        return f"not seeding the population: {source} is population {committed or '?'}, not {key}"
    target = root / "cache" / "populations" / key
    chunks = target / f"realized-{pop.chunk}"
    chunks.mkdir(parents=True, exist_ok=True)
    for name in ("population.json", "psds.xml", "intrinsic_samples.ecsv"):
        if (source / name).exists() and not (target / name).exists():
            shutil.copy2(source / name, target / name)
    if (source / "injections.xml.gz").exists() and not (target / "injections.xml").exists():
        part = target / "injections.partial.xml"
        with gzip.open(source / "injections.xml.gz", "rb") as fin, open(part, "wb") as fout:
            shutil.copyfileobj(fin, fout)
        part.replace(target / "injections.xml")
    n = 0
    for f in sorted((source / "chunks").glob("events-*.xml.gz")):
        if not (chunks / f.name).exists():
            shutil.copy2(f, chunks / f.name)
            n += 1
    return f"seeded {target} from {source} ({n} chunk(s) copied)"


def seed_study(study: Path, root: Path, config: Path) -> list[str]:
    """Copy the configuration and the result records of the committed ``study/`` folder into ROOT; what was done."""
    notes = []
    committed = study / "config.toml"
    if committed.exists():
        if not config.exists():
            config.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(committed, config)
            notes.append(f"configuration {config} <- {committed}")
        elif config.read_bytes() != committed.read_bytes():
            notes.append(f"WARNING: {config} is not {committed}: the seeded results' keys hold the committed "
                         "configuration's hash, so under this one every row is planned again")
    out = root / "study"
    records = study / "results.jsonl.gz"
    if records.exists():
        out.mkdir(parents=True, exist_ok=True)
        n = seed_records(records, out / "results.jsonl")
        notes.append(f"{n} result record(s) seeded into {out / 'results.jsonl'} from {records}")
    for name in ("realizations.jsonl", "localisations.jsonl"):
        if (study / name).exists() and not (out / name).exists():
            out.mkdir(parents=True, exist_ok=True)
            shutil.copy2(study / name, out / name)
            notes.append(f"{out / name} <- {study / name}")
    return notes


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--population", required=True, help=f"the recipe ({', '.join(RECIPES)})")
    ap.add_argument("--injections", type=int, default=15000)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--from", dest="source", type=Path, required=True,
                    help="the committed population folder (its sibling study/ holds the result records)")
    ap.add_argument("--root", type=Path, required=True)
    ap.add_argument("--config", type=Path, required=True, help="the run's configuration file (ROOT/config.toml)")
    args = ap.parse_args()
    if args.population not in RECIPES:
        print(f"--population: no recipe {args.population!r} (one of {', '.join(RECIPES)})", file=sys.stderr)
        return 2
    try:
        notes = [seed_population(args.population, args.injections, args.seed, args.source, args.root)]
        notes += seed_study(args.source.parent / "study", args.root, args.config)
    except (OSError, EOFError, UnicodeDecodeError) as exc:  # a truncated or unreadable committed file
        print(f"population_o4_seed.py: cannot seed {args.root} from {args.source}: {type(exc).__name__}: {exc}",
              file=sys.stderr)
        return 2
    for line in notes:
        print(f"== {line}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
