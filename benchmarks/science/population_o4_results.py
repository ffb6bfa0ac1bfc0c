#!/usr/bin/env python3
"""A population study's results in the papers' layout, and its provenance, from the running study.

Reads what ``benchmarks/science/population_o4.sh`` writes under ROOT (the population cache and
``study/results.jsonl``, ``realizations.jsonl``, ``localisations.jsonl``), for the run's recipe (``--population``;
default: the recipe whose population ROOT's cache holds: ``o4`` or ``o4-real``), and writes, under OUT (default
benchmarks/results/science/population_o4/ for ``o4-real``, the release of issue 55;
population_o4/previous_2026-12-06_o4_recipe/ for ``o4``):

* ``results.csv``: one row per (event, solver), :data:`POPULATION_COLUMNS` (``coverage_executed``: the plan's
  coverage as ZTF would execute its queues), events named ``o4-KKKK-ID`` (``o4real-KKKK-ID`` for ``o4-real``);
* ``tables.md`` and ``figures/``: every table and figure, rebuilt from ``results.csv`` alone (``--tables-only``
  does just that); ``release_tables.md``: the release's tables (issue 55: medians and bootstrap intervals beside
  means, paired differences against the service, zero-execution events, the events not all of whose six rows
  are done, a warning when the rows come from more than one commit; ``benchmarks/science/release_tables.py``;
  with ``study/executed_curves.jsonl.gz``, our rows at gwemopt's open-shutter time: ``population_o4_replan.py``,
  ``population_o4_curves.py``);
* ``provenance.md`` and ``population/``: the recipe, commands, seeds, PSDs, counts per class, the CPU cost
  per event and stage (for ``o4-real`` also its sources, ranges, epochs, FAR-like threshold and the
  coincidences each chunk kept, and the commits that planned the rows); the small files
  (``population.json``, ``psds.xml``, ``intrinsic_samples.ecsv``, ``injections.xml.gz``, every realised chunk's
  ``events-KKKK.xml.gz``), enough for ``population_o4.sh`` to resume on another machine without simulating again;
* ``study/``: the run's ``config.toml`` and its result records (``results.jsonl.gz``: the last record of every
  key, without the configuration each repeats; ``realizations.jsonl``, ``localisations.jsonl``), from which
  ``population_o4.sh`` (``population_o4_seed.py``) seeds ROOT so no finished (map, row) is planned again. The
  sky maps stay under ROOT (``bayestar-localize-coincs`` makes them again, deterministically, from the chunks).

    .venv/bin/python benchmarks/science/population_o4_results.py [--population o4-real] [--root DIR] [--out DIR]
        [--tables-only]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
from pathlib import Path

from mushrooms.evaluation.study.mass_models import FARAH_PDB
from mushrooms.evaluation.study.population_rows import (population_events, population_rows,
                                                        read_population_csv, write_population_csv)
from mushrooms.evaluation.study.population_figures import population_figures
from mushrooms.evaluation.study.population_tables import population_tables
from mushrooms.evaluation.study.recipes import (O4_DEVIATIONS, O4_RANGES_MPC, O4_REAL_RANGES_MPC, O4_REAL_SOURCES,
                                                RECIPES, recipe_population)
from mushrooms.evaluation.study.matched_tables import read_curves
from mushrooms.evaluation.study.release_tables import RELEASE_ROWS, commits_of, release_tables
from mushrooms.evaluation.study.store import ResultStore, export_records

HERE = Path(__file__).resolve().parent


def _jsonl(path: Path) -> list[dict]:
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            pass
    return out


def _gzip(source: Path, target: Path) -> None:
    """``target``: ``source`` gzipped (reproducibly: no name, no time in the header), when it changed."""
    import gzip

    if target.exists() and target.stat().st_mtime >= source.stat().st_mtime:
        return
    with open(source, "rb") as fin, open(target, "wb") as raw:
        with gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as fout:
            shutil.copyfileobj(fin, fout)


def _median(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3g}" if xs else "-"


def cpu_costs(study: Path, realized: list[dict]) -> dict[str, list[float]]:
    """CPU seconds per event and stage: realisation per injection, localisation, each solver's task."""
    loc = [r["cpu_s"] for r in _jsonl(study / "localisations.jsonl") if r.get("ok") and not r.get("cached")]
    plans: dict[str, list[float]] = {}
    for rec in ResultStore(study / "results.jsonl").records().values():
        if rec.get("ok") and rec.get("cpu_s") is not None:
            plans.setdefault(rec["solver"], []).append(float(rec["cpu_s"]))
    fresh = [r for r in realized if not r.get("cached")]
    per_inj = [r["cpu_s"] / r["injections"] for r in fresh if r["injections"]]
    return {"realise_per_injection": per_inj, "localise": loc, **{f"plan_{k}": v for k, v in plans.items()}}


