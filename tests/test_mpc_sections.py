"""MPCSpec.with_section (psbmpc_jax/scenario/schema.py): the one way code (the experiment scripts, a user's
sweep) replaces fields of a method's settings section after loading a scenario."""

from __future__ import annotations

import dataclasses
import pathlib
import re

import pytest

from psbmpc_jax.scenario import load_scenario

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_with_section_replaces_only_the_named_fields():
    sc = load_scenario("tengesdal2020_a", method="sbmpc")
    before = sc.mpc.sbmpc
    field = dataclasses.fields(before)[0].name
    value = getattr(before, field)
    changed = sc.mpc.with_section("sbmpc", **{field: value})
    assert changed.sbmpc == before and changed is not sc.mpc
    other = next(f for f in dataclasses.fields(before) if isinstance(getattr(before, f.name), float))
    new = sc.mpc.with_section("sbmpc", **{other.name: getattr(before, other.name) * 2})
    assert getattr(new.sbmpc, other.name) == 2 * getattr(before, other.name)
    assert getattr(sc.mpc.sbmpc, other.name) == getattr(before, other.name)      # the original untouched
    for f in dataclasses.fields(before):
        if f.name != other.name:
            assert getattr(new.sbmpc, f.name) == getattr(before, f.name)


def test_with_section_refuses_unknown_sections_and_fields():
    mpc = load_scenario("tengesdal2020_a", method="sbmpc").mpc
    with pytest.raises(ValueError, match="no section 'nope'"):
        mpc.with_section("nope", x=1)
    with pytest.raises(TypeError):
        mpc.with_section("sbmpc", not_a_field=1)


def test_no_experiment_script_replaces_a_section_by_attribute():
    """``dataclasses.replace(mpc, smooth=...)`` fails since the sections moved into ``MPCSpec.sections``; three
    experiment scripts broke that way unnoticed.  They go through ``with_section``."""
    pattern = re.compile(r"replace\(\s*\w+\.mpc\s*,\s*(?!(?:preset|config|params|behaviours|n_ps|period|method|sections|given|given_params)=)\w+=")
    offenders = [str(p.relative_to(ROOT)) for p in (ROOT / "experiments").rglob("*.py")
                 if pattern.search(p.read_text())]
    assert offenders == []
