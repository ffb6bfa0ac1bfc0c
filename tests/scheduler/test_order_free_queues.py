"""A plan's queue set runs the same whichever open queue ZTF's scheduler takes (issue 52, finding 12; Q20).

ztf_sim's main loop takes the *last* valid, non-empty queue in submission order, its ToO switch
(and this executor before) the *first*.  Submitting the same queues in reverse order turns one rule
into the other, so a set whose execution does not depend on the rule runs the same both ways round.
On time (the run ``coverage_as_executed`` reports) the very same run is asserted (late or off-speed
runs are measured in benchmarks/execution/switch_rules.py).  A hand-made plan on a real night at Palomar (2026-03-20 06:00 UTC, the Sun 47 deg down): two blocks;
the first block's last field has set below airmass 2.5 before its passes reach it, so its g pass is
still open with a target left when its r pass opens -- two open queues at one switch.
"""

from __future__ import annotations

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.offline import configure_astropy_offline
from mushrooms.scheduler_core.executed import done_pairs
from mushrooms.scheduler_core.plan.document import EventInfo, Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.plan.exports import to_trigger_queues
from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.sky.visibility import site
from mushrooms.scheduler_core.schedulers.as_executed import execute_plan_queues

configure_astropy_offline()
EPOCH = Time("2026-03-20T06:00:00", scale="utc")
LST = float(EPOCH.sidereal_time("apparent", longitude=site().lon).deg)


def _fields(wanted):
    """The ZTF fields nearest each (hour angle, Dec) at the epoch, all different."""
    fields = load_ztf_fields()
    ra, dec = np.asarray(fields.ra), np.asarray(fields.dec)
    ha = (LST - ra + 180.0) % 360.0 - 180.0
    out = []
    for h, d in wanted:
        order = np.argsort((ha - h) ** 2 + (dec - d) ** 2)
        j = next(int(j) for j in order if int(j) not in out)
        out.append(j)
    return [(int(fields.ids[j]), float(ra[j]), float(dec[j])) for j in out]


@pytest.fixture(scope="module")
def plan():
    a, b, setting, c, d = _fields([(-10.0, 30.0), (-4.0, 30.0), (62.0, 0.0), (2.0, 35.0), (8.0, 35.0)])
    obs = []
    for block, members, g0, r0 in ((0, (a, b, setting), 0.0, 2000.0), (1, (c, d), 3000.0, 5000.0)):
        for band, t0 in (("g", g0), ("r", r0)):
            for i, (fid, ra, dec) in enumerate(members):
                obs.append(Observation(field_id=fid, ra=ra, dec=dec, filter=band, start=t0 + i * 330.0,
                                       exposure_s=300.0, block=block, probability_share=0.1))
    obs.sort(key=lambda o: o.start)
    return Plan(plan_id="order-free", start=EPOCH, end=EPOCH + TimeDelta(4 * 3600.0, format="sec"),
                observations=tuple(obs),
                metrics=PlanMetrics(coverage=0.0, solver="hand", status="ok", mip_gap=None, runtime_s=0.0,
                                    n_fields=5, n_exposures=len(obs)),
                event=EventInfo(), config={"cadence_s": 1800.0, "filters": ["g", "r"]})


def _run(plan, queues, **kwargs):
    return [(e.field_id, e.filter, round(float((e.start - EPOCH).to_value("s")), 1), e.status)
            for e in execute_plan_queues(plan, queues, **kwargs)]


def _pairs(plan, queues, **kwargs):
    """The fields done in g and r at least the cadence apart (E3)."""
    return set(done_pairs(execute_plan_queues(plan, queues, **kwargs), ("g", "r"), cadence_s=1800.0).both)


def test_on_time_the_queue_set_runs_the_same_whichever_open_queue_the_scheduler_takes(plan):
    queues = to_trigger_queues(plan)
    submitted = _run(plan, queues)
    assert submitted == _run(plan, queues[::-1])  # first-wins <-> last-wins: the very same exposures (Q20)
    assert len(_pairs(plan, queues)) == 4  # the four fields that stay up, each a cadence apart
