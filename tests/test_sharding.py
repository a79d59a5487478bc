"""Tests of :func:`psbmpc_jax.sharding.solve_sharded` (behaviour axis split over devices with shard_map).

The in-process session has a single CPU device (its device count is fixed once JAX initialises), so the
multi-device comparisons run in a subprocess with ``--xla_force_host_platform_device_count=4``: 4 devices
(B = 64 divides evenly) and 3 devices (B = 64 -> 66, padded with masked copies of behaviour 0).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax import Planner, PlannerConfig, solve
from psbmpc_jax.packing import BehaviourArrays, pad_behaviours
from psbmpc_jax.sharding import _sharded_fn, check_devices, solve_sharded

from conftest import CAPS, ROOT, SMALL_BEHAVIOURS, pad_arrays, random_situation, run_on_four_host_devices

CFG = PlannerConfig(dtype="float64", T=30.0, dt=0.5, n_samples=128)
PER_B = ("total", "do", "colregs", "so", "path", "C", "mu", "so_j")


def prepared(seed: int, config: PlannerConfig = CFG, **caps):
    planner = Planner(config, behaviours=SMALL_BEHAVIOURS)
    arrays, state, params, samples = planner.prepare(random_situation(seed), key=jax.random.key(seed))
    return pad_arrays(arrays, **{**CAPS, **caps}), state, params, samples


def _get(ev, name):
    return ev.costs[name] if name in ev.costs else getattr(ev, name)


def assert_same(got_out, want_out, n_real: int, rtol: float = 1e-12):
    """Two solve results ``(plan, state, evaluation)`` agree on the first ``n_real`` behaviours."""
    (got_plan, got_state, got), (want_plan, want_state, want) = got_out, want_out
    assert int(got_plan.best) == int(want_plan.best) and int(got_plan.status) == int(want_plan.status) == 0
    np.testing.assert_array_equal(np.asarray(got_state.last_offsets), np.asarray(want_state.last_offsets))
    assert int(got.best) == int(want.best)
    np.testing.assert_array_equal(np.asarray(got.best_offsets), np.asarray(want.best_offsets))
    for name in PER_B:
        g, w = np.asarray(_get(got, name)), np.asarray(_get(want, name))
        assert g.shape == w.shape, name
        np.testing.assert_allclose(g[:n_real], w[:n_real], rtol=rtol, atol=1e-300, err_msg=name)
    for name in ("x", "y", "chi", "U"):
        np.testing.assert_allclose(np.asarray(getattr(got.own, name))[:, :n_real],
                                   np.asarray(getattr(want.own, name))[:, :n_real], rtol=rtol, atol=1e-12)
        np.testing.assert_allclose(np.asarray(getattr(got.obstacles, name)),
                                   np.asarray(getattr(want.obstacles, name)), rtol=rtol, atol=1e-12)
    np.testing.assert_allclose(np.asarray(got.obs_cov), np.asarray(want.obs_cov), rtol=rtol, atol=1e-15)


# ------------------------------------------------------------------------------------------ in process
def test_single_device_matches_evaluate():
    fn, _ = _sharded_fn(CFG, tuple(jax.local_devices()))
    sizes = []
    for seed in (0, 4):
        arrays, state, params, samples = prepared(seed)
        n_real = int(np.sum(np.asarray(arrays.behaviours.mask)))
        want = solve(arrays, state, params, samples, config=CFG)
        got = solve_sharded(arrays, state, params, samples, CFG)          # default: jax.local_devices()
        assert_same(got, want, n_real)
        assert int(got[2].n_pc_blocks) == int(want[2].n_pc_blocks)
        assert np.all(np.isinf(np.asarray(got[2].total)[n_real:]))       # padded behaviours masked
        sizes.append(fn._cache_size())
    # one compiled program per (config, device set, terms, shapes): the second seed must not recompile.
    # Other tests may have compiled the same function for other term sets, so compare, not count.
    assert sizes[1] == sizes[0] >= 1


def test_unbucketed_behaviour_count_and_mc():
    """B = 30 (not a multiple of 64) and the Monte Carlo estimator's sample table (replicated input)."""
    cfg = CFG.replace(estimator="mc")
    arrays, state, params, samples = prepared(2, cfg, B=None)
    beh = arrays.behaviours
    arrays = arrays._replace(behaviours=BehaviourArrays(beh.offsets[:30], beh.mask[:30]))
    want = solve(arrays, state, params, samples, config=cfg)
    got = solve_sharded(arrays, state, params, samples, cfg, devices=jax.local_devices()[:1])
    assert got[2].total.shape == (30,) and got[2].own.x.shape[1] == 30
    assert_same(got, want, 30)


