"""Sequential depth (psbmpc_jax.depth): loop trips of hand-made programs with known counts, a small solve, and
``psbmpc-jax bench --depth``."""

from __future__ import annotations

import functools
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax

from psbmpc_jax.depth import DepthReport, scan_trips, sequential_depth, sequential_depth_only


def _same(a, b) -> bool:
    la, lb = jax.tree.leaves(a), jax.tree.leaves(b)
    return len(la) == len(lb) and all(np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True)
                                      for x, y in zip(la, lb))


def _site(report: DepthReport, where: str, kind: str):
    (hit,) = [s for s in report.sites if where in s.where and s.kind == kind]
    return hit


def _check(fn, *args) -> DepthReport:
    """The report of ``fn(*args)``, its outputs checked against ``jax.jit(fn)``, its counts against
    :func:`sequential_depth_only`."""
    report = sequential_depth(fn, *args)
    assert _same(report.outputs, jax.jit(fn)(*args))
    only = sequential_depth_only(fn, *args)
    assert only == report and only.outputs is None
    assert report.depth == sum(s.trips for s in report.sites)
    assert report.loop_executions == sum(s.executions for s in report.sites)
    json.dumps(report.to_dict())
    return report


@pytest.mark.parametrize("length, unroll, trips", [(10, 1, 10), (10, 5, 2), (10, 10, 0), (10, True, 0), (10, 3, 3),
                                                   (10, 0, 0), (10, 20, 0), (0, 1, 0)])
def test_scan_trips(length, unroll, trips):
    def f(x):
        return lax.scan(lambda c, _: (c * 1.5 + 1.0, c), x, None, length=length, unroll=unroll)

    assert scan_trips(length, length if unroll is True else unroll) == trips
    r = _check(f, jnp.float32(0.5))
    (site,) = r.sites
    assert (site.kind, site.executions, site.trips, site.length, r.depth, r.loop_executions) == \
        ("scan", 1, trips, length, trips, 1)
    assert site.unroll == (length if unroll is True else unroll)
    assert "tests/test_depth.py:" in site.where and site.where.endswith(".f)")


def test_fori_loop_static_and_traced_bounds():
    def f(x, n):
        a = lax.fori_loop(0, 7, lambda i, c: c + i, x)         # Python bounds: a scan of 7
        b = lax.fori_loop(0, n, lambda i, c: c * 2, a)         # traced bound: a while loop of n trips
        return b

    for n in (0, 3, 11):
        r = _check(f, jnp.float32(1.0), jnp.int32(n))
        assert {s.kind: s.trips for s in r.sites} == {"scan": 7, "while": n}
        assert r.depth == 7 + n and r.loop_executions == 2


def test_loops_in_a_while_body_count_once_per_trip():
    def f(x, n):
        body = lambda i, c: lax.scan(lambda a, _: (a * 0.5 + 1.0, None), c, None, length=3)[0]  # noqa: E731
        return lax.fori_loop(0, n, body, x)

    for n in (0, 4):
        r = _check(f, jnp.float32(1.0), jnp.int32(n))
        assert r.depth == n + 3 * n
        assert sorted((s.kind, s.executions, s.trips) for s in r.sites) == \
            ([("scan", n, 3 * n)] if n else []) + [("while", 1, n)]


def test_while_data_dependent():
    def f(x):
        return lax.while_loop(lambda c: c < 100.0, lambda c: c * 2.0 + 1.0, x)

    r = _check(f, jnp.float32(3.0))           # 3, 7, 15, 31, 63, 127
    assert r.sites[0].trips == 5 and r.depth == 5


def test_nested_while_in_scan_is_interpreted_per_trip():
    def f(x, ks):
        def body(c, k):
            m = lax.while_loop(lambda s: s[0] < k, lambda s: (s[0] + 1, s[1] * 1.25 + 0.5), (jnp.int32(0), c))[1]
            return m, m + k

        return lax.scan(body, x, ks)

    ks = jnp.array([3, 0, 5, 2], jnp.int32)
    r = _check(f, jnp.float32(0.5), ks)
    scan, inner = _site(r, ".f)", "scan"), _site(r, ".body)", "while")
    assert (scan.trips, scan.executions) == (4, 1)
    assert (inner.trips, inner.executions, inner.min_trips, inner.max_trips) == (10, 4, 0, 5)
    assert r.depth == 4 + 10 and r.loop_executions == 5


