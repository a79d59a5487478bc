"""The measurements behind two layout constants, on this device, one interleaved run:

* ``rollout_unroll``: the own-ship rollout alone (1 014 behaviours x 300 steps, float32) at unroll 1, 2, 4, 8, 16
  (``layouts.GPU_UNROLL`` stays small because unrolling makes XLA recompute the recurrence);
* ``geometry.ARGMAX_TILE``: the culled grounding argmax alone at tiles of 32, 64 and 128 time steps on the fig5
  point's 13 Nidelva polygons (1 014 behaviours, T 150 s), fig9's raw 21 961-vertex polygon (own-ship still) and
  the three 176-vertex islands of ``bench_cpu_targets.py`` (1 014 behaviours, T 120 s).

Usage: python benchmarks/bench_layout_choices.py [--repeats 10] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import jax
import jax.numpy as jnp

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import environment_meta, time_interleaved, write_results  # noqa: E402


def rollout_slots(unrolls):
    from psbmpc_jax.apps.bench_points import behaviours_for
    from psbmpc_jax.ownship import make_path, ownship_rollouts
    from psbmpc_jax.params import Params

    p, beh = Params(), jnp.asarray(behaviours_for(1014), jnp.float32)
    path = make_path(jnp.asarray([[0.0, 100.0, 500.0, 900.0]]), jnp.asarray([[0.0, 50.0, 60.0, 300.0]]),
                     jnp.asarray([4], jnp.int32))
    st = jnp.asarray([0.0, 0.0, 0.3, 2.0])
    out = []
    for u in unrolls:
        t0 = time.perf_counter()
        fn = jax.jit(lambda s, b, u=u: ownship_rollouts(s, path, 2.0, b, p, 300, 0.5, unroll=u).x)
        c = fn.lower(st, beh).compile()
        out.append({"point": {"what": "rollout", "unroll": u, "compile_s": round(time.perf_counter() - t0, 2)},
                    "call": lambda c=c: c(st, beh)})
    return out


def argmax_slots(tiles):
    from bench_cpu_targets import situation as islands

    from psbmpc_jax import Params, Planner, PlannerConfig
    from psbmpc_jax.apps.bench_points import Point, behaviours_for, situation_for
    from psbmpc_jax.costs.grounding import _search_score
    from psbmpc_jax.evaluate import context
    from psbmpc_jax.geometry import edge_table, polygon_argmax

    cases = {"fig5 13 polygons": (situation_for(Point("x", "n_cbs", 1014, n_cbs=1014, n_ps=1)), 150.0, 1014),
             "fig9 raw polygon": (situation_for(Point("x", "n_vertices", 0.0, eps=0.0, still=True, largest_only=True,
                                                   n_so=1)), 150.0, 1014),
             "three islands": (islands(True), 120.0, 1014)}
    out = []
    for name, (sit, T, n_cbs) in cases.items():
        cfg = PlannerConfig(T=T)
        inputs, _, params, _ = Planner(cfg, behaviours=behaviours_for(n_cbs)).prepare(sit)
        ctx = jax.jit(lambda i, p: context(i, jnp.zeros(2), p, cfg))(inputs, params)
        poly, tw = inputs.world.polygons, jnp.exp(-params.G4 * ctx.t)
        score, bound = _search_score(Params())
        tables = edge_table(jnp.asarray(poly.vertices), jnp.asarray(poly.next))
        for tile in tiles:
            f = jax.jit(lambda x, y, tile=tile: polygon_argmax(x, y, tw, score, bound, tables, poly.next, poly.n, False,
                                                              tile=tile))
            c = f.lower(ctx.own.x, ctx.own.y).compile()
            out.append({"point": {"what": "argmax", "case": name, "tile": tile},
                        "call": lambda c=c, x=ctx.own.x, y=ctx.own.y: c(x, y)})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args(argv)
    slots = rollout_slots((1, 2, 4, 8, 16)) + argmax_slots((32, 64, 128))
    points = time_interleaved(slots, args.repeats)
    for pt in points:
        print({k: v for k, v in pt.items() if k in ("what", "unroll", "compile_s", "case", "tile", "median_ms")})
    write_results(args.out, "layout_choices", environment_meta("layout constants: rollout unroll and argmax tile",
                                                               repeats=args.repeats, schedule="interleaved"), points)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
