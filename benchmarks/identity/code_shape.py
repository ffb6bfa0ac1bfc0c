"""The package's shape for a refactor's before/after: module sizes, longest functions, import graph.

Counts are read with :mod:`ast` from the source tree given (default: the
``mushrooms`` package beside this script), so two checkouts can be compared::

    python benchmarks/identity/code_shape.py /path/to/checkout/mushrooms > shape.txt

Module lines are physical lines of the file; a function's length is
``end_lineno - lineno + 1`` of its ``def`` (decorators excluded, nested
functions counted on their own as well), and its *lines of code* are that
length less the lines of its docstring (the house limit: 80 lines of code,
500 lines a module). The import graph is the one
``tests/test_architecture.py`` checks (every import, lazy ones included),
summarised per layer (``mushrooms.<first part>``), and the room graph of
``mushrooms.scheduler_core`` and of its ``schedulers`` (the rooms that test
declares).
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import sys
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
#: The house limits: lines of code of a function (docstring aside), lines of a module.
MAX_FUNCTION_CODE = 80
MAX_MODULE_LINES = 500


def _scanner():
    spec = importlib.util.spec_from_file_location("arch", REPO / "tests" / "test_architecture.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def docstring_lines(node: ast.AST) -> int:
    """Lines of a function's docstring (0 without one)."""
    body = getattr(node, "body", [])
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        return body[0].end_lineno - body[0].lineno + 1
    return 0


def functions(path: Path, code: bool = False) -> list[tuple[int, str]]:
    """(length in lines, qualified name) of every function in a file; ``code``: lines of code (docstring aside)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out: list[tuple[int, str]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = child.end_lineno - child.lineno + 1 - (docstring_lines(child) if code else 0)
                out.append((n, f"{prefix}{child.name}"))
                visit(child, f"{prefix}{child.name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
    visit(tree, "")
    return out


def layer(module: str) -> str:
    parts = module.split(".")
    return ".".join(parts[:2]) if len(parts) > 1 else parts[0]


def stdlib_importers(package: Path, name: str) -> list[str]:
    """Modules of the package that import the top-level module ``name`` (e.g. argparse)."""
    root = package.parent
    hits = []
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import) and any(a.name.split(".")[0] == name for a in node.names):
                hits.append(path); break
            if isinstance(node, ast.ImportFrom) and not node.level and (node.module or "").split(".")[0] == name:
                hits.append(path); break
    return [str(p.relative_to(root)) for p in hits]


def _stack_order(rooms: dict[str, set[str]]) -> list[str]:
    """The rooms bottom first (a room after every room it imports; alphabetical among equals)."""
    order: list[str] = []
    left = dict(rooms)
    while left:
        ready = sorted(r for r, deps in left.items() if not (deps & set(left)))
        if not ready:  # a loop: list the rest as they are
            return order + sorted(left)
        order += ready
        for r in ready:
            del left[r]
    return order


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("package", nargs="?", default=str(REPO / "mushrooms"))
    p.add_argument("--top", type=int, default=25)
    args = p.parse_args(argv)
    package = Path(args.package).resolve()
    files = sorted(package.rglob("*.py"))
    sizes = sorted(((len(f.read_text().splitlines()), str(f.relative_to(package.parent))) for f in files), reverse=True)
    funcs = sorted(((n, f"{f.relative_to(package.parent)}:{q}") for f in files for n, q in functions(f)), reverse=True)
    code = sorted(((n, f"{f.relative_to(package.parent)}:{q}") for f in files for n, q in functions(f, code=True)),
                  reverse=True)
    print(f"# code shape of {package}")
    print(f"modules {len(files)}, lines {sum(s for s, _ in sizes)}, functions {len(funcs)}")
    print(f"modules > 500 lines: {sum(s > 500 for s, _ in sizes)}; > 400: {sum(s > 400 for s, _ in sizes)}")
    print(f"functions > 100 lines: {sum(n > 100 for n, _ in funcs)}; > 60: {sum(n > 60 for n, _ in funcs)}")
    print(f"\n## largest modules (lines)")
    for s, name in sizes[:args.top]:
        print(f"{s:6d}  {name}")
    print(f"\n## longest functions (lines)")
    for n, name in funcs[:args.top]:
        print(f"{n:6d}  {name}")
    over_f = [(n, name) for n, name in code if n > MAX_FUNCTION_CODE]
    over_m = [(s, name) for s, name in sizes if s > MAX_MODULE_LINES]
    print(f"\n## over the house limits: functions > {MAX_FUNCTION_CODE} lines of code (docstring aside): "
          f"{len(over_f)}; modules > {MAX_MODULE_LINES} lines: {len(over_m)}")
    for n, name in over_f:
        print(f"{n:6d}  {name}  (lines of code)")
    for s, name in over_m:
        print(f"{s:6d}  {name}  (module lines)")
    print(f"\n## longest functions (lines of code, docstring aside)")
    for n, name in code[:args.top]:
        print(f"{n:6d}  {name}")
    arch = _scanner()
    graph = arch.import_graph(package)
    print(f"\n## import graph: {len(graph)} modules, {sum(len(v) for v in graph.values())} edges, "
          f"cycles {len(arch.import_cycles(graph))}, forbidden edges {len(arch.layering_violations(graph))}")
    edges = Counter((layer(a), layer(b)) for a, ts in graph.items() for b in ts if layer(a) != layer(b))
    for (a, b), n in sorted(edges.items()):
        print(f"{n:4d}  {a} -> {b}")
    for package_name, groups in ((arch.LIBRARY, arch.LIBRARY_GROUPS), (arch.SCHEDULERS, arch.SCHEDULER_GROUPS)):
        rooms = arch.room_graph(graph, package_name, groups)
        print(f"\n## rooms of {package_name}: {len(rooms)}, loops {len(arch.import_cycles(rooms))}"
              f" (a room -> the rooms it imports)")
        for room in _stack_order(rooms):
            print(f"      {room:12s} -> {', '.join(sorted(rooms[room])) or '-'}")
    config_mods = {m for m in graph if m in ("mushrooms.config", "mushrooms.tool.config")}
    importers = sorted(a for a, ts in graph.items() if ts & config_mods)
    print(f"\n## modules importing the config assembly ({', '.join(sorted(config_mods)) or 'none'}): {len(importers)}")
    for m in importers:
        print(f"      {m}")
    ap = stdlib_importers(package, "argparse")
    print(f"\n## modules importing argparse: {len(ap)}")
    for m in ap:
        print(f"      {m}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