def test_pad_behaviours():
    beh = np.arange(7 * 2 * 2, dtype=float).reshape(7, 2, 2)
    mask = np.array([True] * 5 + [False] * 2)
    arrays = prepared(0)[0]._replace(behaviours=BehaviourArrays(jnp.asarray(beh), jnp.asarray(mask)))

    def padded(multiple):
        out = pad_behaviours(arrays, multiple).behaviours
        return np.asarray(out.offsets), np.asarray(out.mask)

    pb, pm = padded(4)
    assert pb.shape == (8, 2, 2) and pm.shape == (8,)
    np.testing.assert_array_equal(pb[:7], beh)
    np.testing.assert_array_equal(pb[7], beh[0])                           # masked copy of behaviour 0
    np.testing.assert_array_equal(pm, [True] * 5 + [False] * 3)
    pb, pm = padded(3)
    assert pb.shape[0] == 9 and not pm[7:].any()
    pb, pm = padded(7)                                                     # already a multiple
    np.testing.assert_array_equal(pb, beh)
    np.testing.assert_array_equal(pm, mask)


class _FakeDevice:
    """Not a jax device, on a platform no real device has (the mix check must fire on any host, GPU too)."""
    platform = "not-a-platform"


def test_device_errors():
    arrays, state, params, samples = prepared(0)
    with pytest.raises(ValueError, match="at least one device"):
        solve_sharded(arrays, state, params, samples, CFG, devices=[])
    with pytest.raises(ValueError, match="one platform"):
        check_devices([jax.local_devices()[0], _FakeDevice()])
    with pytest.raises(ValueError, match="jax devices"):
        solve_sharded(arrays, state, params, samples, CFG, devices=["cpu:0"])
    with pytest.raises(ValueError, match="distinct"):
        check_devices(jax.local_devices()[:1] * 2)
    assert check_devices(None) == tuple(jax.local_devices())


def test_behaviour_errors():
    arrays, state, params, samples = prepared(0)
    beh = arrays.behaviours
    empty = arrays._replace(behaviours=BehaviourArrays(beh.offsets[:0], beh.mask[:0]))
    with pytest.raises(ValueError, match="at least one real"):
        solve_sharded(empty, state, params, samples, CFG)
    all_masked = arrays._replace(behaviours=BehaviourArrays(beh.offsets, jnp.zeros_like(beh.mask)))
    with pytest.raises(ValueError, match="at least one real"):
        solve_sharded(all_masked, state, params, samples, CFG)
    with pytest.raises(ValueError, match="PlannerConfig"):
        solve_sharded(arrays, state, params, samples, "float64")
    with pytest.raises(ValueError, match="PlannerState"):
        solve_sharded(arrays, (1.0, 0.0), params, samples, CFG)


# ------------------------------------------------------------------------------------------ 4 host devices
SCRIPT = textwrap.dedent("""
    import importlib.util, sys
    import jax, numpy as np
    spec = importlib.util.spec_from_file_location("sharding_conftest", sys.argv[1])
    conf = importlib.util.module_from_spec(spec); spec.loader.exec_module(conf)
    tests = importlib.util.spec_from_file_location("sharding_tests", sys.argv[2])
    sys.modules["conftest"] = conf
    t = importlib.util.module_from_spec(tests); tests.loader.exec_module(t)
    from psbmpc_jax import solve
    from psbmpc_jax.packing import unpack
    from psbmpc_jax.sharding import solve_sharded
    if len(sys.argv) > 3:
        jax.config.update("jax_compilation_cache_dir", sys.argv[3])
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    devs = jax.local_devices()
    assert len(devs) == 4 and jax.config.jax_enable_x64, (devs, jax.config.jax_enable_x64)
    for seed in (0, 2, 4):
        arrays, state, params, samples = t.prepared(seed)
        n_real = int(np.sum(np.asarray(arrays.behaviours.mask)))
        want_out = solve(arrays, state, params, samples, config=t.CFG)
        want = want_out[2]
        for n_dev in (4, 3):
            got_out = solve_sharded(arrays, state, params, samples, t.CFG, devices=devs[:n_dev])
            t.assert_same(got_out, want_out, n_real)
            got = got_out[2]
            assert set(got.total.sharding.device_set) <= set(devs[:n_dev])
            assert len(got.C.sharding.device_set) == n_dev            # really spread over the devices
            if n_dev == 4:                                            # 64 % 4 == 0: no extra padding
                assert int(got.n_pc_blocks) == int(want.n_pc_blocks)
            else:                                                     # 2 masked copies of behaviour 0 added
                assert int(got.n_pc_blocks) >= int(want.n_pc_blocks)
        res = unpack(got, conf.random_situation(seed), conf.SMALL_BEHAVIOURS, 0.0)
        ref = unpack(want, conf.random_situation(seed), conf.SMALL_BEHAVIOURS, 0.0)
        assert res.best_index == ref.best_index
        # per behaviour the same code on the same inputs, in float64 equal to the last bits or within rounding
        # (as the module documents: XLA:CPU vectorises a 16-behaviour slice and the 64-behaviour table
        # differently; one total of 30 came out 1 ulp apart at the default optimisation level)
        np.testing.assert_allclose(res.costs["total"], ref.costs["total"], rtol=1e-14, atol=0)
    print("SHARDING-OK", len(devs))
""")


def test_four_host_devices(request):
    # at XLA's default optimisation level, as users compile (LLVM's optimisation off, conftest's default for the
    # suite, is another program)
    proc = run_on_four_host_devices(request, SCRIPT, [ROOT / "tests" / "conftest.py", Path(__file__).resolve()])
    assert "SHARDING-OK 4" in proc.stdout