def test_static_nested_loops_are_multiplied():
    def f(x):
        def body(c, _):
            c = lax.fori_loop(0, 6, lambda i, a: a * 0.5 + i, c)            # 6 trips per outer trip
            return c, lax.scan(lambda a, _: (a + 1.0, a), c, None, length=4, unroll=2)[1]

        return lax.scan(body, x, None, length=5)

    r = _check(f, jnp.float32(1.0))
    assert r.depth == 5 + 5 * 6 + 5 * 2
    assert sorted((s.executions, s.trips) for s in r.sites) == [(1, 5), (5, 10), (5, 30)]


def test_cond_counts_the_taken_branch_only():
    def f(x, n):
        loop = lambda v: lax.fori_loop(0, n, lambda i, c: c + 1.0, v)  # noqa: E731
        return lax.cond(x > 0, loop, lambda v: v - 1.0, x)

    assert _check(f, jnp.float32(1.0), jnp.int32(4)).depth == 4
    r = _check(f, jnp.float32(-1.0), jnp.int32(4))
    assert r.depth == 0 and r.sites == ()

    def g(i, x):                      # switch over branches with different static loops
        return lax.switch(i, [lambda v: v, lambda v: lax.fori_loop(0, 3, lambda k, c: c * 2, v),
                              lambda v: lax.fori_loop(0, 9, lambda k, c: c + k, v)], x)

    assert [_check(g, jnp.int32(i), jnp.float32(1.0)).depth for i in (0, 1, 2, 7)] == [0, 3, 9, 9]


def test_loops_inside_jit_checkpoint_and_custom_jvp():
    @jax.jit
    def inner(x, n):
        return lax.while_loop(lambda c: c[0] < n, lambda c: (c[0] + 1, jnp.sin(c[1])), (0, x))[1]

    @jax.custom_jvp
    def smooth(x):
        return lax.fori_loop(0, 3, lambda i, c: c * 0.5, x)

    smooth.defjvp(lambda p, t: (smooth(p[0]), t[0]))

    def f(x, n):
        return jax.checkpoint(lambda v: inner(v, n) + smooth(v))(x) + inner(x, n + 1)

    r = _check(f, jnp.float32(0.3), jnp.int32(2))
    assert _site(r, ".inner)", "while").executions == 2
    assert _site(r, ".inner)", "while").trips == 2 + 3
    assert _site(r, ".smooth)", "scan").trips == 3
    assert r.depth == 8


def test_report_table_and_merge():
    def f(x):
        for n in (2, 5):                    # one site, two executions of different lengths
            x = lax.scan(lambda c, _: (c + 1.0, None), x, None, length=n)[0]
        return x

    r = _check(f, jnp.float32(0.0))
    (site,) = r.sites
    assert (site.executions, site.trips, site.min_trips, site.max_trips, site.length) == (2, 7, 2, 5, None)
    text = r.table()
    assert "trips/execution" in text and "3.5 (2..5)" in text and text.splitlines()[-1].startswith("total")
    with pytest.raises(ValueError, match="callable"):
        sequential_depth(3)


def test_small_solve():
    from psbmpc_jax import Planner
    from psbmpc_jax.apps.bench_points import behaviours_for
    from psbmpc_jax.examples import nidelva_head_on
    from psbmpc_jax.params import PlannerConfig
    from psbmpc_jax.solve import solve

    config = PlannerConfig(T=20.0).for_platform("cpu")
    planner = Planner(config, behaviours=behaviours_for(9))
    args = planner.prepare(nidelva_head_on(n_ps=1, n_so=4))
    fn = functools.partial(solve, config=config)
    r = sequential_depth(fn, *args)
    assert _same(r.outputs, fn(*args))
    assert sequential_depth_only(fn, *args) == r
    assert r.depth > 0 and r.loop_executions > 0
    roll = _site(r, "(los_rollout)", "scan")
    assert roll.length == config.n_steps + 1
    assert roll.trips == roll.executions * scan_trips(roll.length, roll.unroll)


def test_point_config_layout_platform():
    import argparse

    from psbmpc_jax.apps.bench import add_bench_arguments, build_plan
    from psbmpc_jax.apps.bench_points import point_config

    ap = argparse.ArgumentParser()
    add_bench_arguments(ap)
    args = ap.parse_args(["--preset", "smoke", "--depth", "--layout-platform", "gpu"])
    p = build_plan(args)[0]
    cpu, gpu = point_config(args, p, "cpu"), point_config(args, p, "gpu")
    assert cpu.grounding_search == "bounded" and gpu.grounding_search not in ("auto", "bounded", "culled")
    assert point_config(ap.parse_args(["--preset", "smoke", "--grounding-search", "culled"]), p, "gpu") \
        .grounding_search == "culled"
    with pytest.raises(ValueError, match="refine"):
        build_plan(ap.parse_args(["--preset", "refine", "--depth"]))


