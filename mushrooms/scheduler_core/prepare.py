"""Build the :class:`~.problem.PlanningProblem` for one sky map and start time."""

from __future__ import annotations

import numpy as np
from astropy.time import Time

from .config import PlanningConfig
from .instruments.active import covering_polygons, description_of
from .instruments.defaults import telescope_entry
from .instruments.description import TelescopeDescription
from .sky.fields import Camera, FieldGrid, field_footprints, load_ztf_fields, telescope_grid
from .schedulers.gain import worth_a_visit
from .sky.footprints import Footprints
from .problem import PlanningProblem
from .sky.windows import Windows
from .sky.skymap import SkyMap
from .sky.visibility import observability_windows

__all__ = ["prepare_problem", "telescope_grid_and_camera"]


def prepare_problem(skymap: SkyMap, config: PlanningConfig, start: Time, grid: FieldGrid | None = None,
                    footprints: Footprints | None = None, windows: Windows | None = None,
                    telescope: TelescopeDescription | None = None) -> PlanningProblem:
    """Candidate fields, footprints and windows of one telescope for a sky map.

    The telescope is the one ``config`` plans (``config.telescope``, ZTF by
    default); a caller planning a described telescope passes its
    description and a configuration made for it,
    ``PlanningConfig.for_telescope(telescope, table)``, so that one
    :class:`~.problem.PlanningProblem` per telescope can be built for any
    telescope of ``[scheduler] telescopes`` (``problem.telescope`` names it).
    Its grid, the detectors behind its covering filters, its site, mount and
    limits come from the description (``docs/design/telescopes.md``, section 4).

    Candidates are the grid fields inside the declination band that hold
    some probability, at least ``config.min_gain`` (see :mod:`.gain`), and
    can be observed for at least one exposure within the horizon.

    The pieces that do not depend on the sky map may be passed in, computed
    once and reused (the daemon keeps them per night): ``grid``,
    ``footprints`` (of the whole grid at ``config.nside``, rows in grid
    order) and ``windows`` (of at least the grid's in-band fields over
    ``[start, start + horizon]``, s since ``start``, e.g. from
    :func:`~.visibility.windows_from_mask`).  Omitted pieces are computed.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at ``config.nside``.
    config : PlanningConfig
        Planning parameters.
    start : astropy.time.Time
        Horizon start (UTC).
    grid : FieldGrid, optional
        The telescope's field grid (default: ZTF's :func:`~.fields.load_ztf_fields`, or the
        description's).
    footprints : Footprints, optional
        Footprints of every grid field (default :func:`~.fields.field_footprints`).
    windows : Windows, optional
        Precomputed windows over the horizon; rows of fields that are not
        candidates are ignored.
    telescope : TelescopeDescription, optional
        The telescope planned; it must be the one ``config`` names
        (default: ``config.telescope``'s description, or ZTF's constants).

    Raises
    ------
    ValueError
        ``config`` made for another telescope, footprints not of the grid,
        or covering filters with no detector in common.

    Returns
    -------
    PlanningProblem

    Examples
    --------
    >>> from importlib.resources import files
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> night = Time("2019-05-01T03:00:00", scale="utc")
    >>> problem = prepare_problem(skymap, config, night)
    >>> problem.field_ids.size == problem.footprints.field_ids.size
    True
    >>> problem.start.isot, problem.config.solver
    ('2019-05-01T03:00:00.000', 'greedy')
    """
    if skymap.nside != config.nside:
        raise ValueError(f"sky map nside {skymap.nside} differs from config nside {config.nside}")
    grid, camera = telescope_grid_and_camera(config, telescope, grid)
    footprints = footprints if footprints is not None else field_footprints(grid, config.nside, camera)
    if footprints.nside != config.nside or not np.array_equal(footprints.field_ids, grid.ids):
        raise ValueError("footprints must cover the whole grid, in grid order, at config.nside")
    in_band = (grid.dec >= config.dec_min_deg) & (grid.dec <= config.dec_max_deg)
    has_prob = worth_a_visit(footprints, skymap.prob, config.min_gain)
    sel = in_band & has_prob
    if windows is None:
        windows = observability_windows(grid.ids[sel], grid.ra[sel], grid.dec[sel], start, config)
    else:
        keep = np.isin(windows.field_ids, grid.ids[sel])
        windows = Windows(windows.field_ids[keep], windows.start[keep], windows.end[keep])
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


def telescope_grid_and_camera(config: PlanningConfig, telescope: TelescopeDescription | None = None,
                              grid: FieldGrid | None = None) -> tuple[FieldGrid, Camera | None]:
    """The field grid (``grid`` when given) and the covering detectors (None: ZTF's 16 CCDs) of the telescope.

    The telescope is ``config.telescope`` (its description when ``telescope`` is not given);
    :func:`~.fields.field_footprints` with the pair returned gives the footprints every part of
    the planner uses for it (the first plan, the re-plans and the following nights).
    """
    if telescope is not None and telescope_entry(telescope) != config.telescope:
        raise ValueError(f"config plans telescope {config.telescope!r}, not {telescope_entry(telescope)!r}: "
                         f"build it with PlanningConfig.for_telescope(telescope, table)")
    if config.telescope == "ztf":
        return (grid if grid is not None else load_ztf_fields()), None
    telescope = telescope if telescope is not None else description_of(config)
    camera = Camera(covering_polygons(telescope, tuple(config.filters)), telescope.footprint.radius_deg)
    return (grid if grid is not None else telescope_grid(telescope)), camera
