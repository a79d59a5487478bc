"""The shape annotations of the kernels' signatures (psbmpc_jax/array_types.py): the checker binds each dimension
name to one size and refuses a mismatch by name; on small cases the shapes the annotated functions of solve.py,
objective.py and rollout_kernel.py return are the shapes their annotations state."""

from __future__ import annotations

from typing import Annotated

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Planner, PlannerConfig
from psbmpc_jax.array_types import Shape, check_shapes, shapes_of
from psbmpc_jax.objective import objective
from psbmpc_jax.ownship import make_path
from psbmpc_jax.rollout_kernel import los_rollout_kernel
from psbmpc_jax.solve import Plan, break_ties, selection_cost, signed_distance, solve

from conftest import SMALL_BEHAVIOURS, random_situation


def _f(a: Annotated[jax.Array, Shape("B n_M 2")], b: Annotated[jax.Array, Shape("B")]) -> tuple[
        Annotated[jax.Array, Shape("")], int]:
    return jnp.sum(a), 0


def test_names_bind_once_and_a_mismatch_is_named():
    sizes = check_shapes(_f, {"a": np.zeros((4, 3, 2)), "b": np.zeros(4), "return": (np.float64(1.0), 0)})
    assert sizes == {"B": 4, "n_M": 3}
    with pytest.raises(ValueError, match=r"_f.b: axis 0 \(B\) has size 5, expected 4 \(annotation \[B\]\)"):
        check_shapes(_f, {"a": np.zeros((4, 3, 2)), "b": np.zeros(5)})
    with pytest.raises(ValueError, match=r"_f.a: axis 2 \(2\) has size 3, expected 2"):
        check_shapes(_f, {"a": np.zeros((4, 3, 3))})
    with pytest.raises(ValueError, match=r"_f.a: shape \(4, 3\) has 2 axes, the annotation \[B n_M 2\] has 3"):
        check_shapes(_f, {"a": np.zeros((4, 3))})
    with pytest.raises(ValueError, match=r"_f.return\[0\]: shape \(2,\) has 1 axes"):
        check_shapes(_f, {"return": (np.zeros(2), 0)})
    with pytest.raises(ValueError, match=r"_f.c has no Shape annotation"):
        check_shapes(_f, {"c": 1.0})
    assert shapes_of(_f)["return"] == (Shape(""), None)


def test_the_public_kernels_are_annotated():
    assert set(shapes_of(Plan)) == {"best", "offsets", "total", "status"}
    assert set(shapes_of(break_ties)) == {"rank", "valid", "offsets", "return"}
    assert set(shapes_of(signed_distance)) == {"px", "py", "return"}
    assert set(shapes_of(selection_cost)) == {"return"}
    assert set(shapes_of(objective)) == {"controls", "last_offsets", "return"}
    assert {"x0", "chi_offsets", "U_cmd", "lateral_offset", "seg_speed", "return"} <= set(shapes_of(los_rollout_kernel))


def test_solve_and_objective_return_the_annotated_shapes():
    config = PlannerConfig(T=10.0, dt=1.0, grounding_mode="grid", grid_spacing=2.0)
    planner = Planner(config, behaviours=SMALL_BEHAVIOURS)
    inputs, state, params, samples = planner.prepare(random_situation(0, T=10.0, n_polygons=2))
    plan, _, ev = solve(inputs, state, params, samples, config=config)
    n_b, n_m = np.shape(inputs.behaviours.offsets)[:2]                 # padded behaviour table [B, n_M, 2]
    sizes = check_shapes(Plan, {k: v for k, v in plan._asdict().items() if k != "costs"})
    assert sizes == {"n_M": n_m}
    rank = selection_cost(ev, inputs, params, config)
    sizes = check_shapes(selection_cost, {"return": rank})
    valid = inputs.behaviours.mask & jnp.isfinite(ev.total)
    check_shapes(break_ties, {"rank": rank, "valid": valid, "offsets": inputs.behaviours.offsets,
                              "return": break_ties(rank, valid, inputs.behaviours.offsets)}, sizes)
    assert sizes == {"B": n_b, "n_M": n_m}
    px, py = ev.own.x[-1], ev.own.y[-1]                                 # the end points of the behaviours [B]
    dist = signed_distance(px, py, inputs.world.polygons)
    sizes = check_shapes(signed_distance, {"px": px, "py": py, "return": dist})
    assert sizes == {"B": n_b, "P": np.shape(inputs.world.polygons.vertices)[0]}
    controls = jnp.asarray(SMALL_BEHAVIOURS[3])
    out = jax.jit(lambda c: objective(c, inputs, params, samples, config))(controls)
    assert check_shapes(objective, {"controls": controls, "return": out}) == {"K": n_m}



def test_the_rollout_kernel_returns_the_annotated_shapes():
    rng = np.random.default_rng(0)
    rows, n = 5, 6
    x0 = jnp.asarray(np.c_[rng.normal(0, 5, (rows, 2)), rng.uniform(-1, 1, rows), rng.uniform(0.5, 3, rows)])
    path = make_path(jnp.asarray([[0.0, 30.0, 60.0]]), jnp.asarray([[0.0, 5.0, 20.0]]), jnp.asarray([3], jnp.int32))
    chi, u, lat = jnp.zeros((n, rows)), jnp.ones((n, rows)), jnp.zeros(rows)
    out = los_rollout_kernel(x0, path, chi, u, lat, 8.0, 6.0, 3.0, 5.0, 0.5, interpret=True)
    assert len(out) == 7                                   # x, y, chi, U, cos chi, sin chi, segment
    sizes = check_shapes(los_rollout_kernel, {"x0": x0, "chi_offsets": chi, "U_cmd": u, "lateral_offset": lat,
                                              "return": out})
    assert sizes == {"R": rows, "N": n, "T": n + 1}
    with pytest.raises(ValueError, match=r"los_rollout_kernel.return\[6\]: axis 1 \(R\) has size 4, expected 5"):
        check_shapes(los_rollout_kernel, {"return": (*out[:6], out[6][:, :4])})
