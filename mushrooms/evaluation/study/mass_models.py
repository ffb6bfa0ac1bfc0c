"""Intrinsic distributions of compact binaries for ``bayestar-inject --distribution-samples``.

The O4 observing-scenarios recipe (Kiendrebeogo et al. 2023, arXiv
2306.09234; lpsinger/observing-scenarios-simulations at 06d4e93, its
``scripts/farah.py``) draws masses and spins from samples of the "Power law
+ Dip + Break" (PDB) mass model of Farah et al. 2022 (ApJ 931, 108) at its
maximum-posterior hyperparameters (LIGO-T2100512).  Those samples are not
reachable from here, so :func:`sample_pdb_binaries` draws from the model
itself with the hyperparameters of Kiendrebeogo et al.'s Table 2
(:data:`FARAH_PDB`), restricted to binaries with a neutron-star secondary
(BNS and NSBH: the classes ZTF follows up).

Component mass density, all masses source-frame (Msun)::

    p(m) ∝ ℓ(m | M_min, η_min) · h(m | M_max, η_max) · n(m) · m^α1              (m < M_gap_high)
                                                            · M_gap_high^(α1-α2) m^α2   (m ≥ M_gap_high)
    n(m) = 1 - A ℓ(m | M_gap_low, η_gap_low) h(m | M_gap_high, η_gap_high)
    ℓ(m | M, η) = 1 / (1 + (M / m)^η),   h(m | M, η) = 1 / (1 + (m / M)^η)

paired as ``p(m1, m2) ∝ p(m1) p(m2) (m2 / m1)^β`` with ``m2 <= m1``.  Spins
are aligned components of isotropic spins (``spin_z = a cos θ``, ``cos θ``
uniform in [-1, 1], as ``farah.py`` projects them), with magnitudes uniform
in [0, 0.4] for a neutron star and [0, 1) for a black hole (the class
boundary :data:`NS_MAX_MASS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PDB_DISTRIBUTION", "PDBParameters", "FARAH_PDB", "NS_MAX_MASS", "NS_MAX_SPIN", "pdb_density", "sample_pdb_binaries",
           "binary_class"]

#: ``Population.distribution`` of binaries drawn by :func:`sample_pdb_binaries` (BNS and NSBH).
PDB_DISTRIBUTION = "farah_pdb_bns_nsbh"
#: Neutron star / black hole boundary of the recipe's classes (source-frame Msun).
NS_MAX_MASS = 3.0
#: Largest spin magnitude of a neutron star (dimensionless).
NS_MAX_SPIN = 0.4


@dataclass(frozen=True)
class PDBParameters:
    """Hyperparameters of the PDB mass model (masses in source-frame Msun).

    Attributes
    ----------
    alpha_1, alpha_2 : float
        Power-law index below and above the break at ``m_gap_high``.
    a_dip : float
        Depth of the dip (0: none, 1: empty gap).
    m_gap_low, m_gap_high : float
        Edges of the dip (Msun).
    eta_gap_low, eta_gap_high : float
        Sharpness of the dip's edges.
    m_min, eta_min : float
        Low-mass turn-on (Msun) and its sharpness.
    m_max, eta_max : float
        High-mass roll-off (Msun) and its sharpness.
    beta : float
        Pairing index on the mass ratio.
    """

    alpha_1: float = -2.16
    alpha_2: float = -1.46
    a_dip: float = 0.97
    m_gap_low: float = 2.72
    m_gap_high: float = 6.13
    eta_gap_low: float = 50.0
    eta_gap_high: float = 50.0
    m_min: float = 1.16
    eta_min: float = 50.0
    m_max: float = 54.38
    eta_max: float = 4.91
    beta: float = 1.89


#: Kiendrebeogo et al. 2023, Table 2 (Farah et al. 2022's maximum-posterior PDB(pair) hyperparameters).
FARAH_PDB = PDBParameters()


def _high_pass(m: np.ndarray, m0: float, eta: float) -> np.ndarray:
    """ℓ(m | m0, η): rises from 0 to 1 through ``m0``."""
    return 1.0 / (1.0 + (m0 / m) ** eta)


def _low_pass(m: np.ndarray, m0: float, eta: float) -> np.ndarray:
    """h(m | m0, η): falls from 1 to 0 through ``m0``."""
    return 1.0 / (1.0 + (m / m0) ** eta)


def pdb_density(m: np.ndarray, p: PDBParameters = FARAH_PDB) -> np.ndarray:
    """The unnormalised PDB component-mass density at source-frame masses ``m`` (Msun)."""
    m = np.asarray(m, dtype=float)
    dip = 1.0 - p.a_dip * _high_pass(m, p.m_gap_low, p.eta_gap_low) * _low_pass(m, p.m_gap_high, p.eta_gap_high)
    power = np.where(m < p.m_gap_high, m ** p.alpha_1, p.m_gap_high ** (p.alpha_1 - p.alpha_2) * m ** p.alpha_2)
    return _high_pass(m, p.m_min, p.eta_min) * _low_pass(m, p.m_max, p.eta_max) * dip * power


def _component_masses(rng: np.random.Generator, n: int, p: PDBParameters, m_lo: float,
                      m_hi: float) -> np.ndarray:
    """``n`` independent draws of the component density on [m_lo, m_hi] (inverse CDF on a fine log grid)."""
    grid = np.geomspace(m_lo, m_hi, 20001)
    pdf = pdb_density(grid, p)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(grid))])
    return np.interp(rng.uniform(0.0, cdf[-1], size=n), cdf, grid)


def sample_pdb_binaries(rng: np.random.Generator, n: int, p: PDBParameters = FARAH_PDB,
                        max_secondary: float = NS_MAX_MASS, m_lo: float = 0.5,
                        m_hi: float = 200.0) -> dict[str, np.ndarray]:
    """``n`` binaries of the paired PDB model whose secondary is below ``max_secondary`` (BNS and NSBH).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    n : int
        Binaries wanted.
    p : PDBParameters
        The mass model.
    max_secondary : float
        Keep binaries with ``mass2 < max_secondary`` (Msun; the neutron-star boundary).
    m_lo, m_hi : float
        Support of the component masses (Msun).

    Returns
    -------
    dict of numpy.ndarray
        ``mass1 >= mass2`` (source-frame Msun), ``spin1z``, ``spin2z``: the
        columns ``bayestar-inject --distribution-samples`` reads.
    """
    out: list[np.ndarray] = []
    have = 0
    while have < n:
        m = _component_masses(rng, 2 * max(4 * n, 1024), p, m_lo, m_hi).reshape(-1, 2)
        m1, m2 = m.max(axis=1), m.min(axis=1)
        keep = (m2 < max_secondary) & (rng.uniform(size=m1.size) < (m2 / m1) ** p.beta)  # pairing (q^β <= 1)
        out.append(np.column_stack([m1[keep], m2[keep]]))
        have += int(keep.sum())
    masses = np.concatenate(out)[:n]
    spins = []
    for mass in masses.T:
        a_max = np.where(mass < NS_MAX_MASS, NS_MAX_SPIN, 1.0)
        spins.append(rng.uniform(0.0, 1.0, size=n) * a_max * rng.uniform(-1.0, 1.0, size=n))
    return {"mass1": masses[:, 0], "mass2": masses[:, 1], "spin1z": spins[0], "spin2z": spins[1]}


def binary_class(mass1: np.ndarray, mass2: np.ndarray, boundary: float = NS_MAX_MASS) -> np.ndarray:
    """``"BNS"``, ``"NSBH"`` or ``"BBH"`` per binary, from source-frame component masses (Msun)."""
    m1, m2 = np.maximum(mass1, mass2), np.minimum(mass1, mass2)
    return np.where(m1 < boundary, "BNS", np.where(m2 < boundary, "NSBH", "BBH"))
