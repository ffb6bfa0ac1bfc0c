"""Running ligo.skymap's command-line tools (BAYESTAR) from a study's tasks.

A tool runs in a session of its own with ``OMP_NUM_THREADS`` set (one core
per worker), is killed with its process group when the calling thread is
interrupted, and (on Linux) dies with the worker process that started it.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Sequence

__all__ = ["run_tool"]


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Linux: the tool gets SIGKILL when the worker that started it dies (no orphaned BAYESTAR runs)."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:
        pass


def run_tool(cmd: Sequence[str], cwd: str | Path | None = None, omp_threads: int | None = None) -> float:
    """Run one ligo.skymap tool; its CPU time (s, children's user+sys); raise with its stderr tail.

    The tool runs in a session of its own, is killed with its process group
    when the calling thread is interrupted, and (on Linux) dies with the
    worker process that started it.
    """
    import signal

    env = dict(os.environ)
    if omp_threads is not None:
        env["OMP_NUM_THREADS"] = str(omp_threads)
    exe = shutil.which(cmd[0])
    if exe is None:
        raise RuntimeError(f"{cmd[0]} not found on PATH (ligo.skymap with lalsuite: pip install 'mushrooms[simulate]')")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    exe = os.path.abspath(exe)  # a relative PATH entry (``.venv/bin``) would not resolve from ``cwd``
    proc = subprocess.Popen([exe, *cmd[1:]], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
    try:
        stdout, stderr = proc.communicate()
    except BaseException:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
        raise
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        tail = " | ".join((stderr or stdout).strip().splitlines()[-3:])
        raise RuntimeError(f"{cmd[0]} exited {proc.returncode}: {tail}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
