"""Top level: evaluate recorded tracks (:func:`evaluate_tracks`) or a trajectory file (:func:`evaluate_file`)."""

from __future__ import annotations

from .encounters import PairContext, dcpa, find_windows, score_window
from .geometry import GIVE_WAY, pair_geometry, stages
from .maneuvers import detect_maneuvers
from .params import EvalParams, get_params
from .results import Evaluation
from ..limits import check_evaluation, check_evaluation_time, evaluation_samples
from .tracks import Tracks, check_units, own_index, load_runs

__all__ = ["evaluate_tracks", "evaluate_file", "PAIR_MODES", "run_shapes"]

#: ``own``: the own-ship against every other vessel; ``all``: every ordered pair (i, j), i != j.
PAIR_MODES = ("own", "all")


def _pairs(n_vessels: int, own: int, mode: str) -> list[tuple[int, int]]:
    if mode == "own":
        return [(own, j) for j in range(n_vessels) if j != own]
    return [(i, j) for i in range(n_vessels) for j in range(n_vessels) if i != j]


def run_shapes(runs, dt: float) -> list[tuple[int, int]]:
    """``(samples, vessels)`` of every :class:`Tracks` of ``runs`` resampled every ``dt`` seconds (what
    :func:`psbmpc_jax.limits.check_evaluation_time` estimates the time of)."""
    return [(evaluation_samples(float(tr.t[-1] - tr.t[0]), dt), tr.n_vessels) for tr in runs]


def evaluate_tracks(tracks: Tracks, params: EvalParams | str | None = "default", *, own=None,
                    pairs: str = "own", **overrides) -> Evaluation:
    """Score every encounter in ``tracks`` (``docs/evaltool.md``, "What is computed").

    Args:
        tracks: the recorded tracks (:class:`Tracks`; uniform or not in time: they are resampled onto a grid
            of ``params.sample_interval_s``).
        params: an :class:`EvalParams`, or a preset name (``"default"``, ``"inland_small"``).
        own: the own-ship (name or index; default ``tracks.own``).
        pairs: ``"own"`` scores the own-ship against each other vessel; ``"all"`` scores every ordered pair
            (each vessel against each other one).
        **overrides: parameter fields to change (``r_stage2_m=100`` ...).

    Returns:
        :class:`Evaluation` with one :class:`Encounter` per entry of a pair into the stage-2 range.

    Raises:
        ValueError: invalid parameters, own-ship, pair mode, tracks shorter than one sample interval, or tracks
            whose units are implausible (:func:`psbmpc_jax.evaltool.tracks.check_units`: speeds above 100 m/s,
            latitude/longitude in degrees read as metres).
        psbmpc_jax.limits.ResourceError: the resampled tracks would need more memory than the limit
            (:func:`psbmpc_jax.limits.check_evaluation`), or scoring them would take longer than the time limit
            (:func:`psbmpc_jax.limits.check_evaluation_time`), checked before anything is allocated.
    """
    p = get_params(params, **overrides)
    if pairs not in PAIR_MODES:
        raise ValueError(f"pairs must be one of {PAIR_MODES}, got {pairs!r}")
    own_i = tracks.own if own is None else own_index(own, tracks.names)
    check_units(tracks)
    # the memory of the resampled tracks and of every pair's geometry, before any of it is allocated
    check_evaluation(float(tracks.t[-1] - tracks.t[0]), p.sample_interval_s, tracks.n_vessels, pairs,
                     setting=f"evaluation of {tracks.source or 'tracks'}: sample_interval_s")
    check_evaluation_time(run_shapes([tracks], p.sample_interval_s), pairs,
                          what=f"evaluation of {tracks.source or 'tracks'}",
                          sample_interval=f"sample_interval_s = {p.sample_interval_s:g} s")
    tr = tracks.resample(p.sample_interval_s)
    dt = p.sample_interval_s
    man = [detect_maneuvers(tr.course[v], tr.speed[v], dt, p) for v in range(tr.n_vessels)]

    # pass 1: the encounter windows of every ordered pair needed (the own-ship's with every vessel, for C_x,gw)
    wanted = _pairs(tr.n_vessels, own_i, pairs)
    geo, windows = {}, {}
    for i, j in wanted:
        g = pair_geometry(tr.north, tr.east, tr.course, tr.speed, i, j, p)
        geo[i, j] = g
        windows[i, j] = find_windows(g, tr.speed[i], tr.speed[j], i, j, p)
    give_way_spans: dict[int, list[tuple[int, int, int]]] = {i: [] for i in range(tr.n_vessels)}
    for (i, j), ws in windows.items():
        give_way_spans[i] += [(j, w.k_s, w.k_c) for w in ws if w.complete and w.situation in GIVE_WAY]

    # pass 2: score
    encounters = []
    for i, j in wanted:
        g = geo[i, j]
        st = stages(g.r, p)
        for w in windows[i, j]:
            spans = [(tr.names[other], a, b) for other, a, b in give_way_spans[i] if other != j]
            ctx = PairContext(w=w, g=g, stage=st, course=tr.course[i], speed=tr.speed[i], maneuvers=man[i],
                       give_way_spans=spans, p=p)
            d = dcpa(tr.north, tr.east, tr.course, tr.speed, i, j, w.k_s)
            encounters.append(score_window(ctx, tr.names, tr.t, d))
    return Evaluation(params=p, names=tr.names, own=own_i, t=tr.t, pairs=pairs, encounters=tuple(encounters),
                      maneuvers={tr.names[v]: tuple(man[v]) for v in range(tr.n_vessels)}, source=tracks.source,
                      resampled=tr)


def evaluate_file(path, params: EvalParams | str | None = "default", *, own=None, pairs: str = "own",
                  dt: float | None = None, **overrides) -> list[Evaluation]:
    """Evaluate every run of a trajectory file (a user CSV, an AIS-style CSV, or the simulator's
    ``trajectories.npz`` / ``.csv`` or its output folder; see :func:`psbmpc_jax.evaltool.load_runs`, which
    ``own`` and ``dt`` are passed to): one :class:`Evaluation` per run (a CSV has one).  The time of scoring
    every run is checked before the first is scored (:func:`psbmpc_jax.limits.check_evaluation_time`)."""
    p = get_params(params, **overrides)
    if pairs not in PAIR_MODES:
        raise ValueError(f"pairs must be one of {PAIR_MODES}, got {pairs!r}")
    runs = load_runs(path, own=own, dt=dt)
    check_evaluation_time(run_shapes(runs, p.sample_interval_s), pairs, what=f"evaluation of {path}",
                          sample_interval=f"sample_interval_s = {p.sample_interval_s:g} s")
    return [evaluate_tracks(tr, p, pairs=pairs) for tr in runs]
