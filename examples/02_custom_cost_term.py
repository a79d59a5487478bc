"""Add your own cost term with ``@cost_term`` and plan with it.

    python examples/02_custom_cost_term.py            # the paper's 1014 behaviours
    python examples/02_custom_cost_term.py --quick    # 39 behaviours; also PSBMPC_EXAMPLE_QUICK=1

A cost term is a frozen dataclass (``@cost_term`` makes it one and registers it as a JAX pytree).  Its
fields are its parameters: they are traced values, so a new weight never recompiles, and they can be
differentiated.  ``name`` is the cost column it adds; ``__call__(ctx, params, config, samples)`` returns a
:class:`~psbmpc_jax.costs.base.TermValue` holding the cost of every row (behaviour) of ``ctx``.  See
``psbmpc_jax/costs/base.py`` for what the context holds, and ``SpeedLoss`` in ``tests/test_objective.py``
for a term with a float64 ``reference`` counterpart (the test oracle).

The term below is a *comfort zone*: besides the collision cost of the paper, which only sees the
d_safe disc, it charges for passing closer than ``d_comfort`` to any prediction scenario of any
obstacle, weighted by the scenario probability.
"""

from __future__ import annotations

import os
import sys

import jax.numpy as jnp
import numpy as np

from psbmpc_jax import DEFAULT_TERMS, Planner, PlannerConfig, cost_term, paper_behaviours
from psbmpc_jax.costs.base import TermValue
from psbmpc_jax.examples import paper_head_on

QUICK = os.environ.get("PSBMPC_EXAMPLE_QUICK") == "1" or "--quick" in sys.argv[1:]


@cost_term
class ComfortZone:
    """weight x Σ_i Σ_s w_i P_s · mean_t max(0, 1 - d_t / d_comfort)²  for every behaviour."""

    weight: float = 1.0          # parameters: the dataclass fields (traced: new values do not recompile)
    d_comfort: float = 60.0      # [m]
    name = "comfort"             # the cost column (a class attribute, not a parameter)
    smooth = True                # piecewise smooth in the controls (the gradient can be trusted)

    def __call__(self, ctx, params, config, samples):
        own, obs = ctx.own, ctx.obstacles                         # own: [T, B]; obstacles: [T, O, S]
        dx = own.x[:, :, None, None] - obs.x[:, None, :, :]       # [T, B, O, S]
        dy = own.y[:, :, None, None] - obs.y[:, None, :, :]
        d = jnp.sqrt(dx * dx + dy * dy + 1e-9)                    # + eps: finite gradient at d = 0
        closeness = jnp.maximum(0.0, 1.0 - d / self.d_comfort) ** 2
        per_scenario = jnp.mean(closeness, axis=0)                # [B, O, S]
        valid = ctx.scen_valid[None]                              # padded obstacles/scenarios count 0
        weighted = jnp.where(valid, per_scenario * ctx.scen_weight[None], 0.0)
        return TermValue(self.weight * jnp.sum(weighted, axis=(1, 2)))


def describe(result) -> str:
    return ", ".join(f"M{m + 1}: u={u:g}, chi={np.rad2deg(c):+g} deg" for m, (u, c) in enumerate(result.offsets))


def main() -> int:
    behaviours = paper_behaviours(1 if QUICK else 2)
    config = PlannerConfig(estimator="quadrature")
    situation = paper_head_on()                     # river head-on, two vessels coming down (no chart)

    base = Planner(config, behaviours=behaviours)
    result, _ = base.plan(situation)
    print(f"default terms {base.cost_names[1:]}: chosen #{result.best_index} ({describe(result)})")

    # the first plan with the extra term compiles a new solve (new term class); the second weight does not
    # (its value is a traced leaf): compare the solve times
    for weight in (10.0, 100.0):
        planner = Planner(config, behaviours=behaviours, terms=DEFAULT_TERMS + (ComfortZone(weight=weight),))
        result, _ = planner.plan(situation)
        row = result.ranking(1)[0]
        print(f"with comfort weight {weight:g}: chosen #{result.best_index} ({describe(result)}); "
              f"costs " + ", ".join(f"{n}={row[n]:.3f}" for n in planner.cost_names)
              + f"; solve {result.solve_time_s * 1e3:.0f} ms")
    print("cost columns: " + ", ".join(planner.cost_names))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