#: Where each recipe's results and committed population go by default, and its events' name prefix.
LAYOUT = {"o4": ("population_o4/previous_2026-12-06_o4_recipe", Path("/work/population_o4"), "o4"),
          "o4-real": ("population_o4", Path("/work/population_o4_real"), "o4real")}


def _realise_command(pop, seed: int) -> list[str]:
    """The realisation of chunk k (and, for ``o4-real``, its rewrite)."""
    out = [f"bayestar-realize-coincs --seed {seed}+1+k -j 1 -l error -o events-k.xml.gz injections-k.xml "
           f"--reference-psd psds.xml --snr-threshold 1 --net-snr-threshold {pop.net_snr_threshold} "
           f"--min-triggers 1 --duty-cycle {pop.duty_cycle} --keep-subthreshold --measurement-error gaussian-noise "
           f"--detector {' '.join(d for d, _, _ in pop.psd_scales)}"]
    if pop.post == "o4-real":
        out.append(f"python -c 'from mushrooms.evaluation.study.o4_real import apply_o4_real; "
                   f"apply_o4_real(\"events-k.xml.gz\", {seed}+1+k)'   # epochs, duty cycles, FAR-like threshold")
    return out


def o4_real_notes(events_files: list[Path]) -> list[str]:
    """``o4-real``: its ranges, sources, epochs, FAR-like threshold and the coincidences each chunk kept."""
    from ligo.skymap.io import events as gw_events

    from mushrooms.evaluation.study.o4_real import FAR_THRESHOLD_HZ, LOW_SIGNIFICANCE_FAR_HZ, O4_EPOCHS, \
        SINGLE_DETECTOR_PENALTY, snr_threshold

    days = sum(d for _, d, _ in O4_EPOCHS)
    lines = [f"Noise curves: BNS ranges {O4_REAL_RANGES_MPC} Mpc (`recipes.O4_REAL_RANGES_MPC`; "
             "`recipes.bns_range_mpc`).", "",
             "Epochs (`o4_real.O4_EPOCHS`): each coincidence falls in an epoch with probability proportional to its "
             "length; a detector that did not observe then is removed, the others are on with their duty cycle:", "",
             "| epoch | days | share | detectors (duty cycle) |", "|---|---|---|---|"]
    lines += [f"| {name} | {d:.0f} | {d / days:.3f} | " + ", ".join(f"{k} {v:.3f}" for k, v in duty.items()) + " |"
              for name, d, duty in O4_EPOCHS]
    lines += ["", f"FAR-like threshold (`o4_real.far_like_hz`): kept when FAR <= {FAR_THRESHOLD_HZ:.3e} Hz (one per "
              f"30 days), FAR = {LOW_SIGNIFICANCE_FAR_HZ:.3e} Hz x exp(-(rho^2 - 64)/2) over the triggers (SNR >= 4) "
              f"of the detectors left, single-detector SNR less {SINGLE_DETECTOR_PENALTY}: network SNR "
              f"{snr_threshold(2):.2f} for a coincidence, {snr_threshold(1):.2f} for one detector.", "",
              "Sources (`recipes.O4_REAL_SOURCES`; \"estimate\" where no source was found):",
              *[f"- {x}" for x in O4_REAL_SOURCES], "",
              "Coincidences each realised chunk kept (50 injections each, realised with every detector on and "
              "network SNR >= 8, then rewritten as O4 was; the network of each kept coincidence is the detectors "
              "left with a trigger). The frozen code does not record how many each rewrite dropped.", "",
              "| chunk | kept | networks |", "|---|---|---|"]
    total = 0
    for k, f in enumerate(events_files):
        nets: dict[str, int] = {}
        for event in gw_events.open(str(f)).values():
            net = "".join(sorted(s.detector[0] for s in event.singles if s.snr is not None and s.snr >= 4.0))
            nets[net or "-"] = nets.get(net or "-", 0) + 1
        kept = sum(nets.values())
        total += kept
        lines.append(f"| {k} | {kept} | " + (", ".join(f"{n} {c}" for n, c in sorted(nets.items())) or "-") + " |")
    lines += [f"| all {len(events_files)} | {total} | |"]
    return lines


