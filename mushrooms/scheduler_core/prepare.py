"""Build the :class:`~.problem.PlanningProblem` for one sky map and start time."""

from __future__ import annotations

import numpy as np
from astropy.time import Time

from .config import PlanningConfig
from .fields import field_footprints, load_ztf_fields
from .gain import worth_a_visit
from .problem import PlanningProblem
from .skymap import SkyMap
from .visibility import observability_windows

__all__ = ["prepare_problem"]


def prepare_problem(skymap: SkyMap, config: PlanningConfig, start: Time) -> PlanningProblem:
    """Candidate fields, footprints and windows for a sky map.

    Candidates are the grid fields inside the declination band that hold
    some probability, at least ``config.min_gain`` (see :mod:`.gain`), and
    can be observed for at least one exposure within the horizon.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at ``config.nside``.
    config : PlanningConfig
        Planning parameters.
    start : astropy.time.Time
        Horizon start (UTC).

    Returns
    -------
    PlanningProblem
    """
    if skymap.nside != config.nside:
        raise ValueError(f"sky map nside {skymap.nside} differs from config nside {config.nside}")
    grid = load_ztf_fields()
    footprints = field_footprints(grid, config.nside)
    in_band = (grid.dec >= config.dec_min_deg) & (grid.dec <= config.dec_max_deg)
    has_prob = worth_a_visit(footprints, skymap.prob, config.min_gain)
    sel = in_band & has_prob
    windows = observability_windows(grid.ids[sel], grid.ra[sel], grid.dec[sel], start, config)
    observable = np.isin(grid.ids, windows.observable_fields()) & sel
    ids = grid.ids[observable]
    return PlanningProblem(
        config=config,
        start=start,
        prob=skymap.prob,
        field_ids=ids,
        ra=grid.ra[observable],
        dec=grid.dec[observable],
        footprints=footprints.subset(ids),
        windows=windows,
    )
