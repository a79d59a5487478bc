"""argparse value types shared by the command-line modules: each raises an ArgumentTypeError saying what
is allowed."""

from __future__ import annotations

import argparse
import math

#: Largest integer any option takes (stops 400-digit numbers before they reach an allocation).
MAX_INT = 1_000_000_000
#: Most Monte Carlo runs (``--runs``), as in scenario files (:data:`psbmpc_jax.scenario_checks.MAX_RUNS`).
MAX_RUNS = 10_000
#: Largest PRNG seed (``--seed``): 32 bits, as in scenario files.
MAX_SEED = 2 ** 32 - 1


def _number(cast, text: str, what: str):
    if len(text.strip()) > 40:
        raise argparse.ArgumentTypeError(f"expected {what}, got a {len(text.strip())}-character number")
    try:
        return cast(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None


def _at_most(v: int, hi: int, what: str) -> int:
    if v > hi:
        raise argparse.ArgumentTypeError(f"expected {what} <= {hi}, got {v}")
    return v


def positive_int(text: str) -> int:
    v = _number(int, text, "a positive integer")
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer (>= 1), got {v}")
    return _at_most(v, MAX_INT, "a positive integer")


def nonneg_int(text: str) -> int:
    v = _number(int, text, "an integer >= 0")
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {v}")
    return _at_most(v, MAX_INT, "an integer >= 0")


def runs_int(text: str) -> int:
    """Monte Carlo runs: an integer in 1..MAX_RUNS."""
    return _at_most(positive_int(text), MAX_RUNS, "a number of runs")


def seed_int(text: str) -> int:
    """A PRNG seed: an integer in 0..2**32 - 1."""
    v = _number(int, text, "an integer seed >= 0")
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer seed >= 0, got {v}")
    return _at_most(v, MAX_SEED, "an integer seed")


def devices_arg(text: str):
    """Local devices to split the runs over: a positive integer or ``all``."""
    if text.strip() == "all":
        return "all"
    try:
        return positive_int(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected a positive integer or 'all', got {text!r}"[:200]) from None


def odd_int(text: str) -> int:
    v = positive_int(text)
    if v % 2 == 0:
        raise argparse.ArgumentTypeError(f"n_ps must be odd, got {v}")
    return v


def positive_float(text: str) -> float:
    v = _number(float, text, "a number > 0")
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def nonneg_float(text: str) -> float:
    v = _number(float, text, "a number >= 0")
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return v
