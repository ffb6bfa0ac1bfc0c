"""Import a package's public names on first use (PEP 562), for the packages' ``__init__``.

A package whose ``__init__`` re-exports names of heavy submodules (numpy,
astropy, healpy) would load them whenever any light submodule is imported
(:mod:`.config`, :mod:`.tables`, :mod:`.errors`: what reading a
configuration needs).  :func:`lazy_exports` gives the package a module
``__getattr__`` and ``__dir__`` that import a name's submodule on first use
and keep the name in the package.  Imports only the standard library.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, str], public: list[str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package with lazily imported names.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : mapping of str to str
        Public name -> the submodule (relative to ``package``, e.g. ``".alert"``) defining it.
    public : list of str
        The package's ``__all__``.

    Returns
    -------
    (getattr, dir) : tuple of callables
        Assign them to the package's ``__getattr__`` and ``__dir__``.

    Examples
    --------
    In a package's ``__init__.py``::

        __getattr__, __dir__ = lazy_exports(__name__, {"Alert": ".alert"}, __all__)
    """
    def __getattr__(name: str) -> Any:
        where = exports.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(package)
        value = getattr(importlib.import_module(where, package), name)
        setattr(module, name, value)
        return value

    def __dir__() -> list[str]:
        return sorted(set(vars(importlib.import_module(package))) | set(public))

    return __getattr__, __dir__
