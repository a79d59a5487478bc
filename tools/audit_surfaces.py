"""A fresh audit of the surfaces of "nothing lost, nothing silent": every case of that issue's list, tried as a
user would (the command line where there is one, else the library), each in its own bounded process.

Every case runs in a fresh Python process with a wall-clock timeout and an address-space limit
(``resource.setrlimit(RLIMIT_AS)``), and with ``PSBMPC_MEMORY_LIMIT`` set to the memory the audit grants
(``--memory``), so the library's own estimates are checked against a limit the process really has.  A case
reports one of:

* ``error``   -- refused with a clear message that names the field, file or path (the case's pattern matches);
* ``correct`` -- a result that the case checked and found right (a gradient against finite differences, a
  status that is not "ok", protected files unchanged);
* ``unclear`` -- refused, but the message does not name what the case requires;
* ``silent``  -- accepted nonsense or a wrong result;
* ``crash``   -- a raw traceback, an exception that is not the library's ``ValueError`` / ``OutputError``,
  the process killed (out of memory) or ``runaway`` -- past its timeout.

Usage::

    python tools/audit_surfaces.py [--cases NAME,...] [--timeout 240] [--memory 4GiB] [--json OUT.json]

Prints one line per case and the counts; ``--json`` writes a record (device, versions, commit, every case and
its outcome; refuses an existing file).  The exit status is 1 when any case is not ``error`` / ``correct``.
The export and plot cases use the synthetic simulation result of ``tests/test_export.py`` (no solver).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import pathlib
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))           # this checkout's psbmpc_jax (its commit in the record), not an installed one
MARK = "@@AUDIT@@"

#: Runs in the child before the case's code: ``case(tmp, shared)`` returns a dict; a ValueError or the library's
#: OutputError is a refusal, anything else propagates (a traceback: a crash).
PRELUDE = r'''
import json, os, pathlib, subprocess, sys, tempfile
sys.path.insert(0, os.path.join(os.environ["AUDIT_ROOT"], "tests"))
from psbmpc_jax.safe_io import OutputError
ROOT = pathlib.Path(os.environ["AUDIT_ROOT"])
SHARED = pathlib.Path(os.environ["AUDIT_SHARED"])

def cli(*argv, timeout=None):
    """The command line as a user runs it: (exit status, stdout, stderr)."""
    p = subprocess.run([sys.executable, "-m", "psbmpc_jax.apps.cli", *map(str, argv)], capture_output=True,
                       text=True, cwd=os.environ["AUDIT_TMP"], timeout=timeout)
    return p.returncode, p.stdout, p.stderr

def cli_outcome(rc, out, err):
    """A command line's refusal (exit 2, one message, no traceback) -> an error; a traceback -> a crash."""
    if "Traceback" in err or rc not in (0, 1, 2):        # 1: run finished, some runs failed (a collision)
        return dict(kind="crash", detail=f"exit {rc}: {err[-1500:]}")
    if rc == 2:
        return dict(kind="error", message=err.strip()[-1500:])
    return None

def accepted(detail):
    return dict(kind="result", ok=False, detail="accepted: " + detail)

def scenario(mpc=None, **top):
    d = {"name": "audit", "simulation": {"dt_s": 0.5, "duration_s": 60},
         "mpc": {"preset": "nidelva", "update_period_s": 5, **(mpc or {})},
         "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                      "waypoints_m": [[0, 0], [300, 0]]},
         "targets": [{"name": "TS1", "position_m": [200, 10], "course_deg": 180, "speed_mps": 2}]}
    d.update(top)
    return d

def run_file(tmp, d, *extra):
    """Write scenario ``d`` and ``psbmpc-jax run`` it: a refusal, a crash, or None when it ran."""
    import yaml
    p = tmp / "scenario.yaml"
    p.write_text(yaml.safe_dump(d))
    rc, out, err = cli("run", p, "--out", tmp / "out", "--no-figures", "--quiet", *extra)
    return cli_outcome(rc, out, err)
'''

EPILOGUE = r'''
_tmp = pathlib.Path(os.environ["AUDIT_TMP"])
try:
    _res = case(_tmp)
except (ValueError, OutputError) as _e:
    _res = dict(kind="error", type=type(_e).__name__, message=str(_e))
