"""Settings of the gradient refinement (``psbmpc_refine``): the ``mpc.refine`` section of a scenario file, parsed
here (registered by :mod:`psbmpc_jax.methods.builtin`).  Light: no JAX."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


from ..checks import integer, multiple_of
from ..config import (as_bool, as_choice, as_mapping, as_number, check_keys)
from ..params import PlannerConfig
from .smooth_settings import MAX_STARTS


@dataclass(frozen=True)
class RefineSpec:
    """``mpc.refine``: the gradient refinement after the PSB-MPC grid search (``psbmpc_refine``): starts,
    horizon [s] (None: the PSB-MPC horizon ``config.T``), the COLREGS term (``"fis"`` or ``"none"``), ``block``:
    how long each refined control is held [s] (``mpc.refine.block_s``, a multiple of ``config.dt``; None: the
    MPC update period, so the refined controls change no faster than the planner re-plans);
    ``fis_e_cl`` / ``fis_n_y``: ``mpc.fis.e_cl_m`` / ``n_y`` when the file gives them (None: the refinement's
    own defaults); ``previous_start``: start 1 is the previous refinement, shifted to now (needs n_starts >= 2;
    default: on whenever n_starts >= 2, docs/refine.md "Closed loop")."""

    n_starts: int = 4
    horizon: float | None = None
    colregs: str = "fis"
    block: float | None = None
    fis_e_cl: float | None = None
    fis_n_y: int | None = None
    previous_start: bool = True


_REFINE_KEYS = ("n_starts", "horizon_s", "colregs", "block_s", "previous_start")


_REFINE_COLREGS = ("fis", "none")


def parse_refine(d, config: PlannerConfig) -> RefineSpec:
    w = "mpc.refine"
    d = as_mapping(d, w)
    check_keys(d, _REFINE_KEYS, w)
    kw: dict[str, Any] = {}
    if "n_starts" in d:
        kw["n_starts"] = integer(d["n_starts"], f"{w}.n_starts", ge=1, le=MAX_STARTS)
    if "horizon_s" in d:
        h = as_number(d["horizon_s"], f"{w}.horizon_s", gt=0)
        if h > config.T * (1 + 1e-9):
            raise ValueError(f"{w}.horizon_s ({h:g}) must be <= the PSB-MPC horizon mpc.config T ({config.T:g}); "
                             f"leave it out for the whole horizon")
        multiple_of(h, config.dt, f"{w}.horizon_s", "the PSB-MPC step mpc.config dt")
        kw["horizon"] = h
    if "colregs" in d:
        kw["colregs"] = as_choice(d["colregs"], _REFINE_COLREGS, f"{w}.colregs")
    if "block_s" in d:
        b = as_number(d["block_s"], f"{w}.block_s", gt=0)
        limit = kw.get("horizon", config.T)
        if b > limit * (1 + 1e-9):
            raise ValueError(f"{w}.block_s ({b:g}) must be <= the refined horizon ({limit:g} s)")
        multiple_of(b, config.dt, f"{w}.block_s", "the PSB-MPC step mpc.config dt")
        kw["block"] = b
    n_starts = kw.get("n_starts", RefineSpec.n_starts)
    if "previous_start" in d:
        kw["previous_start"] = as_bool(d["previous_start"], f"{w}.previous_start")
        if kw["previous_start"] and n_starts < 2:
            raise ValueError(f"{w}.previous_start needs {w}.n_starts >= 2 (start 0 is the grid's choice), got "
                             f"n_starts {n_starts}")
    else:
        kw["previous_start"] = n_starts >= 2          # the default: on whenever there is a second start
    return RefineSpec(**kw)
