"""Which code planned a result: the git commit of the source tree the ``mushrooms`` package runs from.

Every bench row and study record carries it (``commit``), so a table built
from rows made at different times says which code made each.  A tree with
uncommitted changes to the package gets ``-dirty``; a snapshot without git
(``git archive`` of a commit) names itself through ``$MUSHROOMS_CODE_COMMIT``.
"""

from __future__ import annotations

import functools
import os
import subprocess
from pathlib import Path

__all__ = ["ENV_COMMIT", "code_commit"]

#: Environment variable naming the commit of a source tree without git (a snapshot).
ENV_COMMIT = "MUSHROOMS_CODE_COMMIT"


def _git(root: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30,
                          check=True, stdin=subprocess.DEVNULL).stdout.strip()


@functools.lru_cache(maxsize=1)
def code_commit() -> str:
    """The commit of the running ``mushrooms`` code: ``$MUSHROOMS_CODE_COMMIT``, else ``git rev-parse HEAD`` of the
    tree holding the package (``<sha>-dirty`` when the package has uncommitted changes), else ``unknown``."""
    named = os.environ.get(ENV_COMMIT, "").strip()
    if named:
        return named
    package = Path(__file__).resolve().parents[1]
    try:
        head = _git(package.parent, "rev-parse", "HEAD")
        dirty = _git(package.parent, "status", "--porcelain", "--untracked-files=no", "--", package.name)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head + ("-dirty" if dirty else "") if head else "unknown"
