"""Provenance of a result file: the source commit and the software versions it was produced with.

Shared by the benchmark harness (:mod:`psbmpc_jax.apps.bench`, ``benchmarks/``) and the simulator's outputs
(:mod:`psbmpc_jax.sim.output`).
"""

from __future__ import annotations

import os
import platform
import subprocess

import numpy as np


def commit() -> str:
    """``git rev-parse HEAD`` of the package's checkout (``-dirty`` with uncommitted changes to tracked
    files), or ``"unknown"`` outside a git checkout."""
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True, cwd=here)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, cwd=here).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def versions() -> dict:
    """``{"python", "jax", "jaxlib", "numpy"}`` version strings."""
    import jax

    try:
        import jaxlib

        jaxlib_v = jaxlib.__version__
    except (ImportError, AttributeError):
        jaxlib_v = "unknown"
    return {"python": platform.python_version(), "jax": jax.__version__, "jaxlib": jaxlib_v,
            "numpy": np.__version__}
