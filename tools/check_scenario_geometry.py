#!/usr/bin/env python
"""Geometry check of closed-loop scenario files: route clearance to land and nominal CPAs.

The logic lives in :mod:`psbmpc_jax.scenario_checks` (the loader ``psbmpc_jax.scenario.load_scenario`` applies
its land checks to every file it loads).  This script prints, per file,

* the report of :func:`psbmpc_jax.scenario_checks.route_clearances` (read from the YAML directly, so it also
  reports on files the loader refuses): per ship whether the start is in water, its distance to land, the
  minimum distance to land of every leg of its route (start prepended unless within 1 m of the first
  waypoint), the part of the route's extension beyond the last waypoint covered within
  ``simulation.duration_s`` at nominal speed; per pair of ships the nominal closest point of approach;
* the loader's verdict: ``loader: ok`` or the ``ValueError`` that ``load_scenario`` raises (a ship starting
  on land, a waypoint or leg through land, ships starting too close, sizes above the limits), and its
  warnings.

Usage::

    python tools/check_scenario_geometry.py                      # the built-in nidelva and sakshaug files
    python tools/check_scenario_geometry.py path/to/scenario.yaml ...

Exit status 1 if the loader refuses any file.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import warnings

from psbmpc_jax.scenario_checks import check_file, format_report, route_clearances  # noqa: F401 (re-exported)

REPO = pathlib.Path(__file__).resolve().parents[1]
SCENARIO_DIR = REPO / "psbmpc_jax" / "scenarios"
DEFAULT_FILES = (SCENARIO_DIR / "nidelva.yaml", SCENARIO_DIR / "sakshaug.yaml")


def loader_verdict(path) -> tuple[bool, str]:
    """(ok, text): what ``load_scenario`` says about the file (its error, or ok and its warnings)."""
    from psbmpc_jax.scenario import load_scenario

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            load_scenario(pathlib.Path(path))
        except ValueError as exc:
            return False, f"loader: REFUSED: {exc}"
    lines = ["loader: ok"] + [f"  warning: {w.message}" for w in caught]
    return True, "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", help="scenario YAML files (default: the nidelva and sakshaug files)")
    args = ap.parse_args(argv)
    status = 0
    for f in args.files or DEFAULT_FILES:
        print(f"== {f}")
        print(format_report(check_file(f)))
        ok, text = loader_verdict(f)
        print(text)
        status = status or (0 if ok else 1)
    return status


if __name__ == "__main__":
    sys.exit(main())
