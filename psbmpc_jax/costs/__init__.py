"""Cost terms: the PSB-MPC terms of eq. (9) (collision probability + kinetic factor, COLREGS, grounding, path)
and the smooth SB-MPC family of Smooth-SBMPC (sigmoid-gated collision risk, fuzzy COLREGS, smooth
manoeuvring cost), and the Monte-Carlo + Kalman-filter collision risk of Tengesdal, Brekke & Johansen 2020
(``mcskf``). Each term is a ``@cost_term`` class (``costs.base``)."""

from .base import Context, TermValue, cost_term
from .manoeuvring import SmoothManoeuvringTerm, gamma_johansen, gamma_sequence, gamma_smooth
from .sbmpc import FuzzyColregsTerm, SbmpcHazardTerm, SmoothCollisionTerm, sbmpc_costs
from .colregs_fuzzy import encounter_inputs, fis_colregs
from .informed import InformedSbmpcTerm
from .mcskf import Psbmpc2020Term

__all__ = ["Context", "TermValue", "cost_term", "SmoothManoeuvringTerm", "gamma_johansen", "gamma_sequence",
           "gamma_smooth", "FuzzyColregsTerm", "SbmpcHazardTerm", "SmoothCollisionTerm", "sbmpc_costs",
           "encounter_inputs", "fis_colregs", "Psbmpc2020Term", "InformedSbmpcTerm"]