def test_bench_depth_cli(tmp_path, capsys):
    from psbmpc_jax.apps.bench_depth import DEPTH_FIELDS, DEPTH_SCHEMA
    from psbmpc_jax.apps.cli import main

    out = tmp_path / "depth.jsonl"
    assert main(["bench", "--preset", "smoke", "--depth", "--out", str(out), "--layout-platform", "cpu"]) == 0
    assert "trips/execution" in capsys.readouterr().out
    recs = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["value"] for r in recs] == [9, 39]
    for r in recs:
        assert set(r) == set(DEPTH_FIELDS) and r["schema"] == DEPTH_SCHEMA
        assert r["layout_platform"] == "cpu" and r["grounding_search"] == "bounded" and r["T"] == 10.0
        assert r["depth"] == sum(s["trips"] for s in r["sites"]) > 0
        assert {"where", "kind", "executions", "trips"} <= set(r["sites"][0])
    # a file of timing records is refused (psbmpc-jax report could not read it any more), and the other way round
    bench = tmp_path / "bench.jsonl"
    bench.write_text(json.dumps({"schema": "psbmpc-bench/1"}) + "\n")
    with pytest.raises(SystemExit):
        main(["bench", "--preset", "smoke", "--depth", "--quiet", "--out", str(bench)])
    assert "depth records go to a file of their own" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["bench", "--preset", "smoke", "--quiet", "--out", str(out)])
    assert "timing records go to another file" in capsys.readouterr().err


# ------------------------------------------------------------------------------------ pinned structure
def _paper_solve(platform: str, **config_fields):
    """fig5's 1 014-behaviour point (Nidelva head-on, n_ps 1, 2 obstacles, 13 polygons, exact grounding,
    quadrature, T 150 s) with the default configuration's layouts chosen as on ``platform``."""
    from psbmpc_jax import Params, Planner
    from psbmpc_jax.apps.bench_points import Point, behaviours_for, situation_for
    from psbmpc_jax.params import PlannerConfig
    from psbmpc_jax.solve import solve

    p = Point(sweep="pin", swept="n_cbs", value=1014, n_cbs=1014, n_ps=1)
    config = PlannerConfig(T=p.T, **config_fields).for_platform(platform)
    planner = Planner(config, params=Params(r_ct=p.r_ct), behaviours=behaviours_for(p.n_cbs))
    return functools.partial(solve, config=config), planner.prepare(situation_for(p))


def test_default_gpu_layout_depth_is_pinned():
    """The default configuration's GPU program at paper scale has no loop step left: the own-ship and obstacle
    rollouts are one Pallas kernel each (chosen as on a GPU; interpreted here), and every other stage (collision
    points, all 13 polygons' edges, selection) is loop-free.  With the scan rollouts (where the kernel's
    self-check fails on a GPU) the two rollouts are the only loops, 150 trips each.  A change that adds a loop to
    the GPU program fails here: measure it (``psbmpc-jax bench --depth --layout-platform gpu``) and update the pin
    on purpose."""
    fn, args = _paper_solve("gpu")
    r = sequential_depth_only(fn, *args)
    assert r.depth == 0 and r.loop_executions == 2
    assert [(s.where.split(" ")[-1], s.kind, s.executions) for s in r.sites] == [("(los_rollout_kernel)", "kernel", 2)]
    fn, args = _paper_solve("gpu", rollout_kernel="scan")
    r = sequential_depth_only(fn, *args)
    assert r.depth == 300 and r.loop_executions == 2
    assert [(s.where.split(" ")[-1], s.kind, s.trips) for s in r.sites] == [("(los_rollout)", "scan", 300)]


def test_default_cpu_layout_depth_is_pinned():
    """The CPU program of the same point: the culled grounding search's loops dominate (4 003 trips when this
    was written, benchmarks/results/depth_cpu_layouts_20261128.jsonl; the rollouts 602 of them).  Pinned from
    above with 4 % slack so that a regression of the CPU layouts' structure shows."""
    fn, args = _paper_solve("cpu")
    r = sequential_depth_only(fn, *args)
    assert 3000 <= r.depth <= 4170, r.table()
    roll = _site(r, "(los_rollout)", "scan")
    assert roll.trips == 602
