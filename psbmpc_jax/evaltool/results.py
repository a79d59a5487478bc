"""Result structures of the evaluation: per-encounter scores, encounters, and the whole evaluation.

Every structure has ``to_dict()`` giving JSON-ready Python numbers (angles in degrees, with ``_deg`` in the
key).  A score or penalty that does not apply to an encounter (e.g. S14 in a crossing) is None, never 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from .maneuvers import Maneuver
from .params import EvalParams

if TYPE_CHECKING:
    from .tracks import Tracks

__all__ = ["EncounterScores", "Term", "Encounter", "Evaluation", "SCORE_NAMES", "STATUSES"]

#: Encounter statuses: ``scored`` (every applicable score computed), ``nar`` (no applicable rule: only the
#: safety scores), ``no_risk`` (risk gate: only the safety scores), ``incomplete`` (the CPA is the last sample
#: of the data: nothing scored), ``not_moving`` (the evaluated vessel is below ε_U over the whole encounter:
#: nothing scored).
STATUSES = ("scored", "nar", "no_risk", "incomplete", "not_moving")


@dataclass(frozen=True)
class EncounterScores:
    """Every score (S) and penalty (P) of one encounter, in [0, 1]; None where it does not apply.

    ``S_sit`` is the situation score: S13 (overtaking, either role), S14 (head-on) or S15 (crossing, either
    role). Naming (``docs/evaltool.md``, "Scores and penalties"): ``P_na_delta`` = P_Δ^¬ap, ``P_na_delta_chi`` =
    P_Δχ^¬ap, ``P_na_delta_u`` = P_ΔU^¬ap; ``P_x``, ``P_x_delta_chi``, ``P_x_delta_u_up``, ``P_x_delta_u_down`` and
    ``C_x_gw`` for the stand-on stages x = 2, 3; ``P_pt`` the stand-on port-turn penalty.
    """

    S_sit: float | None = None
    S13: float | None = None
    S14: float | None = None
    S15: float | None = None
    S16: float | None = None
    S17: float | None = None
    S_safety: float | None = None
    S_r: float | None = None
    S_theta: float | None = None
    S_alpha: float | None = None
    S_beta: float | None = None
    P_delay: float | None = None
    P_na_delta: float | None = None
    P_na_delta_chi: float | None = None
    P_na_delta_u: float | None = None
    P_nsb: float | None = None
    P_sts: float | None = None
    P_ah13: float | None = None
    P_ah15: float | None = None
    P_2: float | None = None
    P_2_delta_chi: float | None = None
    P_2_delta_u_up: float | None = None
    P_2_delta_u_down: float | None = None
    C_2_gw: float | None = None
    P_3: float | None = None
    P_3_delta_chi: float | None = None
    P_3_delta_u_up: float | None = None
    P_3_delta_u_down: float | None = None
    C_3_gw: float | None = None
    P_pt: float | None = None

    def to_dict(self) -> dict:
        return {f.name: _num(getattr(self, f.name)) for f in fields(self)}


#: The names of every score and penalty, in the order of :class:`EncounterScores`.
SCORE_NAMES = tuple(f.name for f in fields(EncounterScores))


@dataclass(frozen=True)
class Term:
    """One score or penalty of an encounter as the scoring computed it, with what made it fire.

    Attributes:
        name: the key in :class:`EncounterScores` (``"P_delay"``, ``"S_r"`` ...).
        value: its value (the same number as in the scores; None where the score does not apply).
        k: the sample index (evaluation grid) of the event that set it -- the manoeuvre start for P_delay,
            the sample of the largest course deviation for P_na_delta_chi ... -- or None when nothing fired.
        why: the condition that decided it, in words with the numbers used.
        data: the inputs of its formula (angles in degrees, ranges in metres, times in seconds).
    """

    name: str
    value: float | None
    k: int | None
    why: str
    data: dict = field(default_factory=dict)

    def to_dict(self, t: np.ndarray | None = None) -> dict:
        d = {"name": self.name, "value": _num(self.value), "k": None if self.k is None else int(self.k),
             "why": self.why, "data": {key: _jsonable(v) for key, v in self.data.items()}}
        if t is not None:
            d["t_s"] = None if self.k is None else float(t[self.k])
        return d


@dataclass(frozen=True)
class Encounter:
    """One encounter of vessel ``vessel`` (evaluated) with vessel ``other``.

    Attributes:
        vessel, other: names; vessel_index, other_index: their indices in the tracks.
        situation: ``OTSO``, ``OTGW``, ``HO``, ``CRGW``, ``CRSO`` or ``NAR`` (locked at the encounter start).
        status: one of :data:`STATUSES`.
        k_detect, k_start, k_cpa, k_end: sample indices (evaluation grid) of detection (range first within
            r_Stage2), encounter start (first classified sample), CPA, and end of the window (exclusive).
        t_detect, t_start, t_cpa: the times of those samples [s].
        r_detect: range at the encounter start (r_det) [m]; r_cpa: range at CPA [m].
        alpha_cpa, beta_cpa: contact angle and relative bearing at CPA [rad].
        stage_first_t: ``{2: t, 3: t, 4: t}`` first time in [k_start, k_cpa] at each stage reached [s].
        maneuver: the give-way manoeuvre that counts (first manoeuvre of ``vessel`` overlapping
            [k_start, k_cpa]), None if none or not give-way; r_maneuver its start range [m].
        dcpa_start: constant-velocity distance at CPA predicted at the encounter start [m].
        scores: :class:`EncounterScores`.
        terms: every score and penalty computed, as :class:`Term` (value, the sample that fired it, the
            condition), in the order the scoring computed them; the explanation of the score
            (:mod:`psbmpc_jax.evaltool.explain`).  Not part of :meth:`to_dict`.
    """

    vessel: str
    other: str
    vessel_index: int
    other_index: int
    situation: str
    status: str
    k_detect: int
    k_start: int
    k_cpa: int
    k_end: int
    t_detect: float
    t_start: float
    t_cpa: float
    r_detect: float
    r_cpa: float
    alpha_cpa: float
    beta_cpa: float
    dcpa_start: float
    stage_first_t: dict = field(default_factory=dict)
    maneuver: Maneuver | None = None
    r_maneuver: float | None = None
    scores: EncounterScores = field(default_factory=EncounterScores)
    terms: tuple = ()

    @property
    def score(self) -> float | None:
        """The situation score S_sit (None when not scored)."""
        return self.scores.S_sit

    def to_dict(self, t: np.ndarray | None = None) -> dict:
        return {
            "vessel": self.vessel, "other": self.other, "vessel_index": int(self.vessel_index),
            "other_index": int(self.other_index), "situation": self.situation, "status": self.status,
            "k_detect": int(self.k_detect), "k_start": int(self.k_start), "k_cpa": int(self.k_cpa),
            "k_end": int(self.k_end), "t_detect_s": _num(self.t_detect), "t_start_s": _num(self.t_start),
            "t_cpa_s": _num(self.t_cpa), "r_detect_m": _num(self.r_detect), "r_cpa_m": _num(self.r_cpa),
            "alpha_cpa_deg": _num(math.degrees(self.alpha_cpa)), "beta_cpa_deg": _num(math.degrees(self.beta_cpa)),
            "dcpa_start_m": _num(self.dcpa_start),
            "stage_first_t_s": {str(k): _num(v) for k, v in sorted(self.stage_first_t.items())},
            "maneuver": None if self.maneuver is None else self.maneuver.to_dict(t),
            "r_maneuver_m": _num(self.r_maneuver),
            "scores": self.scores.to_dict(),
        }


@dataclass(frozen=True, eq=False)          # holds arrays: compare fields explicitly
class Evaluation:
    """The evaluation of one set of tracks.

    Attributes:
        params: the parameters used.
        names: vessel names; own: the own-ship's index.
        t: the evaluation grid [s] (the tracks resampled at ``params.sample_interval_s``).
        pairs: ``"own"`` (own-ship against every other vessel) or ``"all"`` (every ordered pair).
        encounters: every encounter found, ordered by evaluated vessel, other vessel, time.
        maneuvers: per vessel name, the detected manoeuvres.
        source: where the tracks came from.
        resampled: the tracks on the evaluation grid (what was scored; for explanations and figures).
    """

    params: EvalParams
    names: tuple
    own: int
    t: np.ndarray
    pairs: str
    encounters: tuple
    maneuvers: dict
    source: str | None = None
    resampled: Tracks | None = None

    def of(self, vessel: str | None = None, other: str | None = None) -> list[Encounter]:
        """The encounters of ``vessel`` (default: the own-ship) with ``other`` (default: any)."""
        vessel = self.names[self.own] if vessel is None else vessel
        return [e for e in self.encounters if e.vessel == vessel and (other is None or e.other == other)]

    def to_dict(self) -> dict:
        """JSON-ready document: parameters, vessels, the grid, manoeuvres and every encounter."""
        return {
            "source": self.source, "own": self.names[self.own], "vessels": list(self.names), "pairs": self.pairs,
            "grid": {"t0_s": float(self.t[0]), "t_end_s": float(self.t[-1]), "n": int(self.t.size),
                     "dt_s": self.params.sample_interval_s},
            "params": self.params.as_dict(),
            "maneuvers": {name: [m.to_dict(self.t) for m in ms] for name, ms in self.maneuvers.items()},
            "encounters": [e.to_dict(self.t) for e in self.encounters],
        }


def _jsonable(v):
    """A JSON-ready copy of a term's datum: numbers through :func:`_num`, strings, bools and None as they are,
    lists element-wise."""
    if v is None or isinstance(v, (str, bool)):
        return v
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return _num(v)


def _num(v):
    """JSON-safe number: None stays None, NaN/inf become None, NumPy scalars become Python floats."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None
