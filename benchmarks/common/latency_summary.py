"""The first-plan latency summary of the daemon benchmarks (``speed/notify_latency.py``, ``speed/submit_latency.py``).

One line per arm (its latencies in seconds, their median, what else the
script measured beside them), then the whole summary printed and written to
``<out>/<name>`` (the folder made when missing).
"""

from __future__ import annotations

import statistics
from pathlib import Path
from typing import Sequence

__all__ = ["latency_line", "write_summary"]


def latency_line(label: str, latencies: Sequence[float], digits: int = 3, extra: str = "") -> str:
    """``<label> first-plan latency_s: <each> median <m>  <extra>`` (seconds, ``digits`` decimals)."""
    each = " ".join(f"{x:.{digits}f}" for x in latencies)
    return f"{label:8s} first-plan latency_s: {each}  median {statistics.median(latencies):.{digits}f}  {extra}".rstrip()


def write_summary(lines: Sequence[str], out: Path, name: str) -> Path:
    """Print the summary and write it to ``out / name``; the file written."""
    text = "\n".join(lines)
    print(text)
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    path.write_text(text + "\n")
    return path