def provenance(recipe: str, pop_dir: Path, events_files: list[Path], events: dict, rows: list[dict], costs: dict,
               injections: int, seed: int, code: list[str]) -> str:
    """provenance.md: recipe, commands, seeds, PSDs, counts per class, CPU per stage, the code (``code``)."""
    pop, loc = recipe_population(recipe, injections, seed=seed)
    n_real = min(len(events_files) * pop.chunk, injections)
    classes: dict[str, int] = {}
    for e in events.values():
        classes[e["event_class"]] = classes.get(e["event_class"], 0) + 1
    planned = {r["event"] for r in rows}
    planned_classes: dict[str, int] = {}
    for e in events.values():
        if e["event"] in planned:
            planned_classes[e["event_class"]] = planned_classes.get(e["event_class"], 0) + 1
    psd_cmd = " ".join(f"--{d} {m} --{d}-scale {s}" for d, m, s in pop.psd_scales)
    lines = [
        f"# O4 population (recipe `{recipe}`): provenance", "",
        f"Recipe: {RECIPES[recipe].description}. Population key `{pop.key()}` "
        f"(cache `{pop_dir}`), {injections} injections, seed {seed}, chunks of {pop.chunk}.", "",
        f"Commands (run by `mushrooms study --simulate {injections} --population {recipe} --seed {seed} "
        f"--chunk {pop.chunk}`):", "", "```",
        f"bayestar-sample-model-psd -o psds.xml {psd_cmd}",
        f"bayestar-inject -l error --seed {seed} --distribution-samples intrinsic_samples.ecsv "
        f"--reference-psd psds.xml --waveform {pop.waveform} --snr-threshold 4 --min-triggers 1 "
        f"--nsamples {injections} -j 1 -o injections.xml",
        f"# chunk k = injections [{pop.chunk}k, {pop.chunk}(k+1)):", *_realise_command(pop, seed),
        f"bayestar-localize-coincs events-k.xml.gz --coinc-event-id ID {' '.join(loc.arguments())}", "```", "",
        f"`intrinsic_samples.ecsv`: {pop.intrinsic_samples} draws (numpy default_rng({seed})) of the PDB model "
        f"(`mass_models.sample_pdb_binaries`, hyperparameters {FARAH_PDB}).",
    ]
    if recipe == "o4-real":
        lines += o4_real_notes(events_files)
        lines += ["", "Shared with recipe `o4` (masses, spins, waveform, seeds, injection cut): where that differs "
                  "from Kiendrebeogo et al. 2023 (its first item's ranges are replaced by the ones above, and the "
                  "duty cycle and SNR cut by the epochs and the threshold):"]
    else:
        lines += [f"Noise curves: BNS ranges {O4_RANGES_MPC} Mpc (`recipes.bns_range_mpc`).", "",
                  "Where this differs from Kiendrebeogo et al. 2023 (lpsinger/observing-scenarios-simulations "
                  "06d4e93):"]
    lines += [*[f"- {d}" for d in O4_DEVIATIONS], "",
              f"Realised so far (the cache's leading chunks, made here or taken from the committed ones): "
              f"{len(events_files)} chunks ({n_real} injections), {len(events)} coincidences "
              f"({', '.join(f'{k} {v}' for k, v in sorted(classes.items()))}); planned: {len(planned)} events "
              f"({', '.join(f'{k} {v}' for k, v in sorted(planned_classes.items()))}).", "",
              *cpu_table(costs, events_files, n_real, recipe), "", *code]
    return "\n".join(lines) + "\n"


