"""The design documents and the code stay in step.

* Every equation label defined in ``docs/design/*.md`` (a line starting
  ``(B4)``, ``(S1)``, ``(X3)`` ...) names a block of the code that builds
  it, and every such label the code cites is defined in the documents.
  Data-driven: a new equation (say ``(X6)``) is picked up from the text.
* The constraint blocks of the two MILP builders are each a section
  headed by their equation's label.
* Every repository path the README, the documents and the package's
  docstrings mention exists.
"""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "docs" / "design"
PACKAGE = ROOT / "mushrooms"

#: A label as the documents define it: at the start of a line, e.g. "(B4) ..." or "    (X3) ...".
_DEFINED = re.compile(r"^\s*\(([A-Z]\d+)\)", re.MULTILINE)
_CITED = re.compile(r"\(([A-Z]\d+)\)")


def _doc_labels() -> dict[str, str]:
    """label -> document defining it."""
    labels: dict[str, str] = {}
    for doc in sorted(DESIGN.glob("*.md")):
        for label in _DEFINED.findall(doc.read_text()):
            assert labels.get(label, doc.name) == doc.name, f"({label}) defined in {labels[label]} and {doc.name}"
            labels[label] = doc.name
    return labels


def _sources() -> dict[str, str]:
    return {str(p.relative_to(ROOT)): p.read_text() for p in sorted(PACKAGE.rglob("*.py"))}


def _code_labels(prefixes: set[str]) -> dict[str, set[str]]:
    """label -> modules citing it (only labels with a documented prefix letter)."""
    cited: dict[str, set[str]] = {}
    for path, text in _sources().items():
        for label in _CITED.findall(text):
            if label[0] in prefixes:
                cited.setdefault(label, set()).add(path)
    return cited


def test_the_design_documents_define_the_models_equations():
    labels = _doc_labels()
    # the block MILP, the slot model, the bound, the source model and the detection objective
    for family, least in (("B", 12), ("S", 4), ("U", 5), ("K", 1), ("D", 1), ("X", 5)):
        assert sum(label[0] == family for label in labels) >= least, family


def test_every_documented_equation_has_its_block_in_the_code():
    labels = _doc_labels()
    cited = _code_labels({label[0] for label in labels})
    missing = sorted(set(labels) - set(cited), key=lambda s: (s[0], int(s[1:])))
    assert not missing, f"equations with no block citing them in mushrooms/: {missing}"


def test_every_equation_the_code_cites_is_documented():
    labels = _doc_labels()
    cited = _code_labels({label[0] for label in labels})
    unknown = {label: sorted(paths) for label, paths in cited.items() if label not in labels}
    assert not unknown, f"labels cited in the code but defined in no docs/design/*.md: {unknown}"


def _function_source(name: str) -> str:
    """The source of the package's (only) function called ``name``, wherever it lives."""
    found = []
    for path, text in _sources().items():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef) and node.name == name:
                found.append(ast.get_source_segment(text, node))
    assert len(found) == 1, f"{name}: {len(found)} definitions"
    return found[0]


@pytest.mark.parametrize("builder, rows, family", [("build_block_model", "_block_rows", "B"),
                                                   ("build_slot_model", "slot_model_rows", "S")])
def test_each_milp_constraint_block_is_a_section_named_after_its_equation(builder, rows, family):
    """The builder (objective, bounds) and its row function (the constraint blocks) cite every equation."""
    source = _function_source(builder) + "\n" + _function_source(rows)
    wanted = {label for label, doc in _doc_labels().items() if label[0] == family and doc == "milp.md"}
    sections = set(re.findall(r"#\s*\((" + family + r"\d+)\)", source))
    assert sections == wanted, f"{builder}: sections {sorted(sections)} vs milp.md {sorted(wanted)}"
    # and each constraint block is named after its equation, the number the comment cites
    named = set(re.findall(r'rows\.block\(\s*"(' + family + r'\d+) ', _function_source(rows)))
    assert named == wanted - {family + "0"}, f"{rows}: named blocks {sorted(named)} vs milp.md {sorted(wanted)}"
    docstring = ast.get_docstring(ast.parse(_function_source(builder)).body[0])
    assert "docs/design/milp.md" in docstring


# --------------------------------------------------------------------- paths the prose mentions
_TOP = ("docs", "mushrooms", "tests", "benchmarks", "systemd")
#: A repository path: starts at a top-level directory of the repository ...
_REPO_PATH = re.compile(r"(?<![\w./~-])((?:" + "|".join(_TOP) + r")/[\w./*-]*[\w*])")
#: ... or at a package directory (``scheduler_core/kilonova.py``), relative to ``mushrooms/``.
_PACKAGE_PATH = re.compile(r"(?<![\w./~-])((?:scheduler_core|handlers|daemon|evaluation)/[\w./*-]*[\w*])")
_MD_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
_MD_NAME = re.compile(r"(?<![\w./-])([\w-]+\.md)\b")


def _prose() -> dict[Path, str]:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), ROOT / "benchmarks" / "README.md",
             ROOT / "systemd" / "README.md", ROOT / "config.toml"]
    texts = {p: p.read_text() for p in files if p.exists()}
    for path in sorted(PACKAGE.rglob("*.py")):  # docstrings and comments: the text of the module
        texts[path] = path.read_text()
    return texts


def _exists(token: str, base: Path) -> bool:
    token = token.rstrip(".")
    for root in (ROOT, base):
        if any(root.glob(token)) if "*" in token else (root / token).exists():
            return True
    return False


def _tracked_names() -> set[str]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    names = {Path(line).name for line in out.stdout.splitlines()}
    # a fresh checkout without git metadata: the files on disk
    return names or {p.name for p in ROOT.rglob("*.md")}


def test_every_repository_path_in_the_prose_exists():
    missing = []
    for path, text in _prose().items():
        where = path.relative_to(ROOT)
        for token in _REPO_PATH.findall(text):
            if not _exists(token, path.parent):
                missing.append(f"{where}: {token}")
        for token in _PACKAGE_PATH.findall(text):
            if not _exists(token, PACKAGE):
                missing.append(f"{where}: {token}")
        if path.suffix == ".md":
            for target in _MD_LINK.findall(text):
                if "://" not in target and not (path.parent / target).exists():
                    missing.append(f"{where}: link {target}")
    assert not missing, "paths that do not exist:\n" + "\n".join(missing)


def test_every_markdown_file_named_exists_in_the_repository():
    names = _tracked_names()
    missing = sorted({f"{path.relative_to(ROOT)}: {name}" for path, text in _prose().items()
                      for name in _MD_NAME.findall(text) if name not in names})
    assert not missing, "documents named but absent: " + ", ".join(missing)
