"""Child processes of a process, read from Linux's /proc: the campaign tests and ``benchmarks/bench_campaign_rows.py``
find the campaign's worker processes with it (to kill one mid-way)."""

from __future__ import annotations

import pathlib


def children(pid: int, needle: bytes) -> list[int]:
    """Processes whose parent is ``pid`` and whose command line holds ``needle`` (empty where /proc is absent)."""
    out = []
    proc = pathlib.Path("/proc")
    for p in proc.iterdir() if proc.is_dir() else ():
        if not p.name.isdigit():
            continue
        try:
            ppid = int((p / "stat").read_text().rsplit(")", 1)[1].split()[1])
            cmd = (p / "cmdline").read_bytes()
        except (OSError, IndexError, ValueError):
            continue
        if ppid == pid and needle in cmd:
            out.append(int(p.name))
    return out
