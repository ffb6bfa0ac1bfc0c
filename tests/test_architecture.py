"""The package's shape, read from its source with ast: no import cycle, and data flows one way.

Layers: ``daemon -> handlers -> scheduler_core``; ``mushrooms.evaluation``
(benchmark, efficiency, baselines) sits beside them and only imports the
scheduler.  Every import counts, at module level or inside a function
(a lazy import is still a dependency), and relative imports are resolved.

Configuration only at the top: the config loader
(:mod:`mushrooms.tool.config`) and ``argparse`` belong to the command layer
(``mushrooms.tool``, ``mushrooms.cli``); the layers below are handed plain
objects.  For ``argparse`` the scan also reads imports from outside the
package (:func:`outside_imports`).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "mushrooms"

#: (importer prefix, imported prefix): imports that must not exist.
FORBIDDEN = (
    ("mushrooms.scheduler_core", "mushrooms.evaluation"),
    ("mushrooms.handlers", "mushrooms.evaluation"),
    ("mushrooms.daemon", "mushrooms.evaluation"),
    ("mushrooms.scheduler_core", "mushrooms.handlers"),
    ("mushrooms.scheduler_core", "mushrooms.daemon"),
    ("mushrooms.handlers", "mushrooms.daemon"),
    # the daemon is below the command layer: it never reaches up into the tools
    ("mushrooms.daemon", "mushrooms.tool"),
    ("mushrooms.daemon", "mushrooms.cli"),
    ("mushrooms.scheduler_core", "mushrooms.tool"),
    ("mushrooms.handlers", "mushrooms.tool"),
    # evaluation is a library the tools call (run_bench, run_study): it never reaches up into them
    ("mushrooms.evaluation", "mushrooms.tool"),
    ("mushrooms.evaluation", "mushrooms.cli"),
    ("mushrooms.evaluation", "mushrooms.daemon"),
)


#: The config loader.
CONFIG_MODULES = ("mushrooms.tool.config",)
#: Only these import the config loader (or ``argparse``).
COMMAND_LAYER = ("mushrooms.tool", "mushrooms.cli")


def module_files(package_dir: Path) -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package ``__init__``) for every .py under ``package_dir``."""
    root = package_dir.parent
    out: dict[str, tuple[Path, bool]] = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_pkg)
    return out


