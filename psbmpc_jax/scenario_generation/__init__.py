"""COLREGS-typed encounter generation: own-ship + 1-N targets of requested types (head-on, crossing give-way /
stand-on, overtaking, overtaken), drawn from documented ranges of relative course, target speed, CPA distance,
time to CPA and relative bearing, in open water or placed on a chart, reproducible from a seed, written as
ordinary scenario files.  See ``docs/encounter_generation.md``.

    from psbmpc_jax.scenario_generation import generate_encounters, write_scenarios, classify_straight_line
    batch = generate_encounters("crossing_give_way", 100, seed=0)          # the "harbour" preset
    write_scenarios(batch, "generated/crossing")                          # + generated/crossing/encounters.json
    classify_straight_line(batch.encounters[0].scenario)                   # ('CRGW',)

The types follow the evaluation tool's classification (:mod:`psbmpc_jax.evaltool`, the sectors of Woerner (2016) as
used by Hagen et al. (2023)): the generator keeps a draw only if that classification, read with the scenario's own
evaluation parameters, gives the requested type with a margin, so generation and evaluation agree by
construction.

Modules: :mod:`~psbmpc_jax.scenario_generation.settings` (ranges, presets), :mod:`~.sectors` (pair geometry and the
classification check), :mod:`~.sampling` (drawing, land), :mod:`~.files` (writing, straight-line check).
"""

from .files import MANIFEST, classify_straight_line, straight_line_tracks, write_scenarios
from .sampling import (MAX_TRIES, REJECTION_REASONS, EncounterBatch, GeneratedEncounter, GenerationContext, Land,
                       generate_encounter, generate_encounters, prepare)
from .settings import (ENCOUNTER_TYPES, PRESETS, SITUATION_CODES, EncounterRanges, GenerationSettings, get_settings,
                       settings_from_dict)

__all__ = ["ENCOUNTER_TYPES", "SITUATION_CODES", "EncounterRanges", "GenerationSettings", "PRESETS", "get_settings",
           "settings_from_dict", "generate_encounter", "generate_encounters", "prepare", "GeneratedEncounter",
           "EncounterBatch", "GenerationContext", "Land", "REJECTION_REASONS", "MAX_TRIES", "write_scenarios",
           "straight_line_tracks", "classify_straight_line", "MANIFEST"]
