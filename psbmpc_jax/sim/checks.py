"""Host-side argument checks shared by the simulation modules."""

from __future__ import annotations

import math


def positive_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    """``value`` as a float that is finite and > 0 (>= 0 with ``allow_zero``); ValueError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a finite real number, got {value!r}") from exc
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {bound}, got {value!r}")
    return v