def import_graph(package_dir: Path) -> dict[str, set[str]]:
    """Module -> the package's own modules it imports (any depth in the file, relative ones resolved).

    ``from pkg import name`` is an edge to ``pkg.name`` when that is a module,
    else to ``pkg`` (its ``__init__``).  Imports outside the package are left out.
    """
    modules = module_files(package_dir)
    top = package_dir.name
    graph: dict[str, set[str]] = {}
    for name, (path, is_pkg) in modules.items():
        here = name.split(".") if is_pkg else name.split(".")[:-1]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    # "import a.b.c" imports a, a.b and a.b.c: the deepest that is ours is the edge
                    for k in range(len(parts), 0, -1):
                        if ".".join(parts[:k]) in modules:
                            targets.add(".".join(parts[:k]))
                            break
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[:len(here) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                if module.split(".")[0] != top:
                    continue
                for alias in node.names:
                    sub = f"{module}.{alias.name}"
                    targets.add(sub if sub in modules else module)
        graph[name] = {t for t in targets if t in modules and t != name}
    return graph


def outside_imports(package_dir: Path) -> dict[str, set[str]]:
    """Module -> top-level names of what it imports from outside the package (standard library, third party).

    Any depth in the file counts (a function-level import too); ``import a.b``
    and ``from a.b import c`` are ``a``.  Relative imports are the package's
    own and are left out, as are imports of the package by its absolute name.
    """
    modules = module_files(package_dir)
    top = package_dir.name
    out: dict[str, set[str]] = {}
    for name, (path, _) in modules.items():
        names: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names.add(node.module.split(".")[0])
        out[name] = {n for n in names if n != top}
    return out


#: The public underscore API of :func:`collections.namedtuple` (not a private reach-in).
NAMEDTUPLE_API = frozenset({"_replace", "_asdict", "_fields", "_make", "_field_defaults"})


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _defined_here(tree: ast.AST) -> set[str]:
    """Names a module defines itself: functions, classes, assigned names and attributes (``self._x = ...``)."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
    return names


def private_reach_ins(package_dir: Path) -> list[str]:
    """Every private name (``_x``, not a dunder) one module of the package takes from another.

    Three forms: ``from .other import _x``; ``other._x`` on a module the file
    imported; and ``obj._x`` (``self.store._x`` too) where the module does not
    define ``_x`` itself, i.e. a reach into another module's object.  Names on
    what comes from outside the package (``os._exit``, a library's constants)
    and the namedtuple API (``_replace``...) are not counted.
    """
    modules = module_files(package_dir)
    top = package_dir.name
    out: list[str] = []
    for name, (path, is_pkg) in modules.items():
        here = name.split(".") if is_pkg else name.split(".")[:-1]
        tree = ast.parse(path.read_text(), filename=str(path))
        own_modules: set[str] = set()   # local names bound to one of the package's modules
        outside: set[str] = set()       # local names bound to something from outside the package
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[:len(here) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                for alias in node.names:
                    local = alias.asname or alias.name
                    if module.split(".")[0] != top:
                        outside.add(local)
                        continue
                    if _private(alias.name):
                        out.append(f"{name}: from {module} import {alias.name}")
                    if f"{module}.{alias.name}" in modules:
                        own_modules.add(local)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    local = alias.asname or alias.name.split(".")[0]
                    (own_modules if alias.name.split(".")[0] == top else outside).add(local)
        defined = _defined_here(tree) - own_modules - outside
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and _private(node.attr)) or node.attr in NAMEDTUPLE_API:
                continue
            root, depth = node.value, 1
            while isinstance(root, ast.Attribute):
                root, depth = root.value, depth + 1
            if isinstance(root, ast.Call):
                root_name = ""  # super()._x, make()._x: judged by the name alone
            elif isinstance(root, ast.Name):
                root_name = root.id
            else:
                root_name = ""
            if root_name in outside:
                continue
            if root_name in own_modules and depth == 1:
                out.append(f"{name}: {root_name}.{node.attr} (module {root_name})")
            elif node.attr not in defined and not (root_name in ("self", "cls") and depth == 1):
                out.append(f"{name}: {ast.unparse(node)}")
    return sorted(set(out))


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:  # recursion depth is bounded by the package's size
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(cycles)


def _within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def layering_violations(graph: dict[str, set[str]], forbidden=FORBIDDEN) -> list[str]:
    """``importer -> imported`` lines for every edge a (from, to) rule forbids."""
    return sorted(f"{a} -> {b}" for a, targets in graph.items() for b in targets
                  for src, dst in forbidden if _within(a, src) and _within(b, dst))


# ---------------------------------------------------------------- the real package
@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(PACKAGE_DIR)


def test_the_graph_sees_the_package(graph):
    # a sanity check that the scan reads what it should: known edges, lazy ones included
    assert "mushrooms.scheduler_core.planner" in graph
    assert "mushrooms.scheduler_core.problem" in graph["mushrooms.scheduler_core.planner"]
    assert "mushrooms.evaluation.efficiency" in graph["mushrooms.evaluation.bench.scoring"]  # a function-level import
    assert len(graph) > 50


def test_no_import_cycle(graph):
    assert import_cycles(graph) == []


def test_no_module_uses_another_modules_private_names():
    # a private name is the module's own business: what another module needs is public API
    assert private_reach_ins(PACKAGE_DIR) == []


def test_data_flows_one_way(graph):
    assert layering_violations(graph) == []


DAEMON = "mushrooms.daemon"


def room_graph(graph: dict[str, set[str]], package: str = DAEMON,
               groups: dict[str, str] | None = None) -> dict[str, set[str]]:
    """The imports between a package's rooms: its subpackages, and its top-level modules as ``groups`` name them.

    ``groups`` maps a top-level module's name (``"planner"``) to its room
    (``"planning"``); without it the top-level modules are left out (the
    daemon's).  Imports inside a room and of the package's ``__init__`` are
    not edges.
    """
    groups = groups or {}

    def room(module: str) -> str | None:
        parts = module[len(package) + 1:].split(".") if _within(module, package) and module != package else []
        if len(parts) > 1:  # a module inside a subpackage
            return parts[0]
        return groups.get(parts[0]) if parts else None
    rooms: dict[str, set[str]] = {}
    for a, targets in graph.items():
        ra = room(a)
        if ra is None:
            continue
        rooms.setdefault(ra, set()).update(rb for b in targets if (rb := room(b)) not in (None, ra))
    return rooms


def top_level_modules(graph: dict[str, set[str]], package: str) -> set[str]:
    """The names of a package's own modules that sit directly in it (not in a subpackage, not a subpackage)."""
    packages = {m.rsplit(".", 1)[0] for m in graph if _within(m, package) and m != package}
    return {m[len(package) + 1:] for m in graph if _within(m, package) and m != package
            and "." not in m[len(package) + 1:] and m not in packages}


def test_the_daemons_rooms_form_a_stack(graph):
    # a room may use the rooms below it, never one that uses it back: no loop between rooms
    rooms = room_graph(graph)
    assert {"intake", "planning", "loop", "state", "submission"} <= set(rooms)
    assert import_cycles(rooms) == []


def test_room_scan_names_a_loop_between_two_rooms():
    looped = {"mushrooms.daemon.a.x": {"mushrooms.daemon.b.y"}, "mushrooms.daemon.b.y": set(),
              "mushrooms.daemon.b.z": {"mushrooms.daemon.a.w", "mushrooms.daemon.top"}}
    assert import_cycles(room_graph(looped)) == [["a", "b"]]


LIBRARY = "mushrooms.scheduler_core"
#: The library's top-level modules, grouped as rooms (its subpackages are rooms of their own).
LIBRARY_GROUPS = {
    # leaves: errors, the parsers of tables, ranges and times, the cache folder, lazy names, the work clock
    **dict.fromkeys(("errors", "tables", "ranges", "times", "cachedir", "lazy", "budget"), "base"),
    # [scheduler] and the names it checks against (scheduler names, light-curve names)
    **dict.fromkeys(("config", "config_checks", "solvers_registry", "lightcurve_names"), "settings"),
    # what the telescope did: executed exposures and the filter-sequence rules read from them
    **dict.fromkeys(("executed", "sequences"), "records"),
    # the planning problem, a scheduler's result, and which of two results is preferred
    **dict.fromkeys(("problem", "preference"), "problem"),
    # sky map in, checked plan out: prepare, run the schedulers, re-plan, the nights, the anytime revisions
    **dict.fromkeys(("planner", "prepare", "replan", "nights", "anytime", "clock", "joint_plans", "joint_parts"),
                    "planning"),
}
SCHEDULERS = "mushrooms.scheduler_core.schedulers"
#: The top-level modules of ``schedulers``: what every method or the planner shares.
SCHEDULER_GROUPS = dict.fromkeys(("gain", "as_executed", "completions"), "shared")


def test_every_top_level_module_of_the_library_has_a_room(graph):
    # a new module joins a room (and so the stack below) instead of slipping past the room test
    assert sorted(top_level_modules(graph, LIBRARY) - set(LIBRARY_GROUPS)) == []
    assert sorted(top_level_modules(graph, SCHEDULERS) - set(SCHEDULER_GROUPS)) == []
    assert sorted(set(LIBRARY_GROUPS) - top_level_modules(graph, LIBRARY)) == []  # no stale name either


def test_the_librarys_rooms_form_a_stack(graph):
    # base < settings, instruments < sky < records < telescope < plan < source < problem < schedulers < planning:
    # a room may use the rooms below it, never one that uses it back
    rooms = room_graph(graph, LIBRARY, LIBRARY_GROUPS)
    assert {"base", "settings", "instruments", "sky", "records", "telescope", "plan", "source", "problem",
            "schedulers", "planning"} == set(rooms)
    assert import_cycles(rooms) == []
    # the two that ran back up before the rooms: the telescope model under the schedulers, the sky under the plan
    assert "schedulers" not in rooms["telescope"] and "plan" not in rooms["sky"] | rooms["settings"]


def test_the_schedulers_methods_form_a_stack(graph):
    # one room per method of docs/design/milp.md, the MILP adapter at the bottom, the portfolio on top
    # (and the joint plan of several telescopes, docs/design/telescopes.md section 5, above it)
    rooms = room_graph(graph, SCHEDULERS, SCHEDULER_GROUPS)
    assert {"milp", "greedy", "blocks", "slots", "bounds", "detection", "portfolio", "shared", "joint"} == set(rooms)
    assert import_cycles(rooms) == []
    assert rooms["milp"] == set()  # the adapter knows no method
    assert all("joint" not in used for used in rooms.values())  # no single-telescope method uses the joint plan


def test_room_scan_groups_top_level_modules_into_rooms():
    lib = {"pkg.sub.x": {"pkg.top"}, "pkg.top": {"pkg.low"}, "pkg.low": {"pkg.sub.y"}, "pkg.sub.y": set()}
    assert room_graph(lib, "pkg") == {"sub": set()}  # without groups the top-level modules are not rooms
    rooms = room_graph(lib, "pkg", {"top": "up", "low": "down"})
    assert rooms == {"sub": {"up"}, "up": {"down"}, "down": {"sub"}}
    assert import_cycles(rooms) == [["down", "sub", "up"]]
    assert import_cycles(room_graph(lib, "pkg", {"top": "up", "low": "up"})) == [["sub", "up"]]
    assert top_level_modules({"pkg.a": set(), "pkg.sub": set(), "pkg.sub.b": set()}, "pkg") == {"a"}


def test_scheduler_core_is_a_library_on_its_own(graph):
    # a notebook can use it without the service, the tools or the file-level config of the package
    outside = sorted(f"{a} -> {b}" for a, targets in graph.items() if _within(a, "mushrooms.scheduler_core")
                     for b in targets if not _within(b, "mushrooms.scheduler_core"))
    assert outside == []


def _in_command_layer(module: str) -> bool:
    return any(_within(module, prefix) for prefix in COMMAND_LAYER)


def config_importers(graph: dict[str, set[str]]) -> set[str]:
    """Modules outside the command layer that import the config loader."""
    return {a for a, targets in graph.items() if not _in_command_layer(a)
            for b in targets if b in CONFIG_MODULES}


def test_only_the_command_layer_imports_the_config(graph):
    # every layer below gets its sections handed in (Service(config, paths), run_trigger, replay_notices,
    # run_bench(settings, maps), run_study(settings, inputs)): no exception
    assert sorted(config_importers(graph)) == []
    # the config loader lives in the command layer only: no re-export of it elsewhere (the old mushrooms.config)
    assert "mushrooms.config" not in graph
    assert sorted(m for m in graph if m.rsplit(".", 1)[-1] == "config" and not _in_command_layer(m)
                  and not _within(m, "mushrooms.scheduler_core")) == []


def test_only_the_command_layer_imports_argparse():
    outside = outside_imports(PACKAGE_DIR)
    assert "argparse" in outside["mushrooms.cli"]  # the scan sees the standard library
    assert sorted(m for m, names in outside.items() if "argparse" in names and not _in_command_layer(m)) == []


def test_handlers_use_only_the_scheduler(graph):
    outside = sorted(f"{a} -> {b}" for a, targets in graph.items() if _within(a, "mushrooms.handlers")
                     for b in targets if not (_within(b, "mushrooms.handlers") or _within(b, "mushrooms.scheduler_core")))
    assert outside == []


# ---------------------------------------------------------------- the scan itself, on a tiny package
def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = tmp_path / "pkg" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return tmp_path / "pkg"


def test_scan_finds_a_cycle_through_a_lazy_relative_import(tmp_path):
    pkg = _package(tmp_path, {
        "__init__.py": "",
        "a.py": "from .sub.b import f\n",
        "sub/__init__.py": "",
        "sub/b.py": "def f():\n    from ..c import g\n    return g\n",
        "c.py": "import pkg.a\n",
        "d.py": "from pkg.sub import b\nimport json\n",
    })
    graph = import_graph(pkg)
    assert graph["pkg.a"] == {"pkg.sub.b"}
    assert graph["pkg.sub.b"] == {"pkg.c"}
    assert graph["pkg.d"] == {"pkg.sub.b"}
    assert import_cycles(graph) == [["pkg.a", "pkg.c", "pkg.sub.b"]]


def test_scan_passes_an_acyclic_package_and_names_a_forbidden_edge(tmp_path):
    pkg = _package(tmp_path, {
        "__init__.py": "",
        "scheduler_core/__init__.py": "from .x import y\n",
        "scheduler_core/x.py": "y = 1\n",
        "evaluation/__init__.py": "",
        "evaluation/bench.py": "from ..scheduler_core import x\n",
    })
    graph = import_graph(pkg)
    assert import_cycles(graph) == []
    rules = (("pkg.scheduler_core", "pkg.evaluation"),)
    assert layering_violations(graph, rules) == []
    (pkg / "scheduler_core" / "x.py").write_text("def late():\n    from ..evaluation import bench\n")
    graph = import_graph(pkg)
    assert layering_violations(graph, rules) == ["pkg.scheduler_core.x -> pkg.evaluation.bench"]
    assert import_cycles(graph) == [["pkg.evaluation.bench", "pkg.scheduler_core.x"]]


def test_scan_sees_imports_from_outside_the_package_at_any_depth(tmp_path):
    pkg = _package(tmp_path, {
        "__init__.py": "",
        "a.py": "import argparse\nimport os.path as osp\nfrom . import b\n",
        "b.py": "def f():\n    from json import loads\n    import pkg.a\n    from .a import osp\n    return loads\n",
        "c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import argparse\n",
    })
    outside = outside_imports(pkg)
    assert outside["pkg.a"] == {"argparse", "os"}
    assert outside["pkg.b"] == {"json"}  # the package's own imports, relative or absolute, are left out
    assert outside["pkg"] == set()
    assert outside["pkg.c"] == {"typing", "argparse"}  # a type-checking import still counts


def test_config_rule_names_an_importer_below_the_command_layer(tmp_path):
    pkg = _package(tmp_path, {
        "__init__.py": "",
        "tool/__init__.py": "",
        "tool/config.py": "X = 1\n",
        "tool/run.py": "from .config import X\n",
        "daemon/__init__.py": "",
        "daemon/service.py": "def f():\n    from ..tool import config\n",
    })
    graph = {a.replace("pkg.", "mushrooms.", 1): {b.replace("pkg.", "mushrooms.", 1) for b in t}
             for a, t in import_graph(pkg).items()}
    assert config_importers(graph) == {"mushrooms.daemon.service"}


def test_private_scan_names_every_kind_of_reach_in_and_spares_a_module_its_own(tmp_path):
    pkg = _package(tmp_path, {
        "__init__.py": "",
        "rows.py": "_TABLE = 1\n\ndef _row():\n    return _TABLE\n\nclass Rows:\n    def _put(self):\n"
                   "        return self._put\n",
        "user.py": ("import os\nfrom . import rows\nfrom .rows import _row, Rows\n\n"
                    "def f(r: Rows, other):\n    os._exit\n    rows._TABLE\n    r._put()\n"
                    "    other.p._replace(a=1)\n    return _row()\n"),
        "own.py": ("class Box:\n    def __init__(self):\n        self._size = 1\n\n"
                   "    def same(self, other: 'Box'):\n        return other._size == self._size\n\n"
                   "def size(box: Box):\n    return box._size\n"),
    })
    assert private_reach_ins(pkg) == [
        "pkg.user: from pkg.rows import _row",
        "pkg.user: r._put",
        "pkg.user: rows._TABLE (module rows)",
    ]
