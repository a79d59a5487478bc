"""Per-platform layouts (psbmpc_jax/layouts.py) and one compiled program per shape (psbmpc_jax/jitting.py).

The GPU's layouts (flat grounding search, dense collision points, unrolled rollouts) give the same numbers as
the CPU's on the same inputs, for every estimator and both grounding modes, in float64 (run here on the CPU
through ``layout_platform="gpu"``); ``for_platform`` resolves the ``auto`` choices; bad values are refused with
the field named; ``solve`` called as the README shows and through ``Planner.plan`` share one compiled program."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from psbmpc_jax import Planner, PlannerConfig
from psbmpc_jax.evaluate import DEFAULT_TERMS
from psbmpc_jax.layouts import DENSE_PC_ELEMENTS, GPU_UNROLL, resolve_pc_layout, resolve_unroll
from psbmpc_jax.solve import PlannerState, solve

from conftest import SMALL_BEHAVIOURS, random_situation

BASE = dict(T=20.0, dt=0.5, dtype="float64", n_samples=64, ce_max_iter=3)


def test_for_platform_resolves_the_auto_layouts():
    gpu = PlannerConfig().for_platform("gpu")
    assert (gpu.grounding_search, gpu.rollout_unroll, gpu.layout_platform) == ("flat", GPU_UNROLL, "gpu")
    assert gpu.pc_layout == "auto"                                 # resolved from the problem's size when traced
    assert gpu.rollout_kernel == ("pallas" if jax.default_backend() == "cpu" else gpu.rollout_kernel)
    assert PlannerConfig().for_platform("cpu").rollout_kernel == "scan"
    cpu = PlannerConfig().for_platform("cpu")
    assert (cpu.grounding_search, cpu.rollout_unroll, cpu.layout_platform) == ("bounded", 1, "cpu")
    kept = PlannerConfig(grounding_search="dense", rollout_unroll=3).for_platform("gpu")
    assert (kept.grounding_search, kept.rollout_unroll) == ("dense", 3)
    assert PlannerConfig().for_platform("cuda").layout_platform == "gpu"


def test_collision_layout_resolution():
    assert resolve_pc_layout("auto", 10, 32, "cpu") == "compact"
    assert resolve_pc_layout("auto", 10, 32, "gpu") == "dense"
    assert resolve_pc_layout("auto", DENSE_PC_ELEMENTS, 2, "gpu") == "compact"
    assert resolve_pc_layout("compact", 10, 32, "gpu") == "compact"
    assert resolve_pc_layout("dense", 10 ** 12, 32, "cpu") == "dense"
    assert resolve_unroll("auto", "cpu") == 1 and resolve_unroll("auto", "gpu") == GPU_UNROLL
    assert resolve_unroll(5, "gpu") == 5


@pytest.mark.parametrize("field, value", [("rollout_unroll", 0), ("rollout_unroll", True), ("rollout_unroll", 2.5),
                                          ("rollout_unroll", "full"), ("layout_platform", "tpu"),
                                          ("grounding_search", "fast"), ("pc_layout", "sparse")])
def test_bad_layout_values_name_the_field(field, value):
    with pytest.raises(ValueError, match=f"PlannerConfig.{field} must be"):
        PlannerConfig(**{field: value})


@pytest.mark.parametrize("estimator, mode, seed", [("quadrature", "exact", 3), ("ce", "exact", 5),
                                                   ("mc", "grid", 7), ("quadrature", "grid", 8)])
def test_gpu_layouts_give_the_cpu_layouts_numbers(estimator, mode, seed):
    """The same solve with the CPU's and the GPU's layouts (run on this CPU): equal totals and terms to
    1e-12 relative, the same choice."""
    sit = random_situation(seed, T=BASE["T"], n_polygons=2)
    key = jax.random.key(seed)
    out = {}
    for plat in ("cpu", "gpu"):
        cfg = PlannerConfig(estimator=estimator, grounding_mode=mode, **BASE).for_platform(plat)
        out[plat], _ = Planner(cfg, behaviours=SMALL_BEHAVIOURS).plan(sit, key=key)
    cpu, gpu = out["cpu"], out["gpu"]
    for name in ("total", "do", "colregs", "so", "path"):
        np.testing.assert_allclose(gpu.costs[name], cpu.costs[name], rtol=1e-12, atol=1e-12, err_msg=name)
    assert np.max(cpu.costs["so"]) > 0 and np.max(cpu.costs["do"]) > 0         # both hazards present
    assert gpu.best_index == cpu.best_index


def test_solve_as_in_the_readme_and_planner_plan_share_one_program():
    """``solve(..., config=c)`` (README), ``solve(..., config=c, terms=DEFAULT_TERMS)`` and ``Planner.plan`` (which
    passes its terms) compile once together."""
    cfg = PlannerConfig(**{**BASE, "T": 12.0, "quad_span": 6.25})             # a config no other test compiles
    planner = Planner(cfg, behaviours=SMALL_BEHAVIOURS)
    sit = random_situation(11, T=12.0)
    inputs, state, params, samples = planner.prepare(sit)
    n0 = solve._cache_size()
    a = solve(inputs, state, params, samples, config=cfg)
    assert solve._cache_size() == n0 + 1
    b = solve(inputs, state, params, samples, config=cfg, terms=DEFAULT_TERMS)
    c = solve(inputs, PlannerState(), params, samples, cfg)
    res, _ = planner.plan(sit)
    assert solve._cache_size() == n0 + 1
    assert int(a[0].best) == int(b[0].best) == int(c[0].best) == res.best_index
    compiled = solve.lower(inputs, state, params, samples, config=cfg).compile()
    assert int(compiled(inputs, state, params, samples)[0].best) == res.best_index   # called like the function
    assert compiled.memory_analysis() is not None
