"""Sum the per-test profile written with ``PSBMPC_TEST_PROFILE=DIR`` (tests/compile_profile.py).

    python tools/suite_profile.py DIR [--top 40] [--json OUT.json --commit SHA]

Prints the suite's wall and compile seconds (summed over workers), the files by wall time with their compile
share, the slowest tests, and the compiled programs by total compile seconds and count (a program compiled
many times across tests is a candidate for one shared shape)."""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path


def load(folder: Path) -> list[dict]:
    """Every test's row, in each worker's order, with the worker's name (its file) as ``worker``."""
    rows = []
    for path in sorted(folder.glob("*.jsonl")):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            try:
                rows.append({**json.loads(line), "worker": path.stem})
            except json.JSONDecodeError as exc:
                raise SystemExit(f"{path}:{n}: not a JSON line ({exc})") from None
    if not rows:
        raise SystemExit(f"{folder}: no *.jsonl profile lines (run pytest with PSBMPC_TEST_PROFILE={folder})")
    return rows


def cache_clears(rows: list[dict]) -> tuple[int, float]:
    """The memory-map guard's cache clears and the compile seconds, after a clear, of programs (by name) that the
    same worker had compiled before it: an upper bound of what the clears cost (a name covers every shape)."""
    clears, after = 0, 0.0
    seen: dict[str, set] = defaultdict(set)
    evicted: dict[str, set] = defaultdict(set)
    for r in rows:
        w = r.get("worker", "")
        for name, sec in r["programs"].items():
            if name in evicted[w]:
                after += sec
            seen[w].add(name)
        if r.get("caches_cleared"):
            clears += 1
            evicted[w] |= seen[w]
    return clears, after


def write_record(rows: list[dict], out: Path, commit: str | None) -> None:
    """Per-file and per-program sums, the slowest tests and the run's environment, as one JSON document."""
    import os
    import platform
    import sys
    from datetime import datetime, timezone

    import jax

    if out.exists():
        raise SystemExit(f"{out}: exists; give a new file name (records are never overwritten)")
    files: dict = defaultdict(lambda: {"wall_s": 0.0, "compile_s": 0.0, "tests": 0})
    progs: dict = defaultdict(lambda: {"compile_s": 0.0, "tests": 0})
    for r in rows:
        f = files[r["test"].split("::")[0]]
        f["wall_s"] += r["wall_s"]
        f["compile_s"] += r["compile_s"] + r["trace_s"] + r["lower_s"]
        f["tests"] += 1
        for name, sec in r["programs"].items():
            progs[name]["compile_s"] += sec
            progs[name]["tests"] += 1
    doc = {"meta": {"what": "per-test profile of the test suite (PSBMPC_TEST_PROFILE)", "commit": commit,
                    "date": datetime.now(timezone.utc).isoformat(timespec="seconds"), "python": sys.version.split()[0],
                    "jax": jax.__version__, "platform": platform.machine(), "cpu_count": os.cpu_count()},
           "totals": {"tests": len(rows), "worker_s": round(sum(r["wall_s"] for r in rows), 1),
                      "trace_lower_compile_s": round(sum(r["compile_s"] + r["trace_s"] + r["lower_s"] for r in rows), 1),
                      "compiles": sum(r["n_compiles"] for r in rows),
                      "cache_clears": cache_clears(rows)[0],
                      "compile_s_after_clears_upper_bound": round(cache_clears(rows)[1], 1)},
           "files": {k: {kk: round(vv, 1) if isinstance(vv, float) else vv for kk, vv in v.items()}
                     for k, v in sorted(files.items(), key=lambda kv: -kv[1]["wall_s"])},
           "programs": {k: {"compile_s": round(v["compile_s"], 1), "tests": v["tests"]}
                        for k, v in sorted(progs.items(), key=lambda kv: -kv[1]["compile_s"])[:100]},
           "slowest": [{"test": r["test"], "wall_s": round(r["wall_s"], 1), "compile_s": round(r["compile_s"], 1),
                        "n_compiles": r["n_compiles"]} for r in sorted(rows, key=lambda r: -r["wall_s"])[:60]]}
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(out.suffix + ".tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    tmp.replace(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--top", type=int, default=40)
    ap.add_argument("--json", type=Path, default=None, help="also write the sums as a JSON record (refuses to "
                    "overwrite an existing file)")
    ap.add_argument("--commit", default=None, help="the commit the profiled run tested (stored in --json)")
    a = ap.parse_args(argv)
    rows = load(a.folder)
    if a.json is not None:
        write_record(rows, a.json, a.commit)
    wall = sum(r["wall_s"] for r in rows)
    comp = sum(r["compile_s"] + r["trace_s"] + r["lower_s"] for r in rows)
    print(f"{len(rows)} tests: {wall:.0f} worker-s, of which trace+lower+compile {comp:.0f} s "
          f"({100 * comp / wall:.0f} %), {sum(r['n_compiles'] for r in rows)} compiles")
    clears, after = cache_clears(rows)
    print(f"{clears} cache clears by the memory-map guard; compiling again, after them, programs of the names "
          f"compiled before: at most {after:.0f} s")
    files: dict = defaultdict(lambda: [0.0, 0.0, 0])
    for r in rows:
        f = files[r["test"].split("::")[0]]
        f[0] += r["wall_s"]
        f[1] += r["compile_s"] + r["trace_s"] + r["lower_s"]
        f[2] += 1
    print(f"\n{'file':58s} {'wall s':>8s} {'compile':>8s} {'tests':>6s}")
    for name, (w, c, n) in sorted(files.items(), key=lambda kv: -kv[1][0])[:a.top]:
        print(f"{name:58s} {w:8.1f} {100 * c / max(w, 1e-9):7.0f}% {n:6d}")
    print(f"\n{'test':90s} {'wall s':>8s} {'compile s':>9s} {'n':>4s}")
    for r in sorted(rows, key=lambda r: -r["wall_s"])[:a.top]:
        print(f"{r['test'][:90]:90s} {r['wall_s']:8.1f} {r['compile_s']:9.1f} {r['n_compiles']:4d}")
    progs: dict = defaultdict(lambda: [0.0, 0, set()])
    for r in rows:
        for name, s in r["programs"].items():
            p = progs[name]
            p[0] += s
            p[1] += 1
            p[2].add(r["test"].split("::")[0])
    print(f"\n{'program':50s} {'compile s':>9s} {'tests':>6s} {'files':>6s}")
    for name, (s, n, fs) in sorted(progs.items(), key=lambda kv: -kv[1][0])[:a.top]:
        print(f"{name[:50]:50s} {s:9.1f} {n:6d} {len(fs):6d}")


if __name__ == "__main__":
    main()