def cpu_table(costs: dict, events_files: list[Path], n_real: int, recipe: str) -> list[str]:
    """The CPU cost per event and stage, and what a full population would cost."""
    lines = ["CPU cost per event and stage (CPU-s, rusage; this machine, 2 cores shared by several sessions, "
             "nice 19): realisation (per injection) and localisation are the tools' CPU time, each plan row its "
             "task's (the worker process and the tools it waited for, gwemopt's interpreter included):", "",
             "| stage | n | median | mean |", "|---|---|---|---|"]
    for k, xs in costs.items():
        lines.append(f"| {k} | {len(xs)} | {_median(xs)} | {sum(xs) / len(xs):.3g} |" if xs else f"| {k} | 0 | - | - |")
    n_coinc = sum(len(population_events([f])) for f in events_files) or 1
    return lines + ["", projection(costs, n_real / n_coinc, deterministic=recipe == "o4-real")]


#: CPU-s of ``bayestar-sample-model-psd`` and ``bayestar-inject`` (``--nsamples 15000``, 1000 intrinsic samples,
#: ``-j 1``) measured on 2026-12-05 (rusage of the tools).
INJECT_CPU_S_2026_12_05 = 144.0
#: CPU-s per injection of ``bayestar-realize-coincs`` measured on 2026-12-04 (1350 injections), used when a run
#: realised no chunk itself (its chunks came from the committed ones).
REALISE_PER_INJECTION_2026_12_04 = 0.588


def projection(costs: dict[str, list[float]], injections_per_detection: float, events: int = 1199,
               deterministic: bool = False) -> str:
    """What ``events`` events cost: the mean CPU-s per event of every stage (realising the injections behind one
    detection, localising it, each row's plan), their sum, and the wall time on N single-thread workers."""
    mean = {k: sum(v) / len(v) for k, v in costs.items() if v}
    per_inj = mean.get("realise_per_injection")
    source = "this run" if per_inj is not None else "2026-12-04's run"
    per_inj = REALISE_PER_INJECTION_2026_12_04 if per_inj is None else per_inj
    parts = {"realise": per_inj * injections_per_detection, **{k: v for k, v in mean.items()
                                                              if k != "realise_per_injection"}}
    total = sum(parts.values())
    hours = events * total / 3600.0
    return (f"Per event (means, CPU-s): " + ", ".join(f"{k} {v:.1f}" for k, v in parts.items())
            + f" (realisation: {per_inj:.3f} CPU-s per injection ({source}) x {injections_per_detection:.1f} "
            f"injections per detection); total {total:.0f} CPU-s. {events} events: {hours:.0f} CPU-hours, i.e. "
            + ", ".join(f"{hours / n:.1f} h on {n} worker{'s' if n > 1 else ''}" for n in (1, 2, 8, 32, 128))
            + f" (plus bayestar-inject once, serial: {INJECT_CPU_S_2026_12_05:.0f} CPU-s measured on 2026-12-05 for "
            "15,000 injections from 1000 intrinsic samples). gwemopt's runs have a long tail (its rows that "
            "timed out or were killed are not in the means); "
            + ("the service rows' optimisation has a deterministic (work) budget (`[scheduler] deterministic = "
               "true`), so its plans, not its CPU-s, are the same under any load." if deterministic else
               "the service row's optimisation has a wall-clock budget (`time_limit_s`), so on a loaded machine "
               "it gets fewer CPU-s than on a free core, where it would use up to that budget more."))


