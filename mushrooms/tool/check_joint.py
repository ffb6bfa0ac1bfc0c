"""``mushrooms check FILE.joint.json MAP``: a joint plan of several telescopes (issue 53 item 2).

Every telescope's part (``plans``) is checked as a plan on its own, with its
own embedded configuration (its telescope's grid, detectors, site, limits,
filters and cadence); then the joint metrics are recomputed from the parts'
fields with the checker's own geometry: the union (each pixel once), each
telescope's share, the probability covered more than once, and the union
must lie under the certified bound (J8).  ``observations`` must be the
parts' observations, each naming its part's telescope.
"""

from __future__ import annotations

import argparse
from typing import Any, Callable

__all__ = ["check_joint"]


def _joint_problems(doc: dict, skymap: Any, configs: list[Any]) -> list[str]:
    """The joint metrics against the parts (one line per problem)."""
    import numpy as np

    from ..scheduler_core.plan.check_geometry import polygon_mask
    from ..scheduler_core.plan.check_telescope import check_scope
    from ..scheduler_core.plan.checker import TOL_COVERAGE

    names, metrics, parts = doc.get("telescopes", []), doc.get("metrics", {}), doc["plans"]
    count = np.zeros(skymap.prob.size, np.int32)
    shares = {}
    for name, part, cfg in zip(names, parts, configs):
        mask = polygon_mask({o["field_id"] for o in part.get("observations", [])}, skymap.nside, check_scope(cfg))
        count += mask
        shares[name] = float(skymap.prob[mask].sum())
    union, twice = float(skymap.prob[count > 0].sum()), float(skymap.prob[count > 1].sum())
    out = []
    for key, value in [("union", union), ("more_than_once", twice)] + [(f"share.{n}", s) for n, s in shares.items()]:
        reported = metrics.get(key) if "." not in key else metrics.get("share", {}).get(key.split(".", 1)[1])
        if not isinstance(reported, (int, float)) or abs(float(reported) - value) > TOL_COVERAGE:
            out.append(f"metrics.{key}: reported {reported!r} but the parts' footprints hold {value:.5f}")
    bound = metrics.get("upper_bound")
    if not isinstance(bound, (int, float)) or float(metrics.get("union", 0.0)) > float(bound):
        out.append(f"metrics.union {metrics.get('union')!r} above the certified upper bound {bound!r}")
    want = sorted((o["start"], o["field_id"], o["filter"], n) for n, p in zip(names, parts) for o in p["observations"])
    have = sorted((o.get("start"), o.get("field_id"), o.get("filter"), o.get("telescope"))
                  for o in doc.get("observations", []))
    if want != have:
        out.append("observations: not the parts' observations, each with its telescope")
    return out


def check_joint(args: argparse.Namespace, doc: dict, map_path: Any, check_part: Callable[[dict, str], int]) -> int:
    """Check every part with ``check_part(part, label)``, then the joint metrics; 0 when all pass, else 1."""
    from ..scheduler_core import PlanningConfig, read_skymap
    from ..scheduler_core.errors import InputError

    parts, names = doc.get("plans"), doc.get("telescopes")
    if not isinstance(parts, list) or not isinstance(names, list) or len(parts) != len(names) or not parts \
            or not all(isinstance(p, dict) for p in parts):
        raise InputError(f"{args.plan}: a joint_plan needs one plan document per telescope (plans, telescopes)")
    status = max(check_part(part, f"{args.plan} [{name}]") for name, part in zip(names, parts))
    try:
        configs = [PlanningConfig.from_mapping(p.get("config") or {}) for p in parts]
    except (TypeError, ValueError) as exc:
        raise InputError(f"{args.plan}: embedded config: {exc}") from None
    skymap = read_skymap(map_path, nside=configs[0].nside)
    problems = _joint_problems(doc, skymap, configs)
    if not problems:
        print(f"{args.plan}: OK: joint plan of {', '.join(map(str, names))}, union {doc['metrics']['union']:.4f} "
              f"under the bound {doc['metrics']['upper_bound']:.4f}")
        return status
    print(f"{args.plan}: FAILED with {len(problems)} problem(s) in the joint metrics:")
    for line in problems:
        print(f"  {line}")
    return 1
