"""Mutation-testing benchmark (mutmut 3) of the checker, visibility, fields and slew modules.

Not part of the default test run.  It copies the package and the tests into a
scratch directory, writes a ``[tool.mutmut]`` section there (so the project's
own pyproject.toml stays clean), runs mutmut over the chosen modules with a
fast, targeted test selection, and prints the score per module and every
surviving mutant.

Usage (from the repository root; run it niced on a shared machine)::

    nice -n 10 .venv/bin/python benchmarks/attacks/mutation.py [--modules checker,slew,...] [--jobs 2] [--keep DIR]
        [--functions check_plan,mount_reachable] [--sample N --seed S] [--root DIR]

Each module is exercised only by the tests that are about it:

========== ==========================================================
module     tests
========== ==========================================================
checker    tests/scheduler/test_checker.py
slew       tests/scheduler/test_slew.py
visibility tests/scheduler/test_visibility.py
fields     tests/scheduler/test_fields.py
========== ==========================================================
"""

from __future__ import annotations

import argparse
import fnmatch
import random
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = "mushrooms/scheduler_core"
TESTS = {
    "checker": ["tests/scheduler/test_checker.py"],
    "slew": ["tests/scheduler/test_slew.py"],
    "visibility": ["tests/scheduler/test_visibility.py"],
    "fields": ["tests/scheduler/test_fields.py"],
}


def _toml_list(items: list[str]) -> str:
    return "[" + ", ".join(f'"{x}"' for x in items) + "]"


def run(modules: list[str], jobs: int, keep: Path | None, root: Path = ROOT, only: list[str] | None = None,
        sample: int = 0, seed: int = 0) -> int:
    work = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="mushrooms-mutation-"))
    work.mkdir(parents=True, exist_ok=True)
    for sub in ("mushrooms", "tests"):
        if not (work / sub).exists():
            shutil.copytree(root / sub, work / sub, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    tests = sorted({t for m in modules for t in TESTS[m]})
    text = (root / "pyproject.toml").read_text()
    text += (
        "\n[tool.mutmut]\n"
        f"source_paths = {_toml_list([f'{PKG}/{m}.py' for m in modules])}\n"
        f"pytest_add_cli_args_test_selection = {_toml_list(tests)}\n"
        'pytest_add_cli_args = ["-q", "-x", "-p", "no:cacheprovider"]\n'
        'also_copy = ["mushrooms", "tests"]\n'
    )
    (work / "pyproject.toml").write_text(text)
    print(f"mutating {', '.join(modules)} in {work} with {', '.join(tests)}", flush=True)
    cmd = [sys.executable, "-m", "mutmut", "run", "--max-children", str(jobs)]
    if sample or only:
        # generate the mutants and the test map, run none, then pick the ones asked for
        subprocess.call(cmd + ["no-such-mutant"], cwd=work)
        names = [line.split(":")[0].strip() for line in _results(work).splitlines() if ":" in line]
        if only:
            names = [n for n in names if any(fnmatch.fnmatch(n, f"*.x_{f}__mutmut_*") for f in only)]
        if sample and sample < len(names):
            names = sorted(random.Random(seed).sample(names, sample))
        print(f"running {len(names)} mutants", flush=True)
        cmd += names
    code = subprocess.call(cmd, cwd=work)
    report(_results(work), work)
    return code


def _results(work: Path) -> str:
    return subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"], cwd=work,
                          capture_output=True, text=True).stdout


def report(results: str, work: Path) -> None:
    """Score per module: killed / (killed + survived); survivors listed with their diff."""
    status = Counter()
    survivors = []
    for line in results.splitlines():
        m = re.match(r"\s*(mushrooms\.scheduler_core\.(\w+)\.\S+):\s*(\w[\w ]*)$", line)
        if not m:
            continue
        name, module, state = m.group(1), m.group(2), m.group(3).strip()
        status[module, state] += 1
        if state == "survived":
            survivors.append(name)
    for module in sorted({k[0] for k in status}):
        killed, survived = status[module, "killed"], status[module, "survived"]
        other = {s: n for (mod, s), n in status.items() if mod == module and s not in ("killed", "survived")}
        score = killed / (killed + survived) if killed + survived else float("nan")
        print(f"{module:12s} killed {killed:4d}  survived {survived:4d}  score {score:6.1%}  other {other}")
    for name in survivors:
        print(f"\n--- survived: {name}")
        diff = subprocess.run([sys.executable, "-m", "mutmut", "show", name], cwd=work, capture_output=True,
                              text=True).stdout
        print(diff.strip())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--modules", default="checker,slew,visibility,fields")
    ap.add_argument("--jobs", type=int, default=2, help="parallel mutant runs (default 2)")
    ap.add_argument("--keep", type=Path, help="work directory to use and keep (default: a temporary one)")
    ap.add_argument("--functions", help="only mutants of these functions (comma-separated names or globs)")
    ap.add_argument("--sample", type=int, default=0, help="run a seeded random sample of this many mutants")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--root", type=Path, default=ROOT,
                    help="source tree to mutate (default: this one; e.g. an exported older commit)")
    args = ap.parse_args(argv)
    modules = [m.strip() for m in args.modules.split(",") if m.strip()]
    unknown = sorted(set(modules) - set(TESTS))
    if unknown:
        print(f"unknown module(s): {', '.join(unknown)}; choose from {', '.join(TESTS)}", file=sys.stderr)
        return 2
    only = [f.strip() for f in args.functions.split(",") if f.strip()] if args.functions else None
    return run(modules, args.jobs, args.keep, args.root, only, args.sample, args.seed)


if __name__ == "__main__":
    sys.exit(main())
