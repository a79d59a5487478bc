"""The simulator's runs axis split over several local devices (:func:`psbmpc_jax.sharding.solve_batch`,
``simulate(devices=...)``, ``psbmpc-jax run --devices``).

The in-process session has one CPU device (JAX fixes the count when it starts), so the comparison with the
single-device results runs in a subprocess with ``--xla_force_host_platform_device_count=4``: the head-on
scenario, 5 runs on one device and on 4 (padded to 8), compared bit for bit; with ``PSBMPC_SLOW_TESTS=1`` also
8 runs on 4 (2 solves each) and on 3 (padded to 9).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from psbmpc_jax.apps.argtypes import devices_arg
from psbmpc_jax.apps.cli import main
from psbmpc_jax.scenario import load_scenario
from psbmpc_jax.sharding import local_devices, pad_batch
from psbmpc_jax.sim import simulate
from psbmpc_jax.sim.simulator import check_devices_split, resolve_batch_mode

from conftest import run_on_four_host_devices



# ------------------------------------------------------------------------------------------ in process
def test_local_devices():
    assert local_devices("all") == tuple(jax.local_devices())
    assert local_devices(1) == tuple(jax.local_devices()[:1])
    for bad in (0, -2, True, 1.0, "two", None):
        with pytest.raises(ValueError, match="integer >= 1 or 'all'"):
            local_devices(bad)
    n = len(jax.local_devices())
    with pytest.raises(ValueError, match=rf"devices={n + 1}: this process has {n} local .*allowed: 1\.\.{n}"):
        local_devices(n + 1)


def test_batch_mode_with_devices():
    assert resolve_batch_mode("auto", 4) == "vmap"
    assert resolve_batch_mode("vmap", 2) == "vmap"
    with pytest.raises(ValueError, match="batch 'loop' makes one call per solve"):
        resolve_batch_mode("loop", 2)
    assert resolve_batch_mode("loop", 1) == "loop"


def test_pad_batch():
    tree = (jnp.arange(5.0), jnp.arange(10.0).reshape(5, 2))
    a, b = pad_batch(tree, 4)
    np.testing.assert_array_equal(a, [0, 1, 2, 3, 4, 0, 0, 0])          # copies of row 0
    assert b.shape == (8, 2)
    np.testing.assert_array_equal(b[5:], np.tile(b[:1], (3, 1)))
    same = pad_batch(tree, 5)                                             # already a multiple
    assert same[0].shape == (5,)


def test_simulate_refuses_more_devices_than_there_are():
    sc = dataclasses.replace(load_scenario("head_on"), duration=10.0)
    n = len(jax.local_devices())
    with pytest.raises(ValueError, match=f"devices={n + 1}: this process has {n}"):
        simulate(sc, runs=1, devices=n + 1)
    with pytest.raises(ValueError, match="integer >= 1 or 'all'"):
        simulate(sc, runs=1, devices="four")


def test_all_devices_on_one_device_is_unsplit():
    """``devices="all"`` on a one-device host: exactly the default call (batch auto stays auto)."""
    if len(jax.local_devices()) != 1:
        pytest.skip("needs a single-device process")
    sc = dataclasses.replace(load_scenario("head_on"), duration=10.0)
    assert check_devices_split(sc, "all") == tuple(jax.local_devices())
    a = simulate(sc, runs=1, seed=2, devices="all")
    b = simulate(sc, runs=1, seed=2)
    assert a.summary["devices"] == b.summary["devices"] == 1
    assert a.summary["batch_mode"] == b.summary["batch_mode"] == resolve_batch_mode("auto")
    np.testing.assert_array_equal(a.states, b.states)


def test_devices_argument():
    assert devices_arg("all") == "all" and devices_arg("3") == 3
    for bad in ("0", "x", "-1", "2.5"):
        with pytest.raises(argparse.ArgumentTypeError, match="positive integer or 'all'"):
            devices_arg(bad)


def test_cli_refuses_devices_before_simulating(tmp_path, capsys):
    n = len(jax.local_devices())
    with pytest.raises(SystemExit) as exc:
        main(["run", "head_on", "--runs", "1", "--devices", str(n + 1), "--out", str(tmp_path), "--quiet"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument --devices: devices={n + 1}: this process has {n}" in err
    assert not any(tmp_path.iterdir())                                     # nothing simulated, nothing written
    with pytest.raises(SystemExit) as exc:
        main(["run", "head_on", "--devices", "none"])
    assert exc.value.code == 2
    assert "positive integer or 'all'" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------ 4 host devices
SCRIPT = textwrap.dedent("""
    import dataclasses, json, os, sys, tempfile
    import jax, numpy as np
    if len(sys.argv) > 2:
        jax.config.update("jax_compilation_cache_dir", sys.argv[2])
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    from psbmpc_jax import sharding
    from psbmpc_jax.apps.cli import main
    from psbmpc_jax.evaluate import DEFAULT_TERMS
    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.sim.simulator import check_devices_split
    devs = jax.local_devices()
    assert len(devs) == 4 and jax.config.jax_enable_x64, devs

    def timeless(m):   # a run's metrics without its wall-clock solve times
        if isinstance(m, dict):
            return {k: timeless(v) for k, v in m.items() if "solve_time" not in k}
        if isinstance(m, list):
            return [timeless(v) for v in m]
        return m

    runs, splits = json.loads(sys.argv[1])           # fast: 5 runs on 4 devices (padded to 8)
    sc = dataclasses.replace(load_scenario("head_on"), duration=30.0)
    one = simulate(sc, runs=runs, seed=3, batch="vmap")                # one device: the reference
    # the own-ship manoeuvred (offsets other than (1, 0)) and the runs differ: the comparison means something
    own = one.offsets[:, 0]
    assert np.any(own[..., 1] != 0.0) and not np.array_equal(one.states[0], one.states[1])
    for n_dev in splits:
        split = simulate(sc, runs=runs, seed=3, devices=n_dev)         # auto -> vmap
        assert one.summary["devices"] == 1 and split.summary["devices"] == n_dev, split.summary["devices"]
        assert split.summary["batch_mode"] == "vmap"
        for name in ("states", "track_x", "track_P", "offsets", "best_costs"):
            a, b = getattr(one, name), getattr(split, name)
            assert a.shape == b.shape and a.dtype == b.dtype, name
            assert np.array_equal(a, b, equal_nan=True), (n_dev, name, np.argwhere(a != b)[:5])
        for a, b in zip(one.metrics, split.metrics):
            assert json.dumps(timeless(a), sort_keys=True) == json.dumps(timeless(b), sort_keys=True)
        assert all(c["device_calls"] == 1 and c["solves"] == runs for c in split.calls)
        # the split program is the one that ran (jit's cache of the split call holds a compiled program)
        fn, shardings = sharding._batch_fn(sc.mpc.config, tuple(DEFAULT_TERMS), tuple(devs[:n_dev]))
        assert shardings is not None and fn._cache_size() >= 1
    assert check_devices_split(sc, "all") == tuple(devs)
    # a scenario none of whose controllers splits its batch is refused (nothing silently left on one device)
    smooth = load_scenario("head_on", method="smooth_sbmpc")
    for call in (lambda: check_devices_split(smooth, 2), lambda: simulate(smooth, runs=1, devices=2)):
        try:
            call()
        except ValueError as exc:
            assert "no controller of scenario 'head_on' splits" in str(exc) and "smooth_sbmpc" in str(exc), exc
        else:
            raise AssertionError("smooth_sbmpc with devices=2 was not refused")
    try:
        simulate(sc, runs=1, devices=2, batch="loop")
    except ValueError as exc:
        assert "batch 'loop' makes one call per solve" in str(exc), exc
    else:
        raise AssertionError("devices=2 with batch loop was not refused")
    out = tempfile.mkdtemp()
    try:
        main(["run", "head_on", "--method", "smooth_sbmpc", "--devices", "all", "--out", out, "--quiet"])
    except SystemExit as exc:
        assert exc.code == 2 and not os.listdir(out), (exc.code, os.listdir(out))
    else:
        raise AssertionError("run --devices all with smooth_sbmpc was not refused")
    print("RUNS-SHARDING-OK", len(devs))
""")


def run_split_check(request, runs: int, splits: tuple):
    """The script above in a process with 4 host devices: ``runs`` runs of head-on on one device and on each of
    ``splits`` devices."""
    # XLA's default optimisation level, as users compile (test_sharding.py does the same)
    proc = run_on_four_host_devices(request, SCRIPT, [json.dumps([runs, list(splits)])])
    assert "RUNS-SHARDING-OK 4" in proc.stdout
    assert "argument --devices: devices=4: no controller of scenario 'head_on' splits" in proc.stderr


def test_four_host_devices_equal_one_bit_for_bit(request):
    """5 runs (not a multiple of 4: padded to 8) on 4 devices equal one device."""
    run_split_check(request, 5, (4,))


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("PSBMPC_SLOW_TESTS"), reason="slow (two more compiles): PSBMPC_SLOW_TESTS=1")
def test_more_splits_equal_one_bit_for_bit(request):
    """8 runs on 4 devices (2 each, no padding) and on 3 (padded to 9) equal one device."""
    run_split_check(request, 8, (4, 3))
