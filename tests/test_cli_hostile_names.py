"""Hostile text in a sky map reaches the observer safely (issue 52, LOW).

A sky-map file name with terminal escapes, and a FITS ``OBJECT`` that is
matplotlib mathtext, through ``mushrooms plan`` in a real process on a copy
of a real map: the log, stdout and the ``.txt`` show the escapes escaped
(never a raw ESC or BEL), and ``--plot`` draws the ``OBJECT`` as text
instead of exiting 70 after the plan was written.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def mushrooms(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, cwd=cwd,
                          timeout=600)


def _raw_controls(data: bytes) -> list[int]:
    """C0 controls other than newline and tab, DEL, and the UTF-8 of C1 controls and bidi overrides."""
    text = data.decode("utf-8", "replace")
    return sorted({ord(c) for c in text if (ord(c) < 32 and c not in "\n\t") or 0x7F <= ord(c) <= 0x9F
                   or 0x202A <= ord(c) <= 0x202E or 0x2066 <= ord(c) <= 0x2069})


def test_a_sky_map_file_name_with_terminal_escapes_is_shown_escaped(tmp_path):
    name = "S1\x1b]0;pwned\x07\x1b[2J\u202egnp.fits"  # set the window title, clear the screen, reverse the text
    hostile = tmp_path / name
    shutil.copy(MAP, hostile)
    r = mushrooms("plan", str(hostile), "--solver", "greedy", "--start", "2022-07-23T02:00:00Z", "--set",
                  "scheduler.nside=64", "-o", str(tmp_path / "plan.json"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    txt = (tmp_path / "plan.txt").read_bytes()
    assert b"S1\\x1b]0;pwned\\x07\\x1b[2J" in txt, txt[:400]  # shown, escaped
    for where, data in (("stdout", r.stdout), ("stderr", r.stderr), ("plan.txt", txt),
                        ("plan.html", (tmp_path / "plan.html").read_bytes())):
        assert _raw_controls(data) == [], where


def test_a_fits_object_of_mathtext_is_drawn_as_text(tmp_path):
    from astropy.io import fits

    with fits.open(MAP) as hdus:
        hdus[1].header["OBJECT"] = "$\\frac{$"
        hdus.writeto(tmp_path / "object.fits")
    r = mushrooms("plan", str(tmp_path / "object.fits"), "--solver", "greedy", "--start", "2022-07-23T02:00:00Z",
                  "--set", "scheduler.nside=64", "-o", str(tmp_path / "plan.json"), "--plot",
                  str(tmp_path / "plan.png"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr.decode()[-2000:]
    assert (tmp_path / "plan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"Traceback" not in r.stderr


def test_a_triggered_sky_map_file_name_with_terminal_escapes_is_shown_escaped(tmp_path):
    name = "S1\x1b]0;pwned\x07\x1b[2J\u202egnp.fits"
    shutil.copy(MAP, tmp_path / name)
    (tmp_path / "c.toml").write_text('[scheduler]\nsolver = "greedy"\nnside = 64\n[daemon]\nstate_path = "st.sqlite"\n'
                                     '[outbound]\ndirectory = "out"\n')
    r = mushrooms("trigger", "--config", "c.toml", name, cwd=tmp_path)  # no daemon: planned here
    assert r.returncode == 0, r.stderr
    assert b"S1\\x1b]0;pwned\\x07\\x1b[2J" in r.stdout
    (txt,) = (tmp_path / "out").glob("mushrooms-*.txt")
    for where, data in (("stdout", r.stdout), ("stderr", r.stderr), ("outbox .txt", txt.read_bytes())):
        assert _raw_controls(data) == [], where
