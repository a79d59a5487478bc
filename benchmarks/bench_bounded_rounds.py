"""The bounded grounding search alone, by rounds: this checkout against an older copy of the package, one
interleaved run.

The points of ``tests/test_bounded_search.py`` (three star-shaped islands of 58 + 59 + 59 vertices, one with a
hole, packed to 4 polygons; ``--columns`` straight runs at 3-9 m/s in a fan of courses over T = 241 steps of
0.5 s, float32) searched by :func:`psbmpc_jax.bounded_search.bounded_candidates` (jitted, the default grounding
score without wind) with the first round only, the first two, and all of :data:`~psbmpc_jax.bounded_search.ROUNDS`.
Recorded per slot: median / min / max of the interleaved repeats and the pairs left unproven; both versions must
leave the same number unproven.  ``--baseline DIR``: a directory holding another copy of the package renamed
``psbmpc_old`` (as for ``bench_cpu_targets.py``).

Usage: PYTHONPATH=.:/tmp/oldpkg python benchmarks/bench_bounded_rounds.py --baseline /tmp/oldpkg [--columns 1014]
[--repeats 15] [--out DIR]
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

import jax
import jax.numpy as jnp

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "tests"))
from _common import environment_meta, time_interleaved, write_results  # noqa: E402


def slots_for(package: str, tree: str, columns: int) -> list:
    from test_bounded_search import fan, islands, pack      # the test's chart and points

    bs = importlib.import_module(f"{package}.bounded_search")
    params = importlib.import_module(f"{package}.params").Params()
    score, bound = importlib.import_module(f"{package}.costs.grounding")._search_score(params)
    tables, nxt, n = pack(islands())
    tables = tables.astype(jnp.float32)
    px, py, tw = (a.astype(jnp.float32) for a in fan(columns, T=241, seed=1))
    out = []
    for label, rounds in (("round 1", bs.ROUNDS[:1]), ("rounds 1-2", bs.ROUNDS[:2]), ("all rounds", bs.ROUNDS)):
        f = jax.jit(lambda px, py, tw, rounds=rounds: bs.bounded_candidates(px, py, tw, score, bound, tables, nxt,
                                                                             n, False, rounds=rounds))
        unproven = int(jnp.sum(~f(px, py, tw)[1]))
        out.append({"point": {"tree": tree, "rounds": label, "columns": columns, "unproven_pairs": unproven},
                    "call": lambda f=f: f(px, py, tw)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default=None, help="directory holding the package psbmpc_old")
    ap.add_argument("--columns", type=int, default=1014)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--out", default=os.path.join(HERE, "results"))
    a = ap.parse_args(argv)
    if a.columns < 1 or a.repeats < 1:
        ap.error("--columns and --repeats must be >= 1")
    jax.config.update("jax_enable_x64", True)          # the test module's fan/pack build float64, cast to float32
    slots = slots_for("psbmpc_jax", "new", a.columns)
    if a.baseline:
        sys.path.insert(0, a.baseline)
        slots += slots_for("psbmpc_old", "old", a.columns)
        for new, old in zip(slots[:3], slots[3:]):
            if new["point"]["unproven_pairs"] != old["point"]["unproven_pairs"]:
                raise SystemExit(f"{new['point']['rounds']}: {new['point']['unproven_pairs']} unproven pairs new, "
                                 f"{old['point']['unproven_pairs']} old: not the same search")
    points = time_interleaved(slots, a.repeats)
    for p in points:
        print(f"{p['tree']:3s} {p['rounds']:10s} unproven {p['unproven_pairs']:5d}  median "
              f"{p['median_ms']:7.2f} ms", flush=True)
    meta = environment_meta("bounded grounding search alone, by rounds", repeats=a.repeats, baseline=a.baseline,
                            schedule="interleaved", load_avg=os.getloadavg())
    write_results(a.out, "bounded_rounds", meta, points)
    return 0


if __name__ == "__main__":
    sys.exit(main())
