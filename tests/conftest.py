"""Shared test setup: offline astropy, a per-session footprint cache, data paths."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
DATA = TESTS / "data"
_CACHE_KEY = pytest.StashKey[Path]()


def _validated(method):
    """Wrap a ``to_document`` so that every document tests produce is checked against the schema."""
    import functools

    from mushrooms.scheduler_core.plan.schema import validate_document

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        doc = method(self, *args, **kwargs)
        validate_document(doc)
        return doc

    wrapper.__wrapped_by_schema__ = True
    return wrapper


def _validate_every_document() -> None:
    from mushrooms.scheduler_core.plan.observability import NotObservable
    from mushrooms.scheduler_core.plan.document import Plan

    for cls, name in ((Plan, "to_document"), (NotObservable, "to_document")):
        method = getattr(cls, name)
        if not getattr(method, "__wrapped_by_schema__", False):
            setattr(cls, name, _validated(method))


def pytest_configure(config: pytest.Config) -> None:
    from astropy.utils import iers

    iers.conf.auto_download = False  # no network, ever
    iers.conf.auto_max_age = None
    # A fresh footprint cache for every session: a disk cache left by an
    # earlier run (keyed on inputs, not on code) would hide a footprint bug.
    # Under pytest-xdist the controller makes it and its workers share it
    # (the cache writes a file under a temporary name, then renames it).
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None and workerinput.get("mushrooms_cache_dir"):
        cache = Path(workerinput["mushrooms_cache_dir"])
    else:
        cache = Path(tempfile.mkdtemp(prefix="mushrooms-footprints-"))
        config.stash[_CACHE_KEY] = cache  # the process that made it removes it
    os.environ["MUSHROOMS_CACHE_DIR"] = str(cache)
    _validate_every_document()  # every plan and not_observable document must follow the schema


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node) -> None:
    """pytest-xdist: hand a starting worker the session's footprint cache."""
    node.workerinput["mushrooms_cache_dir"] = os.environ["MUSHROOMS_CACHE_DIR"]


def pytest_unconfigure(config: pytest.Config) -> None:
    cache = config.stash.get(_CACHE_KEY, None)
    if cache is not None:
        shutil.rmtree(cache, ignore_errors=True)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """tests/data."""
    return DATA
