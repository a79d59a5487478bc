"""Differentiate the PSB-MPC cost with respect to the maneuver offsets, and refine the grid-search choice.

    python examples/03_gradient.py            # the paper's 1014 behaviours for the grid search, 40 descent steps
    python examples/03_gradient.py --quick    # 39 behaviours (n_M = 1), 10 steps; also PSBMPC_EXAMPLE_QUICK=1

``psbmpc_jax.objective(controls, inputs, params, samples, config)`` is the cost of ONE control input
(per-maneuver offsets ``[n_M, 2]``: speed factor, course offset [rad]) through a dense, gradient-safe
layout; ``vmap`` of it over the behaviour table is the grid search.  Here:

1. plan once (grid search) and take the chosen behaviour;
2. check that ``objective`` gives the same total for it;
3. ``jax.value_and_grad`` of the total w.r.t. the offsets, checked against a central difference;
4. a few projected gradient steps from the grid choice (speed factor kept in [0, 1]).

float64 (``jax_enable_x64``) so that the finite-difference check is clean.  The COLREGS indicator is piecewise
constant in the controls (gradient 0), the collision (quadrature estimator), grounding and path terms are
piecewise smooth.
"""

from __future__ import annotations

import os
import sys

import jax

jax.config.update("jax_enable_x64", True)             # before any array is created

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from psbmpc_jax import Planner, PlannerConfig, objective, paper_behaviours  # noqa: E402
from psbmpc_jax.examples import paper_head_on  # noqa: E402

QUICK = os.environ.get("PSBMPC_EXAMPLE_QUICK") == "1" or "--quick" in sys.argv[1:]


def main() -> int:
    config = PlannerConfig(estimator="quadrature", dtype="float64")
    planner = Planner(config, behaviours=paper_behaviours(1 if QUICK else 2))
    situation = paper_head_on()
    state = planner.init_state()

    # 1. grid search
    result, _ = planner.plan(situation, state)
    start = jnp.asarray(result.offsets)                                  # [n_M, 2] (u, chi [rad])
    print(f"grid search: behaviour #{result.best_index} of {len(planner.behaviours)}, "
          f"total {result.costs['total'][result.best_index]:.6f}")

    # 2. the same cost through the differentiable objective
    inputs, state, params, samples = planner.prepare(situation, state)
    last = jnp.asarray(state.last_offsets)

    def total(controls):
        value, costs = objective(controls, inputs, params, samples, config, last_offsets=last)
        return value, costs

    value_and_grad = jax.jit(jax.value_and_grad(total, has_aux=True))
    (value, costs), grad = value_and_grad(start)
    print(f"objective at it:  total {float(value):.6f} = " + " + ".join(f"{k} {float(v):.4f}"
                                                                        for k, v in costs.items()))

    # 3. the gradient, and a central difference on the first maneuver's course offset
    grad = np.asarray(grad)
    for m in range(grad.shape[0]):
        print(f"d total / d (u, chi) of M{m + 1}: ({grad[m, 0]:+.5f}, {grad[m, 1]:+.5f} per rad)")
    h = 1e-5
    e = np.zeros(start.shape)
    e[0, 1] = h
    f = lambda c: float(value_and_grad(c)[0][0])        # noqa: E731 - the compiled function, value only
    fd = (f(start + e) - f(start - e)) / (2 * h)
    print(f"central difference of d total / d chi_1: {fd:+.5f} (gradient {grad[0, 1]:+.5f})")

    # 4. projected gradient descent from the grid choice (keep the best point seen)
    lower = jnp.asarray([0.0, -np.pi])
    upper = jnp.asarray([1.0, np.pi])
    step = jnp.asarray([0.002, 0.01])                   # per-unit step sizes for (u, chi)
    x, best = start, (float(value), start)
    for _ in range(10 if QUICK else 40):
        (v, _), g = value_and_grad(x)
        if float(v) < best[0]:
            best = (float(v), x)
        x = jnp.clip(x - step * g, lower, upper)
    (v, _), _ = value_and_grad(x)
    if float(v) < best[0]:
        best = (float(v), x)
    refined = np.asarray(best[1])
    print(f"refined: total {best[0]:.6f} (grid {float(value):.6f}) at "
          + ", ".join(f"M{m + 1}: u={u:.3f}, chi={np.rad2deg(c):+.2f} deg" for m, (u, c) in enumerate(refined)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