#: (finished before, which code planned a row): the run's stages, in order.  The second session ran the study
#: from the main checkout while merges moved it (the service row's LNS and block-stage budgets changed there);
#: the rest from fixed snapshots.
CODE_PERIODS = (("2026-12-06T01:34", "snapshots 50ed030 / ddf8b45 (2026-12-05)"),
                ("2026-12-06T04:25", "the main checkout, 0f793b0 to 70a04bc (2026-12-06 01:34-04:21 UTC)"),
                ("9999", "snapshot 975aa11 (= 70a04bc's code; 2026-12-06 04:28-05:55 UTC)"))


def software(root: Path) -> list[str]:
    """Where the code that made the results came from (``ROOT/code-<commit>``: the snapshot the run used) and the
    versions its workers recorded."""
    codes = sorted(p.name.removeprefix("code-") for p in root.glob("code-*"))
    versions: dict[str, set[str]] = {}
    by_period = {label: 0 for _, label in CODE_PERIODS}
    for rec in ResultStore(root / "study" / "results.jsonl").records().values():
        for name, v in (rec.get("versions") or {}).items():
            versions.setdefault(name, set()).add(str(v))
        finished = str(rec.get("finished") or "")
        by_period[next((label for until, label in CODE_PERIODS if finished < until), CODE_PERIODS[-1][1])] += 1
    return [f"Code: the commits {', '.join(codes) or '(unknown)'}, each run from a snapshot in ROOT/code-<commit> "
            "(50ed030 and ddf8b45: branch `population` on main 0f793b0; later commits: main's); package versions on the "
            "workers: " + ", ".join(f"{k} {'/'.join(sorted(v))}" for k, v in sorted(versions.items()))
            + " (`mushrooms` is the editable install's version, not the snapshot's). (event, solver) rows by the code "
            "that planned them: " + "; ".join(f"{label}: {n}" for label, n in by_period.items()) + "."]


def release_code(records: list[dict]) -> list[str]:
    """The commits that planned the rows (a warning when more than one), and the versions the workers recorded."""
    versions: dict[str, set[str]] = {}
    for rec in records:
        for name, v in (rec.get("versions") or {}).items():
            versions.setdefault(name, set()).add(str(v))
    commits = commits_of([{"commit": rec.get("commit") or (rec.get("row") or {}).get("commit")} for rec in records])
    configs = commits_of([{"commit": rec.get("config_hash")} for rec in records])
    head = (f"**WARNING: the rows come from {len(commits)} commits; this is not one frozen release.** "
            if len(commits) > 1 else "")
    head += (f"**WARNING: the rows come from {len(configs)} configurations.** " if len(configs) > 1 else "")
    return [head + "Code: (map, row) results by the commit that planned them (`commit` of each record, "
            "`mushrooms.evaluation.commit.code_commit`): " + "; ".join(f"`{c}` {n}" for c, n in sorted(commits.items()))
            + "; by the hash of their configuration (`study/config.toml`, part of every key): "
            + "; ".join(f"`{c}` {n}" for c, n in sorted(configs.items())) + ". Package versions on the workers: "
            + ", ".join(f"{k} {'/'.join(sorted(v))}" for k, v in sorted(versions.items()))
            + " (gwemopt runs in its own interpreter, `MUSHROOMS_GWEMOPT_PYTHON`, whose version the workers do not "
            "see: `-` here)."]


def detect_recipe(root: Path, injections: int, seed: int) -> str:
    """The recipe whose population ROOT's cache holds (``o4-real`` when none or several do)."""
    found = [name for name in LAYOUT
             if (root / "cache" / "populations" / recipe_population(name, injections, seed=seed)[0].key()).is_dir()]
    return found[0] if len(found) == 1 else "o4-real"


def leading_chunks(pop_dir: Path, chunk: int) -> list[Path]:
    """The cache's realised chunks 0, 1, ... up to the first one missing."""
    files = sorted((pop_dir / f"realized-{chunk}").glob("events-*.xml.gz"))
    return [f for k, f in enumerate(files) if f.name == f"events-{k:04d}.xml.gz"]


