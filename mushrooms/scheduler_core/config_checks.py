"""The checks of ``[scheduler]``: what is wrong with a :class:`~.config.PlanningConfig`, one line each.

:meth:`PlanningConfig.__post_init__ <.config.PlanningConfig>` joins them (in
this order) into one ``ValueError``.  Imports only the standard library and
leaves, as the configuration does.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .instruments.names import filter_names, telescope_problem
from .lightcurve_names import PAPER_LIGHTCURVES
from .solvers_registry import SOLVER_NAMES

__all__ = ["filter_sequence_problems", "grid_problems", "scheduler_problems", "stage_problems", "telescope_problems",
           "ZTF_FILTERS",
           "MAX_TIME_STEPS", "MAX_SEQUENCE"]

#: The filters of the ZTF camera (its filter exchanger holds g, r and i).
ZTF_FILTERS = ("g", "r", "i")

#: Most steps of the observability time grid (``horizon_h`` / ``time_step_s``): 24 h at 10 s.  Measured
#: with ``mushrooms plan`` (greedy, MS220722v, load 1.3): 120 s steps 7.6 s, 10 s steps 13.6 s; 0.01 s
#: steps ran for minutes.
MAX_TIME_STEPS = 8640

#: The longest filter sequence (``filters``): eight visits of a field in one night, a 300 s exposure every
#: half hour (ZTF's GW programme ran three, g-r-g, in O4).
MAX_SEQUENCE = 8



def filter_sequence_problems(filters: object, telescope: str = "ztf") -> list[str]:
    """(F0) What is wrong with a ``filters`` setting (empty: nothing), one line each.

    The filters are checked against ``telescope``'s (ZTF's g, r, i by
    default; another telescope's from its description's ``[filters]``).
    """
    if isinstance(filters, str) or not isinstance(filters, (tuple, list)):
        return [f"filters must be a list of ZTF filters such as [\"g\", \"r\", \"g\"], got {filters!r}"]
    seq = tuple(filters)
    problems = []
    if not 1 <= len(seq) <= MAX_SEQUENCE:
        problems.append(f"filters must hold 1 to {MAX_SEQUENCE} visits, got {len(seq)}")
    allowed = ZTF_FILTERS if telescope == "ztf" else filter_names(telescope)
    which = "ZTF" if telescope == "ztf" else telescope
    if allowed is not None and any(f not in allowed for f in seq):
        problems.append(f"filters must be {which} filters ({', '.join(allowed)}), got {list(seq)!r}")
    repeats = [i + 1 for i in range(1, len(seq)) if seq[i] == seq[i - 1]]
    if repeats:
        problems.append(f"filters must change filter at every visit (visit {repeats[0]} repeats the one "
                        f"before it), got {list(seq)!r}")
    return problems


def grid_problems(cfg: Any) -> list[str]:
    """What is wrong with the sky, the time grid and the filter sequence (F6)."""
    problems = []
    if cfg.pair_max_s and cfg.pair_max_s < cfg.cadence_s:
        problems.append(f"pair_max_s ({cfg.pair_max_s:g} s) must be 0 or at least cadence_s "
                        f"({cfg.cadence_s:g} s)")
    elif cfg.pair_max_s and cfg.pair_max_s < (len(cfg.filters) - 1) * cfg.cadence_s:  # (F6) k visits
        problems.append(f"pair_max_s ({cfg.pair_max_s:g} s) must be 0 or hold the sequence "
                        f"{'-'.join(cfg.filters)}: at least {len(cfg.filters) - 1} x cadence_s "
                        f"({(len(cfg.filters) - 1) * cfg.cadence_s:g} s)")
    if cfg.dec_min_deg >= cfg.dec_max_deg:
        problems.append(f"dec_min_deg ({cfg.dec_min_deg:g}) must be less than dec_max_deg ({cfg.dec_max_deg:g})")
    if cfg.time_step_s > 0 and cfg.horizon_s / cfg.time_step_s > MAX_TIME_STEPS:
        problems.append(f"horizon_h / time_step_s = {cfg.horizon_s / cfg.time_step_s:.0f} time steps, more than "
                        f"{MAX_TIME_STEPS} (24 h at 10 s): raise time_step_s or shorten horizon_h")
    if cfg.nside < 1 or cfg.nside & (cfg.nside - 1):
        problems.append(f"nside must be a power of 2, got {cfg.nside}")
    if not 0 < cfg.horizon_h <= 24 * 7:
        problems.append(f"horizon_h must be in (0, 168] h, got {cfg.horizon_h}")
    for name in ("time_step_s", "exposure_s", "cadence_s", "time_limit_s"):
        if getattr(cfg, name) <= 0:
            problems.append(f"{name} must be > 0, got {getattr(cfg, name)}")
    if cfg.airmass_max < 1:
        problems.append(f"airmass_max must be >= 1, got {cfg.airmass_max}")
    problems += filter_sequence_problems(cfg.filters, _first_telescope(cfg))
    if (isinstance(cfg.filters, (tuple, list)) and len(cfg.filters) > 2
            and (len(cfg.filters) - 1) * cfg.cadence_s > cfg.pair_separation_s):
        problems.append(f"filters {list(cfg.filters)!r} need {len(cfg.filters) - 1} cadences of "
                        f"{cfg.cadence_s:g} s within pair_max_s = {cfg.pair_separation_s:g} s: no field "
                        f"could be planned (F6)")
    if cfg.exposure_menu_s and isinstance(cfg.filters, (tuple, list)) and len(cfg.filters) != 2:
        problems.append(f"exposure_menu_s needs a pair of filters (the detection stage plans pairs), got the "
                        f"sequence {list(cfg.filters)!r}")
    return problems


def _first_telescope(cfg: Any) -> str:
    """The telescope a configuration plans (the first of ``telescopes``; ZTF when the entry is unusable)."""
    names = cfg.telescopes
    if isinstance(names, (tuple, list)) and names and isinstance(names[0], str) and not telescope_problem(names[0]):
        return names[0]
    return "ztf"


def telescope_problems(cfg: Any) -> list[str]:
    """What is wrong with ``telescopes``: a list of known names or description files, at least one, no repeats."""
    names = cfg.telescopes
    if isinstance(names, str) or not isinstance(names, (tuple, list)) or not names:
        return [f"telescopes must be a list of telescope names such as [\"ztf\"], got {names!r}"]
    problems = [p for p in (telescope_problem(n) for n in names) if p]
    if len(set(names)) != len(names):
        problems.append(f"telescopes must not repeat a telescope, got {list(names)!r}")
    return problems


def scheduler_problems(cfg: Any) -> list[str]:
    """What is wrong with the schedulers' settings: name, slot grid, MILP, blocks, least gain."""
    problems = []
    if cfg.solver not in SOLVER_NAMES:
        problems.append(f"solver must be one of {', '.join(SOLVER_NAMES)}, got {cfg.solver!r}")
    if not cfg.slot_positions or any(int(n) < 1 for n in cfg.slot_positions):
        problems.append(f"slot_positions must be positive integers, got {cfg.slot_positions!r}")
    if cfg.slot_margin_s < 0:
        problems.append(f"slot_margin_s must be >= 0, got {cfg.slot_margin_s}")
    if cfg.milp_backend not in ("auto", "highs", "gurobi"):
        problems.append(f"milp_backend must be auto, highs or gurobi, got {cfg.milp_backend!r}")
    if cfg.n_fields is not None and cfg.n_fields < 1:
        problems.append(f"n_fields must be >= 1, got {cfg.n_fields}")
    if cfg.min_block_size < 0:
        problems.append(f"min_block_size must be >= 0, got {cfg.min_block_size}")
    if cfg.n_blocks_max < 1:
        problems.append(f"n_blocks_max must be >= 1, got {cfg.n_blocks_max}")
    cap = getattr(cfg, "max_open_shutter_s", None)
    if cap is not None and not (isinstance(cap, (int, float)) and not isinstance(cap, bool) and 1.0 <= cap <= 604800.0):
        problems.append(f"max_open_shutter_s must be in [1, 604800] s or unset, got {cap!r}")
    elif cap is not None and cfg.solver in ("blocks", "milp"):
        problems.append(f"max_open_shutter_s needs solver greedy, slots or hybrid (the block MILP holds no S4), "
                        f"got solver = {cfg.solver!r}")
    for name in ("min_gain", "min_coverage"):
        if not 0.0 <= getattr(cfg, name) < 1.0:
            problems.append(f"{name} must be in [0, 1), got {getattr(cfg, name)}")
    return problems


