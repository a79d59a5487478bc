"""The ship a tuning was made for (:class:`DesignShip`): the methods' default settings
(:attr:`psbmpc_jax.methods.Method.design_ship`) and the MPC presets (:attr:`psbmpc_jax.presets.MPCPreset.design_ship`)
state it, and a scenario whose ships lie outside it is refused at load
(:meth:`psbmpc_jax.methods.Method.check_fit`).  No package imports: the presets and the method protocol both
read it."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DesignShip", "SCALE_PARAMS"]

#: The PSB-MPC parameters (fields of :class:`psbmpc_jax.params.Params`) that depend on the ship's scale: the
#: distances in metres (safety zone ``d_safe``, scenario spacing ``r_ct``, COLREGS range ``d_close``, the LOS
#: lookahead and acceptance radius of the own-ship and the obstacles) and the time constants of the kinematic
#: prediction in seconds (course and speed, own-ship and obstacles).  They are the parameters the presets made
#: for another ship than the default's (``tengesdal2020``, ``akdag2022``) change.  A scenario that runs the
#: grid search (``psbmpc``, ``psbmpc_refine``) on a ship outside its preset's design ship has tuned the preset
#: for its ship only when its ``mpc.params`` give every one of them; other keys (``K_coll``, ``K_chi_port``, ...)
#: are weights that do not carry the scale (:meth:`psbmpc_jax.methods.Method.untuned`).
SCALE_PARAMS: tuple[str, ...] = ("d_safe", "r_ct", "d_close", "os_lookahead", "ob_lookahead", "os_R_a", "ob_R_a",
                                 "os_T_chi", "os_T_U", "ob_T_chi", "ob_T_U")


@dataclass(frozen=True)
class DesignShip:
    """The ship a tuning (a method's default settings, an MPC preset) was made for, and the ships it is taken
    to fit.

    Distances in a method's settings (safety zones, COLREGS ranges, corridors, route-exchange ranges) are in
    metres of its design ship's scale, and its times and speed bounds follow the design speed.  The rule
    (the same for every method): the defaults fit a ship whose length and cruise speed are each within a
    factor :attr:`factor` (3) of the design ship's, and whose cruise speed lies in ``speed_range`` when one is
    given (a bound the cost drives the ship to, e.g. the two-level method's U_max).  A scenario that gives the
    method's own section (:attr:`psbmpc_jax.methods.Method.tuning_sections`; for the grid search, whose tuning
    is the preset, every one of :data:`SCALE_PARAMS` under ``mpc.params``) has tuned it and is not checked.

    Attributes:
        length_m, speed_mps: the design ship's length [m] and cruise speed [m/s]; None where the source names
            no length (or no speed, and no ``speed_range`` is given): that side is not compared.
        source: where the tuning comes from (paper by authors and year, or "our proposal ...").
        factor: the fit factor (> 1).
        speed_range: an explicit (lowest, highest) cruise speed [m/s] that replaces the factor rule for speed.
    """

    length_m: float | None
    speed_mps: float | None
    source: str
    factor: float = 3.0
    speed_range: tuple | None = None

    def misfit(self, length: float, speed: float) -> str | None:
        """Why a ship of ``length`` [m] at cruise speed ``speed`` [m/s] is outside the fit, or None."""
        why = []
        if self.length_m is not None:
            lo_l, hi_l = self.length_m / self.factor, self.length_m * self.factor
            if length > 0 and not lo_l <= length <= hi_l:     # a point target (length 0) has no scale to compare
                why.append(f"length {length:g} m outside {lo_l:.3g}-{hi_l:.3g} m")
        speeds = self.speed_range or (None if self.speed_mps is None else
                                      (self.speed_mps / self.factor, self.speed_mps * self.factor))
        if speeds is not None:
            lo_u, hi_u = speeds
            if not lo_u <= speed <= hi_u:
                why.append(f"cruise speed {speed:g} m/s outside {lo_u:.3g}-{hi_u:.3g} m/s")
        return "; ".join(why) or None
