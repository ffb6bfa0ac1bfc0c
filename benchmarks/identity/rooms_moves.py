"""Issue 54's module moves, for a branch written before them: find and fix the old module paths.

``--check`` lists every import of ``mushrooms.*`` (relative ones resolved,
at any depth) that names no module of the tree; ``--fix FILE...`` rewrites
the old dotted names and paths (``schedulers.slot_schedule``,
``schedulers/slots.py``, ``telescope.coverage``...) in the files given to
the new ones.  Give ``--fix`` only files written before the moves: a new
package path equal to an old module name (``schedulers.portfolio`` the
package, ``schedulers.portfolio`` the old module) is read as the old one.
Relative imports (``from ..schedulers.lns import``) are listed by
``--check`` and fixed by hand.

    python benchmarks/identity/rooms_moves.py --check
    python benchmarks/identity/rooms_moves.py --fix tests/scheduler/test_x.py
"""

from __future__ import annotations

import argparse
import ast
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: old module -> new module, relative to mushrooms.scheduler_core
MOVES = {
    "schedulers.greedy": "schedulers.greedy.schedule",
    "schedulers.blocks": "schedulers.blocks.model",
    "schedulers.block_schedule": "schedulers.blocks.schedule",
    "schedulers.prune": "schedulers.blocks.prune",
    "schedulers.ordering": "schedulers.blocks.ordering",
    "schedulers.slots": "schedulers.slots.model",
    "schedulers.slot_grid": "schedulers.slots.grid",
    "schedulers.slot_schedule": "schedulers.slots.schedule",
    "schedulers.exposure_menu": "schedulers.slots.exposure_menu",
    "schedulers.detection_model": "schedulers.detection.model",
    "schedulers.detection_ceiling": "schedulers.detection.ceiling",
    "schedulers.detection_slots": "schedulers.detection.stage",
    "schedulers.bound": "schedulers.bounds.coverage_bound",
    "schedulers.interval_bound": "schedulers.bounds.interval_bound",
    "schedulers.certified_bound": "schedulers.bounds.certified_bound",
    "schedulers.outer_windows": "schedulers.bounds.outer_windows",
    "schedulers.portfolio": "schedulers.portfolio.portfolio",
    "schedulers.lns": "schedulers.portfolio.lns",
    "schedulers.continuous": "schedulers.portfolio.continuous",
    "schedulers.solvers": "schedulers.milp.solvers",
    "schedulers.lp_file": "schedulers.milp.lp_file",
    "schedulers.rows": "schedulers.milp.rows",
    "schedulers.slew": "telescope.slew",
    "telescope.coverage": "schedulers.as_executed",
    "source.named": "lightcurve_names",
}
NEW = set(MOVES.values())
DOT = re.compile(r"(?<![\w.])((?:mushrooms\.)?(?:scheduler_core\.)?)((?:schedulers|telescope|source)(?:\.\w+)+)")
PATH = re.compile(r"(?<![\w/])((?:mushrooms/)?(?:scheduler_core/)?)((?:schedulers|telescope|source)(?:/\w+)+)\.py\b")


def mapped(name: str) -> str:
    """The new name of a dotted name relative to scheduler_core (unchanged when it is new or did not move)."""
    if any(name == v or name.startswith(v + ".") for v in NEW):
        return name
    for old in sorted(MOVES, key=len, reverse=True):
        if name == old or name.startswith(old + "."):
            return MOVES[old] + name[len(old):]
    return name


def fix(text: str) -> str:
    text = PATH.sub(lambda m: m.group(1) + mapped(m.group(2).replace("/", ".")).replace(".", "/") + ".py", text)
    return DOT.sub(lambda m: m.group(1) + mapped(m.group(2)), text)


def broken_imports(root: Path = REPO) -> list[str]:
    """``file:line: no module X`` for every import of the package naming no module of the tree."""
    def exists(mod: str) -> bool:
        p = root / mod.replace(".", "/")
        return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()
    out = []
    for top in ("mushrooms", "tests", "benchmarks"):
        for f in sorted((root / top).rglob("*.py")):
            if "results" in f.parts:
                continue
            parts = list(f.relative_to(root).with_suffix("").parts)
            base = parts[:-1]
            for n in ast.walk(ast.parse(f.read_text())):
                mods = []
                if isinstance(n, ast.ImportFrom):
                    if n.level and parts[0] == "mushrooms":
                        b = base[:len(base) - (n.level - 1)]
                        mods = [".".join(b + ([n.module] if n.module else []))]
                    elif not n.level:
                        mods = [n.module or ""]
                elif isinstance(n, ast.Import):
                    mods = [a.name for a in n.names]
                out += [f"{f.relative_to(root)}:{n.lineno}: no module {m}" for m in mods
                        if m.startswith("mushrooms") and not exists(m)]
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--check", action="store_true")
    p.add_argument("--fix", nargs="*", default=[])
    args = p.parse_args(argv)
    for name in args.fix:
        f = Path(name)
        text = f.read_text()
        if fix(text) != text:
            f.write_text(fix(text))
            print(f"fixed {f}")
    if args.check:
        bad = broken_imports()
        print("\n".join(bad + [f"{len(bad)} imports name no module"]))
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