def stage_problems(cfg: Any) -> list[str]:
    """What is wrong with the stages after the coverage portfolio: detection, exposure menu, bound."""
    problems = []
    if cfg.detection_lightcurve not in PAPER_LIGHTCURVES and not Path(cfg.detection_lightcurve).is_file():
        problems.append(f"detection_lightcurve must be {', '.join(PAPER_LIGHTCURVES)} or a light-curve file, "
                        f"got {cfg.detection_lightcurve!r}")
    if cfg.objective not in ("coverage", "detection"):
        problems.append(f"objective must be coverage or detection, got {cfg.objective!r}")
    if cfg.detection_levels < 1:
        problems.append(f"detection_levels must be >= 1, got {cfg.detection_levels}")
    if cfg.detection_coverage_weight < 0:
        problems.append(f"detection_coverage_weight must be >= 0, got {cfg.detection_coverage_weight}")
    if cfg.detection_time_limit_s <= 0:
        problems.append(f"detection_time_limit_s must be > 0, got {cfg.detection_time_limit_s}")
    elif cfg.objective == "detection" and cfg.detection_time_limit_s >= cfg.time_limit_s:
        problems.append(f"detection_time_limit_s ({cfg.detection_time_limit_s:g} s) must be less than "
                        f"time_limit_s ({cfg.time_limit_s:g} s): it is the detection stage's share of it")
    menu = tuple(cfg.exposure_menu_s)
    if any(not (1.0 <= float(e) <= 3600.0) for e in menu):
        problems.append(f"exposure_menu_s must hold exposures in [1, 3600] s, got {list(menu)!r}")
    elif list(menu) != sorted(set(float(e) for e in menu)):
        problems.append(f"exposure_menu_s must be increasing without repeats, got {list(menu)!r}")
    if menu and cfg.objective != "detection":
        problems.append("exposure_menu_s needs objective = \"detection\" (exposures are chosen by expected "
                        f"detections), got objective = {cfg.objective!r}")
    if not 0.0 <= cfg.bound_time_limit_s <= 600.0:
        problems.append(f"bound_time_limit_s must be in [0, 600] s (0: the online bound alone), "
                        f"got {cfg.bound_time_limit_s}")
    if not 0.0 <= cfg.detection_max_coverage_loss < 1.0:
        problems.append(f"detection_max_coverage_loss must be in [0, 1), got {cfg.detection_max_coverage_loss}")
    return problems
