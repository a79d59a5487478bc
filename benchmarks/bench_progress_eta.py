"""How honest is the ETA of ``psbmpc-jax run``'s progress bar?  Runs ``psbmpc-jax run`` on each scenario and
records, at the first update past 25 % of the MPC updates, the remaining time tqdm shows (its smoothed rate,
restarted after the compiling first update) and the plain bar's estimate (mean time per update after the first),
then the true remaining time (until the bar closes), and every update's duration.

    python benchmarks/bench_progress_eta.py --case head_on:10 --case crossing_give_way:20
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import psbmpc_jax.sim.simulator as sim
from psbmpc_jax.apps.cli import main

from _common import environment_meta, write_results


def measure(scenario: str, runs: int) -> dict:
    rec: dict = {"scenario": scenario, "runs": runs}
    stamps: list[float] = []
    base = sim._Progress

    class Probe(base):
        def update(self, done):
            super().update(done)
            stamps.append(time.perf_counter())
            if self.bar is not None and "at_25" not in rec and self.done >= 0.25 * self.total:
                fd = self.bar.format_dict
                # tqdm's own rule (format_meter): the smoothed rate, else the mean since the (re)start
                rate = fd["rate"] or ((fd["n"] - fd["initial"]) / fd["elapsed"] if fd["elapsed"] else None)
                rec.update(total_updates=self.total, at_25=self.done, t_25=time.perf_counter(), tqdm_rate=fd["rate"],
                           tqdm_eta_s=(fd["total"] - fd["n"]) / rate if rate else None,
                           mean_eta_s=self.eta(), first_update_s=self.t_first - self.t0)

        def close(self):
            super().close()
            if "t_25" in rec:
                rec["true_remaining_s"] = time.perf_counter() - rec.pop("t_25")

    sim._Progress = Probe
    try:
        with tempfile.TemporaryDirectory() as out:
            rc = main(["run", scenario, "--runs", str(runs), "--no-figures", "--out", out])
    finally:
        sim._Progress = base
    rec["exit_status"] = rc
    rec["update_s"] = [round(b - a, 3) for a, b in zip(stamps, stamps[1:])]
    for k in ("tqdm_eta_s", "mean_eta_s"):
        if rec.get(k) is not None:
            rec[k.replace("_s", "_error")] = round(rec[k] / rec["true_remaining_s"] - 1.0, 3)
    return rec


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", action="append", default=[], metavar="SCENARIO:RUNS")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    args = ap.parse_args()
    points = []
    for case in args.case or ["head_on:10"]:
        name, _, runs = case.partition(":")
        points.append(measure(name, int(runs or 10)))
        p = points[-1]
        print(f"{name} x {p['runs']}: at {p['at_25']}/{p['total_updates']} updates tqdm ETA {p['tqdm_eta_s']:.1f} s, "
              f"mean ETA {p['mean_eta_s']:.1f} s, true {p['true_remaining_s']:.1f} s")
    write_results(args.out, "progress_eta", environment_meta("progress_eta", cases=args.case), points)
