"""The status codes of every solve in the library, in one enum.

Two kinds of solve report a status: the PSB-MPC family's behaviour search (:func:`psbmpc_jax.solve.solve`,
``Plan.status``) and the augmented-Lagrangian NLP solver behind Smooth-SBMPC, the two-level path MPC and the
gradient refinement (:func:`psbmpc_jax.nlp.solve_docp`, ``SolverResult.status``).  Both use :class:`Status`, so a
code means the same thing wherever it is stored or printed:

====  ======================  ============================================================================
code  name                    meaning
====  ======================  ============================================================================
0     ok                      the search found a behaviour with a finite cost / the NLP converged
                              (max violation <= tol and relative change of f <= rel_tol)
1     no finite behaviour     search: every behaviour's total is inf or NaN; the plan is meaningless
2     invalid input           search: a non-finite input or a parameter out of its range
3     max-iter                NLP: outer budget spent; the final point is feasible but not converged
4     infeasible              NLP: outer budget spent with violation > tol, or an empty box
5     non-finite              NLP: f, a constraint or a gradient became NaN/inf
====  ======================  ============================================================================

Device code stores the plain ``int32`` value (``int(Status.OK)``); :func:`status_name` turns any stored value
back into its name.
"""

from __future__ import annotations

import enum

__all__ = ["Status", "STATUS_NAMES", "status_name"]


class Status(enum.IntEnum):
    """Outcome of a solve (see the module docstring for the table)."""

    OK = 0
    NO_FINITE_BEHAVIOUR = 1
    INVALID_INPUT = 2
    MAX_ITER = 3
    INFEASIBLE = 4
    NON_FINITE = 5
    CONVERGED = 0          # the NLP's name for OK (an alias: Status.CONVERGED is Status.OK)


#: code -> readable name, for every code of :class:`Status`.
STATUS_NAMES = {
    Status.OK: "ok",
    Status.NO_FINITE_BEHAVIOUR: "no finite behaviour",
    Status.INVALID_INPUT: "invalid input (non-finite value or parameter out of range)",
    Status.MAX_ITER: "max-iter",
    Status.INFEASIBLE: "infeasible",
    Status.NON_FINITE: "non-finite",
}


def status_name(code) -> str:
    """The name of a stored status code (an ``int``, a NumPy or JAX scalar); a code that is not a
    :class:`Status` is an error naming the allowed codes."""
    try:
        return STATUS_NAMES[Status(int(code))]
    except ValueError:
        raise ValueError(f"status code {code!r} is not one of {sorted(int(s) for s in STATUS_NAMES)}") from None
