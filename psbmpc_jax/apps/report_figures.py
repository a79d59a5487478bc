"""Figures of ``psbmpc-jax report``: box plots of the runtime per swept size in the style of Sec. IV-B/C of the
PSB-MPC paper (Figs. 5-7, 9, 10), one colour per implementation, with a linear-axes panel of the JAX medians and
their least-squares lines.  matplotlib is imported only inside :func:`boxplot` (Agg backend)."""

from __future__ import annotations

import math

import numpy as np

from .report_records import label_order, linear_fit

# Paper figures: (key, sweep name, swept size, fixed n_cbs or None, title)
PAPER_FIGURES = (
    ("fig5", "fig5", "n_cbs", None, "Runtime vs number of control behaviours n_cbs (paper Fig. 5)"),
    ("fig6", "fig6", "n_ps", 39, "Runtime vs prediction scenarios n_ps, n_cbs = 39 (paper Fig. 6)"),
    ("fig7", "fig7", "n_ps", 1014, "Runtime vs prediction scenarios n_ps, n_cbs = 1014 (paper Fig. 7)"),
    ("fig9", "fig9", "n_vertices", None, "Runtime with RDP off/on: total polygon vertices (paper Fig. 9)"),
    ("fig10", "fig10", "n_so", None, "Runtime vs number of static obstacles n_so (paper Fig. 10)"),
)
_COLOURS = {"reference": "#7f7f7f", "JAX-CPU": "#1f77b4", "JAX-GPU": "#2ca02c"}
_EXTRA_COLOURS = ("#d62728", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf", "#bcbd22")


def paper_selection(groups):
    """Map each paper figure to the (sweep, swept) groups it draws (sweep named after the figure, else
    fallback: a non-paper sweep with the right swept size (and n_cbs for fig6/fig7))."""
    paper_names = {p[1] for p in PAPER_FIGURES}
    sel = {}
    for key, sweep, swept, n_cbs, title in PAPER_FIGURES:
        if (sweep, swept) in groups:
            sel[key] = [(sweep, swept)]
            continue
        cands = []
        for (sw, sp), pts in groups.items():
            if sw in paper_names or sp != swept:
                continue
            if n_cbs is not None:
                cb = {r["n_cbs"] for cells in pts.values() for c in cells.values() for r in c.records}
                if cb != {n_cbs}:
                    continue
            cands.append((sw, sp))
        if cands:
            sel[key] = sorted(cands)
    return sel


def boxplot(path, title, swept, pts, *, dpi=110):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    xs = sorted(pts)
    labels = label_order(lab for x in xs for lab in pts[x])
    colours = {}
    extra = iter(_EXTRA_COLOURS * 4)
    for lab in labels:
        colours[lab] = _COLOURS.get(lab) or next(extra)
    nl = len(labels)
    width = 0.8 / nl
    jax_labels = [lab for lab in labels if lab != "reference"]
    # second panel: JAX alone on a linear, true-to-scale x axis with its least-squares line (the reference
    # is 10-100x slower and flattens the JAX boxes in the first panel)
    fit_panel = bool(jax_labels) and len(xs) >= 3 and swept != "n_vertices"
    w_main = max(6.5, 1.1 * len(xs) * max(1, nl / 2) + 2)
    if fit_panel:
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(w_main + 5.5, 4.6), width_ratios=(w_main, 5.5))
    else:
        fig, ax = plt.subplots(figsize=(w_main, 4.6))
    all_t = [t for x in xs for c in pts[x].values() for t in c.times if t > 0]
    log = bool(all_t) and max(all_t) / min(all_t) > 100.0
    skipped_marks = []
    for i, x in enumerate(xs):
        for j, lab in enumerate(labels):
            pos = i + (j - (nl - 1) / 2) * width
            cell = pts[x].get(lab)
            if cell is None:
                continue
            if cell.times:
                _boxes(ax, [cell.times], [pos], width, colours[lab])
            elif cell.skipped:
                skipped_marks.append((pos, lab))
    if log:
        ax.set_yscale("log")
    ylo, yhi = ax.get_ylim()
    for pos, lab in skipped_marks:
        ybase = ylo * (yhi / ylo) ** 0.04 if log else ylo + 0.04 * (yhi - ylo)
        ax.text(pos, ybase, "skipped", rotation=90, ha="center", va="bottom", fontsize=7, color=colours[lab])
    ax.set_xticks(range(len(xs)))
    if swept == "n_vertices" and len(xs) == 2:
        ax.set_xticklabels([f"RDP on\n{xs[0]} vertices", f"RDP off\n{xs[1]} vertices"])
    else:
        ax.set_xticklabels([str(x) for x in xs])
    ax.set_xlim(-0.6, len(xs) - 0.4)
    ax.set_xlabel(swept)
    ax.set_ylabel("runtime [ms]" + (" (log scale)" if log else ""))
    ax.set_title(title, fontsize=10)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(handles=[Patch(facecolor=colours[lab], alpha=0.75, label=lab) for lab in labels],
              loc="upper left", fontsize=8)
    if fit_panel:
        _jax_fit_panel(ax2, swept, xs, jax_labels, pts, colours)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def _boxes(ax, data, positions, width, colour):
    """One implementation's box plots (filled in its colour, black median, '+' outliers)."""
    bp = ax.boxplot(data, positions=positions, widths=width * 0.85, patch_artist=True, showfliers=True,
                    manage_ticks=False, flierprops=dict(marker="+", markersize=4, markeredgecolor=colour),
                    medianprops=dict(color="black", lw=1.2))
    for b in bp["boxes"]:
        b.set_facecolor(colour)
        b.set_alpha(0.75)


def _jax_fit_panel(ax, swept, xs, labels, pts, colours):
    """JAX series only: box plots at their true x and the least-squares line through the medians."""
    span = float(max(xs) - min(xs)) or 1.0
    width = 0.5 * span / max(len(xs), 2) / len(labels)
    for j, lab in enumerate(labels):
        cells = [(float(x), pts[x][lab]) for x in xs if pts[x].get(lab) is not None and pts[x][lab].times]
        if not cells:
            continue
        shift = (j - (len(labels) - 1) / 2) * width
        _boxes(ax, [c.times for _, c in cells], [x + shift for x, _ in cells], width, colours[lab])
        if len(cells) >= 2:
            fit = linear_fit([x for x, _ in cells], [c.median for _, c in cells])
            line_x = np.array([min(xs), max(xs)], float)
            r2 = "" if math.isnan(fit["r2"]) else f", R² = {fit['r2']:.3f}"
            ax.plot(line_x, fit["slope"] * line_x + fit["intercept"], color=colours[lab], lw=1.2, ls="--",
                    label=f"{lab}: {fit['slope']:.3g} ms/unit{r2}")
    ax.set_xlim(min(xs) - 0.06 * span, max(xs) + 0.06 * span)
    ax.set_xlabel(swept)
    ax.set_ylabel("runtime [ms]")
    ax.set_title("JAX only, linear axes, least-squares line of the medians", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)

