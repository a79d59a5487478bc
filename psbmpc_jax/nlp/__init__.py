"""Generic jitted constrained solver for small smooth problems (the solver of the Smooth-SBMPC DOCP, eq. 27 of
Mahipala & Johansen 2024, which names none; docs/solver.md).

    from psbmpc_jax.nlp import SolverSettings, solve_docp, solve_multistart, safeguard
    res = solve_docp(f, u0, lower=lo, upper=hi, eq=eq, ineq=ineq, settings=SolverSettings(), args=data)
    multi = solve_multistart(f, u0s, lower=lo, upper=hi, eq=eq, ineq=ineq, args=data)
    kept = safeguard(res, u_warm, f, lower=lo, upper=hi, eq=eq, ineq=ineq, args=data)

Augmented Lagrangian (PHR) outer loop, L-BFGS on a box reparametrisation (or projected Adam) inner loop,
fixed iteration bounds.  See ``docs/solver.md``.
"""

from .settings import (BOX_MAPS, CONVERGED, INFEASIBLE, MAX_ITER, METHODS, NON_FINITE,
                       STATUS_NAMES, MultistartResult, Safeguarded, SolverResult, SolverSettings)
from .solver import BATCH_MODES, best_index, max_violation, safeguard, solve_docp, solve_multistart

__all__ = ["SolverSettings", "SolverResult", "MultistartResult", "Safeguarded", "solve_docp",
           "solve_multistart", "safeguard", "max_violation", "best_index", "STATUS_NAMES", "CONVERGED",
           "MAX_ITER", "INFEASIBLE", "NON_FINITE", "METHODS", "BOX_MAPS", "BATCH_MODES"]