def commit_population(out: Path, pop, pop_dir: Path, files: list[Path]) -> None:
    """OUT/population/: what population_o4.sh seeds the population cache with."""
    keep = out / "population"
    (keep / "chunks").mkdir(parents=True, exist_ok=True)
    for name in ("population.json", "psds.xml", "intrinsic_samples.ecsv"):
        shutil.copy2(pop_dir / name, keep / name)
    (keep / "population.key").write_text(pop.key() + "\n")
    if (pop_dir / "injections.xml").exists():  # (made only once a chunk had to be realised)
        _gzip(pop_dir / "injections.xml", keep / "injections.xml.gz")
    for f in files:
        shutil.copy2(f, keep / "chunks" / f.name)


def commit_study(root: Path, study: Path) -> None:
    """``study``: ROOT's configuration and result records (``store.export_records``), and its logs."""
    study.mkdir(parents=True, exist_ok=True)
    if (root / "config.toml").exists():
        shutil.copy2(root / "config.toml", study / "config.toml")
    export_records(root / "study" / "results.jsonl", study / "results.jsonl.gz")
    for name in ("realizations.jsonl", "localisations.jsonl"):
        if (root / "study" / name).exists():
            shutil.copy2(root / "study" / name, study / name)


#: Our rows' executed curves (``population_o4_replan.py`` then ``population_o4_curves.py``), under OUT/study/: with
#: them release_tables.md has the matched-time section.
CURVES = "executed_curves.jsonl.gz"

#: At the top of the release's tables.md: which file holds the release's tables.
LEGACY_NOTE = ("The release's tables (issue 55) are in `release_tables.md`. This file is the earlier studies' layout, "
               "kept for continuity: its baselines are greedy, gwemopt and gwemopt-repaired, so the gwemopt-o4, "
               "gwemopt-skyportal and service-grg rows appear here as if they were ours, and LUMOS's metric needs a "
               "row named gwemopt, which the release does not have.\n\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--population", choices=sorted(LAYOUT), help="the run's recipe (default: ROOT's)")
    ap.add_argument("--root", type=Path, help="the run's ROOT (default: /work/population_o4_real, or the recipe's)")
    ap.add_argument("--out", type=Path, help="default: the recipe's folder under benchmarks/results/science/")
    ap.add_argument("--injections", type=int, default=15000)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--tables-only", action="store_true", help="rebuild the tables from OUT/results.csv alone")
    args = ap.parse_args()
    recipe = args.population or (detect_recipe(args.root, args.injections, args.seed) if args.root else "o4-real")
    folder, default_root, prefix = LAYOUT[recipe]
    root = args.root or default_root
    out = args.out or HERE.parent / "results" / "science" / folder
    if not args.tables_only:
        pop, _ = recipe_population(recipe, args.injections, seed=args.seed)
        pop_dir = root / "cache" / "populations" / pop.key()
        files = leading_chunks(pop_dir, pop.chunk)
        events = population_events(files, prefix=prefix)
        records = list(ResultStore(root / "study" / "results.jsonl").records().values())
        rows = population_rows(records, events)
        write_population_csv(rows, out / "results.csv")
        commit_population(out, pop, pop_dir, files)
        commit_study(root, out / "study")
        costs = cpu_costs(root / "study", _jsonl(root / "study" / "realizations.jsonl"))
        code = software(root) if recipe == "o4" else release_code(records)
        (out / "provenance.md").write_text(
            provenance(recipe, pop_dir, files, events, rows, costs, args.injections, args.seed, code))
    rows = read_population_csv(out / "results.csv")
    release = recipe == "o4-real"
    (out / "tables.md").write_text((LEGACY_NOTE if release else "") + population_tables(rows) + "\n")
    curves, failed = read_curves(out / "study" / CURVES) if (out / "study" / CURVES).exists() else (None, ())
    (out / "release_tables.md").write_text(release_tables(rows, expected=RELEASE_ROWS if release else None,
                                                          curves=curves, failed=failed))
    figures = population_figures(rows, out / "figures", **({"baselines": RELEASE_ROWS[1:], "planned": "coverage_pairs"} if release else {}))
    print(f"{len(rows)} rows -> {out}; figures: {', '.join(str(f) for f in figures)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
