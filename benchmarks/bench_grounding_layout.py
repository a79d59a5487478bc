"""The exact grounding layouts (``PlannerConfig.grounding_search``) side by side on the default device.

Usage:  python benchmarks/bench_grounding_layout.py [--repeats 30] [--out benchmarks/results]

Interleaved rounds (every slot timed once per round), float32, the Nidelva chart (13 Table 2 polygons after
RDP at 2 m, 2 510 edges):
* ``nearest_step``: the last step of the exact cost - each polygon's nearest edge for one point per column
  (``polygon_distance``) - one edge per loop step (``block`` 1, the culled layout) against 32 edges per step
  (the dense layout), for 39 / 1 014 / 2 028 points;
* ``solve``: the whole Nidelva head-on solve (2 obstacles x 5 scenarios, n_cbs 39 and 1 014) with
  ``grounding_search`` ``culled`` and ``dense``.
"""

from __future__ import annotations

import os
import sys

import jax
import jax.numpy as jnp
import numpy as np

from psbmpc_jax import Planner, PlannerConfig, paper_behaviours
from psbmpc_jax.examples import nidelva_head_on
from psbmpc_jax.geometry import edge_table, polygon_distance
from psbmpc_jax.packing import pack_world
from psbmpc_jax.solve import solve

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import interleaved_parser, run_interleaved  # noqa: E402


def nearest_step_slots(situation, sizes=(39, 1014, 2028)):
    world = pack_world(situation.polygons, PlannerConfig(), origin=np.zeros(2))
    poly = world.polygons
    tables = edge_table(poly.vertices, poly.next)
    rng = np.random.default_rng(0)
    pts = {n: (jnp.asarray(rng.uniform(-300.0, 300.0, n), jnp.float32),
               jnp.asarray(rng.uniform(-300.0, 300.0, n), jnp.float32)) for n in sizes}
    slots = []
    for block in (1, 32):
        @jax.jit
        def f(px, py, block=block):
            def one(c, p):
                d, ex, ey = polygon_distance(px, py, p[0], p[1], block=block)
                return c, (d, ex, ey)
            return jax.lax.scan(one, None, (tables, poly.n))[1]
        for n in sizes:
            px, py = pts[n]
            slots.append({"point": {"what": "nearest_step", "block": block, "n_points": n,
                                    "n_edges": int(jnp.sum(poly.n))},
                          "call": (lambda f=f, px=px, py=py: f(px, py))})
    # the two blocks give the same distances (rounding aside)
    for n_i in range(len(sizes)):
        a, b = slots[n_i]["call"](), slots[len(sizes) + n_i]["call"]()
        np.testing.assert_allclose(np.asarray(a[0]), np.asarray(b[0]), rtol=1e-5, atol=1e-3)
    return slots


def solve_slots(situation, n_cbs=(39, 1014)):
    slots = []
    for n in n_cbs:
        beh = paper_behaviours(1) if n == 39 else paper_behaviours(2)
        assert len(beh) == n, (len(beh), n)
        for search in ("culled", "dense"):
            config = PlannerConfig(grounding_search=search)
            prepared = Planner(config, behaviours=beh).prepare(situation, key=jax.random.key(0))
            compiled = solve.lower(*prepared, config=config).compile()
            slots.append({"point": {"what": "solve", "grounding_search": search, "n_cbs": n},
                          "call": (lambda c=compiled, p=prepared: c(*p))})
    return slots


def main(argv=None) -> int:
    args = interleaved_parser(__doc__.splitlines()[0], 30).parse_args(argv)
    situation = nidelva_head_on()
    slots = nearest_step_slots(situation) + solve_slots(situation)
    run_interleaved(slots, args, "grounding_layout",
                    "exact grounding layouts: culled vs dense (PlannerConfig.grounding_search)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
