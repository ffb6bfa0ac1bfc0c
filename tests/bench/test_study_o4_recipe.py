"""The named population recipes, the O4 recipe's mass model and noise curves, and the tools run from it.

The mass model is checked against its own formula (support, pairing, class
fractions, spins); the noise curves by their BNS ranges; a tiny O4 population
(a few injections) goes through the real ``bayestar-inject`` and
``bayestar-realize-coincs`` (marked slow).
"""

from __future__ import annotations

import os
import shutil
import stat
from pathlib import Path

import numpy as np
import pytest

from mushrooms.evaluation.study import defaults
from mushrooms.evaluation.study.ligo_tools import run_tool


def test_a_tool_found_through_a_relative_path_entry_runs_in_another_directory(tmp_path, monkeypatch):
    bindir = tmp_path / "bin"
    bindir.mkdir()
    tool = bindir / "fake-bayestar-tool"
    tool.write_text("#!/bin/sh\necho ran > made.txt\n")
    tool.chmod(tool.stat().st_mode | stat.S_IXUSR)
    workdir = tmp_path / "work"
    workdir.mkdir()
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PATH", "bin" + os.pathsep + os.environ["PATH"])  # relative, as `.venv/bin` would be
    run_tool(["fake-bayestar-tool"], cwd=workdir)
    assert (workdir / "made.txt").read_text() == "ran\n"


def test_pdb_density_has_its_dip_between_the_neutron_star_and_black_hole_peaks():
    from mushrooms.evaluation.study.mass_models import FARAH_PDB, pdb_density

    p = FARAH_PDB
    inside, below, above = pdb_density(np.array([4.0, 2.0, 8.0]))
    assert inside < 0.1 * below and inside < above  # A = 0.97: the gap is nearly empty
    assert pdb_density(np.array([0.9]))[0] < 1e-3 * pdb_density(np.array([1.4]))[0]  # turn-on at m_min
    # the power-law break at the dip's upper edge keeps the density continuous
    eps = 1e-9
    lo, hi = pdb_density(np.array([p.m_gap_high - eps, p.m_gap_high + eps]))
    assert hi == pytest.approx(lo, rel=1e-6)


def test_pdb_binaries_have_a_neutron_star_secondary_ordered_masses_and_bounded_spins():
    from mushrooms.evaluation.study.mass_models import NS_MAX_MASS, NS_MAX_SPIN, binary_class, sample_pdb_binaries

    s = sample_pdb_binaries(np.random.default_rng(4), 5000)
    assert all(len(s[k]) == 5000 for k in ("mass1", "mass2", "spin1z", "spin2z"))
    assert np.all(s["mass1"] >= s["mass2"]) and np.all(s["mass2"] < NS_MAX_MASS)
    assert np.all(s["mass2"] > 0.9)
    ns1 = s["mass1"] < NS_MAX_MASS
    assert np.all(np.abs(s["spin2z"]) <= NS_MAX_SPIN) and np.all(np.abs(s["spin1z"][ns1]) <= NS_MAX_SPIN)
    assert np.all(np.abs(s["spin1z"]) < 1.0) and np.abs(s["spin1z"][~ns1]).max() > NS_MAX_SPIN
    classes = binary_class(s["mass1"], s["mass2"])
    n_nsbh = int(np.sum(classes == "NSBH"))
    assert set(classes) == {"BNS", "NSBH"} and 0.005 < n_nsbh / 5000 < 0.2
    again = sample_pdb_binaries(np.random.default_rng(4), 5000)
    assert np.array_equal(again["mass1"], s["mass1"])  # seeded


def test_pairing_index_favours_equal_component_masses():
    import dataclasses

    from mushrooms.evaluation.study.mass_models import FARAH_PDB, sample_pdb_binaries

    paired = sample_pdb_binaries(np.random.default_rng(1), 4000)
    unpaired = sample_pdb_binaries(np.random.default_rng(1), 4000, dataclasses.replace(FARAH_PDB, beta=0.0))
    q = [np.mean(x["mass2"] / x["mass1"]) for x in (paired, unpaired)]
    assert q[0] > q[1] + 0.02


def test_binary_class_splits_at_three_solar_masses_in_either_order():
    from mushrooms.evaluation.study.mass_models import binary_class

    got = binary_class(np.array([1.4, 8.0, 1.2, 10.0]), np.array([1.3, 1.4, 5.0, 7.0]))
    assert list(got) == ["BNS", "NSBH", "NSBH", "BBH"]


