#!/usr/bin/env python3
"""Why Smooth-SBMPC (Mahipala & Johansen 2024) does not lower the course rate in the reconstructed scene of its
paper (``smooth_000_reconstruction``): variants of the DOCP on the same seeds, and where the applied
course-offset changes come from.

    python experiments/smooth_sbmpc/ablation.py --runs 5 --out /tmp/smooth_ablation

Variants (each the scenario's Smooth-SBMPC with one change; ``sbmpc_init`` is the init stage alone):

* ``sbmpc_init``: the baseline (the paper's Simulation 01 in our reading, docs/smooth_sbmpc.md);
* ``full``: the file as it is (terminal equality x, y, χ, U to Ψ_{N_mpc}, 4 starts);
* ``full_previous``: + the previous update's plan as start 1 (``mpc.smooth.previous_start``);
* ``position``: terminal equality on x, y only;  ``soft``: a quadratic terminal penalty instead;
* ``soft_previous``: both;
* ``full_gamma_x10``: Γ's course- and speed-change weights Δ_χ, Δ_U ×10 (both stages: a sensitivity check of
  the proposed weights, the paper gives none; not a proposed setting);
* ``sbmpc_init_gamma_x10``: the init stage alone with the same weights (the fair baseline of the line above).

Per variant: collisions, groundings, shore clearance, mean |course rate|, path length (as
``experiments/compare_methods.py``), and the mechanism: the total variation of the applied course offset, the
jump of the terminal target Ψ_{N_mpc} between consecutive updates (update m's Ψ at t_m + T_mpc against update
m + 1's prediction of the same instant) and how much of the applied-offset variation falls in updates whose
terminal target jumped by more than 0.5 m.  Writes ``ablation.json`` (with commit, versions, device) under
``--out`` (default: a new ``results_<UTC stamp>/`` folder next to this script).  A folder that already holds
files is refused unless ``--force``; with ``--force`` the variants already in its ``ablation.json`` and not run
again are kept (each row records its commit).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import json
import pathlib
import platform
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))   # experiments/: comparison.py
from comparison import output_folder, utc_stamp  # noqa: E402

STUDY = pathlib.Path(__file__).resolve().parent
SCENARIO = "smooth_000_reconstruction"
VARIANTS = {
    "sbmpc_init": ("sbmpc_init", {}, 1.0),
    "full": ("smooth_sbmpc", {}, 1.0),
    "full_previous": ("smooth_sbmpc", {"previous_start": True}, 1.0),
    "position": ("smooth_sbmpc", {"terminal": "position"}, 1.0),
    "soft": ("smooth_sbmpc", {"terminal": "soft"}, 1.0),
    "soft_previous": ("smooth_sbmpc", {"terminal": "soft", "previous_start": True}, 1.0),
    "full_gamma_x10": ("smooth_sbmpc", {}, 10.0),
    "sbmpc_init_gamma_x10": ("sbmpc_init", {}, 10.0),
}
JUMP_M = 0.5


def mechanism(psi: np.ndarray, controls: np.ndarray, n_mpc: int) -> dict:
    """``psi [M, R, N_init + 1, 4]``, ``controls [M, R, N_mpc, 2]`` recorded at consecutive 1-step updates."""
    jump = np.hypot(*np.moveaxis(psi[1:, :, n_mpc - 1, :2] - psi[:-1, :, n_mpc, :2], -1, 0))   # [M-1, R]
    dchi = np.degrees(np.abs(np.diff(controls[:, :, 0, 1], axis=0)))                         # [M-1, R]
    big = jump > JUMP_M
    total = dchi.sum()
    return {
        "applied_offset_total_variation_deg_per_run": float(total / dchi.shape[1]),
        "terminal_jump_m": {"median": float(np.median(jump)), "p90": float(np.percentile(jump, 90)),
                            "max": float(jump.max()), f"fraction_over_{JUMP_M}_m": float(big.mean())},
        f"share_of_offset_variation_in_updates_with_jump_over_{JUMP_M}_m": float(dchi[big].sum() / total)
        if total else None,
        "corr_jump_offset_change": float(np.corrcoef(jump.ravel(), dchi.ravel())[0, 1]) if total else None,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated, from " + ", ".join(VARIANTS))
    p.add_argument("--out", default=None, help="output folder (default: a new results_<UTC stamp> folder next "
                   "to this script)")
    p.add_argument("--force", action="store_true", help="write into an --out folder that already holds results "
                   "(its ablation.json's other variants are kept)")
    args = p.parse_args(argv)
    names = [v.strip() for v in args.variants.split(",")]
    bad = [v for v in names if v not in VARIANTS]
    if bad:
        p.error(f"--variants: unknown {bad}; allowed: {', '.join(VARIANTS)}")

    import jax

    from psbmpc_jax.provenance import commit
    from psbmpc_jax.scenario import load_scenario
    from psbmpc_jax.methods import smooth
    from psbmpc_jax.sim import simulate
    from psbmpc_jax.smooth.planner import SmoothSBMPCPlanner

    record: list = []
    scale = {"x": 1.0}

    class Recording(SmoothSBMPCPlanner):
        def __init__(self, *a, weights, **kw):
            s = scale["x"]
            weights = dataclasses.replace(weights, Delta_chi_port=weights.Delta_chi_port * s,
                                          Delta_chi_stbd=weights.Delta_chi_stbd * s, Delta_U=weights.Delta_U * s)
            super().__init__(*a, weights=weights, **kw)

        def plan_batch(self, *a, **kw):
            plan = super().plan_batch(*a, **kw)
            record.append((np.asarray(plan.psi), np.asarray(plan.controls)))
            return plan

    smooth.smooth_planner_class = lambda: Recording
    started_at = commit()                  # the code this process imported (later edits do not change it)

    out = output_folder(args.out, STUDY / f"results_{utc_stamp()}", force=args.force)
    old = out / "ablation.json"
    rows = {k: v for k, v in json.loads(old.read_text())["variants"].items() if k not in names} if old.exists() else {}
    for name in names:
        method, changes, scale["x"] = VARIANTS[name]
        sc = load_scenario(SCENARIO, method=method)
        if changes:
            sc = dataclasses.replace(sc, mpc=sc.mpc.with_section("smooth", **changes))
        record.clear()
        t0 = time.perf_counter()
        res = simulate(sc, runs=args.runs, seed=args.seed, progress=False)
        wall = time.perf_counter() - t0
        m = res.metrics
        psi = np.stack([r[0] for r in record])
        ctl = np.stack([r[1] for r in record])
        cr = [x["mean_abs_course_rate_deg_s"] for x in m]
        rows[name] = {
            "method": method, "smooth_changes": changes, "gamma_change_weight_scale": scale["x"],
            "collisions": res.summary["collisions"], "groundings": res.summary["groundings"],
            "min_distance_land_m": min(x["min_distance_land_m"] for x in m),
            "mean_abs_course_rate_deg_s": {"mean": float(np.mean(cr)), "per_run": cr},
            "path_length_m_mean": float(np.mean([x["path_length_m"] for x in m])),
            "mechanism": mechanism(psi, ctl, int(round(sc.mpc.smooth.T_mpc / sc.mpc.smooth.dt))),
            "wall_s": round(wall, 1),
            "commit": started_at,
        }
        r = rows[name]
        print(f"{name}: course rate {r['mean_abs_course_rate_deg_s']['mean']:.3f} deg/s, clearance "
              f"{r['min_distance_land_m']:.2f} m, path {r['path_length_m_mean']:.1f} m, collisions "
              f"{r['collisions']}, groundings {r['groundings']}, offset TV "
              f"{r['mechanism']['applied_offset_total_variation_deg_per_run']:.0f} deg/run, wall {wall:.0f} s",
              flush=True)
        doc = {"scenario": SCENARIO, "runs": args.runs, "seed": args.seed,
               "variants": {k: rows[k] for k in VARIANTS if k in rows},
               "commit": started_at, "device": str(jax.devices()[0]), "platform": platform.platform(),
               "versions": {"python": sys.version.split()[0], "jax": jax.__version__, "numpy": np.__version__},
               "command": "python experiments/smooth_sbmpc/ablation.py "
                          + " ".join(argv if argv is not None else sys.argv[1:]),
               "utc": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}
        (out / "ablation.json").write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
