"""Sum the per-test profile written with ``PSBMPC_TEST_PROFILE=DIR`` (tests/compile_profile.py).

    python tools/suite_profile.py DIR [--top 40]

Prints the suite's wall and compile seconds (summed over workers), the files by wall time with their compile
share, the slowest tests, and the compiled programs by total compile seconds and count (a program compiled
many times across tests is a candidate for one shared shape)."""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path


def load(folder: Path) -> list[dict]:
    rows = []
    for path in sorted(folder.glob("*.jsonl")):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError as exc:
                raise SystemExit(f"{path}:{n}: not a JSON line ({exc})") from None
    if not rows:
        raise SystemExit(f"{folder}: no *.jsonl profile lines (run pytest with PSBMPC_TEST_PROFILE={folder})")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--top", type=int, default=40)
    a = ap.parse_args(argv)
    rows = load(a.folder)
    wall = sum(r["wall_s"] for r in rows)
    comp = sum(r["compile_s"] + r["trace_s"] + r["lower_s"] for r in rows)
    print(f"{len(rows)} tests: {wall:.0f} worker-s, of which trace+lower+compile {comp:.0f} s "
          f"({100 * comp / wall:.0f} %), {sum(r['n_compiles'] for r in rows)} compiles")
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
