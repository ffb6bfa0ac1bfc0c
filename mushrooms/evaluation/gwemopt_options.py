"""gwemopt's named configurations: which options each baseline row passes, and what each option does.

Rows (``mushrooms bench --solvers``, ``mushrooms study``):

``gwemopt`` (and ``gwemopt-repaired``, the same schedule with every
rule-breaking exposure removed)
    The first release's baseline, unchanged (its cache keys too): the
    planning configuration's filters (g, r), exposure (300 s), airmass and
    nside, ``--doChipGaps --doSingleExposure --doAlternatingFilters``, no
    balancing, no tile cap.
``gwemopt-o4``
    The gwemopt command line of skyportal/skyportal issue #4206 (tahumada,
    2023-05-12) in gwemopt 0.4.2's spelling: ``--filters g,r,g
    --exposuretimes 180,180,180 --doSingleExposure --doAlternatingFilters
    --doBalanceExposure --confidence_level 0.9 --airmass 2.5 --mindiff 30
    --max_nb_tiles 15 --doUsePrimary``, greedy schedule, power-law
    allocation, MOC tiles, no chip gaps.  What that issue is: a local
    command line (gwemopt v0.0.84's ``bin/gwemopt_run``) for the Fermi-GBM
    map of GRB 230511, posted to ask for a tile cap in SkyPortal's form
    ("this line produces a schedule lasting ~2 hours"), not a recorded O4
    GW configuration.  Its ``--powerlaw_cl 0.9`` became
    ``--confidence_level`` (gwemopt 28c269f, 2024-06-05); ``--max_nb_tiles
    15,15,15 --doMaxTiles`` (one cap per telescope, v0.0.84
    ``bin/gwemopt_run:188-189``, ``gwemopt/utils.py:969-972``) is
    ``--max_nb_tiles 15`` for one telescope; its plotting and directory
    options (``--doPlots --doSkymap --doMovie --tilingDir
    --configDirectory``) are left out.  It names no grid: the primary grid
    is taken from SkyPortal's ZTF form (below).
``gwemopt-skyportal``
    What SkyPortal's observation-plan form sends gwemopt for ZTF with its
    defaults (skyportal/skyportal 8bd346c, ``skyportal/utils/observation_plan.py``
    ``generate_plan`` 389-486; form defaults ``skyportal/facility_apis/observation_plan.py``
    487-572 and the ZTF form ``skyportal/facility_apis/ztf.py`` 1213-1259):
    filters ``ztfg,ztfr,ztfg`` (ztf.py:1240), 300 s each (observation_plan.py:519-524,
    utils 429-432), block strategy = ``--doAlternatingFilters`` (form 504-508,
    utils 397), greedy (form 509-513), airmass 2.0 (form 526-532),
    balanced exposures (form 550-554, utils 443), primary grid (ztf.py:1241-1245,
    utils 454), no tile cap (form 545-549, utils 438-441), no chip gaps
    (utils 482), nside 512 (utils 419), single exposure (utils 404).  The
    90 % (form 533-539) reaches gwemopt as ``confidence_level = 90.0``
    (utils 421), which both ``< 1.0`` tests ignore (gwemopt ``io/skymap.py:317``,
    SkyPortal utils 606); it acts through the fields SkyPortal hands
    gwemopt: those touching the 90 % credible region (utils 654-776, with
    ``use_skyportal_fields`` true by default, ``config.yaml.defaults:64``),
    which :func:`credible_fields` reproduces and the launcher applies
    (``--mushrooms-fields``, our own option, stripped before gwemopt parses
    the line).  No minimum time difference: the form asks for one (30 min
    default, ``* 60`` into seconds, utils 424-425) only under the
    ``integrated`` strategy (form 659-685); the ``block`` default sends 0.
    Not reproduced: the form's start (now) and end (next nautical
    twilight) - every row plans the same horizon from the event time; the
    deployment's instrument overheads (SkyPortal defaults them to 0, utils
    505-522; the command line uses gwemopt's ``ZTF.config``); reference
    images (``use_references`` defaults to true only where the
    instrument's fields carry reference filters, form 474-485, 728-733).

Each option, in gwemopt 0.4.2 (skyportal/gwemopt 89e5d2f, the version
installed; file:line under ``gwemopt/``):

``--filters``, ``--exposuretimes`` (args.py:109, 116; params.py:104-105)
    One filter and exposure per visit of a field, same length (run.py:34-37).
    The time grid's slot is the longest exposure plus
    ``overhead_per_exposure`` (10 s in ``data/config/ZTF.config:17``), plus
    the 60 s filter change (ZTF.config:18) unless filters alternate in
    blocks (utils/misc.py:37-65).
``--doSingleExposure`` (args.py:108)
    Every tile above 1 % of the best tile's probability (tiles.py:821) gets
    exactly one exposure per filter of the list (tiles.py:823-887) instead
    of power-law time (tiles.py:888-934); the limiting magnitude is scaled
    to the first exposure time (params.py:32-48).
``--doAlternatingFilters`` (args.py:110)
    One block per entry of ``--filters``, in order (coverage.py:161-172,
    tiles.py:469-559): each block a greedy schedule of every tile in that
    filter, the next block starting after the last slot used, shifted so
    that it starts at least 30 min after the previous block's first
    exposure (tiles.py:498-513) - a field late in one block and early in
    the next can still be minutes apart.
``--doBalanceExposure`` (args.py:114)
    With alternating filters: without a tile cap, tries caps of 10 to 200
    tiles and keeps the one giving the most tiles observed in every filter,
    then drops unbalanced tiles in up to 20 rounds (coverage.py:174-186,
    tiles.py:165-359); with a cap, schedules once, marks every tile not
    observed once per filter entry as unbalanced (tiles.py:79-95) and
    schedules again without them (coverage.py:187-216, tiles.py:521-523).
``--mindiff`` (args.py:88), in seconds
    The greedy scheduler skips a tile observed less than ``mindiff`` s
    before the slot (scheduler.py:261-264, ``/ 86400`` to days); with
    alternating blocks the earlier blocks' exposures become the tile's
    epochs (tiles.py:525-532) and slots within ``mindiff`` of them are
    skipped (scheduler.py:161-190).  #4206's ``--mindiff 30`` is 30 s (the
    unit was seconds in v0.0.84 too, ``gwemopt/scheduler.py:145-147``),
    shorter than any block: it changes nothing.
``--max_nb_tiles`` (args.py:118)
    When more tiles were scheduled, keeps the cap's most probable ones and
    schedules again (tiles.py:42-69, 537-545; coverage.py:343-350).
``--confidence_level`` (args.py:90, default 1.0; ``--powerlaw_cl`` before 28c269f)
    Zeroes the pixels outside that credible level in
    ``skymap_raster_schedule``, then sets ``skymap_schedule`` from the
    *uncut* raster (io/skymap.py:317-324); MOC tiles take their probability
    from ``skymap_schedule`` (tiles.py:814-819), so a MOC schedule does not
    change (checked: ``benchmarks/science/gwemopt_confidence_level_check.py``,
    ``benchmarks/results/science/gwemopt_o4/confidence_level_check.txt``).  In
    v0.0.84 ``powerlaw_cl`` acted on MOC tiles only with ``--doMinimalTiling``
    (``gwemopt/moc.py:22-31`` at a962b14), which #4206 did not pass.
``--doUsePrimary`` (args.py:122)
    ZTF fields 1-880 only (moc.py:101-103; SkyPortal's path moc.py:87-88).
``--airmass`` (args.py:106)
    A tile's observable segments are those above the altitude of that
    airmass (segments.py:206, 279-281), at night (Sun below -12 deg,
    segments.py:152), within the hour-angle limits and 20 deg from the
    Moon (segments.py:241-243, 68-72).
``--doChipGaps`` (args.py:121)
    Tiles are the 64 ZTF quadrants (moc.py:21-31) instead of a 6.86 deg square.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from astropy.time import Time

__all__ = ["GwemoptConfig", "GWEMOPT_CONFIGS", "LEGACY", "FIELDS_OPTION", "gwemopt_args", "portable_args",
           "row_planning_config", "credible_fields"]

#: Our launcher's option naming the fields gwemopt may tile (stripped before gwemopt reads the line).
FIELDS_OPTION = "--mushrooms-fields"
#: The first release's row: its options (and so its cache keys) stay as they were.
LEGACY = "gwemopt"


@dataclass(frozen=True)
class GwemoptConfig:
    """One named way of running gwemopt 0.4.2 (the module notes say what each option does).

    Attributes
    ----------
    name : str
        The row name.
    filters : tuple of str or None
        ``--filters`` (None: the planning configuration's).
    exposure_s : float or None
        Every visit's ``--exposuretimes`` entry (s; None: the configuration's).
    airmass : float or None
        ``--airmass`` (None: the configuration's ``airmass_max``).
    nside : int or None
        ``--nside`` (None: the configuration's).
    chip_gaps, balance, primary_grid : bool
        ``--doChipGaps``, ``--doBalanceExposure``, ``--doUsePrimary``.
    mindiff_s : float
        ``--mindiff`` (s; 0: not passed).
    max_nb_tiles : int or None
        ``--max_nb_tiles`` (None: not passed).
    confidence_level : float or None
        ``--confidence_level`` (None: not passed).
    credible_fields : float or None
        Tile only the fields touching this credible region (SkyPortal's
        field selection, :func:`credible_fields`; None: every field).
    """

    name: str
    filters: tuple[str, ...] | None = None
    exposure_s: float | None = None
    airmass: float | None = None
    nside: int | None = None
    chip_gaps: bool = False
    balance: bool = False
    primary_grid: bool = False
    mindiff_s: float = 0.0
    max_nb_tiles: int | None = None
    confidence_level: float | None = None
    credible_fields: float | None = None

    def filters_of(self, config: Any) -> tuple[str, ...]:
        """The filter sequence this configuration plans under ``config``."""
        return tuple(self.filters) if self.filters is not None else tuple(config.filters)

    def exposure_of(self, config: Any) -> float:
        """The exposure (s) of every visit under ``config``."""
        return float(self.exposure_s if self.exposure_s is not None else config.exposure_s)


#: The named configurations (rows ``gwemopt-repaired`` repairs the ``gwemopt`` one).
GWEMOPT_CONFIGS: dict[str, GwemoptConfig] = {
    LEGACY: GwemoptConfig(LEGACY, chip_gaps=True),
    "gwemopt-o4": GwemoptConfig("gwemopt-o4", filters=("g", "r", "g"), exposure_s=180.0, airmass=2.5,
                                balance=True, primary_grid=True, mindiff_s=30.0, max_nb_tiles=15,
                                confidence_level=0.9),
    "gwemopt-skyportal": GwemoptConfig("gwemopt-skyportal", filters=("g", "r", "g"), exposure_s=300.0,
                                       airmass=2.0, nside=512, balance=True, primary_grid=True,
                                       credible_fields=0.9),
}


def gwemopt_args(skymap_path: str | Path, start: Time, config: Any, outdir: str | Path,
                 named: GwemoptConfig = GWEMOPT_CONFIGS[LEGACY], fields: Sequence[int] | None = None) -> list[str]:
    """The gwemopt 0.4.2 command line of one sky map, horizon and named configuration.

    Parameters
    ----------
    skymap_path : str or pathlib.Path
        The sky map (``-e``).
    start : astropy.time.Time
        Horizon start (``--gpstime``; ``--Tobs 0,<horizon in days>``).
    config : PlanningConfig
        Horizon, and the filters, exposure, nside and airmass the named
        configuration leaves to it.
    outdir : str or pathlib.Path
        gwemopt's output directory (``-o``).
    named : GwemoptConfig
        The row's configuration.
    fields : sequence of int, optional
        The fields gwemopt may tile (:data:`FIELDS_OPTION`), for a
        configuration with ``credible_fields``.
    """
    filters = named.filters_of(config)
    exposure = f"{named.exposure_of(config):g}"
    args = ["--telescopes", "ZTF", "-e", str(skymap_path), "-o", str(outdir),
            "--gpstime", f"{Time(start, scale='utc').gps:.3f}", "--Tobs", f"0,{config.horizon_h / 24.0:.6f}",
            "--doTiles", "--tilesType", "moc",
            "--doSchedule", "--scheduleType", "greedy", "--timeallocationType", "powerlaw"]
    args += ["--doChipGaps"] if named.chip_gaps else []
    args += ["--filters", ",".join(filters), "--exposuretimes", ",".join(exposure for _ in filters),
             "--doSingleExposure", "--doAlternatingFilters"]
    args += ["--doBalanceExposure"] if named.balance else []
    args += ["--confidence_level", f"{named.confidence_level:g}"] if named.confidence_level is not None else []
    args += ["--mindiff", f"{named.mindiff_s:g}"] if named.mindiff_s > 0 else []
    args += ["--max_nb_tiles", str(int(named.max_nb_tiles))] if named.max_nb_tiles is not None else []
    args += ["--doUsePrimary"] if named.primary_grid else []
    args += ["--nside", str(named.nside or config.nside),
             "--airmass", f"{(named.airmass if named.airmass is not None else config.airmass_max):g}"]
    if fields is not None:
        args += [FIELDS_OPTION, ",".join(str(int(f)) for f in sorted(set(int(x) for x in fields)))]
    return args


def portable_args(args: Sequence[str]) -> list[str]:
    """The options without the input sky map and output directory (they name local paths): the cache key's."""
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a in ("-e", "-o"):
            skip = True
            continue
        out.append(a)
    return out


def row_planning_config(config: Any, named: GwemoptConfig) -> Any:
    """The planning configuration a gwemopt row is judged under: ``config`` with the row's filters and exposure.

    The checker's sequence rules and the queue export follow the plan's
    filter sequence; windows, airmass limit and cadence stay the
    configuration's, the same rule for every row.
    """
    filters, exposure = named.filters_of(config), named.exposure_of(config)
    if filters == tuple(config.filters) and exposure == float(config.exposure_s):
        return config
    return dataclasses.replace(config, filters=filters, exposure_s=exposure)


def credible_fields(footprints: Any, prob: np.ndarray, level: float) -> list[int]:
    """Fields whose footprint touches the ``level`` credible region (SkyPortal's field selection for a plan).

    The region is the most probable pixels whose cumulative probability
    stays within ``level`` (SkyPortal: localisation tiles with the density
    of the last tile inside ``cum_prob <= level``, ``utils/observation_plan.py:654-675``),
    the most probable pixel always included; a field counts when any of
    its footprint's pixels is in it (``healpix.overlaps``, 762-773).

    Parameters
    ----------
    footprints : Footprints
        Field footprints at the map's resolution.
    prob : numpy.ndarray
        Probability per pixel (NESTED, ``footprints.nside``).
    level : float
        Credible level, in (0, 1].
    """
    if not 0.0 < level <= 1.0:
        raise ValueError(f"credible level must be in (0, 1], got {level}")
    prob = np.asarray(prob, dtype=float)
    order = np.argsort(prob)[::-1]
    inside = np.cumsum(prob[order]) <= level
    inside[0] = True
    region = np.zeros(prob.size)
    region[order[inside]] = 1.0
    touched = footprints.field_probability(region) > 0
    return [int(f) for f in np.asarray(footprints.field_ids)[touched]]
