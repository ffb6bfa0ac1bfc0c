"""No network for astropy: Earth-orientation tables come from the installed astropy-iers-data package.

Every command and the service call :func:`configure_astropy_offline` before
any time or coordinate work, so a plan never stalls on (or fails for) a
download at 3 a.m.

Reading those tables (IERS A and B, about 9 MB of text parsed by
``astropy.io.ascii``) costs about half a second of every command that
touches the sky, more than the greedy plan itself.  The parsed table is
therefore kept in a cache file (:func:`~.scheduler_core.cachedir.cache_dir`, ``earth-orientation-KEY.pickle``)
keyed on the astropy and astropy-iers-data versions and the data files'
sizes and times, and handed to astropy (``iers.earth_orientation_table``)
from there: the same table, read in a few milliseconds.  A cache file is
used only when it and its folder belong to this user and nobody else can
write them; a cache that cannot be written or read is skipped (the tables
are then parsed as before).
"""

from __future__ import annotations

import hashlib
import logging
import os
import pickle
import stat
import tempfile
from pathlib import Path
from typing import Any

from .scheduler_core.cachedir import cache_dir

__all__ = ["configure_astropy_offline"]

log = logging.getLogger(__name__)


def configure_astropy_offline(use_cache: bool = True) -> None:
    """Never let astropy try to download Earth-orientation tables (no network); read them from the cache.

    Parameters
    ----------
    use_cache : bool
        Hand astropy the parsed tables from the cache folder (written on first use).
    """
    from astropy.utils import iers

    iers.conf.auto_download = False
    iers.conf.auto_max_age = None
    if use_cache:
        _cached_earth_orientation(iers)


def _cache_key(iers: Any) -> str:
    import astropy

    parts = [astropy.__version__]
    try:
        import astropy_iers_data

        parts.append(getattr(astropy_iers_data, "__version__", ""))
    except ImportError:  # older astropy: the tables ship with astropy itself
        pass
    for name in ("IERS_A_FILE", "IERS_B_FILE"):
        path = getattr(iers, name, None)
        if path and os.path.exists(path):
            st = os.stat(path)
            parts.append(f"{path}:{st.st_size}:{st.st_mtime_ns}")
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:16]


def _private(st: os.stat_result) -> bool:
    """Owned by this user and writable by nobody else."""
    return st.st_uid == os.geteuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def _cached_earth_orientation(iers: Any) -> None:
    """Set ``iers.earth_orientation_table`` from the cache file, writing it first when missing."""
    folder = cache_dir()
    path = folder / f"earth-orientation-{_cache_key(iers)}.pickle"
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        fd = None
    if fd is not None:
        with os.fdopen(fd, "rb") as fh:
            if _private(os.fstat(fh.fileno())) and _private(os.stat(folder)):
                try:
                    iers.earth_orientation_table.set(pickle.load(fh))
                    return
                except Exception as exc:  # a truncated or foreign file: parse the tables instead
                    log.debug("earth-orientation cache %s unreadable (%s): parsing the tables", path, exc)
    table = iers.earth_orientation_table.get()  # parsed from astropy-iers-data
    iers.earth_orientation_table.set(table)
    tmp = None
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if not _private(os.stat(folder)):
            return
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".earth-orientation-", delete=False) as fh:
            tmp = fh.name
            pickle.dump(table, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
        tmp = None
    except Exception as exc:  # a read-only home (a sandboxed service): no cache, nothing lost
        log.debug("earth-orientation cache not written in %s: %s", folder, exc)
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
