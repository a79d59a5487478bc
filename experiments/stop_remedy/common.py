"""Shared pieces of the stop-remedy study: stop statistics computed from the true tracks, the recording of every
own-ship evaluation of a grid search, and targets whose true motion has constant-velocity process noise."""

from __future__ import annotations

import numpy as np

from psbmpc_jax.safe_io import atomic_write_text
from psbmpc_jax.sim.stops import stop_intervals

#: A ship is stopped while its speed over ground is at or below this [m/s] (the library's metrics use the same).
STOP_SPEED = 0.2
#: A behaviour stops when its first maneuver's speed factor is below this.
STOP_FACTOR = 0.05


def stop_stats(t, speed, threshold: float = STOP_SPEED) -> dict:
    """Stops of one track: ``count`` (maximal intervals with speed <= threshold), ``longest_s`` (the longest,
    measured as the time between its first and last stopped sample), ``first_t_s`` (start of the first) and
    ``stopped_s`` (total)."""
    iv = stop_intervals(t, speed, threshold, 0.0)          # every stretch, however short: the library's rule
    t, slow = np.asarray(t, float), np.asarray(speed, float) <= threshold
    return {"count": len(iv), "longest_s": float(max((b - a for a, b in iv), default=0.0)),
            "first_t_s": iv[0][0] if iv else None,
            "stopped_s": float(np.sum(slow) * (t[1] - t[0])) if len(t) > 1 else 0.0}


def write_record(out, doc: dict, script: str, argv, started_at: str, t_all: float) -> None:
    """Add the run's provenance (commit at the start, wall time, device, platform, versions, the command, UTC time)
    to ``doc`` and write it to ``out`` as JSON, atomically."""
    import datetime as dt
    import json
    import platform
    import sys
    import time

    import jax

    doc.update({"commit": started_at, "wall_s": round(time.perf_counter() - t_all, 1), "device": str(jax.devices()[0]),
                "platform": platform.platform(),
                "versions": {"python": sys.version.split()[0], "jax": jax.__version__, "numpy": np.__version__},
                "command": f"python experiments/stop_remedy/{script} "
                           + " ".join(argv if argv is not None else sys.argv[1:]),
                "utc": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")})
    atomic_write_text(out, json.dumps(doc, indent=1) + "\n")


def course_rate(t, chi) -> float:
    """Mean |dχ/dt| [deg/s] of a track (wrapped differences)."""
    d = np.angle(np.exp(1j * np.diff(np.asarray(chi, float))))
    return float(np.degrees(np.mean(np.abs(d) / np.diff(t))))


def min_target_distance(states) -> tuple[float, int]:
    """(closest approach [m] of the own-ship (ship 0) to any target, which target) of one run's ``[n, K+1, 4]``."""
    d = np.hypot(states[1:, :, 0] - states[0, None, :, 0], states[1:, :, 1] - states[0, None, :, 1])
    i = int(np.argmin(np.min(d, axis=1)))
    return float(np.min(d)), i + 1


class Recorder:
    """Patches :func:`psbmpc_jax.methods.grid.solve` (the loop-mode solve) to keep every evaluation of one ship
    index's solves: ``(total [B], costs {term: [B]}, details {name: array})`` as host float64 arrays, in call
    order.  Use with ``simulate(..., batch="loop")``.  ``details``: the detail names to keep."""

    def __init__(self, details=()):
        self.seen, self.details = [], tuple(details)

    def __enter__(self):
        import jax

        from psbmpc_jax.methods import grid

        self._grid, self._orig = grid, grid.solve

        def recording(*args, **kw):
            out = self._orig(*args, **kw)
            ev = out[2]
            self.seen.append((np.asarray(jax.device_get(ev.total), float),
                              {k: np.asarray(jax.device_get(v), float) for k, v in ev.costs.items()},
                              {k: np.asarray(jax.device_get(ev.details[k]), float) for k in self.details
                               if k in ev.details}))
            return out

        grid.solve = recording
        return self

    def __exit__(self, *exc):
        self._grid.solve = self._orig
        return False


def cv_noise_method(sigma_a: float = 0.03, name: str = "cv_noise"):
    """A target "controller" whose true motion is a constant-velocity model with process noise: at every MPC
    update (period Δ) its velocity takes a random step N(0, σ_a² Δ I₂) (white acceleration of strength σ_a
    integrated over the period) and is commanded as an absolute (speed, course); the ship's autopilot lags
    smooth it.  Run r, ship i draws from ``default_rng([seed, r, 4004, i])``.  Register the returned method
    (:func:`psbmpc_jax.methods.register`) and name it in ``colav``."""
    from psbmpc_jax.methods.base import COST_NAMES, Decision, Method

    class _Controller:
        uses_grid = False
        snapshots = False

        def __init__(self, ships, seed: int, period: float):
            self.ships, self.seed, self.period = tuple(ships), int(seed), float(period)
            self.v, self.rng = {}, {}

        def init(self, n_runs: int) -> None:
            self.v, self.rng = {}, {}

        def decide(self, obs):
            jobs = [(r, i) for r in range(obs.n_runs) for i in self.ships]
            cmd = np.zeros((len(jobs), 2))
            for n, (r, i) in enumerate(jobs):
                if (r, i) not in self.v:
                    x = obs.states[r, i]
                    self.v[(r, i)] = np.array([x[3] * np.cos(x[2]), x[3] * np.sin(x[2])])
                    self.rng[(r, i)] = np.random.default_rng([self.seed, r, 4004, i])
                else:
                    self.v[(r, i)] = self.v[(r, i)] + self.rng[(r, i)].normal(0.0, sigma_a * np.sqrt(self.period), 2)
                v = self.v[(r, i)]
                cmd[n] = (np.hypot(*v), np.arctan2(v[1], v[0]))
            return Decision(jobs=jobs, first=np.tile([1.0, 0.0], (len(jobs), 1)),
                            costs=np.full((len(jobs), len(COST_NAMES)), np.nan), walls=np.zeros(len(jobs)),
                            device_calls=0, wall=0.0, commands=cmd)

    class CvNoise(Method):
        description = f"constant velocity with process noise sigma_a = {sigma_a} m/s^2 (true motion of a target)"

        def build(self, scenario, ships, context):
            return _Controller(ships, scenario.seed, scenario.mpc.period)

        def record(self, scenario) -> dict:
            return {"sigma_a_mps2": sigma_a}

    CvNoise.name = name
    return CvNoise()
