"""argparse value types shared by the command-line modules: each raises an ArgumentTypeError saying what
is allowed."""

from __future__ import annotations

import argparse
import math


def _number(cast, text: str, what: str):
    try:
        return cast(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None


def positive_int(text: str) -> int:
    v = _number(int, text, "a positive integer")
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer (>= 1), got {v}")
    return v


def nonneg_int(text: str) -> int:
    v = _number(int, text, "an integer >= 0")
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {v}")
    return v


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
