"""Helpers of ``test_coordinated_parts.py``: a southern notice, the sky map of a notice, footprints of a document.

The footprints are the plan checker's own geometry (``polygon_mask`` of the
document's embedded configuration), not the planner's: the tests measure the
parts with what ``mushrooms check`` uses.
"""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from daemon_helpers import notice_bytes
from telescope_parts_setup import SID

NSIDE = 64


def gw_only(raw: bytes) -> bytes:
    """The notice without its external coincidence: the service plans its GW map (the one the tests measure on)."""
    doc = json.loads(raw)
    doc["external_coinc"] = None
    return json.dumps(doc).encode()


def notice_skymap(raw: bytes, nside: int = NSIDE) -> Any:
    """The sky map of a notice (its ``event.skymap``), read at ``nside``."""
    from mushrooms.scheduler_core import read_skymap

    return read_skymap(base64.b64decode(json.loads(raw)["event"]["skymap"]), nside=nside)


def footprint(doc: dict, nside: int = NSIDE) -> np.ndarray:
    """Pixels (bool, nested) inside the fields a plan document observes, by the checker's geometry."""
    from mushrooms.scheduler_core import PlanningConfig
    from mushrooms.scheduler_core.plan.check_geometry import polygon_mask
    from mushrooms.scheduler_core.plan.check_telescope import check_scope

    cfg = PlanningConfig.from_mapping(doc.get("config") or {})
    return polygon_mask({o["field_id"] for o in doc.get("observations", [])}, nside, check_scope(cfg)).astype(bool)


def union_and_twice(prob: np.ndarray, docs: list[dict]) -> tuple[float, float]:
    """(union, probability covered by two documents or more) of plan documents on ``prob``."""
    count = sum(footprint(d).astype(np.int32) for d in docs)
    return float(prob[count > 0].sum()), float(prob[count > 1].sum())


def southern_notice(ra_deg: float = 200.0, dec_deg: float = -70.0) -> bytes:
    """MS230425l's PRELIMINARY (named MS181101ab) with its sky map turned on the sky so that its peak lies at (``ra``, ``dec``).

    The real BAYESTAR map (nside 128, nested, PROB only) rotated by the
    rotation taking its most probable pixel to the given point, and cut
    north of -45° (the map has a second mode): Palomar never sees it above
    9° of altitude, La Silla sees it at 50° at its meridian, in the night after
    the notice (25 April 2023, RA 200° is opposite the Sun).
    """
    import astropy_healpix as ah
    from astropy import units as u
    from astropy.io import fits
    from scipy.spatial.transform import Rotation

    raw = gw_only(notice_bytes("MS230425l-preliminary.json", SID))
    prob = notice_skymap(raw, 128).prob
    lon, lat = ah.healpix_to_lonlat(np.arange(prob.size), 128, order="nested")
    xyz = _unit(lon.rad, lat.rad)
    i = int(np.argmax(prob))
    turn, _ = Rotation.align_vectors(_unit(np.radians(ra_deg), np.radians(dec_deg)), xyz[i:i + 1])
    back = turn.inv().apply(xyz)  # each new pixel takes the old probability where the rotation brings it from
    src = ah.lonlat_to_healpix(np.arctan2(back[:, 1], back[:, 0]) * u.rad,
                               np.arcsin(np.clip(back[:, 2], -1, 1)) * u.rad, 128, order="nested")
    new = np.where(lat.deg < -45.0, prob[src], 0.0)  # its second mode, wherever the rotation puts it, cut
    new = new / new.sum()
    doc = json.loads(raw)
    with fits.open(io.BytesIO(base64.b64decode(doc["event"]["skymap"]))) as hdus:
        old = hdus[1].header
        hdu = fits.BinTableHDU.from_columns([fits.Column("PROB", "D", array=new)])
        for key, value in (("PIXTYPE", "HEALPIX"), ("ORDERING", "NESTED"), ("COORDSYS", "C"), ("NSIDE", 128),
                           ("INDXSCHM", "IMPLICIT"), ("OBJECT", old["OBJECT"]), ("DATE-OBS", old["DATE-OBS"]),
                           ("MJD-OBS", old["MJD-OBS"]), ("CREATOR", "BAYESTAR, rotated (test)")):
            hdu.header[key] = value
        out = io.BytesIO()
        fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(out)
    doc["event"]["skymap"] = base64.b64encode(out.getvalue()).decode()
    return json.dumps(doc).encode()


def _unit(lon: Any, lat: Any) -> np.ndarray:
    lon, lat = np.atleast_1d(lon), np.atleast_1d(lat)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1)


def joint_file(outbox: Path, job_folder: str) -> Path:
    """The joint document of a job's parts: ``telescopes/<event>/<job folder>/joint.json``."""
    return outbox / "telescopes" / SID / job_folder / "joint.json"
