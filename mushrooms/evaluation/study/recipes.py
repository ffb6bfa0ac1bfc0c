"""Named population recipes of ``mushrooms study --simulate N --population NAME``.

A recipe is what a population needs to be rebuilt by anyone: the
:class:`~.population.Population` (noise curves, mass and spin distribution,
waveform, detection cuts; the number of injections and the seed come from
the command line) and the :class:`~.localisation.Localisation` options its
coincidences are localised with.

``o3-bns``
    The project's O3 BNS population (``data/populations/SOURCES.md``).
``o4``
    BNS and NSBH detections at O4 sensitivity with the HLV network, after
    the observing-scenarios recipe of Kiendrebeogo et al. 2023 (arXiv
    2306.09234; lpsinger/observing-scenarios-simulations at 06d4e93, its
    ``Makefile`` and ``README.md``).  Where this recipe differs from theirs,
    and why (:data:`O4_DEVIATIONS`): the noise curves are LALSimulation's
    analytic models scaled to the BNS ranges of the recipe's LIGO-T2200043
    files (the DCC files are not reachable here), the PDB mass model is
    sampled from its formula (:mod:`.mass_models`) rather than from the
    LIGO-T2100512 samples and restricted to a neutron-star secondary, the
    waveform is IMRPhenomD throughout (the recipe's default ``o2-uberbank``
    needs SEOBNRv4_ROM data that PyPI's lalsuite does not ship), and
    injections are drawn to single-detector SNR 4 (theirs: 1) so fewer
    realisations are wasted; the detection cuts (network SNR 8, 70 % duty
    cycle, Gaussian measurement error) and the localisation options
    (``--f-low 11 --cosmology``) are theirs.
``o4-real``
    O4 as it was (issue 55): the ``o4`` recipe's masses, waveform and
    localisation with the BNS ranges the detectors really had (H1 155, L1
    160, V1 55 Mpc: :data:`O4_REAL_RANGES_MPC`), each coincidence placed in
    O4a (H1 and L1 only), O4b or O4c (H1, L1 and V1) by the epochs' lengths,
    each detector on with its own duty cycle, and a false-alarm-rate-like
    threshold (one per month) in place of the SNR cut (:mod:`.o4_real`;
    numbers and their sources: :data:`O4_REAL_SOURCES`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .defaults import DEFAULT_CHUNK, DEFAULT_RECIPE, DEFAULT_SEED
from .localisation import Localisation
from .mass_models import PDB_DISTRIBUTION
from .population import Population

__all__ = ["Recipe", "RECIPES", "O4_DEVIATIONS", "O4_RANGES_MPC", "O4_REAL_RANGES_MPC", "O4_REAL_SOURCES",
           "DEFAULT_RECIPE", "recipe_population", "bns_range_mpc"]


@dataclass(frozen=True)
class Recipe:
    """A named way of simulating and localising a population.

    Attributes
    ----------
    population : Population
        The simulation (its ``n_injections``, ``seed`` and ``chunk`` are
        replaced by :func:`recipe_population`).
    localisation : Localisation
        ``bayestar-localize-coincs`` options of its coincidences.
    intrinsic_samples : int or None
        Default mass-spin points given to ``bayestar-inject`` when the
        command line names none (None: the preset distribution).
    description : str
        One line for ``--help`` and the provenance.
    """

    population: Population
    localisation: Localisation
    intrinsic_samples: int | None
    description: str


#: BNS ranges (Mpc) of the recipe's O4 noise curves (LIGO-T2200043-v3): aligo_O4low.txt and the
#: Virgo O4 curve O4_Virgo_78.txt, which the scaled analytic models of the ``o4`` recipe reproduce.
O4_RANGES_MPC = {"H1": 160.0, "L1": 160.0, "V1": 78.0}

#: Where the ``o4`` recipe differs from Kiendrebeogo et al.'s, in words (written into the provenance).
O4_DEVIATIONS = (
    "PSDs: LALSimulation aLIGO175MpcT1800545 (H1, L1) and AdVO4IntermediateT1800545 (V1) scaled to the BNS "
    "ranges of LIGO-T2200043-v3 aligo_O4low.txt (160 Mpc) and O4_Virgo_78.txt (78 Mpc); the DCC files "
    "are not reachable here, so the spectral shapes are the 2018 analytic models'",
    "KAGRA (kagra_3Mpc.txt) left out: the HLV network asked for (at 3 Mpc it localises nothing)",
    "masses: the PDB model of Farah et al. 2022 at Kiendrebeogo et al.'s Table 2 hyperparameters, sampled "
    "from its formula (not the LIGO-T2100512 samples) and restricted to mass2 < 3 Msun (BNS and NSBH); "
    "spins isotropic, magnitude uniform in [0, 0.4] (NS) / [0, 1) (BH), aligned components kept",
    "waveform IMRPhenomD for injection, realisation and localisation (theirs: o2-uberbank, TaylorF2 "
    "below 4 Msun total and SEOBNRv4_ROM above, whose data files PyPI's lalsuite does not ship)",
    "bayestar-inject --snr-threshold 4 (theirs: 1): draws stop at the distance where the best detector's "
    "optimal SNR is 4, far beyond network SNR 8, so fewer injections are realised for nothing",
    "seeds: injections --seed SEED, realisation chunk k --seed SEED+1+k (theirs: one run, --seed 1)",
)

_O4_PSDS = (("H1", "aLIGO175MpcT1800545", 0.8863), ("L1", "aLIGO175MpcT1800545", 0.8863),
            ("V1", "AdVO4IntermediateT1800545", 0.7577))

#: BNS ranges (Mpc) of the ``o4-real`` recipe: what O4 had, not what it was planned to have.
O4_REAL_RANGES_MPC = {"H1": 155.0, "L1": 160.0, "V1": 55.0}
#: The analytic models of ``o4`` rescaled to those ranges (a range scales with ``--X1-scale``).
_O4_REAL_PSDS = (("H1", "aLIGO175MpcT1800545", round(0.8863 * 155.0 / 160.0, 4)),
                 ("L1", "aLIGO175MpcT1800545", 0.8863),
                 ("V1", "AdVO4IntermediateT1800545", round(0.7577 * 55.0 / 78.0, 4)))

#: Where each number of ``o4-real`` comes from (written into the provenance); "estimate" where no source was found.
O4_REAL_SOURCES = (
    "O4a 2023-05-24 to 2024-01-16 (237 days), H1 and L1 only: GWOSC O4a data release page; Virgo did not join O4a "
    "(LIGO news release 2024-04-03)",
    "O4a duty cycles H1 67.5 %, L1 69.0 % (GWTC-4.0, as summarised for the O4a data release); the observing-plans "
    "page in late 2023: LHO 70 %, LLO 75 % over the past month, BNS ranges 155-170 Mpc",
    "O4b 2024-04-10 to 2025-01-28 (293 days) with Virgo: LIGO news release 2024-04-03 (start); the end date is the "
    "start of O4c, announced as 'starting' on 2025-02-03 (EGO news 2025-02-03): 2025-01-28 is an estimate",
    "O4c 2025-01-28 to 2025-11-18 less the 2025-04-01 to 2025-06-04 break (230 days): EGO news 2025-02-03 (break); "
    "O4 ended on 2025-11-18 (LVK user guide, observing capabilities)",
    "LIGO ranges H1 155, L1 160 Mpc: observing-plans page (155-170 Mpc in late 2023), EGO news 2025-02-03 (160-170 "
    "Mpc in early 2025); the split H1 < L1 is an estimate",
    "Virgo range 55 Mpc in O4b/c: an estimate (issue 55: 50-60 Mpc; the observing-plans page gave 35 Mpc in late 2023 "
    "with a goal of 40-45 Mpc before joining); no stored source gives the O4b/c value",
    "O4b/c duty cycles: the O4a LIGO values reused (estimate); Virgo 70 % (estimate)",
    "KAGRA left out (about 10 Mpc when it observed: localises nothing a 55 Mpc Virgo does not)",
    "FAR-like threshold one per month (the significant-alert threshold, config.toml [policy] max_far_hz) with the "
    "offline FAR of o4_real.far_like_hz: network SNR 8.50 for a coincidence, 10.0 for a single detector (estimates)",
    "realised with every detector on (duty cycle 1) and network SNR >= 8, then the epochs, duty cycles and threshold "
    "applied per chunk (o4_real.apply_o4_real, seed SEED+1+k)",
)

RECIPES: dict[str, Recipe] = {
    "o3-bns": Recipe(Population(), Localisation(), None,
                     "O3 BNS (bns_astro, O3 noise curves; data/populations/SOURCES.md)"),
    "o4": Recipe(Population(distribution=PDB_DISTRIBUTION, waveform="IMRPhenomD", psd_scales=_O4_PSDS),
                 Localisation(f_low=11.0, waveform="IMRPhenomD", extra=("--cosmology",)), 1000,
                 "O4 HLV BNS+NSBH after Kiendrebeogo et al. 2023 (PDB masses, LIGO 160 / Virgo 78 Mpc)"),
    "o4-real": Recipe(Population(distribution=PDB_DISTRIBUTION, waveform="IMRPhenomD", psd_scales=_O4_REAL_PSDS,
                                 duty_cycle=1.0, net_snr_threshold=8.0, post="o4-real"),
                      Localisation(f_low=11.0, waveform="IMRPhenomD", extra=("--cosmology",)), 1000,
                      "O4 as it was: O4a HL / O4b-c HLV by epoch length, H1 155 / L1 160 / V1 55 Mpc, per-detector "
                      "duty cycles, FAR <= 1/month (FAR-like, offline)"),
}


def recipe_population(name: str, n_injections: int, seed: int = DEFAULT_SEED, chunk: int = DEFAULT_CHUNK,
                      intrinsic_samples: int | None = None) -> tuple[Population, Localisation]:
    """The population of recipe ``name`` with this size, seed and chunking, and its localisation options.

    ``intrinsic_samples`` None takes the recipe's default.  KeyError for an
    unknown name.
    """
    recipe = RECIPES[name]
    samples = intrinsic_samples if intrinsic_samples is not None else recipe.intrinsic_samples
    population = dataclasses.replace(recipe.population, n_injections=n_injections, seed=seed, chunk=chunk,
                                     intrinsic_samples=samples)
    return population, recipe.localisation


def bns_range_mpc(model: str, scale: float = 1.0, f_low: float = 10.0) -> float:
    """BNS range (Mpc; 1.4+1.4 Msun, SNR 8, averaged over sky and orientation) of a LALSimulation noise model.

    ``scale`` is ``bayestar-sample-model-psd``'s ``--X1-scale`` (the ASD
    divided by it, so the range multiplied by it).
    """
    import lal
    import lalsimulation

    df, f_high = 0.25, 4096.0
    psd = lal.CreateREAL8FrequencySeries(model, 0, 0.0, df, lal.SecondUnit, int(f_high / df) + 1)
    getattr(lalsimulation, f"SimNoisePSD{model}")(psd, f_low)
    metres = lalsimulation.MeasureStandardSirenSenseMonitorRange(psd, f_low, f_high)
    return float(metres / (1e6 * lal.PC_SI) * scale)
