"""Derive ZTF g and r absolute magnitudes from the POSSIS spectra of Bulla (2019), per model and viewing angle.

The spectra are those of ``mbulla/kilonova_models`` (commit 9c2896ad, folder
``bns/bns_grids/superseded/bns_m1_2comp``: the grid of Bulla 2019, MNRAS 489,
5037, reused by Dhawan et al. 2020, ApJ 888, 67): total ejecta mass 0.01-0.10
Msun, half-opening angle of the lanthanide-rich component 15-75 deg, temperature
at 1 d 3000-9000 K; 11 viewing angles equally spaced in cos(theta) from the
equator (0) to the pole (1); 30 epochs 0.5-15 d; fluxes in erg/s/cm^2/A at 10 pc.
The repository has no licence file and its README asks users to cite the papers,
so only the derived magnitudes are shipped (``mushrooms/evaluation/data/SOURCES.md``).

Synthetic photometry: AB magnitude of the photon-counting response ``T``::

    m_AB = -2.5 log10( int f_lambda T lambda dlambda / int f_AB,lambda T lambda dlambda ),
    f_AB,lambda = 3631 Jy * c / lambda^2

with each POSSIS wavelength bin (220 A wide) taken as constant flux over its width.
``T``: ZTF's P48 effective transmissions of ztfquery (``ztfquery/data/filter_p48_{g,r}.dat``,
Apache-2.0, read from a local clone; not shipped).

Usage::

    python benchmarks/science/possis_ztf_table.py KILONOVA_MODELS_GIT ZTFQUERY_GIT OUT.csv.gz
"""

from __future__ import annotations

import gzip
import io
import re
import subprocess
import sys

import numpy as np

COMMIT = "9c2896ad"
FOLDER = "bns/bns_grids/superseded/bns_m1_2comp"
BANDS = ("g", "r")
C_ANGSTROM_S = 2.99792458e18
AB_FNU = 3631e-23  # erg/s/cm^2/Hz
T_MAX_DAYS = 10.0  # epochs kept: follow-up spans days, not weeks


def git_show(repo: str, spec: str) -> str:
    return subprocess.run(["git", "--git-dir", repo, "show", spec], check=True, capture_output=True, text=True).stdout


def transmission(ztfquery: str, band: str) -> tuple[np.ndarray, np.ndarray]:
    text = git_show(ztfquery, f"HEAD:ztfquery/data/filter_p48_{band}.dat")
    data = np.loadtxt(io.StringIO(text), skiprows=1)
    return data[:, 0], data[:, 1]


def read_model(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(wave (nw,), epochs (nt,), flux (nobs, nw, nt)) of one POSSIS file."""
    lines = text.splitlines()
    nobs, nwave = int(lines[0].split()[0]), int(lines[1].split()[0])
    ntime, ti, tf = lines[2].split()[:3]
    ntime, ti, tf = int(ntime), float(ti), float(tf)
    data = np.loadtxt(io.StringIO("\n".join(lines[3:])))
    data = data.reshape(nobs, nwave, ntime + 1)
    dt = (tf - ti) / ntime
    epochs = ti + dt * (np.arange(ntime) + 0.5)
    return data[0, :, 0], epochs, data[:, :, 1:]


def band_weights(wave: np.ndarray, lam: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, float]:
    """Per POSSIS bin, int_bin T lambda dlambda; and int T f_AB lambda dlambda (the AB normalisation)."""
    half = 0.5 * np.diff(wave).mean()
    grid = np.arange(lam.min(), lam.max() + 1.0, 1.0)
    t = np.interp(grid, lam, trans, left=0.0, right=0.0)
    w = np.array([np.sum((t * grid)[(grid >= c - half) & (grid < c + half)]) for c in wave])
    norm = float(np.sum(t * grid * AB_FNU * C_ANGSTROM_S / grid**2))
    return w, norm


def main(models_git: str, ztfquery_git: str, out: str) -> None:
    names = git_show(models_git, f"{COMMIT}:{FOLDER}").split()
    files = sorted(n for n in names if n.startswith("nph"))
    rows = []
    weights = None
    for name in files:
        m = re.search(r"mej([0-9.]+)_phi([0-9]+)_T([0-9.e+]+)\.txt", name)
        mej, phi, temp = float(m.group(1)), int(m.group(2)), float(m.group(3))
        wave, epochs, flux = read_model(git_show(models_git, f"{COMMIT}:{FOLDER}/{name}"))
        keep = epochs <= T_MAX_DAYS
        if weights is None:
            weights = {b: band_weights(wave, *transmission(ztfquery_git, b)) for b in BANDS}
        cos = np.linspace(0.0, 1.0, flux.shape[0])
        for b in BANDS:
            w, norm = weights[b]
            num = np.einsum("w,owt->ot", w, flux[:, :, keep])
            with np.errstate(divide="ignore"):
                mag = -2.5 * np.log10(num / norm)
            for k in range(flux.shape[0]):
                rows.append((mej, phi, temp, cos[k], b, mag[k]))
    header = "mej_msun,phi_deg,t0_k,cos_theta,band," + ",".join(f"t{t:g}" for t in epochs[keep])
    with gzip.open(out, "wt", compresslevel=9) as fh:
        fh.write("# POSSIS (Bulla 2019) grid bns_m1_2comp, ZTF P48 g/r AB absolute magnitudes at 10 pc; "
                 "columns t<days>: epoch (days after merger); inf: no flux. Derived by "
                 "benchmarks/science/possis_ztf_table.py (mushrooms/evaluation/data/SOURCES.md)\n")
        fh.write(header + "\n")
        for mej, phi, temp, cos_t, b, mag in rows:
            cells = ",".join("inf" if not np.isfinite(x) else f"{x:.2f}" for x in mag)
            fh.write(f"{mej:.2f},{phi:d},{temp:.0f},{cos_t:.1f},{b},{cells}\n")
    print(f"{len(files)} models, {len(rows)} rows -> {out}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
