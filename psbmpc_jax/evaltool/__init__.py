"""EvalTool: COLREGS compliance and safety scores of recorded ship encounters (pure NumPy, no JAX).

An open reconstruction of the evaluation of Hagen, Vassbotn, Skogvold, Johansen and Brekke, "Safety and COLREG
evaluation for marine collision avoidance algorithms", Ocean Engineering 288 (2023) 115991, from our written
specification of the tool (the formulas are rebuilt from published numbers and descriptions; no code of the original
tool was used). See ``docs/evaltool.md``.

    from psbmpc_jax.evaltool import Tracks, evaluate_tracks, evaluate_file, aggregate
    tr = Tracks.from_arrays(t, north, east, course, speed, names=["own", "ferry"])   # [V, n] arrays, SI
    ev = evaluate_tracks(tr, "inland_small")             # or an EvalParams; own-ship = tracks.own
    for e in ev.encounters:
        print(e.other, e.situation, e.status, e.scores.S_sit)
    evs = evaluate_file("out/head_on/trajectories.npz", "default")   # one Evaluation per run
    summary = aggregate(evs)                              # JSON-ready mean/min/max per score, counts
    evs = [evaluate_tracks(tr, "default") for tr in tracks_from_simulation(result)]   # a SimulationResult
"""

from .aggregate import aggregate, score_stats
from .evaluate import PAIR_MODES, evaluate_file, evaluate_tracks
from .geometry import SITUATIONS
from .maneuvers import Maneuver, detect_maneuvers
from .params import PRESETS, EvalParams, get_params, preset_names
from .results import SCORE_NAMES, STATUSES, Encounter, EncounterScores, Evaluation
from .tracks import OPTIONAL_COLUMNS, USER_COLUMNS, Tracks, load_runs, load_tracks, tracks_from_simulation

__all__ = ["EvalParams", "PRESETS", "get_params", "preset_names",
           "Tracks", "load_tracks", "load_runs", "tracks_from_simulation", "USER_COLUMNS", "OPTIONAL_COLUMNS",
           "evaluate_tracks", "evaluate_file", "PAIR_MODES",
           "Evaluation", "Encounter", "EncounterScores", "SCORE_NAMES", "STATUSES", "SITUATIONS",
           "Maneuver", "detect_maneuvers", "aggregate", "score_stats"]
