#!/usr/bin/env python3
"""Are this machine's injections the ones behind the committed chunks? Compare each committed chunk's
sim_inspiral rows with the same slice of the new injections.xml (masses, spins, distance, sky position, time).

    python benchmarks/science/population_o4_compare_injections.py ROOT/cache/populations/<key>/injections.xml \
        benchmarks/results/science/population_o4/previous_2026-12-06_o4_recipe/population/chunks   # recipe o4; o4-real: population_o4/population/chunks

A chunk's events file keeps the injections it detected; each must be in its chunk's slice of the new file.
"""
import glob
import sys
from pathlib import Path

from igwn_ligolw import lsctables
from igwn_ligolw import utils as ligolw_utils
from ligo.skymap.io.events.ligolw import ContentHandler

COLS = ("mass1", "mass2", "spin1z", "spin2z", "distance", "longitude", "latitude", "inclination", "geocent_end_time",
        "geocent_end_time_ns")


def rows(path):
    doc = ligolw_utils.load_filename(str(path), contenthandler=ContentHandler)
    return [tuple(getattr(s, c) for c in COLS) for s in lsctables.SimInspiralTable.get_table(doc)]


new = rows(sys.argv[1])
same = differ = 0
for f in sorted(glob.glob(sys.argv[2] + "/events-*.xml.gz")):
    k = int(Path(f).name[7:11])
    old = rows(f)
    if old and set(old) <= set(new[50 * k:50 * (k + 1)]):
        same += 1
    else:
        differ += 1
        print("differs:", f, len(old), old[:1], new[50 * k:50 * k + 1])
print(f"{len(new)} injections; committed chunks whose injections (the detected ones they keep) are in the same slice of this machine's injections: {same}, different: {differ}")
