"""Build the alert shapes of the next observing run from real archived LVK notices (tests/data/notices/shapes/).

Each shape is a real notice of ``tests/data/notices`` with a few fields edited (listed in
``tests/data/notices/SOURCES.md`` and below); the sky map and every other byte of meaning stay
as LVK wrote them.  Run from the repository root::

    python benchmarks/attacks/make_alert_shapes.py

It rewrites the files deterministically (``json.dumps`` with the source's key order, no spaces
added), so a re-run gives the same SHA-256 as recorded in SOURCES.md.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

NOTICES = Path(__file__).resolve().parents[2] / "tests" / "data" / "notices"
OUT = NOTICES / "shapes"


def _load(rel: str) -> dict:
    return json.loads((NOTICES / rel).read_bytes())


def _event(d: dict, **changes) -> dict:
    """``d`` with ``event`` fields changed; a value of ``...`` removes the key."""
    ev = dict(d["event"])
    for k, v in changes.items():
        if v is ...:
            ev.pop(k, None)
        else:
            ev[k] = v
    return {**d, "event": ev}


def shapes() -> dict[str, dict]:
    """File name -> notice (dict)."""
    prelim = _load("json/MS181101ab-preliminary.json")
    early = _load("json/MS181101ab-earlywarning.json")
    ext = _load("json/MS181101ab-ext-update.json")
    out = {
        # a sub-solar-mass search alert: no p_astro classification, no HasRemnant, a HasSSM property
        "MS181101ab-ssm-preliminary.json": _event(
            prelim, search="SSM", classification={}, properties={"HasNS": 1.0, "HasMassGap": 0.0, "HasSSM": 1.0}),
        # an early warning issued 45.654 s before its merger (event.time unchanged)
        "MS181101ab-earlywarning-premerger.json": {**early, "time_created": "2018-11-01T22:22:01Z"},
        # schema 1.3.0: event.mchirp_source, and external_coinc.gcn_notice_id as a string
        "MS181101ab-schema130-update.json": {
            **_event(ext, mchirp_source={"bin_edges": [0.9, 1.05, 1.2, 1.35, 1.5],
                                         "probabilities": [0.05, 0.7, 0.2, 0.05]}),
            "external_coinc": {**ext["external_coinc"], "gcn_notice_id": str(ext["external_coinc"]["gcn_notice_id"])},
        },
        # a CBC notice without classification (the key removed) and with empty properties
        "MS181101ab-unclassified-preliminary.json": _event(prelim, classification=..., properties={}),
        # a low-significance alert (FAR of the real S230528ay, 7.03e-7 Hz)
        "MS181101ab-lowsignificance-preliminary.json": _event(prelim, significant=False, far=7.032685984134245e-07),
        # a notice whose sky map is null (allowed by the schema)
        "MS181101ab-nomap-preliminary.json": _event(prelim, skymap=None),
    }
    return out


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name, d in shapes().items():
        data = json.dumps(d).encode()
        (OUT / name).write_bytes(data)
        print(f"| `shapes/{name}` | {hashlib.sha256(data).hexdigest()[:16]} | {len(data)} bytes |")


if __name__ == "__main__":
    main()
