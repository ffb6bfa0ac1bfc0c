"""O4 as it was: the epochs O4a/b/c, each detector's duty cycle, and a false-alarm-rate-like threshold.

``bayestar-realize-coincs`` knows one duty cycle for every detector and a
network-SNR cut.  The ``o4-real`` recipe realises its injections with every
detector on (duty cycle 1) and a network SNR floor of 8, then rewrites each
realised chunk (:func:`apply_o4_real`, seeded per chunk):

1. **Epoch.**  Each coincidence falls in O4a, O4b or O4c with probability
   proportional to the epoch's length (:data:`O4_EPOCHS`); a detector that
   did not observe in that epoch is removed from it.
2. **Duty cycle.**  Each remaining detector is on with its own duty cycle
   (:data:`O4_EPOCHS`); the others are removed (their triggers and their
   sub-threshold SNRs alike).
3. **FAR-like threshold.**  With the detectors left, ``k`` triggers (SNR >=
   4) and network SNR ``rho`` over them, the candidate's false-alarm rate is
   estimated offline (:func:`far_like_hz`) and the coincidence kept only when
   it is at most :data:`FAR_THRESHOLD_HZ` (one per month: the significant-alert
   threshold the service acts on, ``config.toml [policy] max_far_hz``).

The false-alarm rate, offline.  Real searches rank candidates by a likelihood
ratio whose background is measured on time-shifted data; neither exists in a
simulation.  The approximation keeps the two facts that matter for what is
followed up: a Gaussian-like coincident background falling as
``exp(-rho^2 / 2)``, and single-detector candidates needing a higher SNR (no
coincidence to veto glitches)::

    FAR(rho, k >= 2) = F_8 exp(-(rho^2 - 64) / 2),   F_8 = 2 per day
    FAR(rho, k = 1)  = FAR(rho - delta_1, 2),         delta_1 = 1.5

``F_8`` takes the observing-scenarios recipe's network SNR 8 as the
low-significance public-alert threshold (2 per day); ``delta_1`` is an
estimate (O3/O4 single-detector candidates with FAR below one per month had
SNR of about 10 and more).  At one per month this is a network SNR of 8.50
for a coincidence and 10.0 for a single detector.  Both constants are
estimates, not fits.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

__all__ = ["O4_EPOCHS", "FAR_THRESHOLD_HZ", "LOW_SIGNIFICANCE_FAR_HZ", "SINGLE_DETECTOR_PENALTY",
           "TRIGGER_SNR", "far_like_hz", "snr_threshold", "apply_o4_real"]

#: (epoch, length in days, {detector: duty cycle}); sources and estimates in ``recipes.O4_REAL_SOURCES``.
O4_EPOCHS: tuple[tuple[str, float, Mapping[str, float]], ...] = (
    ("O4a", 237.0, {"H1": 0.675, "L1": 0.690}),
    ("O4b", 293.0, {"H1": 0.675, "L1": 0.690, "V1": 0.70}),
    ("O4c", 230.0, {"H1": 0.675, "L1": 0.690, "V1": 0.70}),
)
#: The follow-up threshold: one false alarm per month (Hz).
FAR_THRESHOLD_HZ = 1.0 / (30.0 * 86400.0)
#: The FAR at network SNR 8 of a coincidence: two per day (Hz).
LOW_SIGNIFICANCE_FAR_HZ = 2.0 / 86400.0
#: The SNR a single-detector candidate gives away against a coincidence.
SINGLE_DETECTOR_PENALTY = 1.5
#: Single-detector SNR of a trigger (bayestar-realize-coincs ``--snr-threshold``).
TRIGGER_SNR = 4.0


def far_like_hz(net_snr: np.ndarray | float, n_triggers: np.ndarray | int) -> np.ndarray:
    """Estimated false-alarm rate (Hz) of a candidate with network SNR ``net_snr`` over ``n_triggers`` detectors."""
    rho = np.asarray(net_snr, float)
    k = np.asarray(n_triggers)
    rho_eff = np.where(k >= 2, rho, rho - SINGLE_DETECTOR_PENALTY)
    far = LOW_SIGNIFICANCE_FAR_HZ * np.exp(-(rho_eff ** 2 - 64.0) / 2.0)
    return np.where(k >= 1, far, np.inf)


def snr_threshold(n_triggers: int, far_hz: float = FAR_THRESHOLD_HZ) -> float:
    """The network SNR at which :func:`far_like_hz` reaches ``far_hz``."""
    rho = math.sqrt(64.0 + 2.0 * math.log(LOW_SIGNIFICANCE_FAR_HZ / far_hz))
    return rho if n_triggers >= 2 else rho + SINGLE_DETECTOR_PENALTY


def _epoch(rng: np.random.Generator) -> Mapping[str, float]:
    days = np.array([d for _, d, _ in O4_EPOCHS])
    return O4_EPOCHS[int(rng.choice(len(O4_EPOCHS), p=days / days.sum()))][2]


def apply_o4_real(events: str, seed: int, out: str | None = None) -> tuple[int, int]:
    """Rewrite a realised events file as O4 was (module notes); ``(kept, dropped)`` coincidences.

    Parameters
    ----------
    events : str
        ``bayestar-realize-coincs`` output (LIGO-LW, maybe gzipped).
    seed : int
        Seed of the epoch and duty-cycle draws (one per chunk).
    out : str, optional
        Where to write (default: in place).
    """
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    rng = np.random.default_rng(seed)
    doc = ligolw_utils.load_filename(str(events), contenthandler=ContentHandler)
    coincs = lsctables.CoincTable.get_table(doc)
    cmap = lsctables.CoincMapTable.get_table(doc)
    sngls = lsctables.SnglInspiralTable.get_table(doc)
    ci = lsctables.CoincInspiralTable.get_table(doc)
    inspiral_defs = {int(d.coinc_def_id) for d in lsctables.CoincDefTable.get_table(doc)
                     if not d.description.startswith("sim_inspiral")}
    sngl_by_id = {int(s.event_id): s for s in sngls}
    members: dict[int, list] = {}
    for row in cmap:
        if row.table_name == "sngl_inspiral":
            members.setdefault(int(row.coinc_event_id), []).append(sngl_by_id[int(row.event_id)])
    drop_sngl: set[int] = set()
    drop_coinc: set[int] = set()
    ci_by_id = {int(r.coinc_event_id): r for r in ci}
    for coinc in coincs:
        cid = int(coinc.coinc_event_id)
        if int(coinc.coinc_def_id) not in inspiral_defs:
            continue
        duty = _epoch(rng)
        kept = []
        for s in sorted(members.get(cid, []), key=lambda s: s.ifo):  # a fixed order: the draws are reproducible
            on = s.ifo in duty and rng.random() < duty[s.ifo]
            (kept if on else []).append(s)
            if not on:
                drop_sngl.add(int(s.event_id))
        trig = [float(s.snr) for s in kept if float(s.snr) >= TRIGGER_SNR]
        rho = math.sqrt(sum(x * x for x in trig))
        if not trig or far_like_hz(rho, len(trig)) > FAR_THRESHOLD_HZ:
            drop_coinc.add(cid)
            drop_sngl.update(int(s.event_id) for s in kept)
        elif cid in ci_by_id:
            ci_by_id[cid].snr = rho
            ci_by_id[cid].ifos = {s.ifo for s in kept}
    # the injection links of a dropped coincidence go with it
    link_of = {int(r.coinc_event_id): int(r.event_id) for r in cmap if r.table_name == "coinc_event"}
    drop_link = {link for link, c in link_of.items() if c in drop_coinc}
    gone = drop_coinc | drop_link
    cmap[:] = [r for r in cmap if int(r.coinc_event_id) not in gone
               and not (r.table_name == "sngl_inspiral" and int(r.event_id) in drop_sngl)]
    coincs[:] = [c for c in coincs if int(c.coinc_event_id) not in gone]
    ci[:] = [r for r in ci if int(r.coinc_event_id) not in drop_coinc]
    sngls[:] = [s for s in sngls if int(s.event_id) not in drop_sngl]
    ligolw_utils.write_filename(doc, str(out or events), trap_signals=None)
    n_inspiral = sum(int(c.coinc_def_id) in inspiral_defs for c in coincs)
    return n_inspiral, len(drop_coinc)
