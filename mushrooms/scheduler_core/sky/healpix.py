"""healpy for its pixel functions, without its plotting half (a faster start of ``mushrooms plan``).

``import healpy`` also imports :mod:`healpy.visufunc`, which loads
matplotlib (about 0.9 s of a 3.5 s ``mushrooms plan --solver greedy``)
whenever matplotlib is installed; healpy's own ``__init__`` skips that part
when ``import matplotlib`` fails.  The scheduler uses only the pixel
functions (``query_disc``, ``pix2vec``, ``ang2vec``, ``pix2ang``,
``ring2nest``, ``ud_grade``, ``npix2nside``, ...), whose results do not depend
on matplotlib, so :data:`hp` is healpy imported with matplotlib hidden for
that one import.  If healpy or matplotlib is already loaded (a ``--plot``
run, a notebook) healpy is imported as usual.  Without matplotlib at import,
healpy's plotting names (``mollview``, ``projplot``, ...) are absent from the
module for the rest of the process; nothing in mushrooms or ligo.skymap's
plotting uses them.

Import this module instead of ``import healpy as hp``::

    from ..sky.healpix import hp
"""

from __future__ import annotations

import sys
from types import ModuleType

__all__ = ["hp"]


def _import_healpy() -> ModuleType:
    """healpy, imported (if not yet) with matplotlib hidden from its ``__init__``."""
    if "healpy" in sys.modules or "matplotlib" in sys.modules:
        import healpy

        return healpy
    sys.modules["matplotlib"] = None  # type: ignore[assignment]  # `import matplotlib` raises ImportError
    try:
        import healpy
    finally:
        if "matplotlib" in sys.modules and sys.modules["matplotlib"] is None:
            del sys.modules["matplotlib"]
    return healpy


#: the healpy module (pixel functions; see the module docstring).
hp: ModuleType = _import_healpy()
