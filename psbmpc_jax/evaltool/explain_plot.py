"""The figure of one explained encounter (:mod:`psbmpc_jax.evaltool.explain`): left, the tracks of both ships
north up with the stage circles (radius r_Stage2/3/4 around the other ship where the stage starts), the
detected manoeuvres, the CPA and a marker where each non-zero penalty fired; right, the range and the
evaluated ship's course over time with the same events.  matplotlib is imported only inside the function.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np

from ..numerics import wrap_angle_host
from ..safe_io import atomic_open
from .results import Encounter, Evaluation

__all__ = ["plot_explanation"]

_STAGE_COLORS = {2: "tab:olive", 3: "tab:orange", 4: "tab:red"}


def _span(ev: Evaluation, e: Encounter) -> slice:
    """The samples drawn: from a quarter of the encounter's length before detection to as much after the CPA."""
    pad = max(10, (e.k_cpa - e.k_detect) // 4)
    return slice(max(0, e.k_detect - pad), min(ev.t.size, e.k_cpa + pad + 1))


def plot_explanation(ev: Evaluation, e: Encounter, x: dict, path, dpi: int = 110) -> pathlib.Path:
    """Draw encounter ``e`` of ``ev`` with its explanation ``x`` (:func:`~psbmpc_jax.evaltool.explain.
    explain_encounter`) and write it to ``path`` as PNG, atomically.  Returns the path."""
    if ev.resampled is None:
        raise ValueError("plot_explanation needs an Evaluation made by evaluate_tracks (it keeps the resampled "
                         "tracks)")
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    tr, t = ev.resampled, ev.t
    assert tr is not None                       # checked above
    i, j = e.vessel_index, e.other_index
    sl = _span(ev, e)
    fig, (ax, axr) = plt.subplots(1, 2, figsize=(13, 6.2), gridspec_kw={"width_ratios": [1.1, 1]})
    ax.plot(tr.east[i, sl], tr.north[i, sl], color="tab:red", lw=1.5, label=f"{e.vessel} (evaluated)")
    ax.plot(tr.east[j, sl], tr.north[j, sl], color="tab:blue", lw=1.5, label=e.other)
    ax.plot(tr.east[i, sl.start], tr.north[i, sl.start], "o", color="tab:red", ms=4)
    ax.plot(tr.east[j, sl.start], tr.north[j, sl.start], "o", color="tab:blue", ms=4)
    for s in x["stages"]:
        if s["stage"] == 1 or s["k"] is None:
            continue
        k, c = s["k"], _STAGE_COLORS[s["stage"]]
        ax.add_patch(plt.Circle((tr.east[j, k], tr.north[j, k]), s["radius_m"], fill=False, ls="--", lw=0.8,
                                color=c))
        ax.plot(tr.east[i, k], tr.north[i, k], "s", color=c, ms=6,
                label=f"stage {s['stage']} from t {s['t_s']:.0f} s (r {s['r_m']:.0f} m)")
        axr.axvline(s["t_s"], color=c, ls="--", lw=0.8)
    ks = e.k_start
    ax.plot(tr.east[i, ks], tr.north[i, ks], "D", color="k", ms=5, mfc="none",
            label=f"encounter start t {e.t_start:.0f} s ({e.situation})")
    for m in x["maneuvers"]:
        a, b = m["start"], min(m["end"], t.size - 1)
        ax.plot(tr.east[i, a:b + 1], tr.north[i, a:b + 1], color="tab:purple", lw=4, alpha=0.45)
        size = (f"{m['delta_course_deg']:+.0f}°" if m["kind"] == "course" else f"{m['delta_speed_mps']:+.1f} m/s")
        ax.annotate(size, (tr.east[i, a], tr.north[i, a]), fontsize=7, color="tab:purple",
                    xytext=(4, -8), textcoords="offset points")
        axr.axvspan(t[a], t[b], color="tab:purple", alpha=0.12)
    kc = e.k_cpa
    ax.plot([tr.east[i, kc], tr.east[j, kc]], [tr.north[i, kc], tr.north[j, kc]], "k-", lw=1)
    ax.plot([tr.east[i, kc], tr.east[j, kc]], [tr.north[i, kc], tr.north[j, kc]], "kx", ms=7,
            label=f"CPA t {e.t_cpa:.0f} s, r {e.r_cpa:.1f} m")
    fired = [d for d in x["terms"] if d["name"].startswith("P_") and d["value"] and d.get("k") is not None]
    at_k: dict = {}                                      # one label per sample, the penalties fired there
    for d in fired:
        at_k.setdefault(d["k"], []).append(f"{d['name']} {d['value']:.2f}")
    for k, names in at_k.items():
        ax.plot(tr.east[i, k], tr.north[i, k], "*", color="k", ms=9)
        ax.annotate("\n".join(names), (tr.east[i, k], tr.north[i, k]), fontsize=7, xytext=(8, 4),
                    textcoords="offset points", bbox={"fc": "w", "alpha": 0.75, "lw": 0})
    east = np.concatenate([tr.east[i, sl], tr.east[j, sl]])
    north = np.concatenate([tr.north[i, sl], tr.north[j, sl]])
    half = 0.55 * max(np.ptp(east), np.ptp(north), 4 * e.r_cpa, 1.0)
    ax.set_xlim(east.mean() - half, east.mean() + half)
    ax.set_ylim(north.mean() - half, north.mean() + half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)

    r = np.hypot(tr.north[j] - tr.north[i], tr.east[j] - tr.east[i])
    axr.plot(t[sl], r[sl], color="k", lw=1.2, label="range [m]")
    axr.plot(e.t_cpa, e.r_cpa, "kx", ms=7)
    axr.set_xlabel("t [s]")
    axr.set_ylabel("range [m]")
    axc = axr.twinx()
    chi0 = tr.course[i, e.k_start]
    dev = np.degrees(wrap_angle_host(tr.course[i, sl] - chi0, include_pi=True))
    axc.plot(t[sl], dev, color="tab:red", lw=1, label=f"course of {e.vessel} − course at start [°]")
    axc.axhline(0, color="tab:red", lw=0.5, ls=":")
    axc.set_ylabel("course change from the encounter start [°] (+ starboard)", color="tab:red")
    for k, names in at_k.items():
        y = math.degrees(math.remainder(tr.course[i, k] - chi0, 2 * math.pi))
        axc.plot(t[k], y, "*", color="k", ms=9)
        axc.annotate(", ".join(n.split()[0] for n in names), (t[k], y), fontsize=7, xytext=(4, 4),
                     textcoords="offset points")
    lines = [f"{x['score'] or 'S_sit'} = {_f(x['S_sit'])}   S_safety {_f(x['S_safety'])}"
             + (f"   dominant {x['dominant']} (−{x['costs'][x['dominant']]:.2f})" if x["dominant"] else "")]
    lines += [f"{d['name']} {d['value']:.2f} at t {d['t_s']:.0f} s" for d in fired]
    axr.text(0.02, 0.02, "\n".join(lines), transform=axr.transAxes, fontsize=8, va="bottom",
             bbox={"fc": "w", "alpha": 0.85, "lw": 0.5})
    run = "" if x["run"] is None else f"run {x['run']}: "
    fig.suptitle(f"{run}{e.vessel} vs {e.other}, {e.situation} ({e.status})"
                 + (f"  {x['composition']}" if x["composition"] else ""), fontsize=9)
    fig.tight_layout()
    path = pathlib.Path(path)
    with atomic_open(path, "wb") as fh:                  # complete or absent, never a partial PNG
        fig.savefig(fh, dpi=dpi, format="png")
    plt.close(fig)
    return path


def _f(v) -> str:
    return "—" if v is None else f"{v:.3f}"