def test_o4_noise_curves_have_the_bns_ranges_of_the_recipe_files():
    pytest.importorskip("lalsimulation")
    from mushrooms.evaluation.study.recipes import O4_RANGES_MPC, RECIPES, bns_range_mpc

    assert 170.0 < bns_range_mpc("aLIGO175MpcT1800545") < 185.0  # the model's name, as a check of the measure
    for det, model, scale in RECIPES["o4"].population.psd_scales:
        assert bns_range_mpc(model, scale) == pytest.approx(O4_RANGES_MPC[det], rel=0.005)
    assert [d for d, _, _ in RECIPES["o4"].population.psd_scales] == ["H1", "L1", "V1"]


def test_recipes_are_the_command_line_choices_and_keep_the_o3_population_as_it_was():
    from mushrooms.evaluation.study import Localisation, Population
    from mushrooms.evaluation.study.mass_models import PDB_DISTRIBUTION
    from mushrooms.evaluation.study.recipes import RECIPES, recipe_population

    assert tuple(RECIPES) == defaults.RECIPE_NAMES and defaults.DEFAULT_RECIPE in RECIPES
    o3, loc3 = recipe_population("o3-bns", 600, seed=1, chunk=40)
    assert o3 == Population(n_injections=600, seed=1, chunk=40) and loc3 == Localisation()
    o4, loc4 = recipe_population("o4", 9000, seed=2)
    assert (o4.n_injections, o4.seed, o4.intrinsic_samples) == (9000, 2, RECIPES["o4"].intrinsic_samples)
    assert o4.distribution == PDB_DISTRIBUTION and o4.waveform == "IMRPhenomD"
    assert loc4.arguments() == ["--f-low", "11.0", "--waveform", "IMRPhenomD", "--cosmology"]
    assert recipe_population("o4", 9000, intrinsic_samples=50)[0].intrinsic_samples == 50
    assert o4.key() != recipe_population("o4", 9000, seed=3)[0].key()


def test_population_option_sets_the_recipe_and_its_localisation(tmp_path):
    from mushrooms.evaluation.study.recipes import RECIPES
    from mushrooms.tool import study as study_tool

    args = study_tool.parser().parse_args(["--simulate", "300", "--population", "o4", "--seed", "7",
                                           "--out", str(tmp_path)])
    inputs = study_tool.study_inputs(args)
    assert inputs.simulate.distribution == RECIPES["o4"].population.distribution
    assert (inputs.simulate.n_injections, inputs.simulate.seed) == (300, 7)
    from mushrooms.tool.bench import load_settings

    settings = study_tool.study_settings(args, load_settings(args))
    assert settings.localisation == RECIPES["o4"].localisation
    plain = study_tool.parser().parse_args(["--out", str(tmp_path)])
    assert study_tool.study_settings(plain, load_settings(plain)).localisation == RECIPES["o3-bns"].localisation
    with pytest.raises(SystemExit):
        study_tool.parser().parse_args(["--population", "o5"])


def _sim_table(path):
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    doc = ligolw_utils.load_filename(str(path), contenthandler=ContentHandler)
    return list(lsctables.SimInspiralTable.get_table(doc))


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("bayestar-inject") is None, reason="needs ligo.skymap's tools (lalsuite)")
def test_a_tiny_o4_population_goes_through_the_real_injection_and_realisation_tools(tmp_path):
    """Six injections of 12 PDB points (~1 min of one core): O4 noise curves, IMRPhenomD, cached chunks."""
    from mushrooms.evaluation.study import inject_population, realize_chunk
    from mushrooms.evaluation.study.mass_models import NS_MAX_MASS
    from mushrooms.evaluation.study.recipes import recipe_population

    pop, _ = recipe_population("o4", 6, seed=3, chunk=3, intrinsic_samples=12)
    injections = Path(inject_population(pop, tmp_path))
    assert injections.parent.name == pop.key()
    rows = _sim_table(injections)
    assert len(rows) == 6 and {r.waveform for r in rows} == {"IMRPhenomD"}
    # detector-frame masses: the secondary is a neutron star redshifted by at most a few per cent at O4 depth
    assert all(r.mass2 < NS_MAX_MASS * 1.2 and r.mass1 >= r.mass2 for r in rows)
    samples = (injections.parent / "intrinsic_samples.ecsv").read_text()
    assert "mass1" in samples and "spin2z" in samples
    from ligo.skymap.io.events.ligolw import ContentHandler  # noqa: F401 (the PSDs are readable by BAYESTAR)
    import lal.series
    from igwn_ligolw import utils as ligolw_utils

    psds = lal.series.read_psd_xmldoc(ligolw_utils.load_filename(str(injections.parent / "psds.xml"),
                                                                 contenthandler=lal.series.PSDContentHandler))
    assert sorted(psds) == ["H1", "L1", "V1"]
    first = realize_chunk(pop, str(injections), 0)
    assert first["injections"] == 3 and not first["cached"] and first["cpu_s"] > 0
    again = realize_chunk(pop, str(injections), 0)
    assert again["cached"] and again["coincidences"] == first["coincidences"]