print("@@AUDIT@@" + json.dumps(_res, default=str))
'''


def C(name, category, issue, code, match=None, timeout=None):
    """A case: ``code`` defines ``case(tmp)``; ``match`` is the pattern a refusal's message must contain."""
    return dict(name=name, category=category, issue=issue, code=textwrap.dedent(code), match=match,
                timeout=timeout)


TINY_RUN = "run_with_trajectories"      # the shared run folder the stale-result cases copy

CASES = [
    # ------------------------------------------------------------------------------------------ data loss
    C("evaluate_out_is_input", "data loss", "evaluate tracks.csv --out tracks.csv overwrites the input", '''
    def case(tmp):
        p = tmp / "tracks.csv"
        text = "t_s,vessel,north_m,east_m\\n" + "".join(f"{t},own,{t},0\\n{t},ts,{200 - t},5\\n" for t in range(0, 100, 2))
        p.write_text(text)
        rc, out, err = cli("evaluate", p, "--out", p)
        if p.read_text() != text:
            return dict(kind="result", ok=False, detail=f"the input was changed (exit {rc})")
        return cli_outcome(rc, out, err) or accepted(f"exit {rc} but the input is unchanged")
    ''', match=r"tracks\.csv.*refusing to write over it"),
    # ------------------------------------------------------------------------------------------ stale results
    C("rerun_leaves_old_trajectories", "stale results",
      "re-running run into the same --out without --save-trajectories leaves the previous trajectories", '''
    def case(tmp):
        import shutil
        out = tmp / "out"
        shutil.copytree(SHARED / "out", out)
        folder = out / "audit_tiny"
        rc, o, e = cli("run", SHARED / "tiny.yaml", "--out", out, "--no-figures", "--quiet")
        r = cli_outcome(rc, o, e)
        if r is None:
            return accepted("a second run into a folder holding another run's results was not refused")
        if r["kind"] == "crash":
            return r
        if "--force" not in r["message"]:
            return dict(kind="error", message=r["message"])
        rc, o, e = cli("run", SHARED / "tiny.yaml", "--out", out, "--no-figures", "--quiet", "--force")
        if cli_outcome(rc, o, e) is not None:
            return cli_outcome(rc, o, e)
        left = [n for n in ("trajectories.npz", "trajectories.csv") if (folder / n).exists()]
        if left:
            return dict(kind="result", ok=False, detail=f"the earlier run's {left} remain beside the new run")
        return cli_outcome(*cli("evaluate", folder)) or accepted("evaluate scored a run that wrote no trajectories")
    ''', match=r"wrote no trajectories", timeout=300),
    C("stale_trajectories_beside_new_run", "stale results",
      "evaluate / load_trajectories use another run's trajectories without a hint", '''
    def case(tmp):
        import shutil
        from psbmpc_jax.sim import load_trajectories
        b = tmp / "b"
        shutil.copytree(SHARED / "out" / "audit_tiny", b)
        lines = (b / "trajectories.csv").read_text().splitlines(keepends=True)
        (b / "trajectories.npz").unlink()
        # other trajectories under the run's name: its rows reordered (the same size, another content)
        (b / "trajectories.csv").write_text("".join(lines[:1] + lines[2:] + lines[1:2]))
        rc, o, e = cli("evaluate", b)
        r = cli_outcome(rc, o, e)
        if r is None:
            return accepted("evaluate scored trajectories that are not the run's")
        if r["kind"] == "crash":
            return r
        load_trajectories(b)
        return accepted("load_trajectories read trajectories that are not the run's")
    ''', match=r"trajectories\.csv"),
    C("trajectories_csv_cut_at_run_boundary", "stale results",
      "a trajectories.csv cut at a run boundary loads as complete", '''
    def case(tmp):
        from psbmpc_jax.sim import load_trajectories
        lines = (SHARED / "out" / "audit_tiny" / "trajectories.csv").read_text().splitlines(keepends=True)
        p = tmp / "trajectories.csv"                       # a copy outside its run folder: no manifest to check
        p.write_text("".join(lines[: 1 + (len(lines) - 1) // 2]))
        tr = load_trajectories(p)
        return accepted(f"loaded {tr.runs} run(s) of a file cut at the run boundary")
    ''', match=r"trajectories\.csv.*declares 2 runs.*cut"),
    # ------------------------------------------------------------------------------------------ gradients
    C("grid_gradient_on_grid_lines", "wrong gradients",
      "grid grounding: the derivative is halved on grid lines", '''
    def case(tmp):
        import jax
        jax.config.update("jax_enable_x64", True)
        import jax.numpy as jnp, numpy as np
        from psbmpc_jax.distance_grid import DistanceGrid, interpolate
        xs, ys = np.meshgrid(np.arange(6.0), np.arange(5.0), indexing="ij")
        h, origin = 0.5, (-1.0, 2.0)
        values = 3.0 * (origin[0] + h * xs) - 2.0 * (origin[1] + h * ys) + 40.0      # a linear field
        grid = DistanceGrid(jnp.asarray(values), jnp.asarray(origin), jnp.asarray(h), jnp.asarray(100.0))
        px = jnp.asarray([origin[0] + h * k for k in (1, 2, 3, 1.5, 2)])             # on lines and corners
        py = jnp.asarray([origin[1] + h * k for k in (1, 2.5, 3, 1, 0)])
        gx, gy = jax.grad(lambda x, y: jnp.sum(interpolate(grid, x, y)[0]), argnums=(0, 1))(px, py)
        ok = np.allclose(np.asarray(gx), 3.0, atol=1e-9) and np.allclose(np.asarray(gy), -2.0, atol=1e-9)
        return dict(kind="result", ok=bool(ok), detail=f"d/dx {np.asarray(gx).tolist()} (3), d/dy {np.asarray(gy).tolist()} (-2)")
    '''),
    C("mc_collision_gradient", "wrong gradients",
      "mc/ce: the collision gradient is non-zero and biased while documented as 0", '''
    def case(tmp):
        import jax
        jax.config.update("jax_enable_x64", True)
        import jax.numpy as jnp, numpy as np
        from psbmpc_jax.costs.collision import pc_ce, pc_mc
        from psbmpc_jax import PlannerConfig
        from psbmpc_jax.params import Params
        from psbmpc_jax.reference import collision_probability as ref_pc
        point = (3.0, -4.0, 6.0, 1.5, 3.0, 5.0)
        cfg, prm = PlannerConfig(n_quad=128, quad_span=10.0), Params(c_sigma=100.0)
        def pq(mx, my):
            return ref_pc((0.0, 0.0), (mx, my), [[6.0, 1.5], [1.5, 3.0]], 5.0, "quadrature", prm, cfg)
        fd = np.array([(pq(3 + 1e-5, -4) - pq(3 - 1e-5, -4)) / 2e-5, (pq(3, -4 + 1e-5) - pq(3, -4 - 1e-5)) / 2e-5])
        args = [jnp.asarray(v) for v in point]
        out = []
        for name, fn in (("mc", lambda a, z: pc_mc(*a, z[0])), ("ce", lambda a, z: pc_ce(*a, z, 0.9, 0.9, 11.618))):
            g = jax.jit(jax.grad(fn))
            gs = np.array([np.asarray(g(args, jax.random.normal(jax.random.key(k), (7, 20000, 2))))[:2]
                           for k in range(8)])
            m, se = gs.mean(0), gs.std(0, ddof=1) / np.sqrt(len(gs))
            out.append((name, bool(np.all(np.abs(m - fd) <= 5 * se + 2e-4)), m.tolist()))
        ok = all(o[1] for o in out)
        return dict(kind="result", ok=ok, detail=f"quadrature d/dmu {fd.tolist()}; " + "; ".join(
            f"{n} {m} ({'agrees' if a else 'DISAGREES'})" for n, a, m in out))
    ''', timeout=300),
    # ------------------------------------------------------------------------------------------ meaningless input
    C("two_level_U_max", "meaningless input", "mpc.two_level.U_max_mps checks the wrong key", '''
    def case(tmp):
        return run_file(tmp, scenario({"method": "two_level", "two_level": {"U_max_mps": 400}})) or accepted("ran")
    ''', match=r"mpc\.two_level\.U_max_mps must be in \(0, 30\]"),
    C("n_ps_101", "meaningless input", "mpc.n_ps: 101 against documented 1-99", '''
    def case(tmp):
        return run_file(tmp, scenario({"n_ps": 101})) or accepted("ran")
    ''', match=r"mpc\.n_ps must be an odd integer from 1 to 99"),
] + [
    C(f"smooth_{label}", "meaningless input", f"the smooth planner accepting {what}", f'''
    def case(tmp):
        import numpy as np
        from psbmpc_jax.smooth.init_stage import SmoothSettings
        from psbmpc_jax.smooth.planner import SmoothSBMPCPlanner
        planner = SmoothSBMPCPlanner((), init_only=True, settings=SmoothSettings(T_init=20.0, T_mpc=10.0, dt=1.0))
        args = dict(state0=[0.0, 0.0, 0.0, 1.0], route=np.array([[0.0, 0.0], [500.0, 0.0]]),
                    targets=np.zeros((0, 4)), last=[1.0, 0.0])
        args.update({change})
        planner.plan(**args)
        return accepted("planned")
    ''', match=match) for label, what, change, match in [
        ("course_90_rad", "a course of 90 rad", "state0=[0.0, 0.0, 90.0, 1.0]", r"state0: course .* not in radians"),
        ("speed_400", "400 m/s", "state0=[0.0, 0.0, 0.0, 400.0]", r"state0: speed .* 400 m/s"),
        ("speed_factor_5", "speed factor 5", "last=[5.0, 0.0]", r"last: the speed factor U_m must be in"),
        ("zero_length_leg", "zero-length legs", "route=np.array([[0.0, 0.0], [0.0, 0.0], [500.0, 0.0]])",
         r"route: leg 0 has zero length")]
] + [
    C("objective_u_1_5", "meaningless input", "objective taking u = 1.5 (negative path cost)", '''
    def case(tmp):
        import numpy as np
        from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation, paper_behaviours
        from psbmpc_jax.objective import objective
        cfg = PlannerConfig(T=20.0, dt=0.5)
        sit = Situation(OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0),
                        (Obstacle([40.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
        inputs, _, params, samples = Planner(cfg, behaviours=paper_behaviours(1)).prepare(sit)
        total, costs = objective(np.asarray([[1.5, 0.0]]), inputs, params, samples, cfg)
        return accepted(f"total {float(total)}, path {float(costs.get('path', float('nan')))}")
    ''', match=r"controls\[0, 0\] = 1\.5.*\[0, 1\]"),
    C("objective_nan_controls_traced", "meaningless input", "objective reporting collision cost 0 for NaN controls", '''
    def case(tmp):
        import jax, jax.numpy as jnp, numpy as np
        from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation, paper_behaviours
        from psbmpc_jax.objective import objective
        cfg = PlannerConfig(T=20.0, dt=0.5)
        sit = Situation(OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0),
                        (Obstacle([40.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
        inputs, _, params, samples = Planner(cfg, behaviours=paper_behaviours(1)).prepare(sit)
        total, costs = jax.jit(lambda c: objective(c, inputs, params, samples, cfg))(jnp.asarray([[jnp.nan, 0.0]]))
        finite = {k: float(v) for k, v in costs.items() if np.isfinite(float(v))}
        if np.isfinite(float(total)) or finite:
            return dict(kind="result", ok=False, detail=f"finite costs for NaN controls: total {float(total)}, {finite}")
        return dict(kind="result", ok=True, detail="NaN total and costs (traced: no host check possible)")
    '''),
    C("solve_nan_own_state", "meaningless input", "low-level solve returning status ok for a NaN own-ship state", '''
    def case(tmp):
        import jax.numpy as jnp, numpy as np
        from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation, paper_behaviours
        from psbmpc_jax.solve import STATUS_NAMES, STATUS_OK, solve
        cfg = PlannerConfig(T=20.0, dt=0.5)
        sit = Situation(OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0),
                        (Obstacle([40.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
        inputs, state, params, samples = Planner(cfg, behaviours=paper_behaviours(1)).prepare(sit)
        bad = inputs._replace(own=inputs.own._replace(state=jnp.asarray(inputs.own.state).at[0].set(jnp.nan)))
        plan, _, _ = solve(bad, state, params, samples, config=cfg)
        s = int(plan.status)
        return dict(kind="result", ok=s != STATUS_OK, detail=f"status {s} ({STATUS_NAMES[s]})")
    '''),
    C("solve_invalid_params", "meaningless input", "low-level solve returning status ok for invalid Params", '''
    def case(tmp):
        import jax.numpy as jnp, numpy as np
        from psbmpc_jax import Obstacle, OwnShip, Planner, PlannerConfig, Situation, paper_behaviours
        from psbmpc_jax.solve import STATUS_NAMES, STATUS_OK, solve
        cfg = PlannerConfig(T=20.0, dt=0.5)
        sit = Situation(OwnShip([0.0, 0.0, 0.0, 2.0], [[0.0, 0.0], [500.0, 0.0]], 2.0),
                        (Obstacle([40.0, 2.0, -2.0, 0.0], np.diag([4.0, 4.0, 0.1, 0.1]), n_ps=3),))
        inputs, state, params, samples = Planner(cfg, behaviours=paper_behaviours(1)).prepare(sit)
        plan, _, _ = solve(inputs, state, params.replace(T_d=jnp.asarray(-5.0)), samples, config=cfg)
        s = int(plan.status)
        return dict(kind="result", ok=s != STATUS_OK, detail=f"T_d = -5: status {s} ({STATUS_NAMES[s]})")
    '''),
] + [
    C(f"evaluate_{label}", "runaway" if label == "ms_timestamps" else "meaningless input",
      f"evaluate scoring tracks {what}" if label != "ms_timestamps" else what, f'''
    def case(tmp):
        p = tmp / "tracks.csv"
        p.write_text({text!r})
        return cli_outcome(*cli("evaluate", p)) or accepted("scored")
    ''', match=match) for label, what, text, match in [
        ("degrees", "in degrees", "t_s,vessel,north_m,east_m\n" + "".join(
            f"{t},own,{63.43 + 4.5e-5 * t:.6f},10.39\n{t},ts,{63.44 - 4.5e-5 * t:.6f},10.39\n" for t in range(0, 121, 20)),
         r"tracks\.csv.*look like latitude/longitude in degrees"),
        ("1e300_m", "at 10^300 m", "t_s,vessel,north_m,east_m\n0,own,0,0\n0,ts,1e300,0\n10,own,10,0\n10,ts,1e300,0\n",
         r"tracks\.csv.*north: 1e\+300 m .*not a position on Earth"),
        ("1e6_mps", "at 10^6 m/s", "t_s,vessel,north_m,east_m,course_deg,speed_mps\n0,own,0,0,0,1e6\n0,ts,100,0,180,1\n"
         "10,own,10,0,0,1e6\n10,ts,90,0,180,1\n", r"tracks\.csv.*speed: 1e\+06 m/s"),
        ("ms_timestamps", "a 4-line CSV spanning 10^9 s (timestamps in ms) drives evaluate past 6 GB", "t_s,vessel,north_m,east_m\n0,own,0,0\n0,ts,100,0\n"
         "1000000000,own,1000,0\n1000000000,ts,-1000,0\n", r"tracks\.csv: sample_interval_s: .*needs about"),
    ]
] + [
    C("geojson_lat_lon", "meaningless input", "a GeoJSON chart in [lat, lon] order accepted", '''
    def case(tmp):
        import json as _j
        ring = [[63.4300, 10.4000], [63.4300, 10.4100], [63.4350, 10.4100], [63.4350, 10.4000], [63.4300, 10.4000]]
        chart = tmp / "latlon.geojson"
        chart.write_text(_j.dumps({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {},
                                   "geometry": {"type": "Polygon", "coordinates": [ring]}}]}))
        d = scenario(origin_latlon={"lat": 63.428, "lon": 10.39}, chart={"file": str(chart)})
        return run_file(tmp, d) or accepted("ran")
    ''', match=r"origin_latlon: the chart's coordinates look like \[lat, lon\] order"),
    C("non_utf8_scenario", "meaningless input", "a non-UTF-8 scenario file reported without the file or encoding", '''
    def case(tmp):
        p = tmp / "latin.yaml"
        p.write_bytes("name: t\\ndescription: Tr\\u00f8ndelag\\n".encode("latin-1"))
        return cli_outcome(*cli("run", p, "--out", tmp / "out", "--no-figures")) or accepted("ran")
    ''', match=r"latin\.yaml.*UTF-8.*0xf8"),
    # ------------------------------------------------------------------------------------------ runaway
    C("sample_interval_1e-6", "runaway", "evaluation.sample_interval_s: 1e-6 loses every result while scoring", '''
    def case(tmp):
        return run_file(tmp, scenario(evaluation={"sample_interval_s": 1e-6})) or accepted("ran")
    ''', match=r"evaluation\.sample_interval_s: scoring tracks"),
    C("horizon_T_50000", "runaway", "mpc.config.T: 50000 (inside the documented limit) passes 8 GB", '''
    def case(tmp):
        return run_file(tmp, scenario({"config": {"T": 50000}})) or accepted("ran")
    ''', match=r"mpc\.config\.T.*needs about .* of memory; the limit is"),
    C("refine_max_iterations", "runaway", "psbmpc_refine at its maximum allowed iterations never finishes", '''
    def case(tmp):
        d = scenario({"method": "psbmpc_refine", "config": {"T": 60},
                      "solver": {"max_outer": 100000, "max_inner": 100000}})
        return run_file(tmp, d) or accepted("ran")
    ''', match=r"mpc\.solver\.max_outer x mpc\.solver\.max_inner: the refinement .* per MPC update"),
    C("smooth_T_init_10000", "runaway", "smooth.T_init_s: 10000 never finishes an update", '''
    def case(tmp):
        from psbmpc_jax.scenario.load import builtin_path
        from psbmpc_jax.config import yaml_load
        import yaml
        path = builtin_path("smooth_000_reconstruction")
        d = yaml_load(path.read_text(encoding="utf-8"), str(path))
        d["mpc"]["smooth"] = dict(d["mpc"].get("smooth") or {}, T_init_s=10000)
        p = tmp / "smooth.yaml"
        p.write_text(yaml.safe_dump(d))
        return cli_outcome(*cli("run", p, "--out", tmp / "out", "--no-figures", "--quiet")) or accepted("ran")
    ''', match=r"mpc\.smooth\.T_init_s.*per MPC update"),
    C("mc_n_samples_1e7", "runaway", "the documented maximum n_samples: 1e7 ends in an XLA out-of-memory traceback", '''
    def case(tmp):
        return run_file(tmp, scenario({"config": {"estimator": "mc", "n_samples": 10000000}})) or accepted("ran")
    ''', match=r"mpc\.config\.n_samples: one solve .* needs about"),
    C("ce_n_samples_1e7", "runaway", "the documented maximum n_samples: 1e7 (ce)", '''
    def case(tmp):
        return run_file(tmp, scenario({"config": {"estimator": "ce", "n_samples": 10000000}})) or accepted("ran")
    ''', match=r"mpc\.config\.n_samples: one solve .* needs about"),
    C("sbmpc_n_mc_1e6", "runaway", "the documented maximum sbmpc.n_mc: 1e6 ends in an XLA out-of-memory traceback", '''
    def case(tmp):
        return run_file(tmp, scenario({"method": "psbmpc_2020", "sbmpc": {"n_mc": 1000000}})) or accepted("ran")
    ''', match=r"mpc\.sbmpc\.n_mc: .*needs about"),
    C("simulation_of_days", "runaway", "(beyond the issue's list) settings each inside its bound whose product is "
      "days of simulation: 86 400 s at a 0.5 s MPC period x 50 runs", '''
    def case(tmp):
        d = scenario(simulation={"dt_s": 0.5, "duration_s": 86400}, monte_carlo={"runs": 50, "seed": 1})
        d["mpc"]["update_period_s"] = 0.5
        d["own_ship"]["waypoints_m"] = [[0, 0], [100000, 0]]
        return run_file(tmp, d) or accepted("ran")
    ''', match=r"simulation\.duration_s = 86400 / mpc\.update_period_s = 0\.5.*monte_carlo\.runs = 50.*the simulation "
                r"takes about .* days.*the limit is"),
    C("evaluate_hours", "runaway", "(beyond the issue's list) an evaluation each of whose tracks fits in memory "
      "whose scoring takes hours: 10 vessels x 10^9 s of tracks (timestamps in ms), every ordered pair scored", '''
    def case(tmp):
        p = tmp / "tracks.csv"
        p.write_text("t_s,vessel,north_m,east_m\\n" + "".join(
            f"{t},v{v},{1000 * v + (1000 if t else 0) * (1 if v % 2 else -1)},{100 * v}\\n"
            for t in (0, 1000000000) for v in range(10)))
        return cli_outcome(*cli("evaluate", p, "--pairs", "all")) or accepted("scored")
    ''', match=r"evaluation of .*tracks\.csv: 1 run\(s\), 1e\+09 samples in all \(sample_interval_s = 1 s\) x up to "
                r"10 vessels, 90 scored pair\(s\) per run \(--pairs = all\): scoring takes about .* h.*the limit is"),
    C("campaign_duration_at_load", "runaway", "(beyond the issue's list) a campaign's duration_s checked after the "
      "file's: a 1-day file refused in a 60 s campaign, a 60 s file in a 1-day campaign accepted until it ran", '''
    def case(tmp):
        import yaml
        from psbmpc_jax.campaign import definition as dfn
        def resolve(duration_file, duration_campaign):
            d = scenario(simulation={"dt_s": 0.5, "duration_s": duration_file}, monte_carlo={"runs": 1})
            d["mpc"]["update_period_s"] = 0.5
            d["own_ship"]["waypoints_m"] = [[0, 0], [100000, 0]]
            d["targets"][0]["waypoints_m"] = [[200, 10], [-90000, 10]]
            p = tmp / f"s{duration_file}.yaml"
            p.write_text(yaml.safe_dump(d))
            return dfn.resolve(dfn.definition_from_dict({"scenarios": [str(p)], "seeds": [0], "runs": 50,
                                                         "chunk_runs": 50, "duration_s": duration_campaign}))
        try:
            resolve(86400, 60)
        except ValueError as e:
            return dict(kind="result", ok=False, detail=f"a 60 s campaign of a 1-day file refused: {e}"[:600])
        resolve(60, 86400)
        return accepted("a 1-day campaign of 50 runs per task")
    ''', match=r"campaign field 'duration_s' = 86400 / mpc\.update_period_s = 0\.5.*campaign chunk_runs = 50.*"
                r"the simulation takes about .* days"),
    C("export_existing_and_unwritable", "runaway", "export/plot functions give raw tracebacks for unwritable or "
      "existing paths", '''
    def case(tmp):
        from test_export import synthetic_result
        from psbmpc_jax.sim import write_trajectories
        from psbmpc_jax.sim.plots import animate_run, write_figures
        res = synthetic_result(2)
        blocker = tmp / "a_file"
        blocker.write_text("x")
        msgs = []
        tries = [("write_trajectories into a file", lambda: write_trajectories(res, blocker / "sub")),
                 ("write_figures into a file", lambda: write_figures(res, blocker / "figs")),
                 ("animate_run onto a folder", lambda: ((tmp / "anim.gif").mkdir(), animate_run(res, 0, tmp / "anim.gif")))]
        write_trajectories(res, tmp / "t", formats=("csv",))
        tries.append(("write_trajectories over an existing file",
                      lambda: write_trajectories(res, tmp / "t", formats=("csv",))))
        for what, fn in tries:
            try:
                fn()
            except (ValueError, OutputError) as e:
                msgs.append(f"{what}: {e}")
                continue
            return accepted(what)
        return dict(kind="error", message=" | ".join(msgs))
    ''', match=r"a_file is a file, not a folder.*a_file is a file, not a folder.*anim\.gif is a folder.*exists already"),
]

#: Two ships head-on, 2 runs of 60 s with 3 behaviours: the run folder the stale-result cases copy.
TINY = (
    "name: audit_tiny\n"
    "simulation: {dt_s: 0.5, duration_s: 60}\n"
    "monte_carlo: {runs: 2, seed: 4}\n"
    "mpc: {preset: nidelva, update_period_s: 5, config: {T: 40},\n"
    "      speed_factors: [[1.0, 0.0]], course_offsets_deg: [[-30, 0, 30]]}\n"
    "sensor: {position_std_m: 2, U_max_mps: 4}\n"
    "own_ship: {name: OS, position_m: [0, 0], course_deg: 0, speed_mps: 2, waypoints_m: [[0, 0], [100, 0]]}\n"
    "targets:\n  - {name: TS1, position_m: [120, 10], course_deg: 180, speed_mps: 2}\n")


def parse_bytes(text: str) -> int:
    from psbmpc_jax.limits import parse_bytes as pb

    return pb(text, "--memory")


def _limits(address_space: int):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))
    return apply


def child_env(memory: int, tmp: pathlib.Path, shared: pathlib.Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               PSBMPC_MEMORY_LIMIT=str(memory), AUDIT_ROOT=str(ROOT), AUDIT_SHARED=str(shared), AUDIT_TMP=str(tmp))
    env.pop("PSBMPC_UPDATE_TIME_LIMIT", None)
    return env


#: Address space a process with JAX and a compiled solve holds besides the work (measured VmSize 1.5 GB after
#: importing JAX): the rlimit is the granted memory plus this.
ADDRESS_SPACE_SLACK = 3 * 2 ** 30


def run_case(case: dict, memory: int, timeout: float, shared: pathlib.Path) -> dict:
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=f"audit_{case['name']}_"))
    code = PRELUDE + case["code"] + EPILOGUE
    t0 = time.perf_counter()
    limit = case["timeout"] or timeout
    try:
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp, timeout=limit,
                           env=child_env(memory, tmp, shared), preexec_fn=_limits(memory + ADDRESS_SPACE_SLACK))
    except subprocess.TimeoutExpired:
        return dict(outcome="runaway", detail=f"did not finish in {limit:g} s", wall_s=round(time.perf_counter() - t0, 1))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    wall = round(time.perf_counter() - t0, 1)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith(MARK)]
    if p.returncode != 0 or not lines:
        return dict(outcome="crash", detail=f"exit {p.returncode}: {p.stderr[-1500:]}", wall_s=wall)
    res = json.loads(lines[-1][len(MARK):])
    kind = res.get("kind")
    if kind == "crash":
        return dict(outcome="crash", detail=res.get("detail", ""), wall_s=wall)
    if kind == "error":
        msg = res.get("message", "")
        clear = case["match"] is not None and re.search(case["match"], msg, re.S) is not None
        return dict(outcome="error" if clear else "unclear", message=msg, wall_s=wall,
                    **({} if clear else {"required": case["match"]}))
    return dict(outcome="correct" if res.get("ok") else "silent", detail=res.get("detail", ""), wall_s=wall)


def make_shared(memory: int, timeout: float) -> pathlib.Path:
    """One real run with trajectories (the stale-result cases copy it)."""
    shared = pathlib.Path(tempfile.mkdtemp(prefix="audit_shared_"))
    (shared / "tiny.yaml").write_text(TINY)
    p = subprocess.run([sys.executable, "-m", "psbmpc_jax.apps.cli", "run", str(shared / "tiny.yaml"), "--out",
                        str(shared / "out"), "--save-trajectories", "--no-figures", "--quiet"], capture_output=True,
                       text=True, timeout=timeout, env=child_env(memory, shared, shared),
                       preexec_fn=_limits(memory + ADDRESS_SPACE_SLACK))
    if p.returncode not in (0, 1) or not (shared / "out" / "audit_tiny" / "trajectories.csv").exists():
        raise SystemExit(f"the shared run failed (exit {p.returncode}): {p.stderr[-2000:]}")
    return shared


def meta() -> dict:
    from psbmpc_jax.provenance import commit

    versions = {}
    for mod in ("jax", "jaxlib", "numpy"):
        try:
            versions[mod] = __import__(mod).__version__
        except ImportError:
            versions[mod] = None
    return {"tool": "tools/audit_surfaces.py", "commit": commit(), "python": platform.python_version(),
            "machine": platform.machine(), "cpu_count": os.cpu_count(), "device": "cpu (JAX_PLATFORMS as set: "
            + os.environ.get("JAX_PLATFORMS", "default") + ")", **versions,
            "load_average": [round(v, 2) for v in os.getloadavg()],
            "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")}


GOOD = ("error", "correct")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--timeout", type=float, default=180.0, help="seconds per case (some cases allow more)")
    ap.add_argument("--memory", default="4GiB", help="memory granted to each case (PSBMPC_MEMORY_LIMIT; the "
                    "address-space limit is this plus 3 GiB)")
    ap.add_argument("--json", type=pathlib.Path, default=None, help="write the record here (never overwritten)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    a = ap.parse_args(argv)
    if a.list:
        for c in CASES:
            print(f"{c['name']:36s} {c['category']:18s} {c['issue']}")
        return 0
    by_name = {c["name"]: c for c in CASES}
    names = [n for n in a.cases.split(",") if n] or list(by_name)
    unknown = [n for n in names if n not in by_name]
    if unknown:
        ap.error(f"--cases: unknown {unknown}; known: {', '.join(by_name)}")
    if a.json is not None and a.json.exists():
        ap.error(f"--json: {a.json} exists already; the audit never overwrites a record")
    memory = parse_bytes(a.memory)
    needs_run = any(by_name[n]["category"] == "stale results" for n in names)
    shared = make_shared(memory, 300.0) if needs_run else pathlib.Path(tempfile.mkdtemp(prefix="audit_shared_"))
    rows = []
    try:
        for n in names:
            c = by_name[n]
            r = run_case(c, memory, a.timeout, shared)
            rows.append(dict(case=n, category=c["category"], issue=c["issue"], **r))
            text = r.get("message") or r.get("detail") or ""
            print(f"{r['outcome']:8s} {n:36s} {r['wall_s']:6.1f} s  {text[-200:]!r}", flush=True)
    finally:
        shutil.rmtree(shared, ignore_errors=True)
    counts = {k: sum(r["outcome"] == k for r in rows) for k in ("error", "correct", "unclear", "silent", "crash",
                                                                 "runaway")}
    print("counts:", json.dumps(counts))
    if a.json is not None:
        from psbmpc_jax.safe_io import atomic_write_text

        doc = {"meta": {**meta(), "memory_granted_bytes": memory, "timeout_s": a.timeout}, "counts": counts,
               "cases": rows}
        atomic_write_text(a.json, json.dumps(doc, indent=1) + "\n")
        print(f"wrote {a.json}")
    return 0 if all(r["outcome"] in GOOD for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
