"""The library's one status enum: unique codes, a name for each, and the solve/NLP constants drawn from it."""

import importlib
import pathlib
import re

import numpy as np
import pytest

import psbmpc_jax
from psbmpc_jax import nlp
from psbmpc_jax.status import STATUS_NAMES, Status, status_name

PACKAGE_DIR = pathlib.Path(psbmpc_jax.__file__).parent
solve_mod = importlib.import_module("psbmpc_jax.solve")    # the module (psbmpc_jax.solve is the function)


def test_codes_are_unique_and_named():
    codes = [int(s) for s in Status]                      # aliases (CONVERGED) are not listed by iteration
    assert len(codes) == len(set(codes)) == len(STATUS_NAMES)
    assert sorted(codes) == list(range(len(codes)))
    assert Status.CONVERGED is Status.OK
    assert len(set(STATUS_NAMES.values())) == len(STATUS_NAMES)


def test_solve_and_nlp_constants_come_from_the_enum():
    assert (solve_mod.STATUS_OK, solve_mod.STATUS_NO_FINITE_BEHAVIOUR, solve_mod.STATUS_INVALID_INPUT) == (
        Status.OK, Status.NO_FINITE_BEHAVIOUR, Status.INVALID_INPUT)
    assert (nlp.CONVERGED, nlp.MAX_ITER, nlp.INFEASIBLE, nlp.NON_FINITE) == (
        Status.OK, Status.MAX_ITER, Status.INFEASIBLE, Status.NON_FINITE)
    assert solve_mod.STATUS_NAMES is STATUS_NAMES and nlp.STATUS_NAMES is STATUS_NAMES
    assert psbmpc_jax.Status is Status


def test_status_name_of_stored_values():
    assert status_name(np.int32(0)) == "ok"
    assert status_name(np.array(3, np.int32)) == "max-iter"
    assert status_name(2).startswith("invalid input")
    with pytest.raises(ValueError, match=r"status code 6 is not one of \[0, 1, 2, 3, 4, 5\]"):
        status_name(6)


def test_no_second_status_table_in_the_package():
    """Only psbmpc_jax/status.py defines a status-name table or raw status codes."""
    pattern = re.compile(r"^\s*(STATUS_NAMES\s*=|STATUS_\w+\s*=\s*\d|(CONVERGED|MAX_ITER|INFEASIBLE|NON_FINITE)\s*=\s*\d)",
                         re.M)
    offenders = [str(p.relative_to(PACKAGE_DIR)) for p in PACKAGE_DIR.rglob("*.py")
                 if p.name != "status.py" and pattern.search(p.read_text())]
    assert offenders == []
