"""The numbers a person asks about a localization: its 50 % and 90 % credible areas and its distance."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from ..sky.skymap import SkyMap
from .document import EventInfo

__all__ = ["localization_facts", "with_map_details"]


def with_map_details(event: EventInfo, skymap: SkyMap) -> EventInfo:
    """The event with the sky-map name, credible areas and distance filled in from the map.

    What the event already states is kept. Give the whole sky map: a re-plan's
    map of the probability still to cover would shrink the areas and move the
    distance (the plan document describes the localization, not the remainder).
    """
    name = None if skymap.source.startswith("<") else Path(skymap.source).name
    facts = {k: v for k, v in localization_facts(skymap).items() if getattr(event, k) is None}
    return dataclasses.replace(event, skymap_name=event.skymap_name or name, **facts)


def localization_facts(skymap: SkyMap) -> dict[str, Any]:
    """Credible areas (deg²) and the all-sky distance posterior (Mpc) of a sky map.

    Returns
    -------
    dict
        ``area_50_deg2``, ``area_90_deg2``, ``distance_mpc`` (posterior
        mean) and ``distance_std_mpc`` (standard deviation): the marginal
        moments of ligo.skymap's distance ansatz
        (:func:`ligo.skymap.distance.parameters_to_marginal_moments`), the
        header's ``DISTMEAN`` without distance layers, None without either.
    """
    facts: dict[str, Any] = {"area_50_deg2": round(skymap.credible_area(0.5), 1),
                             "area_90_deg2": round(skymap.credible_area(0.9), 1),
                             "distance_mpc": None, "distance_std_mpc": None}
    if skymap.has_distance:
        from ligo.skymap.distance import parameters_to_marginal_moments

        # pixels below 1e-6 / n hold under 1e-6 of the probability together: left out, they move the
        # moments by under 1e-6 of the farthest distance (far below the 0.1 Mpc shown), and a sky map's
        # far tail is most of its pixels
        good = (np.isfinite(skymap.distmu) & np.isfinite(skymap.distsigma)
                & (skymap.prob >= 1e-6 / max(skymap.prob.size, 1)))
        mean, std = parameters_to_marginal_moments(skymap.prob[good] / skymap.prob[good].sum(),
                                                   skymap.distmu[good], skymap.distsigma[good])
        if np.isfinite(mean) and np.isfinite(std):
            facts.update(distance_mpc=round(float(mean), 1), distance_std_mpc=round(float(std), 1))
    elif skymap.distmean is not None and np.isfinite(skymap.distmean):
        facts["distance_mpc"] = round(float(skymap.distmean), 1)
    return facts
