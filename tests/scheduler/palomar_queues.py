"""One night at Palomar and the queue payloads the executor tests hand to it (shared by the executor tests).

Epoch 2026-03-20 06:00 UTC at Palomar: the Sun is 47 deg down, the local
sidereal time about 150.9 deg (:data:`LST`).  :func:`target` and
:func:`queue` write the Kowalski payloads of ``exports.to_trigger_queues``
(a queue's window in seconds after the epoch); :func:`run` executes them with
the telescope model (Q1-Q10 of ``docs/design/executed.md``) and
:func:`done_by_field` gives each field's executed exposure.  Used by
``test_telescope_executor.py`` and ``test_ztf_sim_rules.py``.
"""

from __future__ import annotations

from astropy.time import Time, TimeDelta

from mushrooms.offline import configure_astropy_offline
from mushrooms.scheduler_core.sky.visibility import site
from mushrooms.scheduler_core.telescope import TelescopeTiming, execute_queues, queue_set_from_payloads

configure_astropy_offline()
EPOCH = Time("2026-03-20T06:00:00", scale="utc")
LST = float(EPOCH.sidereal_time("apparent", longitude=site().lon).deg)
NIGHT_S = 4 * 3600.0
TIMING = TelescopeTiming()


def target(field_id, ra, dec, filter_id=1, exposure=30.0):
    """One target of a queue (RA and Dec in deg, the exposure in s)."""
    return {"field_id": field_id, "ra": float(ra % 360.0), "dec": float(dec), "filter_id": filter_id,
            "exposure_time": exposure, "program_id": 2, "subprogram_name": "ToO_GW", "program_pi": "Kulkarni/x"}


def queue(name, targets, opens_s=0.0, closes_s=NIGHT_S):
    """A list queue whose validity window runs from ``opens_s`` to ``closes_s`` (s after the epoch)."""
    mjd = (EPOCH + TimeDelta([opens_s, closes_s], format="sec")).mjd
    return {"queue_name": name, "queue_type": "list", "validity_window_mjd": [float(mjd[0]), float(mjd[1])],
            "user": "x", "targets": targets}


def run(queues, start_s=0.0, end_s=NIGHT_S, timing=TIMING):
    """(the queue set, its executed exposures) from ``start_s`` to ``end_s`` (s after the epoch)."""
    qs = queue_set_from_payloads(queues, EPOCH)
    return qs, execute_queues(qs, EPOCH, start_s, end_s, timing)


def done_by_field(queues, start_s=0.0, end_s=NIGHT_S, timing=TIMING):
    """Field id -> its executed exposure (:func:`run`)."""
    qs, done = run(queues, start_s, end_s, timing)
    return {int(qs.field_id[d.target]): d for d in done}


#: Two fields up at the epoch (on the meridian and 3 deg east of it, Dec 33 deg).
UP_A, UP_B = target(101, LST, 33.0), target(102, LST + 3.0, 33.0)
