"""The encounter classification of the simulator's metrics, taken from the COLREGS evaluation tool
(:mod:`psbmpc_jax.evaltool`, Hagen et al. 2023 reconstructed), so that every table of ``summary.md`` and
``metrics.json`` names one situation per encounter.

The tool resamples the tracks onto its grid (``sample_interval_s``), detects each encounter when the range
first falls within ``r_stage2_m`` and locks its situation at the encounter start (the first sample after
detection with an applicable rule).  Here the own-ship's **first** encounter with each target is used:

==========  ======================  ===============================================
tool code   metrics name            meaning
==========  ======================  ===============================================
``HO``      ``head-on``             Rule 14
``CRGW``    ``crossing-give-way``   Rule 15, the own-ship gives way
``CRSO``    ``crossing-stand-on``   Rule 15/17, the own-ship stands on
``OTGW``    ``overtaking``          Rule 13, the own-ship overtakes
``OTSO``    ``overtaken``           Rule 13, the own-ship is overtaken
``NAR``     ``none``                no applicable rule at any sample of the encounter
(none)      ``none``                the target never came within ``r_stage2_m``
==========  ======================  ===============================================
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..evaltool.encounters import find_windows
from ..evaltool.geometry import pair_geometry
from ..evaltool.params import EvalParams
from ..evaltool.tracks import Tracks

__all__ = ["SITUATION_NAMES", "first_encounters"]

#: EvalTool situation code -> the encounter name of :mod:`psbmpc_jax.sim.metrics`.
SITUATION_NAMES = {"HO": "head-on", "CRGW": "crossing-give-way", "CRSO": "crossing-stand-on",
                   "OTGW": "overtaking", "OTSO": "overtaken", "NAR": "none"}


def first_encounters(t, own, targets, params: EvalParams) -> list[dict]:
    """The own-ship's first encounter with each target, as the evaluation tool detects it
    (:func:`psbmpc_jax.evaltool.evaluate_tracks` with ``pairs="own"`` finds the same windows).

    Args:
        t: ``[K]`` times [s]; own: ``[K, 4]``; targets: ``[n, K, 4]`` rows (north, east, chi [rad], U [m/s]).
        params: the evaluation's parameters (the scenario's ``evaluation`` section).

    Returns:
        Per target ``{"situation": code or None, "encounter": metrics name, "t_start_s": time the situation
        was locked or None, "t_detect_s": time the range first fell within r_stage2 or None}``.
    """
    if not isinstance(params, EvalParams):
        raise TypeError(f"params must be an EvalParams, got {type(params).__name__}")
    own = np.asarray(own, dtype=float)
    targets = np.asarray(targets, dtype=float).reshape(-1, own.shape[0], 4)
    if targets.shape[0] == 0:
        return []
    states = np.concatenate([own[None], targets], axis=0)                  # [V, K, 4]
    tracks = Tracks(t=np.asarray(t, dtype=float), north=states[..., 0], east=states[..., 1],
                    course=states[..., 2], speed=states[..., 3],
                    names=tuple(f"v{i}" for i in range(states.shape[0])), own=0)
    tr = tracks.resample(params.sample_interval_s)
    out: list[dict[str, Any]] = []
    for j in range(1, tr.n_vessels):
        g = pair_geometry(tr.north, tr.east, tr.course, tr.speed, 0, j, params)
        windows = find_windows(g, tr.speed[0], tr.speed[j], 0, j, params)
        if not windows:
            out.append({"situation": None, "encounter": "none", "t_start_s": None, "t_detect_s": None})
            continue
        w = windows[0]
        out.append({"situation": w.situation, "encounter": SITUATION_NAMES[w.situation],
                    "t_start_s": float(tr.t[w.k_s]), "t_detect_s": float(tr.t[w.k_d])})
    return out
