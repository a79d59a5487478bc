"""``psbmpc-jax bench --preset refine``: the PSB-MPC + refinement benchmark at Nidelva scale (docs/refine.md):
the grid search, one ``value_and_grad`` of the smooth objective, one library solve and the whole refinement at
the cases of :data:`REFINE_CASES`, timed round-robin; one ``psbmpc-bench-refine/1`` record per slot."""

from __future__ import annotations

import datetime as dt
import json
import os
import platform as _platform
import sys
import time

from ..provenance import commit, versions
from .bench_timing import default_out, select_devices, stats_ms

REFINE_SCHEMA = "psbmpc-bench-refine/1"
#: The refinement benchmark's cases: (case, PlannerConfig overrides of the Nidelva preset, refine horizon [s]
#: (None: the config's T), starts, batch).  "nidelva": the preset's T = 150 s with a 60 s refine horizon;
#: "nidelva_u10": the same with the rollouts 10 steps per loop step (``rollout_unroll``: fewer kernel launches on a
#: GPU); "nidelva_T60": the whole MPC horizon 60 s; "paper000": the Smooth-SBMPC paper's T_init 60 s / T_mpc 20 s at
#: dt 1 s (docs/smooth_sbmpc.md).  Always 2 obstacles x 5 scenarios and the 13 Table 2 polygons (grid mode).
REFINE_CASES: tuple[tuple[str, dict[str, float], float | None, int, str], ...] = (
    ("nidelva", {}, 60.0, 1, "map"),
    ("nidelva", {}, 60.0, 4, "map"),
    ("nidelva", {}, 60.0, 16, "map"),
    ("nidelva", {}, 60.0, 16, "vmap"),
    ("nidelva_u10", {"rollout_unroll": 10}, 60.0, 1, "map"),
    ("nidelva_u10", {"rollout_unroll": 10}, 60.0, 16, "vmap"),
    ("nidelva_T60", {"T": 60.0}, None, 1, "map"),
    ("nidelva_T60", {"T": 60.0}, None, 16, "vmap"),
    ("paper000", {"T": 60.0, "dt": 1.0}, 20.0, 1, "map"),
    ("paper000", {"T": 60.0, "dt": 1.0}, 20.0, 16, "vmap"),
)
REFINE_FIELDS = ("schema", "case", "what", "platform", "device_kind", "host", "dtype", "estimator", "grounding_mode",
                 "T", "dt", "horizon", "n_steps", "n_refine", "n_starts", "batch", "block", "max_outer", "max_inner",
                 "n_cbs", "n_do", "n_ps", "n_so", "compile_s", "times_ms", "median_ms", "min_ms", "max_ms", "q1_ms",
                 "q3_ms", "iterations", "status", "used_warm", "start_index", "cost", "warm_cost", "grid_cost",
                 "warm_grid_cost", "grid_total", "schedule", "versions", "commit", "timestamp")


def _refine_slots(cases, dtype: str, log):
    """Compile and warm up every slot of the refinement benchmark: per configuration the grid search
    (``grid``), one ``value_and_grad`` of the smooth objective at the grid's choice (``value_and_grad``) and
    one library solve from it (``solve_one``: :func:`psbmpc_jax.nlp.solve_docp` alone); per case the whole
    :func:`psbmpc_jax.refine.refine` call (``refine``)."""
    import jax
    import jax.numpy as jnp

    from ..examples import nidelva_head_on
    from ..nlp import solve_docp
    from ..planner import Planner
    from ..presets import build_mpc
    from ..refine import RefineSettings, behaviour_controls, box, problem, refine, refine_data, smooth_terms
    from ..solve import solve

    sit = nidelva_head_on()
    slots, prepared = [], {}
    for case, overrides, horizon, n_starts, batch in cases:
        key = (case, tuple(sorted(overrides.items())), horizon)
        settings = RefineSettings(n_starts=n_starts, batch=batch, horizon=horizon)
        if key not in prepared:
            config, params, beh = build_mpc("nidelva", {**overrides, "dtype": dtype})
            planner = Planner(config, params, beh)
            inputs, state, p, samples = planner.prepare(sit)
            base = dict(case=case, dtype=dtype, estimator=config.estimator, grounding_mode=config.grounding_mode,
                        T=config.T, dt=config.dt, horizon=horizon, n_steps=config.n_steps,
                        n_refine=settings.n_refine(config), n_cbs=len(beh), n_do=len(sit.obstacles),
                        n_ps=max(o.n_ps for o in sit.obstacles), n_so=len(sit.polygons))
            t0 = time.perf_counter()
            grid = solve.lower(inputs, state, p, samples, config=config).compile()
            grid_s = time.perf_counter() - t0
            plan, _, ev = jax.block_until_ready(grid(inputs, state, p, samples))
            n_ref = settings.n_refine(config)
            data = refine_data(inputs, jnp.asarray(state.last_offsets, config.dtype), p, config, smooth_terms())
            f, _ = problem(config, n_ref, 1)
            warm = behaviour_controls(jnp.asarray(inputs.behaviours.offsets)[plan.best], p, config)
            args = (data, warm[n_ref:])
            z0 = warm[:n_ref]
            lo, hi = box(jax.tree.map(jnp.asarray, inputs.behaviours))
            lower, upper = jnp.broadcast_to(lo, z0.shape), jnp.broadcast_to(hi, z0.shape)
            t0 = time.perf_counter()
            vg = jax.jit(jax.value_and_grad(f)).lower(z0, args).compile()
            vg_s = time.perf_counter() - t0
            solver = settings.solver
            t0 = time.perf_counter()
            one = solve_docp.jitted.lower(f, z0, lower, upper, None, None, solver, args).compile()
            one_s = time.perf_counter() - t0
            res = jax.block_until_ready(one(z0, lower, upper, solver, args))
            common = dict(base, n_starts=1, batch=None, block=1, max_outer=solver.max_outer,
                          max_inner=solver.max_inner, grid_total=float(plan.total))
            slots.append(dict(rec=dict(common, what="grid", n_starts=None, compile_s=grid_s),
                              call=lambda g=grid, a=(inputs, state, p, samples): g(*a)))
            slots.append(dict(rec=dict(common, what="value_and_grad", compile_s=vg_s),
                              call=lambda g=vg, z=z0, a=args: g(z, a)))
            slots.append(dict(rec=dict(common, what="solve_one", compile_s=one_s, iterations=int(res.inner_iterations),
                                       status=int(res.status), cost=float(res.f), warm_cost=float(f(z0, args))),
                              call=lambda g=one, z=z0, lo=lower, hi=upper, s=solver, a=args: g(z, lo, hi, s, a)))
            prepared[key] = (config, inputs, state, p, samples, plan, ev, base)
            log(f"{case}: grid search compiled in {grid_s:.1f} s, value_and_grad in {vg_s:.1f} s, one solve in "
                f"{one_s:.1f} s ({int(res.inner_iterations)} iterations)")
        config, inputs, state, p, samples, plan, ev, base = prepared[key]
        t0 = time.perf_counter()
        r = jax.block_until_ready(refine(inputs, plan, state, p, samples, config, settings, evaluation=ev))
        compile_s = time.perf_counter() - t0
        rec = dict(base, what="refine", n_starts=n_starts, batch=batch, block=settings.block,
                   max_outer=settings.solver.max_outer, max_inner=settings.solver.max_inner, compile_s=compile_s,
                   iterations=int(r.iterations), status=int(r.status), used_warm=bool(r.used_warm),
                   start_index=int(r.start_index), cost=float(r.cost), warm_cost=float(r.warm_cost),
                   grid_cost=float(r.grid_cost), warm_grid_cost=float(r.warm_grid_cost), grid_total=float(plan.total))
        a = (inputs, plan, state, p, samples, config, settings)
        slots.append(dict(rec=rec, call=lambda a=a, e=ev: refine(*a, evaluation=e)))
        log(f"{case} {n_starts} start(s) {batch}: compiled in {compile_s:.1f} s, {int(r.iterations)} iterations, "
            f"smooth cost {float(r.warm_cost):.4g} -> {float(r.cost):.4g}")
    return slots


