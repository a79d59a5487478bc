"""Summaries of several evaluations (e.g. the Monte Carlo runs of one scenario): per pair of vessels, the
count of encounters by situation and status, and per score its count, mean, min and max over the encounters
where it applies."""

from __future__ import annotations

import numpy as np

from .results import SCORE_NAMES, Evaluation

__all__ = ["aggregate", "score_stats"]


def score_stats(values) -> dict:
    """``{"n", "mean", "min", "max"}`` of the non-None values (None statistics when there are none)."""
    v = np.array([x for x in values if x is not None], dtype=float)
    if v.size == 0:
        return {"n": 0, "mean": None, "min": None, "max": None}
    return {"n": int(v.size), "mean": float(v.mean()), "min": float(v.min()), "max": float(v.max())}


def _count(items) -> dict:
    out: dict = {}
    for x in items:
        out[x] = out.get(x, 0) + 1
    return dict(sorted(out.items()))


def aggregate(evaluations, scores=SCORE_NAMES) -> dict:
    """Summarise ``evaluations`` (an :class:`Evaluation` or a list of them).

    Returns a JSON-ready dict::

        {"runs": R, "encounters": N,
         "situations": {"HO": 3, ...}, "statuses": {"scored": 3, ...},
         "scores": {"S_sit": {"n", "mean", "min", "max"}, ...},          # over every encounter
         "pairs": [{"vessel", "other", "encounters", "runs_with_encounter", "situations", "statuses",
                    "scores": {...}}, ...]}                              # per (evaluated vessel, other vessel)

    Only scores that apply enter the statistics (a None score is skipped, not counted as 0).
    """
    if isinstance(evaluations, Evaluation):
        evaluations = [evaluations]
    evaluations = list(evaluations)
    everything: list = []
    per_pair: dict[tuple, list] = {}
    runs_of: dict[tuple, set] = {}
    for r, ev in enumerate(evaluations):
        for e in ev.encounters:
            everything.append(e)
            key = (e.vessel, e.other)
            per_pair.setdefault(key, []).append(e)
            runs_of.setdefault(key, set()).add(r)

    def summary(encs) -> dict:
        return {"situations": _count(e.situation for e in encs), "statuses": _count(e.status for e in encs),
                "scores": {name: score_stats(getattr(e.scores, name) for e in encs) for name in scores}}

    pairs = [{"vessel": v, "other": o, "encounters": len(encs), "runs_with_encounter": len(runs_of[v, o]),
              **summary(encs)} for (v, o), encs in per_pair.items()]
    return {"runs": len(evaluations), "encounters": len(everything), **summary(everything), "pairs": pairs}