def refine_benchmark(repeats: int = 20, warmup: int = 2, cases=REFINE_CASES, dtype: str = "float32",
                     log=lambda msg: None) -> list[dict]:
    """The refinement benchmark on the default device: compile every slot, ``warmup`` untimed calls each, then
    ``repeats`` rounds timing every slot once per round (interleaved).  Returns one record per slot (the
    :data:`REFINE_FIELDS` that apply; timings in ms)."""
    import jax

    slots = _refine_slots(cases, dtype, log)
    for slot in slots:
        for _ in range(warmup):
            jax.block_until_ready(slot["call"]())
        slot["times"] = []
    log(f"timing {len(slots)} slots round-robin, {repeats} rounds")
    for _ in range(repeats):
        for slot in slots:
            t0 = time.perf_counter()
            jax.block_until_ready(slot["call"]())
            slot["times"].append(time.perf_counter() - t0)
    dev = jax.devices()[0]
    out = []
    for slot in slots:
        rec = dict(slot["rec"], platform=dev.platform, device_kind=dev.device_kind, schedule="interleaved",
                   **stats_ms(slot["times"]))
        if isinstance(rec.get("compile_s"), float):
            rec["compile_s"] = round(rec["compile_s"], 3)
        out.append(rec)
        log(f"{rec['case']:>12} {rec['what']:>14} {rec.get('n_starts') or '':>3} {rec.get('batch') or '':>5}: "
            f"median {rec['median_ms']:.2f} ms" + (f", {rec['iterations']} iterations" if rec.get('iterations')
                                                     is not None else ""))
    return out


def run_refine_bench(args) -> int:
    """``psbmpc-jax bench --preset refine``: :func:`refine_benchmark` on each selected platform, one
    ``psbmpc-bench-refine/1`` JSON line per slot appended to ``--out``."""
    import jax

    out = args.out or default_out()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    log = (lambda msg: None) if args.quiet else (lambda msg: print(f"[refine] {msg}", file=sys.stderr, flush=True))
    meta = {"host": _platform.node(), "versions": versions(), "commit": commit()}
    n = 0
    with open(out, "a", encoding="utf-8") as fh:
        for plat, devs in select_devices(args.devices).items():
            with jax.default_device(devs[0]):
                recs = refine_benchmark(args.repeats, args.warmup, dtype=args.dtype, log=log)
            for rec in recs:
                full = dict.fromkeys(REFINE_FIELDS)
                full.update(rec, schema=REFINE_SCHEMA, host=meta["host"], versions=meta["versions"],
                            commit=meta["commit"],
                            timestamp=dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"))
                assert set(full) == set(REFINE_FIELDS), set(full) ^ set(REFINE_FIELDS)
                fh.write(json.dumps(full) + "\n")
                n += 1
            fh.flush()
    if not args.quiet:
        print(f"psbmpc-jax bench: {n} refine records appended to {out}", file=sys.stderr)
    return 0
